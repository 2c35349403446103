"""Hexahedral plates meshed from any :class:`gdfe.Design`: film, and a passive coat where printed.

A design's in-plane cells (masks, text layouts, SVG/FOLD drawings, hinges) each say which faces of
the film carry passive material (:class:`gdfe.Material`). The plate model meshes, over the
design's grid of cells:

- the film, ``0 <= z <= h``, wherever the design has film;
- the bottom coat, ``-d_bottom <= z <= 0``, under cells whose bottom face is coated
  (``RIGID``, ``CONTRACT_TOP``);
- the top coat, ``h <= z <= h + d_top``, over cells whose top face is coated
  (``RIGID``, ``CONTRACT_BOTTOM``);

with hexahedra through the thickness (every ply ``layers_per_ply`` elements, the film an even
number so that its mid-plane is a node plane). The coat may be thicker on some cells than on
others: the node planes of a coat are the union of those of each thickness present, and an
element of the coat is kept where the cell's coat reaches it. Each design cell is cut into
``refine x refine`` elements in-plane; ``coarsen`` first merges ``coarsen x coarsen`` blocks of
cells (the majority material of the block: the same masks printed with a coarser pixel); a
coarsening that would change the film's extent or lose a region of one material beyond a block's
rounding (a one-pixel hinge) is refused, naming what it would lose and the factors that keep them.

The film's eigenstrain (the material's, :class:`~reference_fem.BilayerMaterial`) is an
in-plane contraction; the design's ``isotropy`` scales its y component as in GDFE. Per-element
eigenstrains and coat stiffness factors (:attr:`Plate.eigenstrain`, :attr:`Plate.stiffness`)
model effects that GDFE's principle leaves out (a stiffer coat, an anisotropic film).

Units: mm.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from gdfe import _validation as v
from gdfe._validation import GdfeError, GdfeTypeError
from gdfe.material import Material
from .mesh import BOTTOM_COAT, FILM, TOP_COAT, _ply_nodes

__all__ = ["Plate", "plate_mesh", "design_grid", "DesignGrid", "PLATE_RESOLUTIONS"]

#: Presets of :func:`plate_mesh`: elements per design cell in-plane, elements per ply.
PLATE_RESOLUTIONS = {
    "coarse": {"refine": 1, "layers_per_ply": 2},
    "default": {"refine": 2, "layers_per_ply": 2},
    "fine": {"refine": 4, "layers_per_ply": 2},
}

_BOTTOM_COATED = (int(Material.RIGID), int(Material.CONTRACT_TOP))
_TOP_COATED = (int(Material.RIGID), int(Material.CONTRACT_BOTTOM))


@dataclasses.dataclass
class DesignGrid:
    """A design's in-plane cells as a grid.

    Attributes
    ----------
    material : (nx, ny) int array
        :class:`gdfe.Material` code of each cell; -1 where there is no film.
    d_top, d_bottom : (nx, ny) float arrays [mm]
        Coat thickness on each face; NaN where that face is free.
    pixel : (2,) float array [mm]
        Cell size (dx, dy).
    origin : (2,) float array [mm]
        Position of the corner of cell (0, 0).
    """

    material: np.ndarray
    d_top: np.ndarray
    d_bottom: np.ndarray
    pixel: np.ndarray
    origin: np.ndarray

    @property
    def film(self) -> np.ndarray:
        return self.material >= 0


def design_grid(design, d=None) -> DesignGrid:
    """The in-plane grid of a design with the coat thickness of each face of each cell.

    Parameters
    ----------
    design : gdfe.Design
    d : float [mm], optional
        Coat thickness wherever the design does not give one (a cell coated on both faces, a
        design made from ``R`` alone). Default: the design's own (``d_top_mm``, ``d_bottom_mm``,
        ``d_mm`` of its description, else the median of its known ``d``).

    Raises
    ------
    GdfeError
        When a coated face has no thickness from the design and none is given.
    """
    from gdfe.design import Design

    if not isinstance(design, Design):
        raise GdfeTypeError(f"design: expected a gdfe.Design, got {type(design).__name__}")
    if d is not None:
        d = v.check_length("d", d, allow_array=False)
    mesh = design.mesh
    first = np.nonzero(mesh.cell_k == 0)[0]
    ij = mesh.cell_ij[first]
    nx, ny = ij.max(axis=0) + 1
    material = np.full((nx, ny), -1, dtype=np.int64)
    material[ij[:, 0], ij[:, 1]] = design.material[first]
    known = np.full((nx, ny), np.nan)
    if design.d is not None:
        known[ij[:, 0], ij[:, 1]] = design.d[first]
    meta = design.meta or {}
    finite = design.d[np.isfinite(design.d)] if design.d is not None else np.empty(0)

    def fallback(key):
        for k in (key, "d_mm"):
            if meta.get(k) is not None:
                return float(meta[k])
        if d is not None:
            return d
        return float(np.median(finite)) if finite.size else np.nan

    face_top = np.isin(material, _TOP_COATED)
    face_bottom = np.isin(material, _BOTTOM_COATED)
    one_side_top = material == int(Material.CONTRACT_BOTTOM)  # coat on top only: its d is the cell's
    one_side_bottom = material == int(Material.CONTRACT_TOP)
    d_top = np.where(face_top, fallback("d_top_mm") if d is None else d, np.nan)
    d_bottom = np.where(face_bottom, fallback("d_bottom_mm") if d is None else d, np.nan)
    d_top = np.where(one_side_top & np.isfinite(known), known, d_top)
    d_bottom = np.where(one_side_bottom & np.isfinite(known), known, d_bottom)
    missing = (face_top & ~np.isfinite(d_top)) | (face_bottom & ~np.isfinite(d_bottom))
    if missing.any():
        i, j = np.argwhere(missing)[0]
        raise GdfeError(f"d: expected a passive coat thickness in mm (the design gives none for its coated "
                        f"cells, e.g. cell ({i}, {j})), got none; pass d")
    origin = mesh.points[:, :2].min(axis=0)
    return DesignGrid(material=material, d_top=d_top, d_bottom=d_bottom,
                      pixel=np.asarray(mesh.spacing[:2], float), origin=np.asarray(origin, float))


def _coarsened(grid: DesignGrid, k: int) -> DesignGrid:
    """Merge k x k blocks of cells: each block takes the most common material of its film cells.

    Raises
    ------
    GdfeError
        Naming ``coarsen`` where the merge would change the film's extent or lose a region of one
        material (:func:`_coarsening_losses`), with the factors that keep them.
    """
    if k == 1:
        return grid
    lost = _coarsening_losses(grid, k)
    if lost:
        nx, ny = grid.material.shape
        keep = [f for f in range(2, min(nx, ny) + 1) if not _coarsening_losses(grid, f)]
        works = (f"factors that keep them: {', '.join(map(str, keep))}" if keep else
                 "only 1 keeps them (no coarsening)")
        raise GdfeError(f"coarsen: expected a factor that keeps the film's extent and every region of one "
                        f"material, got {k}: {'; '.join(lost[:MAX_LOSSES])}"
                        f"{f' and {len(lost) - MAX_LOSSES} more' if len(lost) > MAX_LOSSES else ''}; {works}")
    return _merged(grid, k)


#: Losses a coarsening's message lists before it says how many more there are.
MAX_LOSSES = 3


def _coarsening_losses(grid: DesignGrid, k: int) -> list:
    """What merging k x k blocks would lose, in words (empty where it keeps the design).

    The film's extent is kept where its grid is a whole number of blocks along x and along y. A
    region (the cells of one material joined side to side: a hinge, a panel, a free-shrinking patch)
    is kept where some block takes its material, and where the blocks that take it, among those the
    region touches, hold as many cells as it has to within half a block (its cell count rounded to
    whole blocks). A region that no block keeps is lost however small: a one-pixel hinge is a fold.
    """
    from scipy import ndimage

    nx, ny = grid.material.shape
    if nx % k or ny % k:
        px, py = -(-nx // k) * k, -(-ny // k) * k
        return [f"the film's grid of {nx} x {ny} cells ({nx * grid.pixel[0]:.4g} x {ny * grid.pixel[1]:.4g} mm) "
                f"is not a whole number of {k} x {k} blocks: padded to {px} x {py} cells "
                f"({px * grid.pixel[0]:.4g} x {py * grid.pixel[1]:.4g} mm), the blocks on its edge would change "
                f"the film's extent"]
    coarse = _block_material(grid.material, k).ravel()
    block = np.kron(np.arange(coarse.size).reshape(nx // k, ny // k), np.ones((k, k), int))  # each cell's block
    out = []
    for code in np.unique(grid.material[grid.film]):
        labels, n = ndimage.label(grid.material == code)
        inside = labels > 0
        size = np.bincount(labels[inside], minlength=n + 1)
        pairs = np.unique(labels[inside] * coarse.size + block[inside])  # (region, block) touched
        region, touched = np.divmod(pairs, coarse.size)
        kept = np.bincount(region, weights=coarse[touched] == code, minlength=n + 1).astype(int) * k * k
        lost = (kept == 0) | (2 * np.abs(kept - size) > k * k)
        boxes = ndimage.find_objects(labels)
        for r in np.flatnonzero(lost[1:]) + 1:
            out.append(_region_loss(grid, boxes[r - 1], Material(int(code)).name.lower(), size[r], kept[r]))
    return out


def _region_loss(grid, box, name, size, kept):
    """``N name cells at x .. mm, y .. mm vanish`` (or ``become M``) of a region in the slices ``box``."""
    lo = grid.origin + np.array([box[0].start, box[1].start]) * grid.pixel
    hi = grid.origin + np.array([box[0].stop, box[1].stop]) * grid.pixel
    change = "vanish" if kept == 0 else f"become {kept}"
    cells = f"{size} {name} cell{'s' if size != 1 else ''}"
    return f"{cells} at x {lo[0]:.4g}-{hi[0]:.4g} mm, y {lo[1]:.4g}-{hi[1]:.4g} mm {change}"


def _blocks(a, k):
    """``(nx/k, ny/k, k*k)``: the values of ``a`` in each k x k block (its shape a whole number of blocks)."""
    nx, ny = a.shape
    return a.reshape(nx // k, k, ny // k, k).transpose(0, 2, 1, 3).reshape(nx // k, ny // k, k * k)


def _block_material(material, k):
    """Each k x k block's material: film where at least half its cells are, of the most common material
    of its film cells (-1 elsewhere)."""
    blocks = _blocks(material, k)
    counts = np.stack([(blocks == c).sum(axis=2) for c in range(4)], axis=2)
    return np.where(2 * counts.sum(axis=2) >= k * k, counts.argmax(axis=2), -1)


def _merged(grid: DesignGrid, k: int) -> DesignGrid:
    """The grid of k x k blocks (the grid a whole number of them): :func:`_block_material`, and the median
    coat thickness of each face over the block."""
    material = _block_material(grid.material, k)

    def thickness(d):
        with warnings.catch_warnings():  # blocks with no coat on that face are NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmedian(_blocks(d, k), axis=2)

    d_top, d_bottom = thickness(grid.d_top), thickness(grid.d_bottom)
    fill_t = np.nanmedian(grid.d_top) if np.isfinite(grid.d_top).any() else np.nan
    fill_b = np.nanmedian(grid.d_bottom) if np.isfinite(grid.d_bottom).any() else np.nan
    d_top = np.where(np.isin(material, _TOP_COATED), np.where(np.isfinite(d_top), d_top, fill_t), np.nan)
    d_bottom = np.where(np.isin(material, _BOTTOM_COATED), np.where(np.isfinite(d_bottom), d_bottom, fill_b),
                        np.nan)
    return DesignGrid(material=material, d_top=d_top, d_bottom=d_bottom, pixel=grid.pixel * k,
                      origin=grid.origin)


@dataclasses.dataclass
class Plate:
    """A meshed plate: film and coats over a design's cells.

    Attributes
    ----------
    mesh : skfem.MeshHex
        Trilinear hexahedral mesh [mm] (the element type of a solve is chosen there).
    ply : (n_el,) int array
        :data:`~reference_fem.mesh.BOTTOM_COAT`, :data:`~reference_fem.mesh.FILM` or
        :data:`~reference_fem.mesh.TOP_COAT` of each element.
    cell : (n_el, 2) int array
        Design cell (i, j) of each element, on the (possibly coarsened) grid.
    grid : DesignGrid
        The design's grid the plate was meshed on.
    h : float [mm]
        Film thickness.
    isotropy : float
        The design's in-plane isotropy: the film's eigenstrain along y is ``isotropy`` times that
        along x.
    refine : int
        Elements per design cell along x and y.
    eigenstrain : (n_el, 3) float array or None
        Per-element eigenstrain of the film (xx, yy, zz), replacing the material's; None: the
        material's, with y scaled by :attr:`isotropy`.
    stiffness : (n_el,) float array or None
        Factor on each element's Young's modulus (a stiffer coat in a region); None: 1.
    meta : dict
    """

    mesh: object
    ply: np.ndarray
    cell: np.ndarray
    grid: DesignGrid
    h: float
    isotropy: float
    refine: int
    eigenstrain: np.ndarray | None = None
    stiffness: np.ndarray | None = None
    meta: dict = dataclasses.field(default_factory=dict)

    @property
    def n_elements(self) -> int:
        return int(self.mesh.t.shape[1])

    @property
    def z_mid(self) -> float:
        """Height of the film's mid-plane [mm]."""
        return 0.5 * self.h

    @property
    def size(self) -> float:
        """Largest in-plane extent of the film [mm] (the part's size, for relative distances)."""
        ij = np.argwhere(self.grid.film)
        ext = (ij.max(axis=0) - ij.min(axis=0) + 1) * self.grid.pixel
        return float(np.hypot(*ext))

    @property
    def in_plane_step(self) -> np.ndarray:
        """Element size along x and y [mm]."""
        return self.grid.pixel / self.refine

    def summary(self) -> dict:
        ij = np.argwhere(self.grid.film)
        return {"n_elements": self.n_elements, "n_cells": int(ij.shape[0]), "h_mm": self.h,
                "pixel_mm": self.grid.pixel.tolist(), "refine": self.refine,
                "element_size_mm": self.in_plane_step.tolist(), "isotropy": self.isotropy,
                "size_mm": self.size, **self.meta}


