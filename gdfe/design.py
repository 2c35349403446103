"""Designs: a film, the passive material printed on its faces, and the film's contraction.

Each in-plane cell of the film carries one of four materials (:class:`gdfe.material.Material`:
rigid, contracting on its top or bottom face, free shrink), set by which faces are coated
with passive material, and the passive thickness ``d`` printed there; a deformation model
(:mod:`gdfe.model`, default the paper's Eq. 3) gives each cell its contraction ratio R.

Inside a contracting cell the in-plane shrink varies linearly through the thickness,
from R on the free face to 1 on the coated one (the paper's C-GDFE, Fig. 5).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import re

import numpy as np

from gdfe._images import read_mask
from gdfe._validation import (GdfeError, GdfeTypeError, check_choice, check_file, check_int, check_keys,
                              check_positive, check_length, check_number, check_ratio, describe,
                              read_text, LENGTH_RANGE, R_MIN, RATIO_WHAT)
from gdfe.calibration import DEFAULT_H, PAPER_K
from gdfe.material import LAYOUT_CHARS, Material
from gdfe.mesh import DEFAULT_NZ, HexMesh, sheet_mesh
from gdfe.model import as_model, paper_model
from gdfe.physical_ranges import MAX_CONTRACTION, RANGES, check_contraction, looks_like_micrometres
from gdfe.resources import check_design_cells

log = logging.getLogger(__name__)

__all__ = ["Material", "Design", "grid_design", "hinge", "from_masks", "from_rows", "load_design", "DESIGN_KEYS",
           "DESIGN_READERS", "DesignSource", "FilmSpec", "register_design_reader", "paper_film", "check_process",
           "check_resolution", "MAX_CELL_TURN"]

#: The sections of a design file that every design has, around the tables of the design sources.
_FIXED_KEYS = [("film", ("h", "R", "d", "K", "nz", "isotropy", "model")),
               ("process", None),  # the part's process variables: any names
               ("simulate", ("steps", "tol", "max_iter", "method", "contact", "on_drift"))]
#: The sections of a design file and the keys of each (:func:`load_design`): ``[film]``, one table per
#: registered design source (:func:`register_design_reader`), ``[process]`` and ``[simulate]``.
DESIGN_KEYS = dict(_FIXED_KEYS)
#: The sections of which a design file has exactly one: how its film is laid out (the registered sources).
DESIGN_KINDS = []


@dataclasses.dataclass
class Design:
    """A meshed film with its material map.

    Attributes
    ----------
    mesh : HexMesh
        The film in its flat, printed state [mm].
    material : (m,) int array
        :class:`Material` code of each cell.
    R : (m,) float array
        Contraction ratio of each cell's free face(s), in [0.01, 1] (``gdfe._validation.R_MIN``); ignored for rigid cells.
    h : float [mm]
        Active-film thickness.
    isotropy : float
        Transverse contraction relative to the contraction along x: the free face shrinks
        by ``R`` along x and by ``1 - isotropy * (1 - R)`` along y. 1 (the default) is the
        in-plane isotropic shrink of the pre-strained film; 0 shrinks along x only.
    regions : dict of str -> (k,) int array
        Named groups of cells (e.g. ``"panel_a"``, ``"hinge"``, ``"panel_b"``).
    meta : dict
        Free-form description (the parameters the design was made from).
    d : (m,) float array [mm] or None
        Passive thickness printed on each cell (the coat a one-side-coated cell bends
        against); NaN where none is known. A deformation model turns it into ``R``.
    contraction : (m, 2) float array or None
        Explicit contraction ``1 - R`` of the top and bottom face of every cell, where a
        model's mechanism spreads or caps it (see :meth:`face_contraction`); None: from
        ``material`` and ``R``.
    model : DeformationModel or None
        The model the contractions came from (:mod:`gdfe.model`); None where ``R`` was given.
    """

    mesh: HexMesh
    material: np.ndarray
    R: np.ndarray
    h: float
    isotropy: float = 1.0
    regions: dict = dataclasses.field(default_factory=dict)
    meta: dict = dataclasses.field(default_factory=dict)
    d: np.ndarray | None = None
    contraction: np.ndarray | None = None
    model: object = None

    def __post_init__(self):
        m = self.mesh.n_cells
        self.material = np.asarray(self.material, dtype=np.int8)
        self.R = np.broadcast_to(np.asarray(self.R, dtype=float), (m,)).copy()
        if self.material.shape != (m,):
            raise GdfeError(f"material: expected shape ({m},), got {self.material.shape}")
        if not np.isin(self.material, list(map(int, Material))).all():
            raise GdfeError(f"material: expected codes {[int(c) for c in Material]}, "
                             f"got {sorted(set(self.material.tolist()))}")
        check_ratio("R", self.R)
        self.h = check_length("h", self.h)
        self.isotropy = check_number("isotropy", self.isotropy, minimum=0.0, maximum=1.0,
                                     what="a number in [0, 1]")
        if self.d is not None:
            if isinstance(self.d, (str, bytes, bool, np.bool_)):
                raise GdfeTypeError(f"d: expected passive thicknesses in mm, got {describe(self.d)}")
            self.d = np.broadcast_to(np.asarray(self.d, dtype=float), (m,)).copy()
            known = self.d[np.isfinite(self.d)]
            if np.any(known <= 0):
                raise GdfeError(f"d: expected positive passive thicknesses in mm, got {known[known <= 0][0]:g}")
            if np.isinf(self.d).any():
                raise GdfeError("d: expected finite passive thicknesses in mm (NaN where none), got inf")
        if self.contraction is not None:
            c = np.asarray(self.contraction, dtype=float)
            if c.shape != (m, 2) or not np.isfinite(c).all() or np.any(c < 0) or np.any(c >= 1):
                raise GdfeError(f"contraction: expected an ({m}, 2) array of contractions in [0, 1), "
                                f"got shape {c.shape}")
            self.contraction = c

    @property
    def n_cells(self) -> int:
        return self.mesh.n_cells

    def with_R(self, R) -> "Design":
        """A copy of the design with other contraction ratios (scalar or per cell).

        The ratios replace whatever a model gave: the copy has no explicit per-face
        contraction and no model.
        """
        return dataclasses.replace(self, R=np.broadcast_to(np.asarray(R, float), self.R.shape).copy(),
                                   contraction=None, model=None)

    def face_contraction(self):
        """Contraction ``1 - R`` of the top and of the bottom face of every cell (0 where coated).

        The explicit :attr:`contraction` when a model's mechanism set one, else from
        :attr:`material` and :attr:`R`.

        Returns
        -------
        top, bottom : (m,) float arrays
        """
        if self.contraction is not None:
            return self.contraction[:, 0].copy(), self.contraction[:, 1].copy()
        mat = self.material
        s = 1.0 - self.R
        top = np.where((mat == Material.CONTRACT_TOP) | (mat == Material.FREE_SHRINK), s, 0.0)
        bottom = np.where((mat == Material.CONTRACT_BOTTOM) | (mat == Material.FREE_SHRINK), s, 0.0)
        return top, bottom

    def region_cells(self, name) -> np.ndarray:
        """Cell indices of region ``name``, through the whole thickness."""
        try:
            return self.regions[name]
        except KeyError:
            raise GdfeError(f"region: expected one of {sorted(self.regions)}, got {name!r}") from None

    def summary(self) -> dict:
        counts = {mat.name.lower(): int((self.material == mat).sum()) for mat in Material}
        out = {"n_cells": self.n_cells, "n_points": self.mesh.n_points, "h_mm": self.h,
               "spacing_mm": self.mesh.spacing.tolist(), "isotropy": float(self.isotropy),
               "cells_by_material": counts, **self.meta}
        if self.d is not None and np.isfinite(self.d).any():
            known = self.d[np.isfinite(self.d)]
            out["d_mm_range"] = [float(known.min()), float(known.max())]
        if self.model is not None:
            out["model"] = self.model.name
        return out


#: The largest turn of one cell's fold [rad]: its length times the fold's curvature (1 - R)/h
#: (Eq. 2). Beyond half a turn a cell is longer than half the circumference pi h/(1 - R) of the
#: circle its film rolls into: within the one cell the film turns back on itself, and the film on
#: either side of it would fold through each other; the solver then stalls in its self-contact
#: steps (gdfe.hinge(2.6, R=0.05, h=0.05), 3.17 rad per cell, ran over a minute) or works on
#: cells of any length (`gdfe hinge -L 1e5 --cells 16`, 6580 rad per cell, 11 minutes without
#: output). A one-cell hinge of 2.11 rad still folds within 0.25 rad of Eq. 2
#: (studies/fig07_crease_fold.py at its coarse resolution).
MAX_CELL_TURN = math.pi


def check_resolution(design, name="pixel"):
    """Refuse a design whose cells are too long for the fold they make (:data:`MAX_CELL_TURN`).

    Parameters
    ----------
    design : Design
    name : str
        The argument that set the cell size, for the message (``pixel``, ``cell_size``).
    """
    top, bottom = design.face_contraction()
    bend = np.abs(top - bottom)  # 1 - R of the free face, where one face is coated
    dx, dy = design.mesh.spacing[:2]
    turn = bend * max(dx, dy * design.isotropy) / design.h
    k = int(np.argmax(turn)) if turn.size else 0
    if turn.size and turn[k] > MAX_CELL_TURN:
        most = MAX_CELL_TURN * design.h / bend[k]
        size = dx if dx >= dy * design.isotropy else dy
        raise GdfeError(f"{name}: expected cells of at most half the circumference of the circle the film rolls "
                        f"into (pi h/(1 - R) = {most:.3g} mm for h = {design.h:g} mm, R = {1 - bend[k]:.3g}), got "
                        f"{size:.3g} mm: each cell would turn by {turn[k]:.3g} rad, more than half a turn")
    return design


def grid_design(material2d, R=None, h=DEFAULT_H, pixel=0.1, nz=DEFAULT_NZ, isotropy=1.0, film=None,
                regions2d=None, meta=None, d=None, model=None, process=None):
    """A design from an in-plane grid of materials.

    The contraction of every cell comes either from ``R`` directly or from a deformation
    model (:mod:`gdfe.model`, default the paper's Eq. 3) applied to the passive thickness
    ``d`` printed on each cell.

    Parameters
    ----------
    material2d : (nx, ny) int array
        :class:`Material` code of each in-plane cell; column ``i`` runs along x, row ``j`` along y.
    R : float or (nx, ny) float array, optional
        Contraction ratio of the free faces, in [0.01, 1]; without it, from ``model`` and ``d``.
    h : float [mm]
        Film thickness.
    pixel : float or (2,) float [mm]
        In-plane cell size (dx, dy).
    nz : int
        Cell layers through the thickness (default :data:`gdfe.mesh.DEFAULT_NZ`, 1).
    isotropy : float
        See :class:`Design`.
    film : (nx, ny) bool array, optional
        Where the film is; default everywhere.
    regions2d : dict of str -> (nx, ny) bool array, optional
        Named in-plane regions.
    meta : dict, optional
    d : float or (nx, ny) float array [mm], optional
        Passive thickness printed on each cell (NaN where none).
    model : DeformationModel or path of a model file, optional
        The deformation model that gives ``R`` from ``d`` (default: the paper's Eq. 3).
    process : dict, optional
        The part's process variables, for a model's process mechanisms (``partial_activation``,
        ``batch``), e.g. ``{"T_C": 150, "lot": "B"}``.

    Raises
    ------
    GdfeError
        Among others, cells too long for their fold (:func:`check_resolution`).
    """
    return _warn_unused_process(_warn_aspect(check_resolution(_warn_film(_grid_design(
        material2d, R, h, pixel, nz, isotropy, film, regions2d, meta, d, model, process)))))


def _warn_film(design):
    """Warn of a film or coat thickness outside its physical range, and of a contraction beyond the
    film's free shrink (:mod:`gdfe.physical_ranges`): one warning each per design, not per cell.

    The design is built as asked: a thickness in micrometres where mm are meant, or a coat that asks
    more shrink of the film than it has, is most likely a mistake of the input, but one the simulation
    can run, so it is said, not refused.

    Parameters
    ----------
    design : Design

    Returns
    -------
    Design
        ``design`` itself.
    """
    known = design.d[np.isfinite(design.d)] if design.d is not None else np.empty(0)
    for name, what, values in (("h", "the film's thickness", np.array([design.h])),
                               ("d", "the coat's thickness", known)):
        note = _thickness_note(name, what, values)
        if note:
            log.warning("%s", note)
    top, bottom = design.face_contraction()
    found = check_contraction(np.concatenate([top, bottom, [0.0]]))
    if found is not None:
        c = found["value"]
        log.warning("the film's free face contracts by 1 - R = %.3g (R = %.3g), more than the film's free shrink of "
                    "at most %g allows (pre-strained polystyrene shrinks in-plane by at most 50-60 %%): the fold "
                    "is an extrapolation; check R, or d (a thinner coat contracts more)", c, 1.0 - c, MAX_CONTRACTION)
    return design


def _thickness_note(name, what, values):
    """The warning on thicknesses ``values`` [mm] of ``name`` outside their range, or None."""
    r = RANGES[name]
    out = np.unique(values[(values < r.lo) | (values > r.hi)])
    if not out.size:
        return None
    given = f"{out[0]:g} mm" if out.size == 1 else f"{out[0]:g} to {out[-1]:g} mm"
    note = f"{what}: {name} = {given} is outside the physical range [{r.lo:g}, {r.hi:g}] mm ({r.why})"
    big = out[-1]
    if looks_like_micrometres(name, big):
        note += f"; lengths are in mm: {big:g} looks like micrometres, {name} = {big / 1000.0:g} mm"
    return note


def _warn_aspect(design):
    """Warn of elongated cells under in-plane isotropic shrink (after the design passed its checks)."""
    dx, dy = design.mesh.spacing[:2]
    if design.isotropy > 0 and max(dx, dy) > 1.5 * min(dx, dy):
        # measured by studies/fig07_crease_fold.py (fine tube meshes): a tube's fold per hinge
        # falls from 0.755 to 0.255 rad as the cells' aspect goes from 1 to 5.4 (isotropic
        # shrink); square cells converge under refinement
        log.warning("cells of %g x %g mm with in-plane isotropic shrink: elongated cells stiffen "
                    "the fold; use square cells (aspect <= 1.5)", dx, dy)
    return design


#: Process variables whose name says their unit, and the values a heat-shrinking part can have:
#: a temperature in degrees Celsius above absolute zero and below the film's decomposition (polystyrene
#: degrades from about 300 C; an oven for shrink film runs at 100-160 C), in kelvin likewise, a time
#: in seconds, minutes or hours that is not negative.
PROCESS_UNIT_RANGES = {"_C": (-273.15, 500.0, "a temperature in degrees Celsius"),
                       "_K": (0.0, 773.15, "a temperature in kelvin"),
                       "_s": (0.0, math.inf, "a time in seconds"), "_min": (0.0, math.inf, "a time in minutes"),
                       "_h": (0.0, math.inf, "a time in hours")}


def check_process(name, process):
    """A part's process variables: None, or a mapping of names to finite numbers or text labels.

    A number whose name ends in a unit (:data:`PROCESS_UNIT_RANGES`: ``T_C`` in degrees Celsius, ``t_s``
    in seconds, ...) must lie in that unit's physical range.
    """
    if process is None:
        return None
    if not isinstance(process, dict):
        raise GdfeTypeError(f"{name}: expected a mapping of process variables (e.g. {{'T_C': 150, 'lot': 'B'}}), "
                            f"got {describe(process)}")
    for k, v in process.items():
        if not isinstance(k, str) or not k.strip():
            raise GdfeError(f"{name}: expected names of process variables, got the name {describe(k)}")
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, str)) or (
                isinstance(v, float) and not np.isfinite(v)):
            raise GdfeError(f"{name}: {k}: expected a finite number or a text label, got {describe(v)}")
        if isinstance(v, str) and not v.strip():
            raise GdfeError(f"{name}: {k}: expected a finite number or a text label, got an empty text")
        unit = next((u for u in PROCESS_UNIT_RANGES if k.endswith(u) and len(k) > len(u)), None)
        if unit is not None and not isinstance(v, str):
            lo, hi, what = PROCESS_UNIT_RANGES[unit]
            if not lo <= v <= hi:
                raise GdfeError(f"{name}: {k}: expected {what} in [{lo:g}, {hi:g}], got {v:g}")
    return dict(process)


def process_used(model, process):
    """The process variables of ``process`` that ``model``'s process mechanisms read (a sorted list)."""
    if not process or model is None:
        return []
    cols = getattr(model, "columns", {}) or {}
    return sorted(k for k in process if k in cols.values())


def _record_process(design, model, process):
    """Write what made the contraction into ``design.meta``: its source, the process variables and which
    of them the model used."""
    meta = design.meta
    meta["contraction_source"] = (f"model {model.name!r}" if model is not None else "R given")
    if process:
        meta["process"] = dict(process)
        meta["process_used"] = process_used(model, process)
    return design


def _warn_unused_process(design, name="process"):
    """One warning naming the process variables the contraction did not use (kept in ``meta``)."""
    given = design.meta.get("process") or {}
    unused = [k for k in given if k not in (design.meta.get("process_used") or [])]
    if unused and "process_unused" not in design.meta:  # said once, by the first caller that sees it
        why = ("the contraction ratio R was given directly" if design.model is None else
               f"model {design.model.name!r} has no process mechanism that reads them (it reads "
               f"{', '.join(sorted((design.model.columns or {}).values())) or 'none'})")
        log.warning("%s: %s not used: %s; recorded in the result, but they change nothing", name,
                    ", ".join(unused), why)
        design.meta["process_unused"] = unused
    return design


def _grid_design(material2d, R, h, pixel, nz, isotropy, film, regions2d, meta, d, model, process):
    material2d = np.asarray(material2d)
    process = check_process("process", process)
    if R is not None:
        R = check_ratio("R", R)
    if material2d.ndim != 2:
        raise GdfeError(f"material2d: expected a 2-D grid, got shape {material2d.shape}")
    pixel = check_length("pixel", pixel)
    if np.ndim(pixel) > 1 or np.size(pixel) not in (1, 2):
        raise GdfeError(f"pixel: expected a cell size or a pair (dx, dy) in mm, got {describe(pixel)}")
    dx, dy = np.broadcast_to(np.asarray(pixel, float), (2,))
    h = check_length("h", h)
    isotropy = check_number("isotropy", isotropy, minimum=0.0, maximum=1.0, what="a number in [0, 1]")
    nz = check_int("nz", nz)
    keep = np.ones(material2d.shape, bool) if film is None else np.asarray(film, bool)
    if keep.shape != material2d.shape:
        raise GdfeError(f"film: expected shape {material2d.shape}, got {keep.shape}")
    model = as_model(model)
    if R is not None and model is not None:
        raise GdfeError("R, model: expected a contraction ratio R or a deformation model, not both")
    if R is None and d is None:
        raise GdfeError("R, d: expected a contraction ratio R, or the passive thickness d for the "
                        "deformation model")
    check_design_cells("film", float(keep.sum()) * nz)  # before the mesh is made
    mesh = sheet_mesh(keep, dx, dy, h, nz=nz)
    i, j = mesh.cell_ij.T
    d_cells = None
    if d is not None:
        d2 = np.broadcast_to(np.asarray(d, float), material2d.shape)
        d_cells = d2[i, j]
    regions = {}
    for name, mask in (regions2d or {}).items():
        mask = np.asarray(mask, bool)
        regions[name] = np.nonzero(mask[i, j])[0]
    meta = dict(meta or {})
    if R is None:
        design = Design(mesh=mesh, material=material2d[i, j], R=1.0, h=h, isotropy=isotropy,
                        regions=regions, meta=meta, d=d_cells)
        model = model or paper_model()
        _check_coat(model, design, process)
        return _record_process(model.apply(design, process), model, process)
    R2 = np.broadcast_to(np.asarray(R, float), material2d.shape)
    return _record_process(Design(mesh=mesh, material=material2d[i, j], R=R2[i, j], h=h, isotropy=isotropy,
                                  regions=regions, meta=meta, d=d_cells), None, process)


def _check_coat(model, design, process=None):
    """Refuse a coat on which ``model`` gives a contraction ratio below ``R_MIN`` (the film would all but
    vanish), naming the thinnest coat that gives at least ``R_MIN`` (:meth:`DeformationModel.check_coats`)."""
    if design.d is None:
        return
    one_side = (design.material == Material.CONTRACT_TOP) | (design.material == Material.CONTRACT_BOTTOM)
    model.check_coats(design.d[one_side & np.isfinite(design.d)], design.h, process, ratio=R_MIN)


#: What each kind of design calls its film, for the message of a film in pieces.
_FILM_NAMES = {"layout": "rows", "masks": "masks", "svg": "drawing", "fold": "crease pattern"}


def check_one_piece(design):
    """Refuse a design whose film is in several pieces (cells joined by no side) before a solve:
    each piece would move on its own, and the solve has nothing to hold one piece against
    another (it would run to its iteration limit). A design of several pieces is still a valid
    geometry (for the penetration check of parts laid one into another); only its solve is refused.

    Raises
    ------
    GdfeError
        Naming the pieces (cells and extent in mm, the three largest).
    """
    from scipy import ndimage

    mesh = design.mesh
    ij = getattr(mesh, "cell_ij", None)
    if ij is None or len(ij) == 0:
        return
    ij = np.asarray(ij, int)
    shape = tuple(ij.max(axis=0) + 1)
    film = np.zeros(shape, bool)
    film[ij[:, 0], ij[:, 1]] = True
    labels, n = ndimage.label(film)  # pieces joined side to side (cells touching at a corner are not joined)
    if n <= 1:
        return
    sizes = np.bincount(labels.ravel())[1:]
    cell_label = labels[ij[:, 0], ij[:, 1]]
    where = []
    for k in np.argsort(-sizes)[:3]:
        pts = mesh.points[np.asarray(mesh.cells)[cell_label == k + 1].ravel()]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        where.append(f"{sizes[k]} cells at x {lo[0]:.3g}-{hi[0]:.3g} mm, y {lo[1]:.3g}-{hi[1]:.3g} mm")
    more = f" and {n - 3} more" if n > 3 else ""
    kind = (design.meta or {}).get("kind")
    raise GdfeError(f"{_FILM_NAMES.get(kind, 'film')}: expected one piece of film, got {n} pieces joined by no "
                    f"cell side ({'; '.join(where)}{more}); join them, or simulate each piece as a design of its own")


def hinge(length, d=None, h=DEFAULT_H, K=PAPER_K, R=None, width=0.5, panel_length=1.0,
          cell_size=None, nz=DEFAULT_NZ, isotropy=1.0, face="top", model=None, process=None):
    """The paper's folding specimen: two rigid panels joined by a contracting hinge.

    The strip runs along x: ``panel_a`` (x < 0), the hinge of width ``length``
    (0 <= x <= length) coated on one face only, then ``panel_b``. Panels are coated on
    both faces. The hinge's free face shrinks by ``R``; without ``R``, ``R`` comes from
    the deformation model ``model`` at ``d`` (default: the paper's Eq. 3 with ``K``).
    Where the model's contraction reaches into the panels (``hinge_length``), the regions
    ``panel_a``/``panel_b`` are the parts of the panels it does not reach.

    Parameters
    ----------
    length : float [mm]
        Hinge (fold) width L.
    d : float [mm], optional
        Passive-layer thickness (needed unless ``R`` is given).
    h : float [mm]
        Active-film thickness.
    K : float
        Coefficient of Eq. 1 used for Eq. 3.
    R : float, optional
        Contraction ratio of the hinge's free face, overriding the model.
    width : float [mm]
        Strip width (along y). With in-plane isotropic shrink the fold angle depends on
        it (the free face also shrinks across the strip); the default 0.5 mm is narrow
        enough for the cylindrical fold that Eq. 2 assumes (see the README).
    panel_length : float [mm]
        Length of each rigid panel along x (does not change the fold angle).
    cell_size : float [mm], optional
        In-plane cell size; default ``min(length / 16, width / 2)``: 16 cells across the
        hinge, and at least two across the strip with an aspect ratio of at most 1.5.
    nz : int
        Cell layers through the thickness (default :data:`gdfe.mesh.DEFAULT_NZ`, 1).
    isotropy : float
        1: in-plane isotropic shrink (default); 0: shrink along x only.
    face : {"top", "bottom"}
        Which face of the hinge is free (bends towards +z for ``"top"``).
    model : DeformationModel or path of a model file, optional
        The deformation model (:mod:`gdfe.model`); default the paper's Eq. 3 with ``K``.
    process : dict, optional
        The part's process variables, for the model's process mechanisms.
    """
    length = check_length("length", length, allow_array=False)
    width = check_length("width", width, allow_array=False)
    panel_length = check_length("panel_length", panel_length, allow_array=False)
    h = check_length("h", h, allow_array=False)
    process = check_process("process", process)
    nz = check_int("nz", nz)
    model = as_model(model)
    if R is None:
        if d is None:
            raise GdfeError("hinge: give the passive thickness d (mm) or the contraction ratio R")
        d = check_length("d", d)
        model = model or paper_model(K)
    else:
        if model is not None:
            raise GdfeError("R, model: expected a contraction ratio R or a deformation model, not both")
        R = check_ratio("R", R)
    check_choice("face", face, ("top", "bottom"))
    if cell_size is None:  # derived: a cell too small is the length's or the width's, the values given
        cell_size = min(length / 16.0, width / 2.0)
        if cell_size < LENGTH_RANGE[0]:
            which, value, cells = ("width", width, 2) if width / 2.0 <= length / 16.0 else ("length", length, 16)
            raise GdfeError(f"{which}: expected at least {cells * LENGTH_RANGE[0]:g} mm ({cells} cells of at least "
                            f"{LENGTH_RANGE[0]:g} mm across it), got {value:g} mm")
    cell_size = check_length("cell_size", cell_size, allow_array=False)
    if cell_size > length:
        raise GdfeError(f"cell_size: expected at most the hinge's length {length:g} mm (a cell or more across the "
                        f"hinge), got {cell_size:g} mm")
    nh = max(1, int(round(length / cell_size)))
    dx = length / nh
    ny = max(2, int(round(width / cell_size)))
    spec = _HingeSpec(length=length, width=width, h=h, d=d, K=K, R=R, nz=nz, isotropy=isotropy, face=face,
                      model=model, process=process, nh=nh, ny=ny)
    npanel = max(1, int(round(panel_length / dx)))
    des = _hinge_design(spec, npanel)
    reached = _panel_cells_reached(des, npanel)
    if reached is not None and reached >= npanel:
        # the model's contraction runs through a whole panel: the panels are a detail of the test, not of
        # the part, so lengthen them until the contraction stops inside, then add the requested length
        # beyond where it stops: the fold is measured on outer parts as long as the panels asked for
        trial = npanel
        while reached >= trial:
            trial *= 2
            if trial * dx > MAX_PANEL_FACTOR * (length + panel_length):
                raise GdfeError(f"panel_length: the model's contraction reaches more than {trial // 2 * dx:g} mm "
                                f"into the panels of a {length:g} mm hinge; expected it to stop within "
                                f"{MAX_PANEL_FACTOR:g} x (length + panel_length)")
            reached = _panel_cells_reached(_hinge_design(spec, trial), trial)
        longer = reached + npanel
        log.warning("hinge: the model's contraction reaches %.3g mm into the %.3g mm panels; panels lengthened "
                    "to %.3g mm (the fold is measured on their outer %.3g mm)", reached * dx, npanel * dx,
                    longer * dx, npanel * dx)
        des = _hinge_design(spec, longer)
        des.meta["panel_lengthened_from_mm"] = npanel * dx
        des.meta["panel_reach_mm"] = reached * dx
        npanel = longer
    _warn_unused_process(_warn_aspect(check_resolution(_warn_film(des), "cell_size")))
    # x = 0 at the start of the hinge
    des.mesh.points[:, 0] -= npanel * dx
    return des


#: The longest panel :func:`hinge` makes to outlast a model's reach, in units of length + panel_length.
MAX_PANEL_FACTOR = 64.0


@dataclasses.dataclass(frozen=True)
class _HingeSpec:
    """What :func:`hinge` builds, apart from the panels' length (``nh`` cells across the hinge, ``ny`` across
    the strip)."""

    length: float
    width: float
    h: float
    d: float | None
    K: float
    R: float | None
    nz: int
    isotropy: float
    face: str
    model: object
    process: dict | None
    nh: int
    ny: int


def _hinge_design(spec, npanel):
    """The hinge specimen with ``npanel`` cells in each panel; ``panel_a``/``panel_b`` are the panels' cells
    that the model's contraction does not reach (all of a panel's cells when it reaches through)."""
    nh, ny, nz = spec.nh, spec.ny, spec.nz
    dx, dy = spec.length / nh, spec.width / ny
    nx = 2 * npanel + nh
    check_design_cells("hinge", nx * ny * nz)  # before any array of that size is made
    mat = np.full((nx, ny), int(Material.RIGID))
    code = Material.CONTRACT_TOP if spec.face == "top" else Material.CONTRACT_BOTTOM
    mat[npanel:npanel + nh] = int(code)
    cols = np.arange(nx)[:, None] * np.ones((1, ny), int)
    regions2d = {"panel_a": cols < npanel, "hinge": (cols >= npanel) & (cols < npanel + nh),
                 "panel_b": cols >= npanel + nh}
    model, R, d = spec.model, spec.R, spec.d
    meta = {"kind": "hinge", "length_mm": spec.length, "d_mm": d, "K": spec.K if model is None or model.name in
            ("paper", "eq3") else None, "R": R, "width_mm": spec.width, "panel_length_mm": npanel * dx,
            "face": spec.face}
    if R is not None:
        return _grid_design(mat, R, spec.h, (dx, dy), nz, spec.isotropy, None, regions2d, meta,
                            np.where(mat == int(code), np.nan if d is None else d, np.nan), None, spec.process)
    dgrid = np.where(mat == int(code), d, np.nan)
    des = _grid_design(mat, None, spec.h, (dx, dy), nz, spec.isotropy, None, regions2d, meta, dgrid, model,
                       spec.process)
    des.meta["R"] = float(des.R[des.regions["hinge"][0]])
    if des.contraction is not None:  # a mechanism reached into the panels: they end where it stops
        reached = (des.contraction > 0).any(axis=1)
        for name in ("panel_a", "panel_b"):
            cells = des.regions[name]
            keep = cells[~reached[cells]]
            if keep.size:
                des.regions[name] = keep
    return des


def _panel_cells_reached(des, npanel):
    """How many columns of cells into a panel (the deeper of the two) the model's contraction reaches,
    or None when nothing reaches into the panels."""
    if des.contraction is None:
        return None
    column = des.mesh.cell_ij[:, 0]
    hit = column[(des.contraction > 0).any(axis=1)]
    nh = int(des.mesh.cell_ij[:, 0].max()) + 1 - 2 * npanel
    into_a = npanel - int(hit.min()) if hit.size and hit.min() < npanel else 0
    into_b = int(hit.max()) - (npanel + nh) + 1 if hit.size and hit.max() >= npanel + nh else 0
    return max(into_a, into_b)


def from_rows(rows, R=None, h=DEFAULT_H, pixel=0.1, nz=DEFAULT_NZ, isotropy=1.0, d=None, model=None,
              process=None):
    """A design from a text layout, one string per row of cells, first row at the largest y.

    Characters: ``R`` rigid, ``T`` contracts on top (top face free), ``B`` contracts on
    the bottom, ``S`` free shrink, ``.`` no film. The contraction comes from ``R``, or
    from the deformation ``model`` (default the paper's Eq. 3) at the passive thickness ``d``
    [mm] (see :func:`grid_design`).
    """
    if isinstance(rows, (str, bytes)) or not isinstance(rows, (list, tuple, np.ndarray)) or len(rows) == 0:
        raise GdfeError(f"rows: expected a non-empty list of strings, got {describe(rows)}")
    rows = list(rows)
    for k, r in enumerate(rows):
        if not isinstance(r, str) or not r:
            raise GdfeError(f"rows[{k}]: expected a non-empty list of strings, got {describe(r)}")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise GdfeError(f"rows: all rows must have the same length, got lengths {sorted(widths)}")
    grid = np.array([list(r) for r in rows])[::-1].T  # (nx, ny), j = 0 at the bottom row
    bad = sorted({str(c) for c in np.unique(grid)} - set(LAYOUT_CHARS) - {"."})
    if bad:
        where = next((k, r.index(c)) for k, r in enumerate(rows) for c in r if c in bad)
        chars = " ".join(repr(c) for c in bad)
        raise GdfeError(f"rows: unknown layout character(s) {chars} (first in rows[{where[0]}] at column "
                        f"{where[1] + 1}); expected one of R T B S .")
    film = grid != "."
    if not film.any():
        raise GdfeError(f"rows: expected at least one cell of film (R T B S), got only '.' in {describe(rows)}")
    mat = np.zeros(grid.shape, int)
    for ch, code in LAYOUT_CHARS.items():
        mat[grid == ch] = int(code)
    meta = {"kind": "layout", "d_mm": None if d is None else float(check_length("d", d))}
    return grid_design(mat, R, h=h, pixel=pixel, nz=nz, isotropy=isotropy, film=film, meta=meta,
                       d=_one_side_d(mat, d, d, d), model=model, process=process)


def _one_side_d(mat, d, d_top=None, d_bottom=None):
    """Passive thickness of every cell coated on one face: the bottom coat's where the top is free."""
    if d is None and d_top is None and d_bottom is None:
        return None
    d_top = d if d_top is None else d_top
    d_bottom = d if d_bottom is None else d_bottom
    nan = np.nan
    return np.where(mat == Material.CONTRACT_TOP, nan if d_bottom is None else d_bottom,
                    np.where(mat == Material.CONTRACT_BOTTOM, nan if d_top is None else d_top, nan))


def from_masks(top, bottom, pixel, R=None, h=DEFAULT_H, nz=DEFAULT_NZ, isotropy=1.0, film=None, d=None,
               d_top=None, d_bottom=None, model=None, process=None):
    """A design from masks of the passive material printed on the top and bottom faces.

    Parameters
    ----------
    top, bottom : (nx, ny) bool array, array of pixels, or path of an image
        Where passive material is printed on that face: True in a boolean array; dark (and
        opaque) pixels in an image or an array of pixel values (``uint8``, ``uint16``, floats
        in [0, 1]), of any bit depth and mode alike (:mod:`gdfe._images`). Images are read with
        row 0 at the largest y; arrays are indexed ``[i (x), j (y)]``.
    pixel : float [mm]
        Printer pixel size: the in-plane cell size.
    R : float, optional
        Contraction ratio of the film's free faces; without it, from ``model`` and ``d``.
    film : (nx, ny) bool array or image path, optional
        Where the film is (default: the whole rectangle).
    d : float [mm], optional
        Passive thickness of both faces' coat.
    d_top, d_bottom : float [mm], optional
        Passive thickness of each face's coat, where they differ (default ``d``).
    model : DeformationModel or path of a model file, optional
        The deformation model (default: the paper's Eq. 3).
    """
    pixel = check_length("pixel", pixel)
    top = read_mask("top", top)
    bottom = read_mask("bottom", bottom, top.shape)
    keep = None if film is None else read_mask("film", film, top.shape)
    mat = np.where(top & bottom, Material.RIGID,
                   np.where(bottom, Material.CONTRACT_TOP,
                            np.where(top, Material.CONTRACT_BOTTOM, Material.FREE_SHRINK))).astype(int)
    for name, value in (("d", d), ("d_top", d_top), ("d_bottom", d_bottom)):
        if value is not None:
            check_length(name, value)
    meta = {"kind": "masks", "pixel_mm": pixel}
    given = [v for v in (d, d_top, d_bottom) if v is not None]
    if given:
        meta["d_mm"] = float(given[0])
    for name, value in (("d_top_mm", d_top), ("d_bottom_mm", d_bottom)):
        if value is not None:
            meta[name] = float(value)
    return grid_design(mat, R, h=h, pixel=pixel, nz=nz, isotropy=isotropy, film=keep, meta=meta,
                       d=_one_side_d(mat, d, d_top, d_bottom), model=model, process=process)


# -- design sources: one loader, readers registered with it ------------------------------------------
@dataclasses.dataclass(frozen=True)
class FilmSpec:
    """What turns a layout into contraction ratios: a design file's ``[film]`` (or the paper's film).

    Attributes
    ----------
    h : float [mm]
    R : float or None
        The contraction ratio given directly (None: from ``model`` at ``d``).
    d : float [mm] or None
        Passive thickness of the coat.
    nz : int
    isotropy : float
    model : DeformationModel or None
    process : dict
        The part's process variables (the file's ``[process]``, over which the caller's go).
    default : bool
        The paper's film, given to a file read alone without a model (a source that carries a film
        of its own, a print package, keeps its own).
    """

    h: float
    R: float | None
    d: float | None
    nz: int
    isotropy: float
    model: object
    process: dict
    default: bool = False


@dataclasses.dataclass(frozen=True)
class DesignSource:
    """What every design reader receives: the file, its table, the film and the process variables.

    Attributes
    ----------
    path : Path
        The file read: a design file (TOML), or a drawing or package read alone.
    kind : str
        The reader's name (``"hinge"``, ``"svg"``, ...).
    table : dict or None
        The design file's table of this kind; None for a file read alone.
    film : FilmSpec
    """

    path: object
    kind: str
    table: dict | None
    film: FilmSpec

    @property
    def where(self) -> str:
        """``NAME: [kind]`` (a table) or ``NAME`` (a file alone), the start of a message."""
        return f"{self.path.name}: [{self.kind}]" if self.table is not None else self.path.name

    def file(self, key, what="file"):
        """The path that ``key`` of the table names, relative to the design file."""
        value = self.table.get(key) if self.table is not None else None
        if not isinstance(value, str) or not value:
            raise GdfeError(f"{self.where} {key}: expected the path of a {what}, got {describe(value)}")
        return self.path.parent / value

    def masks_design(self, top, bottom, pixel, film=None, **kw):
        """:func:`from_masks` with this source's film, model and process variables."""
        f = self.film
        return from_masks(top, bottom, pixel, f.R, h=f.h, nz=f.nz, isotropy=f.isotropy, film=film,
                          d=kw.pop("d", f.d), model=f.model, process=f.process, **kw)


@dataclasses.dataclass(frozen=True)
class DesignReader:
    """A registered reader of one design source (:func:`register_design_reader`)."""

    kind: str
    read: object
    keys: tuple = ()
    required: tuple = ()
    suffixes: tuple = ()


#: The readers :func:`load_design` knows, by kind; see :func:`register_design_reader`.
DESIGN_READERS = {}


def register_design_reader(kind, read, *, keys=(), required=(), suffixes=()):
    """Teach :func:`load_design` a design source.

    Every reader is called the same way, ``read(source) -> Design`` with a :class:`DesignSource`
    (the file, its table, the :class:`FilmSpec` with the model and the process variables), whether the
    source is a table of a design file (``[kind]`` with ``keys``, of which ``required`` must be
    there) or a file read alone (its ``suffixes``, with the paper's film).

    Modules that read other sources (:mod:`gdfe.fabrication`: SVG and FOLD drawings, print
    packages) register here when they are imported; :mod:`gdfe` imports them.
    """
    if not isinstance(kind, str) or not kind.isidentifier() or kind in ("film", "process", "simulate"):
        raise GdfeError(f"kind: expected the name of a design source, got {describe(kind)}")
    DESIGN_READERS[kind] = DesignReader(kind, read, tuple(keys), tuple(required),
                                        tuple(s.lower() for s in suffixes))
    DESIGN_KEYS.clear()
    DESIGN_KEYS.update(_FIXED_KEYS[:1] + [(k, r.keys) for k, r in DESIGN_READERS.items() if r.keys]
                       + _FIXED_KEYS[1:])
    DESIGN_KINDS[:] = [k for k, r in DESIGN_READERS.items() if r.keys]
    return DESIGN_READERS[kind]


def _reader_of_suffix(path):
    suffix = path.suffix.lower()
    return next((r for r in DESIGN_READERS.values() if suffix in r.suffixes), None)


def paper_film(model=None, process=None):
    """The film of a drawing or package read alone: the paper's (h, d of Figure 6, R by Eq. 3, or by
    ``model`` from that d), one cell through its thickness."""
    from gdfe import paper

    return FilmSpec(h=paper.H, R=None, d=paper.FIG6_D, nz=1, isotropy=1.0, model=as_model(model) or paper_model(),
                    process=check_process("process", process) or {}, default=model is None)


def load_design(path, model=None, process=None):
    """Read a design; returns ``(design, options)``.

    A TOML design file has a ``[film]`` table (``h``; ``R``, or ``d`` with a deformation model:
    ``model = "M.toml"`` (a model file, relative to the design file) or ``K`` of the
    paper's Eq. 3; optional ``nz``, ``isotropy``) and exactly one table of a registered design
    source (:data:`DESIGN_READERS`):

    - ``[hinge]``: ``length``, optional ``width``, ``panel_length``, ``cell_size``, ``face``;
    - ``[layout]``: ``pixel`` and ``rows`` (strings of ``R T B S .``, first row on top);
    - ``[masks]``: ``pixel``, ``top``, ``bottom`` (image paths relative to the file), optional
      ``film``, and ``d_top``/``d_bottom`` where the two faces' coats differ;
    - ``[svg]`` or ``[fold]``: a drawing (registered by :mod:`gdfe.fabrication.drawings`).

    A file of a registered suffix (``.svg``, ``.fold``, a print package ``.zip``) is read alone,
    with the paper's film (:func:`paper_film`).

    An optional ``[process]`` table gives the part's process variables (``T_C = 150``,
    ``lot = "B"``) to a model with process mechanisms. An optional ``[simulate]`` table is
    returned as ``options`` (``steps``, ``tol``, ``max_iter``, ``method``, ``contact`` =
    ``"auto"``, ``"on"`` or ``"off"``, ``on_drift``) for :func:`gdfe.simulate`.

    ``nz`` defaults to :data:`gdfe.mesh.DEFAULT_NZ` (1) for every kind of design. Every section and
    key is checked (:data:`DESIGN_KEYS`): an unknown one is an error with a "did you mean", a
    string or a boolean where a number belongs is an error, and each message names the file,
    the section and the key. The design's ``meta`` records what made its contraction
    (``contraction_source``, the model file and its sha256, the process variables and which the
    model used).

    Parameters
    ----------
    path : str or Path
    model : DeformationModel or path of a model file, optional
        A model that replaces the file's own (``gdfe simulate --model``).
    process : dict, optional
        Process variables for the model's process mechanisms, over the file's ``[process]``
        table (``gdfe simulate --process``).
    """
    path = check_file("design", path, what="design file")
    process = check_process("process", process)
    model_file = _model_file(model)
    reader = _reader_of_suffix(path)
    if reader is not None:  # a drawing or a package alone
        source = DesignSource(path, reader.kind, None, paper_film(model, process))
        des = _sourced(reader.read(source), source, model_file)
        return des, {}
    name = path.name
    doc = _read_toml(path, "design file (TOML)")
    _check_sections(name, doc)
    proc = check_process(f"{name}: [process]", doc.get("process", {}))
    proc = {**proc, **(process or {})}
    film, file_model = _film(name, path, doc, model, proc)
    kinds = [k for k in DESIGN_KINDS if k in doc]
    if len(kinds) != 1:
        raise GdfeError(f"{name}: expected exactly one of {', '.join(f'[{k}]' for k in DESIGN_KINDS)}; "
                        f"got {', '.join(f'[{k}]' for k in kinds) if kinds else 'none'}")
    kind = kinds[0]
    reader = DESIGN_READERS[kind]
    spec = doc[kind]
    if film.R is None and film.d is None and not (kind == "masks" and ("d_top" in spec or "d_bottom" in spec)):
        raise GdfeError(f"{name}: [film] needs R (contraction ratio) or d (passive thickness, mm)")
    for key in reader.required:
        if key not in spec:
            raise GdfeError(f"{name}: [{kind}] is missing {key!r}")
    try:
        des = reader.read(DesignSource(path, kind, spec, film))
    except GdfeError as exc:
        if str(exc).startswith(name):
            raise
        first = re.split(r"[:=\s]", str(exc), maxsplit=1)[0]  # the key the message starts with
        section = "film" if first in DESIGN_KEYS["film"] else kind if first in DESIGN_KEYS[kind] else None
        raise type(exc)(f"{name}: [{section}] {exc}" if section else f"{name}: {exc}") from None
    des = _sourced(des, DesignSource(path, kind, spec, film), model_file or file_model)
    des.meta.setdefault("nz", film.nz)
    return des, _simulate_options(name, doc)


def _read_toml(path, what):
    """A TOML file's document; a syntax error with the file, the line and, for a stray byte-order mark, its name."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python < 3.11
        import tomli as tomllib
    text = read_text(path, what)  # a byte-order mark inside the file is named there
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise GdfeError(f"{path.name}: not valid TOML: {exc}") from None


def _model_file(model):
    """``{"file", "sha256"}`` of a model given as a path (None otherwise)."""
    import hashlib
    from pathlib import Path

    if not isinstance(model, (str, Path)):
        return None
    p = Path(model)
    try:
        return {"file": str(p), "sha256": hashlib.sha256(p.read_bytes()).hexdigest()}
    except OSError:
        return None  # load_model names the file when it reads it


def _sourced(des, source, model_file):
    """The design with what it was read from in ``meta``; one warning for process variables it did not use."""
    des.meta.setdefault("source", str(source.path))
    if model_file is not None:
        des.meta["model_file"] = model_file
    return _warn_unused_process(des, f"{source.path.name}: process")


def _film(name, path, doc, model, proc):
    """The design file's ``[film]`` as a :class:`FilmSpec`, and the model file it names (with its sha256)."""
    if "film" not in doc:
        raise GdfeError(f"{name}: missing [film] table (h, and R or d)")
    film = doc["film"]
    where = f"{name}: [film]"
    h = _entry(f"{where} h", film.get("h", DEFAULT_H), check_length)
    R = None if "R" not in film else _entry(f"{where} R", film["R"], lambda n, v: check_number(
        n, v, minimum=R_MIN, maximum=1.0, what=RATIO_WHAT))
    d = None if "d" not in film else _entry(f"{where} d", film["d"], check_length)
    if R is not None and d is not None:  # as gdfe hinge's --d and --R
        raise GdfeError(f"{name}: [film] gives R = {R:g} and d = {d:g} mm; expected one of them: R sets the "
                        f"contraction directly, so d would be reported and packaged for a film it does not "
                        f"describe; give d for R from Eq. 3 (or a model), or R alone")
    nz = check_int(f"{where} nz", film.get("nz", DEFAULT_NZ))
    iso = _entry(f"{where} isotropy", film.get("isotropy", 1.0), lambda n, v: check_number(
        n, v, minimum=0.0, maximum=1.0, what="a number in [0, 1]"))
    file_model = None
    if model is not None or "model" in film:
        if R is not None:
            raise GdfeError(f"{name}: [film] gives R and a deformation model; expected one of them")
        if "K" in film:
            raise GdfeError(f"{name}: [film] K is the paper's Eq. 3 coefficient; a deformation model "
                            f"has its own parameters: remove K")
        if model is None:
            spec_model = film["model"]
            if not isinstance(spec_model, str) or not spec_model:
                raise GdfeError(f"{name}: [film] model: expected the path of a model file, got {describe(spec_model)}")
            try:
                model = as_model(spec_model, base=path.parent)
            except GdfeError as exc:
                raise type(exc)(f"{name}: [film] model: {exc}") from None
            file_model = _model_file(path.parent / spec_model)
        model = as_model(model)
    elif R is None:
        model = paper_model(_entry(f"{where} K", film.get("K", PAPER_K), check_positive))
    return FilmSpec(h=h, R=R, d=d, nz=nz, isotropy=iso, model=model, process=proc), file_model


def _simulate_options(name, doc):
    """The design file's ``[simulate]`` table, checked."""
    options = dict(doc.get("simulate", {}))
    where = f"{name}: [simulate]"
    for key, check in (("steps", check_int), ("max_iter", check_int)):
        if key in options:
            options[key] = check(f"{where} {key}", options[key])
    if "tol" in options:
        options["tol"] = _entry(f"{where} tol", options["tol"], check_positive)
    for key, choices in (("contact", ("auto", "on", "off")), ("on_drift", ("warn", "stop"))):
        if key in options:  # the choices of gdfe.simulate's contact= and on_drift=
            check_choice(f"{where} {key}", options[key], choices)
    if "method" in options and not isinstance(options["method"], str):  # its name: checked by gdfe.simulate
        raise GdfeTypeError(f"{where} method: expected the name of a method, got {describe(options['method'])}")
    return options


def _read_hinge(src):
    spec, where, f = src.table, src.where, src.film
    extra = {k: _entry(f"{where} {k}", spec[k], check_length) for k in ("width", "panel_length", "cell_size")
             if k in spec}
    if "face" in spec:
        extra["face"] = check_choice(f"{where} face", spec["face"], ("top", "bottom"))
    return hinge(_entry(f"{where} length", spec["length"], check_length), d=f.d, R=f.R, h=f.h, nz=f.nz,
                 isotropy=f.isotropy, model=f.model, process=f.process, **extra)


def _read_layout(src):
    spec, where, f = src.table, src.where, src.film
    pixel = spec["pixel"]
    pixel = (_entry(f"{where} pixel", pixel, check_length) if not isinstance(pixel, list) else
             _pair(f"{where} pixel", pixel))
    rows = spec["rows"]
    if not isinstance(rows, list) or not rows or not all(isinstance(r, str) and r for r in rows):
        raise GdfeError(f"{where} rows: expected a list of strings of R T B S . (first row on top), "
                        f"got {describe(rows)}")
    return from_rows(rows, f.R, h=f.h, pixel=pixel, nz=f.nz, isotropy=f.isotropy, d=f.d, model=f.model,
                     process=f.process)


def _read_masks(src):
    spec, where = src.table, src.where
    files = {key: src.file(key, "mask image") for key in ("top", "bottom", "film") if key in spec}
    thick = {k: _entry(f"{where} {k}", spec[k], check_length) for k in ("d_top", "d_bottom") if k in spec}
    if thick and src.film.R is not None:
        raise GdfeError(f"{where} {', '.join(thick)}: expected no coat thickness beside [film] R = "
                        f"{src.film.R:g}, which sets the contraction directly; give the thicknesses without R "
                        f"(R from Eq. 3 or a model), or R alone")
    return src.masks_design(files["top"], files["bottom"], _entry(f"{where} pixel", spec["pixel"], check_length),
                            film=files.get("film"), **thick)


#: Keys a design file's sections must have.
_REQUIRED = {"hinge": ("length",), "layout": ("pixel", "rows"), "masks": ("pixel", "top", "bottom")}


def _check_sections(name, doc):
    """Every section of a design file known, a table, and its keys known (with a "did you mean")."""
    for key, value in doc.items():
        if not isinstance(value, dict):
            owner = [s for s, keys in DESIGN_KEYS.items() if keys and key in keys]
            hint = f": put it under [{owner[0]}]" if owner else ""
            if key in DESIGN_KEYS:
                raise GdfeError(f"{name}: [{key}]: expected a table, got {key} = {describe(value)}")
            raise GdfeError(f"{name}: {key} = {describe(value)} stands outside any section{hint}; expected sections "
                            f"{', '.join(f'[{s}]' for s in DESIGN_KEYS)}")
    check_keys(name, doc, DESIGN_KEYS, what="section")
    for key, value in doc.items():
        if DESIGN_KEYS[key] is not None:
            check_keys(f"{name}: [{key}]", value, DESIGN_KEYS[key])


def _entry(where, value, check):
    """``check(where, value)`` for one value of a design file: a number, not a list or a table."""
    if isinstance(value, (list, dict)):
        raise GdfeTypeError(f"{where}: expected a number, got {describe(value)}")
    return check(where, value)


def _pair(where, value):
    """A ``[dx, dy]`` pair of lengths."""
    if len(value) != 2:
        raise GdfeError(f"{where}: expected a length or a pair [dx, dy] in mm, got {describe(value)}")
    return tuple(_entry(f"{where}[{k}]", v, check_length) for k, v in enumerate(value))


register_design_reader("hinge", _read_hinge, keys=("length", "width", "panel_length", "cell_size", "face"),
                       required=("length",))
register_design_reader("layout", _read_layout, keys=("pixel", "rows"), required=("pixel", "rows"))
register_design_reader("masks", _read_masks, keys=("pixel", "top", "bottom", "film", "d_top", "d_bottom"),
                       required=("pixel", "top", "bottom"))
