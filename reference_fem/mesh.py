"""Hexahedral meshes of layered strips: the paper's hinge specimen, free bilayers, freeform strips.

A strip runs along x and is made of segments; each segment says which faces of the film carry the
passive coat:

=========  ==========================  ===========================================
coating    passive material on         what the film does on heating
=========  ==========================  ===========================================
``both``   bottom and top face         panel (passive/active/passive): shrinks, stays flat
``top``    top face only               bilayer: curls towards the free bottom face (-z)
``bottom`` bottom face only            bilayer: curls towards the free top face (+z)
``none``   neither                     bare film: shrinks in-plane
=========  ==========================  ===========================================

Through the thickness the film occupies ``0 <= z <= h``, the bottom coat ``-d <= z <= 0`` and the
top coat ``h <= z <= h + d``; a ply is meshed only where a segment has it. Every ply has
``layers_per_ply >= 2`` elements through its thickness.

The strip is uniform across its width, so only ``y >= 0`` is meshed (the plane ``y = 0`` is a
symmetry plane). When the segments are mirror-symmetric about the middle of the strip (the hinge,
the free bilayer) only ``x >= 0`` is meshed as well (``symmetry="xy"``). The x origin is the
middle of the strip.

All lengths in mm.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gdfe import _validation as v
from gdfe._validation import GdfeError
from gdfe.paper import H as PAPER_H

__all__ = ["Segment", "LayeredStrip", "layered_strip", "hinge_mesh", "strip_mesh",
           "HINGE_RESOLUTIONS", "BOTTOM_COAT", "FILM", "TOP_COAT"]

#: Ply codes of :attr:`LayeredStrip.ply`.
BOTTOM_COAT, FILM, TOP_COAT = 0, 1, 2
_COATINGS = {"both": (True, True), "top": (False, True), "bottom": (True, False),
             "none": (False, False)}


@dataclasses.dataclass(frozen=True)
class Segment:
    """A piece of the strip along x.

    Parameters
    ----------
    length : float [mm]
        Extent along x, > 0.
    coating : {"both", "top", "bottom", "none"}
        Faces of the film covered by passive material.
    """

    length: float
    coating: str = "both"

    def __post_init__(self):
        object.__setattr__(self, "length", v.check_positive("segment length", self.length))
        v.check_choice("coating", self.coating, set(_COATINGS))


@dataclasses.dataclass
class LayeredStrip:
    """A meshed layered strip.

    Attributes
    ----------
    mesh : skfem.MeshHex
        Trilinear hexahedral mesh of the meshed part (``y >= 0``, and ``x >= 0`` for ``"xy"``) [mm].
    ply : (n_elements,) int array
        :data:`BOTTOM_COAT`, :data:`FILM` or :data:`TOP_COAT` for each element.
    segments : tuple of Segment
        The strip from its left end (``x = -length / 2``) to its right end.
    h, d, width : float [mm]
        Film thickness, coat thickness, full width of the strip.
    symmetry : {"xy", "y"}
        Symmetry planes of the model: ``x = 0`` and ``y = 0``, or ``y = 0`` only.
    x_edges : (len(segments) + 1,) float array [mm]
        Segment boundaries along x.
    meta : dict
        What the strip was made from (kind, hinge length, ...).
    """

    mesh: object
    ply: np.ndarray
    segments: tuple
    h: float
    d: float
    width: float
    symmetry: str
    x_edges: np.ndarray
    meta: dict = dataclasses.field(default_factory=dict)

    @property
    def length(self) -> float:
        """Full length of the strip along x [mm]."""
        return float(self.x_edges[-1] - self.x_edges[0])

    @property
    def z_mid(self) -> float:
        """Height of the film's mid-plane [mm], the line on which angles and curvatures are read."""
        return 0.5 * self.h

    @property
    def n_elements(self) -> int:
        return int(self.mesh.t.shape[1])

    def segment_of(self, x) -> np.ndarray:
        """Index of the segment containing each reference x (full-strip coordinates) [mm]."""
        x = np.asarray(x, dtype=float)
        return np.clip(np.searchsorted(self.x_edges, x, side="right") - 1, 0, len(self.segments) - 1)

    def summary(self) -> dict:
        return {"length_mm": self.length, "width_mm": self.width, "h_mm": self.h, "d_mm": self.d,
                "symmetry": self.symmetry, "n_elements": self.n_elements,
                "segments": [(s.length, s.coating) for s in self.segments], **self.meta}


