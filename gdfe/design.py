"""Designs: a film, the passive material printed on its faces, and the film's contraction.

Each in-plane cell of the film carries one of four materials, set by which faces are
coated with passive material:

==================  ===========  ==============  =====================================
material            top coated   bottom coated   what the film does on heating
==================  ===========  ==============  =====================================
``RIGID``           yes          yes             keeps its shape (R-GDFE)
``CONTRACT_TOP``    no           yes             top face shrinks by R: bends towards +z
``CONTRACT_BOTTOM`` yes          no              bottom face shrinks by R: bends towards -z
``FREE_SHRINK``     no           no              shrinks uniformly by R in-plane
==================  ===========  ==============  =====================================

Inside a contracting cell the in-plane shrink varies linearly through the thickness,
from R on the free face to 1 on the coated one (the paper's C-GDFE, Fig. 5).
"""

from __future__ import annotations

import dataclasses
import enum
import logging
from pathlib import Path

import numpy as np

from gdfe._validation import (GdfeError, GdfeFileNotFoundError, check_choice, check_number,
                              check_positive, check_ratio)
from gdfe.calibration import DEFAULT_H, PAPER_K, Calibration
from gdfe.mesh import HexMesh, sheet_mesh

log = logging.getLogger(__name__)

__all__ = ["Material", "Design", "grid_design", "hinge", "from_masks", "from_rows", "load_design"]


class Material(enum.IntEnum):
    """Material of a cell, by which faces carry passive material."""

    RIGID = 0
    CONTRACT_TOP = 1
    CONTRACT_BOTTOM = 2
    FREE_SHRINK = 3


