"""Designs of drawings with a film given by its numbers: :func:`svg_design`, :func:`fold_design`.

Both apply :func:`gdfe.from_masks` with ``h`` and ``R`` (or ``d`` by Eq. 3; the paper's
h = 0.29 mm and d = 0.33 mm by default) to the masks of :mod:`gdfe.fabrication.drawings`.
"""

from __future__ import annotations

from gdfe.design import from_masks
from gdfe.fabrication._film import film_ratio
from gdfe.fabrication.drawings import fold_design_with, svg_design_with

__all__ = ["svg_design", "fold_design", "crease_angles"]


def _maker(h, R, d, nz, isotropy):
    h, R, d = film_ratio(h=h, R=R, d=d)

    def make(top, bottom, pixel, film):
        des = from_masks(top, bottom, pixel, R, h=h, nz=nz, isotropy=isotropy, film=film)
        des.meta["d_mm"] = d
        return des

    return make


def svg_design(path, pixel, R=None, h=None, d=None, nz=1, isotropy=1.0, by="layer", colours=None):
    """A design from an SVG drawing of the coating of each face (:func:`gdfe.fabrication.svg_masks`).

    Parameters
    ----------
    path : str or Path
    pixel : float [mm]
        Printer pixel: the in-plane cell size.
    R : float, optional
        Contraction ratio of the free faces; default from Eq. 3 with ``d``.
    h : float [mm], optional
        Film thickness (default the paper's 0.29 mm).
    d : float [mm], optional
        Passive-layer thickness for R by Eq. 3 (default the paper's 0.33 mm).
    nz, isotropy :
        See :func:`gdfe.from_masks`.
    by, colours :
        How faces are told apart (:mod:`gdfe.fabrication.svg`).

    Returns
    -------
    Design
    """
    return svg_design_with(_maker(h, R, d, nz, isotropy), path, pixel, by=by, colours=colours)


def fold_design(path, pixel=None, R=None, h=None, d=None, hinge_width=None, nz=1, isotropy=1.0, scale=None):
    """A design from a FOLD crease pattern: creases become hinges, faces rigid panels.

    Parameters
    ----------
    path : str or Path
        The ``.fold`` file.
    pixel : float [mm], optional
        Printer pixel (default the file's ``gdfe:pixel``, else 0.1 mm).
    R, h, d :
        The film, as for :func:`svg_design`.
    hinge_width : float [mm], optional
        Width of creases without their own (:mod:`gdfe.fabrication.fold`).
    nz, isotropy :
        See :func:`gdfe.from_masks`.
    scale : float [mm per unit], optional
        For unit-less files.

    Returns
    -------
    Design
        Regions ``hinge_E``, ``face_K`` and ``panels``; ``meta["hinges"]`` lists the creases.
    """
    return fold_design_with(_maker(h, R, d, nz, isotropy), path, pixel=pixel, hinge_width=hinge_width, scale=scale)


def crease_angles(result, design=None):
    """Fold angle of every crease of a FOLD design: the rotation between the two faces it joins.

    Each face's best rotation from the flat print to the shape (:func:`gdfe.rigid_align` of
    its panel's vertices) gives the relative rotation of the two faces; its angle is the fold
    (0 flat, pi folded flat onto itself).

    Parameters
    ----------
    result : gdfe.Result or (n, 3) float array [mm]
    design : Design, optional
        The design of :func:`fold_design` (or a design file's ``[fold]``), when ``result``
        is an array.

    Returns
    -------
    list of dict
        Per crease joining two faces: ``edge``, ``faces``, ``angle_rad`` (simulated, >= 0)
        and ``eq2_rad``, the fold that Eq. 2 gives a fully contracting hinge of its width.
    """
    import math

    import numpy as np

    from gdfe._validation import GdfeError
    from gdfe.measure import rigid_align

    if design is None:
        design, points = result.design, result.points
    else:
        points = np.asarray(result, float)
    hinges = design.meta.get("hinges")
    if design.meta.get("kind") != "fold" or hinges is None:
        raise GdfeError("design: expected a design made from a FOLD crease pattern (meta kind 'fold')")
    flat = design.mesh.points
    rot = {}
    out = []
    for h in hinges:
        if len(h.get("faces", [])) != 2:
            continue
        Qs = []
        for k in h["faces"]:
            if k not in rot:
                vid = np.unique(design.mesh.cells[design.region_cells(f"face_{k}")])
                rot[k] = rigid_align(flat[vid], points[vid])[0]
            Qs.append(rot[k])
        rel = Qs[0].T @ Qs[1]
        angle = math.acos(float(np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0)))
        out.append({"edge": h["edge"], "faces": list(h["faces"]), "angle_rad": angle,
                    "eq2_rad": abs(float(h["angle_rad"])), "width_mm": float(h["width_mm"])})
    return out