def layered_strip(segments, h, d, *, width=1.0, element_size=0.25, layers_per_ply=2,
                  junction_size=None, z_ratio=1.0, symmetry=None, meta=None) -> LayeredStrip:
    """Mesh a strip made of coated segments.

    Parameters
    ----------
    segments : sequence of Segment or (length, coating) pairs
        The strip from left to right.
    h : float [mm]
        Film (active layer) thickness, > 0.
    d : float [mm]
        Passive coat thickness, > 0.
    width : float [mm]
        Full width of the strip, > 0.
    element_size : float [mm]
        Target in-plane element edge length, > 0; each segment gets at least two elements along x.
    layers_per_ply : int
        Elements through the thickness of each ply, >= 2. The film gets the next even number so
        that its mid-plane is a node plane.
    junction_size : float [mm], optional
        Element length along x at a junction, where a coat starts or ends (a stress
        concentration); elements grow geometrically (ratio <= 1.5) from there to
        ``element_size``. Default: ``element_size`` (no grading).
    z_ratio : float
        Ratio of successive layer thicknesses in a ply, growing away from the film's faces
        (1: uniform).
    symmetry : {"xy", "y"}, optional
        ``"xy"`` meshes a quarter; it needs mirror-symmetric segments. Default: ``"xy"`` when the
        segments are mirror-symmetric, else ``"y"``.
    meta : dict, optional
        Stored in :attr:`LayeredStrip.meta`.

    Returns
    -------
    LayeredStrip
    """
    from skfem import MeshHex

    segs = tuple(s if isinstance(s, Segment) else Segment(*s) for s in segments)
    if not segs:
        raise GdfeError("segments: expected at least one segment, got none")
    h = v.check_positive("h", h)
    d = v.check_positive("d", d)
    width = v.check_positive("width", width)
    size = v.check_positive("element_size", element_size)
    nply = v.check_int("layers_per_ply", layers_per_ply, minimum=2)
    mirror = all(a.length == b.length and a.coating == b.coating for a, b in zip(segs, segs[::-1]))
    if symmetry is None:
        symmetry = "xy" if mirror else "y"
    v.check_choice("symmetry", symmetry, {"xy", "y"})
    if symmetry == "xy" and not mirror:
        raise GdfeError("symmetry: 'xy' expected segments that are mirror-symmetric about the middle, "
                         f"got {[(s.length, s.coating) for s in segs]}")

    lengths = np.array([s.length for s in segs])
    edges = np.concatenate([[0.0], np.cumsum(lengths)])
    edges -= 0.5 * edges[-1]
    # x nodes: every segment boundary, the middle for the quarter model
    cuts = edges if symmetry == "y" else np.unique(np.concatenate([edges[edges > 0], [0.0]]))
    junctions = [e for i, e in enumerate(edges[1:-1], 1) if segs[i - 1].coating != segs[i].coating]
    fine = size if junction_size is None else v.check_positive("junction_size", junction_size)
    xs = [np.array([cuts[0]])]
    for a, b in zip(cuts[:-1], cuts[1:]):
        near_a = any(abs(a - e) < 1e-12 for e in junctions)
        near_b = any(abs(b - e) < 1e-12 for e in junctions)
        xs.append(_graded(a, b, size, min(fine, size), near_a, near_b)[1:])
    x = np.concatenate(xs)
    ny = max(1, math.ceil(0.5 * width / size - 1e-9))
    y = np.linspace(0.0, 0.5 * width, ny + 1)
    has_bottom = any(_COATINGS[s.coating][0] for s in segs)
    has_top = any(_COATINGS[s.coating][1] for s in segs)
    ratio = v.check_positive("z_ratio", z_ratio)
    coat = _ply_nodes(nply, ratio)  # 0 at the film, 1 at the outer face
    half = _ply_nodes(math.ceil(nply / 2), ratio)
    film = np.concatenate([0.5 * half, 1.0 - 0.5 * half[-2::-1]])
    zs = [(-d * coat)[:0:-1]] if has_bottom else []
    zs.append(h * film)
    if has_top:
        zs.append(h + d * coat[1:])
    z = np.concatenate(zs)

    mesh = MeshHex.init_tensor(x, y, z)
    centre = mesh.p[:, mesh.t].mean(axis=1)
    ply = np.where(centre[2] < 0.0, BOTTOM_COAT, np.where(centre[2] > h, TOP_COAT, FILM))
    seg = np.clip(np.searchsorted(edges, centre[0], side="right") - 1, 0, len(segs) - 1)
    bottom_ok = np.array([_COATINGS[s.coating][0] for s in segs])[seg]
    top_ok = np.array([_COATINGS[s.coating][1] for s in segs])[seg]
    keep = (ply == FILM) | ((ply == BOTTOM_COAT) & bottom_ok) | ((ply == TOP_COAT) & top_ok)
    mesh = mesh.restrict(np.nonzero(keep)[0])
    return LayeredStrip(mesh=mesh, ply=ply[keep].astype(np.int8), segments=segs, h=h, d=d,
                        width=width, symmetry=symmetry, x_edges=edges, meta=dict(meta or {}))


