"""Drawings as designs: an SVG drawing or a FOLD crease pattern, with a film, on the printer's grid.

The film's parameters (h, R or d, a deformation model, the process variables) are not decided
here: every function takes ``make(top, bottom, pixel, film) -> Design``, the caller's way of
turning face masks into a design. The readers of ``[svg]`` and ``[fold]`` tables and of ``.svg``
and ``.fold`` files alone register with :func:`gdfe.design.register_design_reader`, so that
:func:`gdfe.load_design` hands them the same :class:`gdfe.design.DesignSource` as every other
source (its :meth:`~gdfe.design.DesignSource.masks_design` is their ``make``).

All lengths in millimetres.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_keys, check_positive
from gdfe.design import register_design_reader
from gdfe.fabrication.fold import fold_masks, read_fold
from gdfe.fabrication.svg import svg_masks

__all__ = ["svg_design_with", "fold_design_with", "drawing_design", "load_drawing", "DRAWING_SUFFIXES",
           "DRAWING_KEYS"]

#: Files that :func:`gdfe.load_design` reads as drawings.
DRAWING_SUFFIXES = (".svg", ".fold")
#: The keys of a design file's ``[svg]`` and ``[fold]`` tables.
DRAWING_KEYS = {"svg": ("file", "pixel", "by"), "fold": ("file", "pixel", "hinge_width", "scale")}


def svg_design_with(make, path, pixel, by="layer", colours=None):
    """The design of an SVG drawing (:func:`gdfe.fabrication.svg_masks`), its film by ``make``.

    The design's points are placed where the film is on the page (mm, y up from the page's bottom).
    """
    m = svg_masks(path, pixel, by=by, colours=colours)
    des = make(m.top, m.bottom, m.pixel, None if m.film.all() else m.film)
    des.mesh.points[:, :2] += m.origin
    des.meta.update(kind="svg", source=str(path), pixel_mm=m.pixel, faces_by=by, svg_shapes=m.shapes)
    return des


def fold_design_with(make, path, pixel=None, hinge_width=None, scale=None, scale_name="scale"):
    """The design of a FOLD crease pattern (:func:`gdfe.fabrication.fold_masks`), its film by ``make``.

    The contraction ratio and thickness that turn fold angles into hinge widths (Eq. 2) are
    those ``make`` gives a cell coated on its bottom face only. Regions: ``hinge_E`` for the
    crease of edge E, ``face_K`` for the panel of face K, ``panels`` for all of them;
    ``meta["hinges"]`` lists the creases.
    """
    cp = read_fold(path, scale=scale, scale_name=scale_name)
    pixel = check_positive("pixel", pixel if pixel is not None else cp.keys.get("gdfe:pixel", 0.1))
    probe = make(np.array([[False]]), np.array([[True]]), pixel, None)  # one hinge cell: its R and h
    fm = fold_masks(cp, pixel, float(probe.R[0]), float(probe.h), hinge_width=hinge_width)
    des = make(fm.top, fm.bottom, pixel, None if fm.film.all() else fm.film)
    des.mesh.points[:, :2] += fm.origin
    i, j = des.mesh.cell_ij.T
    for rec in fm.hinges:
        des.regions[f"hinge_{rec['edge']}"] = np.nonzero(fm.owner[i, j] == rec["edge"])[0]
    for k, mask in fm.faces.items():
        des.regions[f"face_{k}"] = np.nonzero(mask[i, j])[0]
    des.regions["panels"] = np.nonzero(fm.owner[i, j] < 0)[0]
    des.meta.update(kind="fold", source=str(path), pixel_mm=pixel, hinges=fm.hinges)
    return des


def drawing_design(kind, spec, toml_path, make):
    """The design of a design file's ``[svg]`` or ``[fold]`` table.

    ``[svg]``: ``file`` (relative to the design file), ``pixel`` [mm], optional ``by``
    (``"layer"`` or ``"colour"``). ``[fold]``: ``file``, optional ``pixel`` [mm] (default the
    file's ``gdfe:pixel``, else 0.1), ``hinge_width`` [mm], ``scale`` [mm per unit].

    Parameters
    ----------
    kind : {"svg", "fold"}
    spec : dict
        The table.
    toml_path : Path
        The design file (for relative paths and messages).
    make : callable
        ``make(top, bottom, pixel, film) -> Design``: the design file's ``[film]`` applied
        to masks (``film`` None for the whole rectangle).
    """
    toml_path = Path(toml_path)
    name = toml_path.name
    if not isinstance(spec, dict):
        raise GdfeError(f"{name}: [{kind}]: expected a table")
    check_keys(f"{name}: [{kind}]", spec, DRAWING_KEYS[kind])
    if not isinstance(spec.get("file"), str) or not spec.get("file"):
        raise GdfeError(f"{name}: [{kind}] file: expected the path of the drawing, got {spec.get('file')!r}")
    src = toml_path.parent / spec["file"]
    try:
        if kind == "svg":
            if "pixel" not in spec:
                raise GdfeError("[svg] is missing 'pixel'")
            return svg_design_with(make, src, spec["pixel"], by=spec.get("by", "layer"))
        return fold_design_with(make, src, pixel=spec.get("pixel"), hinge_width=spec.get("hinge_width"),
                                scale=spec.get("scale"), scale_name="[fold] scale")
    except GdfeError as exc:
        raise type(exc)(f"{name}: {exc}") from None


def _make(source):
    """``make(top, bottom, pixel, film)`` of a design source: its film, model and process variables."""
    def make(top, bottom, pixel, film):
        return source.masks_design(top, bottom, pixel, film=film)
    return make


def _read_table(source):
    return drawing_design(source.kind, source.table, source.path, _make(source))


def _read_svg(source):
    if source.table is not None:
        return _read_table(source)
    return svg_design_with(_make(source), source.path, DEFAULT_PIXEL)


def _read_fold(source):
    if source.table is not None:
        return _read_table(source)
    return fold_design_with(_make(source), source.path, scale_name=None)


#: The pixel of an SVG drawing read alone [mm] (a design file's ``[svg]`` gives its own).
DEFAULT_PIXEL = 0.1


def load_drawing(path, from_masks=None, model=None, process=None):
    """A design from an SVG drawing or a FOLD file alone, with the paper's film.

    The film is the paper's (:func:`gdfe.design.paper_film`: h = 0.29 mm, d = 0.33 mm, R by
    Eq. 3, or by ``model`` from that d), one cell through its thickness; SVG drawings are
    rasterised at 0.1 mm, FOLD files at their ``gdfe:pixel`` (else 0.1 mm). A design file
    (TOML) with an ``[svg]`` or ``[fold]`` table gives every choice instead. The same as
    :func:`gdfe.load_design` of the file.

    Parameters
    ----------
    path : str or Path
        The ``.svg`` or ``.fold`` file.
    from_masks : callable, optional
        Not used (kept for the callers of an earlier release): the film is applied by the
        registered reader.
    model : DeformationModel or path of a model file, optional
        A deformation model in place of Eq. 3.
    process : dict, optional
        The part's process variables, for the model's process mechanisms.

    Returns
    -------
    design : Design
    options : dict
        Empty (no ``[simulate]`` options).
    """
    from gdfe.design import load_design

    path = Path(path)
    if path.suffix.lower() not in DRAWING_SUFFIXES:
        raise GdfeError(f"drawing: expected a {' or '.join(DRAWING_SUFFIXES)} file, got {path.name!r}")
    return load_design(path, model=model, process=process)


register_design_reader("svg", _read_svg, keys=DRAWING_KEYS["svg"], required=("file", "pixel"), suffixes=(".svg",))
register_design_reader("fold", _read_fold, keys=DRAWING_KEYS["fold"], required=("file",), suffixes=(".fold",))