#: Characters of the text layout of a design (``from_rows`` and TOML ``rows``).
LAYOUT_CHARS = {"R": Material.RIGID, "T": Material.CONTRACT_TOP, "B": Material.CONTRACT_BOTTOM,
                "S": Material.FREE_SHRINK}


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
        Contraction ratio of each cell's free face(s), in (0, 1]; ignored for rigid cells.
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
    """

    mesh: HexMesh
    material: np.ndarray
    R: np.ndarray
    h: float
    isotropy: float = 1.0
    regions: dict = dataclasses.field(default_factory=dict)
    meta: dict = dataclasses.field(default_factory=dict)

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
        self.h = check_positive("h", self.h)
        self.isotropy = check_number("isotropy", self.isotropy, minimum=0.0, maximum=1.0,
                                     what="a number in [0, 1]")

    @property
    def n_cells(self) -> int:
        return self.mesh.n_cells

    def with_R(self, R) -> "Design":
        """A copy of the design with other contraction ratios (scalar or per cell)."""
        return dataclasses.replace(self, R=np.broadcast_to(np.asarray(R, float), self.R.shape).copy())

    def face_contraction(self):
        """Contraction ``1 - R`` of the top and of the bottom face of every cell (0 where coated).

        Returns
        -------
        top, bottom : (m,) float arrays
        """
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
        return {"n_cells": self.n_cells, "n_points": self.mesh.n_points, "h_mm": self.h,
                "spacing_mm": self.mesh.spacing.tolist(), "isotropy": float(self.isotropy),
                "cells_by_material": counts, **self.meta}


def grid_design(material2d, R, h=DEFAULT_H, pixel=0.1, nz=2, isotropy=1.0, film=None,
                regions2d=None, meta=None):
    """A design from an in-plane grid of materials.

    Parameters
    ----------
    material2d : (nx, ny) int array
        :class:`Material` code of each in-plane cell; column ``i`` runs along x, row ``j`` along y.
    R : float or (nx, ny) float array
        Contraction ratio of the free faces, in (0, 1].
    h : float [mm]
        Film thickness.
    pixel : float or (2,) float [mm]
        In-plane cell size (dx, dy).
    nz : int
        Cell layers through the thickness.
    isotropy : float
        See :class:`Design`.
    film : (nx, ny) bool array, optional
        Where the film is; default everywhere.
    regions2d : dict of str -> (nx, ny) bool array, optional
        Named in-plane regions.
    """
    material2d = np.asarray(material2d)
    if material2d.ndim != 2:
        raise GdfeError(f"material2d: expected a 2-D grid, got shape {material2d.shape}")
    dx, dy = np.broadcast_to(np.asarray(pixel, float), (2,))
    if isotropy > 0 and max(dx, dy) > 1.5 * min(dx, dy):
        # measured by studies/fig07_crease_fold.py (fine tube meshes): a tube's fold per hinge
        # falls from 0.755 to 0.255 rad as the cells' aspect goes from 1 to 5.4 (isotropic
        # shrink); square cells converge under refinement
        log.warning("cells of %g x %g mm with in-plane isotropic shrink: elongated cells stiffen "
                    "the fold; use square cells (aspect <= 1.5)", dx, dy)
    keep = np.ones(material2d.shape, bool) if film is None else np.asarray(film, bool)
    if keep.shape != material2d.shape:
        raise GdfeError(f"film: expected shape {material2d.shape}, got {keep.shape}")
    mesh = sheet_mesh(keep, dx, dy, h, nz=nz)
    i, j = mesh.cell_ij.T
    R2 = np.broadcast_to(np.asarray(R, float), material2d.shape)
    regions = {}
    for name, mask in (regions2d or {}).items():
        mask = np.asarray(mask, bool)
        regions[name] = np.nonzero(mask[i, j])[0]
    return Design(mesh=mesh, material=material2d[i, j], R=R2[i, j], h=h, isotropy=isotropy,
                  regions=regions, meta=dict(meta or {}))


def hinge(length, d=None, h=DEFAULT_H, K=PAPER_K, R=None, width=0.5, panel_length=1.0,
          cell_size=None, nz=1, isotropy=1.0, face="top"):
    """The paper's folding specimen: two rigid panels joined by a contracting hinge.

    The strip runs along x: ``panel_a`` (x < 0), the hinge of width ``length``
    (0 <= x <= length) coated on one face only, then ``panel_b``. Panels are coated on
    both faces. The hinge's free face shrinks by ``R``; without ``R``, ``R`` comes from
    Eq. 3 with ``K``, ``h`` and ``d``.

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
        Contraction ratio of the hinge's free face, overriding Eq. 3.
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
        Cell layers through the thickness.
    isotropy : float
        1: in-plane isotropic shrink (default); 0: shrink along x only.
    face : {"top", "bottom"}
        Which face of the hinge is free (bends towards +z for ``"top"``).
    """
    length = check_positive("length", length)
    width = check_positive("width", width)
    panel_length = check_positive("panel_length", panel_length)
    h = check_positive("h", h)
    if R is None:
        if d is None:
            raise GdfeError("hinge: give the passive thickness d (mm) or the contraction ratio R")
        R = float(Calibration(K=K, h=h).ratio(d))
    R = check_ratio("R", R)
    check_choice("face", face, ("top", "bottom"))
    if cell_size is None:
        cell_size = min(length / 16.0, width / 2.0)
    cell_size = check_positive("cell_size", cell_size)
    nh = max(1, int(round(length / cell_size)))
    dx = length / nh
    npanel = max(1, int(round(panel_length / dx)))
    ny = max(2, int(round(width / cell_size)))
    dy = width / ny
    nx = 2 * npanel + nh
    mat = np.full((nx, ny), int(Material.RIGID))
    code = Material.CONTRACT_TOP if face == "top" else Material.CONTRACT_BOTTOM
    mat[npanel:npanel + nh] = int(code)
    cols = np.arange(nx)[:, None] * np.ones((1, ny), int)
    regions2d = {"panel_a": cols < npanel, "hinge": (cols >= npanel) & (cols < npanel + nh),
                 "panel_b": cols >= npanel + nh}
    des = grid_design(mat, R, h=h, pixel=(dx, dy), nz=nz, isotropy=isotropy, regions2d=regions2d,
                      meta={"kind": "hinge", "length_mm": length, "d_mm": d, "K": K, "R": R,
                            "width_mm": width, "panel_length_mm": npanel * dx, "face": face})
    # x = 0 at the start of the hinge
    des.mesh.points[:, 0] -= npanel * dx
    return des


def from_rows(rows, R, h=DEFAULT_H, pixel=0.1, nz=2, isotropy=1.0):
    """A design from a text layout, one string per row of cells, first row at the largest y.

    Characters: ``R`` rigid, ``T`` contracts on top (top face free), ``B`` contracts on
    the bottom, ``S`` free shrink, ``.`` no film.
    """
    if isinstance(rows, str) or not rows:
        raise GdfeError("rows: expected a non-empty list of strings")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise GdfeError(f"rows: all rows must have the same length, got lengths {sorted(widths)}")
    grid = np.array([list(r) for r in rows])[::-1].T  # (nx, ny), j = 0 at the bottom row
    bad = set(np.unique(grid)) - set(LAYOUT_CHARS) - {"."}
    if bad:
        raise GdfeError(f"rows: unknown layout character(s) {sorted(bad)}; expected one of R T B S .")
    film = grid != "."
    mat = np.zeros(grid.shape, int)
    for ch, code in LAYOUT_CHARS.items():
        mat[grid == ch] = int(code)
    return grid_design(mat, R, h=h, pixel=pixel, nz=nz, isotropy=isotropy, film=film)


def _read_mask(name, value, shape=None):
    """A boolean mask from an array or an image file (dark or opaque pixels = True)."""
    if isinstance(value, (str, Path)):
        path = Path(value)
        if not path.is_file():
            raise GdfeFileNotFoundError(f"{name}: mask image not found: {path}")
        from PIL import Image

        img = Image.open(path)
        if img.mode in ("RGBA", "LA") or (img.mode == "P" and "transparency" in img.info):
            rgba = np.asarray(img.convert("RGBA"), float)
            arr = (rgba[..., 3] > 127) & (rgba[..., :3].mean(-1) < 128)
        else:
            arr = np.asarray(img.convert("L"), float) < 128
        arr = arr[::-1].T  # image row 0 is the top (largest y); grid is (x, y)
    else:
        arr = np.asarray(value, bool)
    if arr.ndim != 2:
        raise GdfeError(f"{name}: expected a 2-D mask, got shape {arr.shape}")
    if shape is not None and arr.shape != shape:
        raise GdfeError(f"{name}: expected a mask of shape {shape} (like 'top'), got {arr.shape}")
    return arr


def from_masks(top, bottom, pixel, R, h=DEFAULT_H, nz=1, isotropy=1.0, film=None):
    """A design from masks of the passive material printed on the top and bottom faces.

    Parameters
    ----------
    top, bottom : (nx, ny) bool array or path of an image
        True (for images: dark pixels, or opaque dark pixels) where passive material is
        printed on that face. Images are read with row 0 at the largest y.
    pixel : float [mm]
        Printer pixel size: the in-plane cell size.
    R : float
        Contraction ratio of the film's free faces.
    film : (nx, ny) bool array or image path, optional
        Where the film is (default: the whole rectangle).
    """
    pixel = check_positive("pixel", pixel)
    top = _read_mask("top", top)
    bottom = _read_mask("bottom", bottom, top.shape)
    keep = None if film is None else _read_mask("film", film, top.shape)
    mat = np.where(top & bottom, Material.RIGID,
                   np.where(bottom, Material.CONTRACT_TOP,
                            np.where(top, Material.CONTRACT_BOTTOM, Material.FREE_SHRINK))).astype(int)
    return grid_design(mat, R, h=h, pixel=pixel, nz=nz, isotropy=isotropy, film=keep,
                       meta={"kind": "masks", "pixel_mm": pixel})


def load_design(path):
    """Read a TOML design file; returns ``(design, options)``.

    The file has a ``[film]`` table (``h``, and ``R`` or ``d`` with optional ``K``, ``nz``,
    ``isotropy``) and exactly one of:

    - ``[hinge]``: ``length``, optional ``width``, ``panel_length``, ``cell_size``, ``face``;
    - ``[layout]``: ``pixel`` and ``rows`` (strings of ``R T B S .``, first row on top);
    - ``[masks]``: ``pixel``, ``top``, ``bottom`` (image paths relative to the file), optional ``film``.

    An optional ``[simulate]`` table is returned as ``options`` (``steps``, ``tol``,
    ``max_iter``, ``method``) for :func:`gdfe.simulate`.
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python < 3.11
        import tomli as tomllib
    path = Path(path)
    if not path.is_file():
        raise GdfeFileNotFoundError(f"design file not found: {path}")
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise GdfeError(f"{path.name}: not valid TOML: {exc}") from None
    film = doc.get("film")
    if not isinstance(film, dict):
        raise GdfeError(f"{path.name}: missing [film] table (h, and R or d)")
    known = {"h", "R", "d", "K", "nz", "isotropy"}
    unknown = set(film) - known
    if unknown:
        raise GdfeError(f"{path.name}: [film] has unknown key(s) {sorted(unknown)}; expected {sorted(known)}")
    h = film.get("h", DEFAULT_H)
    K = film.get("K", PAPER_K)
    if "R" in film:
        R = film["R"]
    elif "d" in film:
        R = float(Calibration(K=K, h=h).ratio(film["d"]))
    else:
        raise GdfeError(f"{path.name}: [film] needs R (contraction ratio) or d (passive thickness, mm)")
    nz = film.get("nz", 2)
    iso = film.get("isotropy", 1.0)
    kinds = [k for k in ("hinge", "layout", "masks") if k in doc]
    if len(kinds) != 1:
        raise GdfeError(f"{path.name}: expected exactly one of [hinge], [layout], [masks]; got {kinds or 'none'}")
    kind = kinds[0]
    spec = doc[kind]
    try:
        if kind == "hinge":
            des = hinge(spec["length"], R=R, h=h, nz=nz, isotropy=iso,
                        **{k: spec[k] for k in ("width", "panel_length", "cell_size", "face") if k in spec})
        elif kind == "layout":
            des = from_rows(spec["rows"], R, h=h, pixel=spec["pixel"], nz=nz, isotropy=iso)
        else:
            base = path.parent
            film_mask = base / spec["film"] if "film" in spec else None
            des = from_masks(base / spec["top"], base / spec["bottom"], spec["pixel"], R, h=h,
                             nz=film.get("nz", 1), isotropy=iso, film=film_mask)
    except KeyError as exc:
        raise GdfeError(f"{path.name}: [{kind}] is missing {exc.args[0]!r}") from None
    des.meta.setdefault("source", str(path))
    options = dict(doc.get("simulate", {}))
    unknown = set(options) - {"steps", "tol", "max_iter", "method"}
    if unknown:
        raise GdfeError(f"{path.name}: [simulate] has unknown key(s) {sorted(unknown)}")
    return des, options