#: Mesh presets of :func:`hinge_mesh`: in-plane size as a fraction of the hinge length (capped),
#: elements per ply, layer growth away from the film, junction element as a fraction of the size.
HINGE_RESOLUTIONS = {
    "coarse": {"size_cap": 0.5, "per_hinge": 2, "layers_per_ply": 2, "z_ratio": 1.5,
               "junction": 1 / 4},
    "default": {"size_cap": 0.25, "per_hinge": 4, "layers_per_ply": 3, "z_ratio": 2.0,
                "junction": 1 / 8},
    "fine": {"size_cap": 0.125, "per_hinge": 8, "layers_per_ply": 4, "z_ratio": 2.0,
             "junction": 1 / 16},
}


def hinge_mesh(length, d, h=PAPER_H, *, panel_length=2.0, width=1.0, free_face="top",
               resolution="default", element_size=None, layers_per_ply=None, junction_size=None,
               z_ratio=None) -> LayeredStrip:
    """The paper's folding specimen: two sandwich panels joined by a hinge coated on one face.

    The hinge (``|x| <= length / 2``) carries the passive coat on one face only; the panels on
    either side are coated on both faces (passive/active/passive) and stay flat.

    Parameters
    ----------
    length : float [mm]
        Hinge (fold) width L, > 0.
    d : float [mm]
        Passive coat thickness, > 0.
    h : float [mm]
        Film thickness, > 0 (0.29 mm in the paper).
    panel_length : float [mm]
        Length of each panel along x, > 0.
    width : float [mm]
        Width of the strip along y (the hinge line), > 0. 1 mm as in :func:`gdfe.hinge`.
    free_face : {"top", "bottom"}
        Face of the film left uncoated in the hinge. The hinge folds towards it: ``"top"`` (the
        default, as in :func:`gdfe.hinge`) folds towards +z.
    resolution : {"coarse", "default", "fine"}
        Preset for the four mesh parameters below (:data:`HINGE_RESOLUTIONS`); any of them
        given explicitly wins.
    element_size : float [mm], optional
        In-plane element size; ``"default"``: ``min(0.25, length / 4)``.
    layers_per_ply : int, optional
        Elements through each ply, >= 2 (the film gets the next even number); ``"default"``: 3.
    junction_size : float [mm], optional
        Element length at the two hinge/panel junctions, where the coat ends on the film and the
        stress concentrates; ``"default"``: ``element_size / 8``.
    z_ratio : float, optional
        Growth of the layer thickness away from the film faces; ``"default"``: 2.

    Notes
    -----
    The fold angle converges slowly under refinement through the thickness (the coat ends in a
    re-entrant corner). For L = 1 mm, d = 0.33 mm the ``"default"`` preset is within about 0.5 %
    of a mesh with 8 graded layers per ply and 0.125 mm elements, ``"coarse"`` within about 2 %.

    Returns
    -------
    LayeredStrip
        Quarter model (``symmetry="xy"``).
    """
    length = v.check_positive("length", length)
    v.check_positive("panel_length", panel_length)
    v.check_choice("free_face", free_face, {"top", "bottom"})
    v.check_choice("resolution", resolution, set(HINGE_RESOLUTIONS))
    preset = HINGE_RESOLUTIONS[resolution]
    if element_size is None:
        element_size = min(preset["size_cap"], length / preset["per_hinge"])
    element_size = v.check_positive("element_size", element_size)
    if junction_size is None:
        junction_size = preset["junction"] * element_size
    if layers_per_ply is None:
        layers_per_ply = preset["layers_per_ply"]
    if z_ratio is None:
        z_ratio = preset["z_ratio"]
    coat = "bottom" if free_face == "top" else "top"
    segs = [Segment(panel_length, "both"), Segment(length, coat), Segment(panel_length, "both")]
    return layered_strip(segs, h, d, width=width, element_size=element_size,
                         layers_per_ply=layers_per_ply, junction_size=junction_size,
                         z_ratio=z_ratio, symmetry="xy",
                         meta={"kind": "hinge", "hinge_length_mm": length,
                               "panel_length_mm": float(panel_length), "free_face": free_face,
                               "resolution": resolution})