def plate_mesh(design, *, resolution="default", refine=None, layers_per_ply=None, coarsen=1, d=None,
               max_coat_levels=4, meta=None) -> Plate:
    """Mesh a design's film and its coats with hexahedra.

    Parameters
    ----------
    design : gdfe.Design
        Any design (masks, layouts, drawings, hinges); its cells must be axis-aligned (as made).
    resolution : {"coarse", "default", "fine"}
        Preset for ``refine`` and ``layers_per_ply`` (:data:`PLATE_RESOLUTIONS`); either given
        explicitly wins.
    refine : int, optional
        Elements per design cell along x and y, >= 1.
    layers_per_ply : int, optional
        Elements through each ply, >= 1; the film gets the next even number (one layer only with
        quadratic elements, whose middle nodes lie on the film's mid-plane).
    coarsen : int
        Merge ``coarsen x coarsen`` blocks of design cells first (>= 1; 1: the design's own cells);
        refused where that changes the film's extent or loses a region of one material.
    d : float [mm], optional
        Coat thickness where the design gives none (see :func:`design_grid`).
    max_coat_levels : int
        Most distinct coat thicknesses per face (each adds node planes).
    meta : dict, optional
        Stored in :attr:`Plate.meta`.

    Returns
    -------
    Plate

    Raises
    ------
    GdfeError
        Naming ``coarsen`` where the merge would lose a region or change the film's extent.
    """
    from skfem import MeshHex

    v.check_choice("resolution", resolution, set(PLATE_RESOLUTIONS))
    preset = PLATE_RESOLUTIONS[resolution]
    refine = v.check_int("refine", preset["refine"] if refine is None else refine)
    nply = v.check_int("layers_per_ply", preset["layers_per_ply"] if layers_per_ply is None else layers_per_ply)
    coarsen = v.check_int("coarsen", coarsen)
    grid = _coarsened(design_grid(design, d), coarsen)
    h = float(design.h)
    film = grid.film
    coat = _ply_nodes(nply, 1.0)
    # the film's mid-plane must carry nodes: an even number of layers, or one quadratic element
    film_layers = 1 if nply == 1 else 2 * math.ceil(nply / 2)
    zs = [h * np.linspace(0.0, 1.0, film_layers + 1)]
    levels = {}
    for face, dd, sign in (("top", grid.d_top, 1.0), ("bottom", grid.d_bottom, -1.0)):
        values = np.unique(np.round(dd[np.isfinite(dd)], 9))
        if values.size > max_coat_levels:
            raise GdfeError(f"d: expected at most {max_coat_levels} distinct {face} coat thicknesses, got "
                            f"{values.size} ({values.min():g} to {values.max():g} mm); round them or raise "
                            f"max_coat_levels")
        levels[face] = values
        for t in values:
            zs.append((h if sign > 0 else 0.0) + sign * t * coat[1:])
    z = np.unique(np.round(np.concatenate(zs), 12))
    nx, ny = film.shape
    x = grid.origin[0] + np.arange(nx * refine + 1) * (grid.pixel[0] / refine)
    y = grid.origin[1] + np.arange(ny * refine + 1) * (grid.pixel[1] / refine)
    full = MeshHex.init_tensor(x, y, z)
    centre = full.p[:, full.t].mean(axis=1)
    ci = np.clip(np.floor((centre[0] - grid.origin[0]) / grid.pixel[0]).astype(int), 0, nx - 1)
    cj = np.clip(np.floor((centre[1] - grid.origin[1]) / grid.pixel[1]).astype(int), 0, ny - 1)
    zc = centre[2]
    ply = np.where(zc < 0.0, BOTTOM_COAT, np.where(zc > h, TOP_COAT, FILM))
    with np.errstate(invalid="ignore"):
        in_top = (ply == TOP_COAT) & (zc < h + np.nan_to_num(grid.d_top[ci, cj], nan=-1.0))
        in_bottom = (ply == BOTTOM_COAT) & (zc > -np.nan_to_num(grid.d_bottom[ci, cj], nan=-1.0))
    keep = film[ci, cj] & ((ply == FILM) | in_top | in_bottom)
    if not keep.any():
        raise GdfeError("design: expected at least one cell of film, got none")
    idx = np.nonzero(keep)[0]
    mesh = full.restrict(idx)
    info = {"coat_levels_mm": {k: vals.tolist() for k, vals in levels.items()}, "coarsen": coarsen,
            "layers_per_ply": nply, "resolution": resolution, **dict(meta or {})}
    return Plate(mesh=mesh, ply=ply[idx].astype(np.int8), cell=np.column_stack([ci[idx], cj[idx]]),
                 grid=grid, h=h, isotropy=float(design.isotropy), refine=refine, meta=info)
