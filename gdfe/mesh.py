"""Structured hexahedral meshes of films.

Vertex order of a cell is VTK's ``VTK_HEXAHEDRON``: the bottom face (0, 1, 2, 3)
counter-clockwise seen from +z, then the top face (4, 5, 6, 7) above it. The film's
bottom face lies at z = 0 and its top face at z = h.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gdfe._validation import GdfeError, check_int, check_length
from gdfe.resources import check_design_cells

__all__ = ["HexMesh", "sheet_mesh", "DEFAULT_NZ"]

#: Cell layers through the film when none is given: the same for every way a design is made
#: (:func:`gdfe.hinge`, layouts, masks, drawings, design files and ``gdfe hinge``).
DEFAULT_NZ = 1

# (di, dj, dk) offsets of the eight vertices of a cell in VTK order
_HEX_OFFSETS = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]
)


@dataclasses.dataclass(frozen=True)
class HexMesh:
    """A hexahedral mesh.

    Attributes
    ----------
    points : (n, 3) float array [mm]
        Vertex coordinates in the flat, as-printed state.
    cells : (m, 8) int array
        Vertex indices of each hexahedron, VTK order.
    cell_ij : (m, 2) int array
        In-plane grid index (column i along x, row j along y) of each cell.
    cell_k : (m,) int array
        Layer index of each cell through the film thickness (0 = bottom).
    spacing : (3,) float array [mm]
        Cell size along x, y, z.
    """

    points: np.ndarray
    cells: np.ndarray
    cell_ij: np.ndarray
    cell_k: np.ndarray
    spacing: np.ndarray

    @property
    def n_points(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_cells(self) -> int:
        return int(self.cells.shape[0])

    def cell_volumes(self) -> np.ndarray:
        """Volume of each cell [mm^3] (cells are boxes in the flat state)."""
        return np.full(self.n_cells, float(np.prod(self.spacing)))


def sheet_mesh(keep, dx, dy, h, nz=DEFAULT_NZ, origin=(0.0, 0.0)):
    """Mesh a film whose in-plane cells are given by a boolean grid.

    Parameters
    ----------
    keep : (nx, ny) bool array
        ``keep[i, j]`` is True where the film has a cell at column ``i`` (along x) and
        row ``j`` (along y). All-True gives a rectangular sheet.
    dx, dy : float [mm]
        In-plane cell size.
    h : float [mm]
        Film thickness.
    nz : int
        Number of cell layers through the thickness (>= 1).
    origin : (2,) float [mm]
        Position of the grid's corner (i = j = 0).

    Returns
    -------
    HexMesh
        Unused vertices are dropped; cells are ordered by layer, then row, then column.
    """
    keep = np.asarray(keep, dtype=bool)
    if keep.ndim != 2 or keep.size == 0:
        raise GdfeError(f"keep: expected a non-empty 2-D boolean grid, got shape {keep.shape}")
    if not keep.any():
        raise GdfeError("film: expected at least one cell of film, got none")
    dx, dy, h = check_length("dx", dx), check_length("dy", dy), check_length("h", h)
    nz = check_int("nz", nz)
    check_design_cells("design", int(np.count_nonzero(keep)) * nz)
    nx, ny = keep.shape
    ii, jj = np.nonzero(keep)
    order = np.lexsort((ii, jj))  # row-major: j slow, i fast
    ii, jj = ii[order], jj[order]
    ncol = ii.size
    kk = np.repeat(np.arange(nz), ncol)
    ii, jj = np.tile(ii, nz), np.tile(jj, nz)
    vi = ii[:, None] + _HEX_OFFSETS[:, 0]
    vj = jj[:, None] + _HEX_OFFSETS[:, 1]
    vk = kk[:, None] + _HEX_OFFSETS[:, 2]
    flat = vi + (nx + 1) * (vj + (ny + 1) * vk)
    # the lattice points used, numbered in order (a dense map: np.unique is slower at 10^6 cells)
    mark = np.zeros((nx + 1) * (ny + 1) * (nz + 1), bool)
    mark[flat.ravel()] = True
    used = np.nonzero(mark)[0]
    number = np.cumsum(mark) - 1
    cells = number[flat].reshape(-1, 8)
    pi = used % (nx + 1)
    pj = (used // (nx + 1)) % (ny + 1)
    pk = used // ((nx + 1) * (ny + 1))
    points = np.column_stack([origin[0] + pi * dx, origin[1] + pj * dy, pk * (h / nz)])
    return HexMesh(
        points=points, cells=cells, cell_ij=np.column_stack([ii, jj]), cell_k=kk,
        spacing=np.array([dx, dy, h / nz]),
    )