def strip_mesh(length, h, d, *, width=1.0, free_face="top", element_size=0.25,
               layers_per_ply=2) -> LayeredStrip:
    """A free bilayer strip: film and passive coat over the whole length (the verification case).

    Parameters
    ----------
    length : float [mm]
        Strip length along x, > 0.
    h, d : float [mm]
        Film and coat thicknesses, > 0.
    width : float [mm]
        Strip width along y, > 0.
    free_face : {"top", "bottom"}
        Uncoated face of the film; the strip curls towards it.
    element_size : float [mm]
        In-plane element size.
    layers_per_ply : int
        Elements through each ply, >= 2.

    Returns
    -------
    LayeredStrip
        Quarter model (``symmetry="xy"``).
    """
    v.check_choice("free_face", free_face, {"top", "bottom"})
    coat = "bottom" if free_face == "top" else "top"
    return layered_strip([Segment(length, coat)], h, d, width=width, element_size=element_size,
                         layers_per_ply=layers_per_ply, symmetry="xy",
                         meta={"kind": "strip", "free_face": free_face})


def _graded(a, b, size, fine, fine_at_a, fine_at_b, ratio=1.5):
    """Nodes from a to b: ``fine`` long at a flagged end, growing by ``ratio`` up to ``size``."""
    length = b - a
    if not (fine_at_a or fine_at_b) or fine >= size:
        n = max(2, math.ceil(length / size - 1e-9))
        return np.linspace(a, b, n + 1)

    def ramp(total):
        steps = []
        while sum(steps) < total - 1e-12:
            steps.append(min(fine * ratio ** len(steps), size))
        if len(steps) > 1 and sum(steps) - total > 0.5 * steps[-1]:
            steps.pop()
        return np.array(steps)

    if fine_at_a and fine_at_b:
        half = ramp(0.5 * length)
        steps = np.concatenate([half, half[::-1]])
    else:
        steps = ramp(length)
        if fine_at_b:
            steps = steps[::-1]
    return a + np.concatenate([[0.0], np.cumsum(steps)]) * (length / steps.sum())


def _ply_nodes(n, ratio):
    """n + 1 node fractions in [0, 1], layer thicknesses growing by ``ratio`` away from 0."""
    steps = ratio ** np.arange(n)
    return np.concatenate([[0.0], np.cumsum(steps)]) / steps.sum()
