"""The film on the printer's grid: its relaxed and printable designs and its mid-surface.

A film of ``nx x ny`` pixels (one cell each, one cell through the thickness, as the printer's
masks are read by :func:`gdfe.from_masks`) carries on each face a coating fraction ``rho`` per
cell. The relaxed design interpolates the face's contraction linearly,
``c = c_0 (1 - rho)``, with ``c_0`` the contraction of a free face next to a coat of
thickness ``d`` (:meth:`gdfe.DeformationModel.contraction`): every cell of the GDFE energy has
the same stiffness, so a fine pattern of coated and free pixels with a coated fraction
``rho`` contracts on average by that amount, and the relaxation is what a halftone of it prints.
The printable design is read from two masks by :func:`gdfe.from_masks` with the same film, ``d``
and model (whose geometric mechanisms, if any, then act on the printed layout).

Lengths in mm.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import scipy.sparse as sp

from gdfe._validation import GdfeError, check_array, check_positive
from gdfe.design import from_masks
from gdfe.model import as_model, paper_model

__all__ = ["Film", "MidSurface"]


@dataclasses.dataclass(frozen=True, eq=False)
class MidSurface:
    """The mid-surface of a one-layer film: one point per in-plane lattice point.

    Attributes
    ----------
    bottom, top : (k,) int arrays
        The design's vertices below and above each lattice point.
    flat : (k, 2) float array [mm]
        Flat coordinates of the lattice points, from the film's centre.
    triangles : (t, 3) int arrays
        Two triangles per cell, counter-clockwise seen from the top face.
    """

    bottom: np.ndarray
    top: np.ndarray
    flat: np.ndarray
    triangles: np.ndarray

    @classmethod
    def of(cls, design, centre):
        mesh = design.mesh
        dx, dy = mesh.spacing[:2]
        P = mesh.points
        if int(mesh.cell_k.max()) != 0:
            raise GdfeError("design: expected one cell through the thickness (a film read from masks)")
        key = np.round(P[:, :2] / [dx, dy]).astype(np.int64)
        k = np.round(P[:, 2] / design.h).astype(int)
        bot, top = np.nonzero(k == 0)[0], np.nonzero(k == 1)[0]
        bot = bot[np.lexsort((key[bot, 1], key[bot, 0]))]
        top = top[np.lexsort((key[top, 1], key[top, 0]))]
        if len(bot) != len(top) or np.any(key[bot] != key[top]):
            raise GdfeError("design: every lattice point needs a vertex on each face")
        index = np.full(tuple(key[bot].max(axis=0) + 1), -1)
        index[key[bot, 0], key[bot, 1]] = np.arange(len(bot))
        i, j = mesh.cell_ij.T
        corners = np.column_stack([index[i + a, j + b] for a, b in ((0, 0), (1, 0), (1, 1), (0, 1))])
        tris = np.concatenate([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]])
        return cls(bottom=bot, top=top, flat=P[bot, :2] - centre, triangles=tris)

    def points(self, V):
        """Mid-surface points ``(k, 3)`` [mm] of the design's vertices ``V``."""
        return 0.5 * (V[self.bottom] + V[self.top])

    def pull_back(self, g, n):
        """The gradient by the design's ``n`` vertices ``(n, 3)`` of a gradient by the mid-surface points ``g``."""
        out = np.zeros((n, 3))
        out[self.bottom] += 0.5 * g
        out[self.top] += 0.5 * g
        return out

    @functools.cached_property
    def averaging(self):
        """The sparse ``(k, n)`` matrix of :meth:`points`."""
        k = len(self.bottom)
        n = int(max(self.bottom.max(), self.top.max())) + 1
        rows = np.concatenate([np.arange(k), np.arange(k)])
        return sp.csr_matrix((np.full(2 * k, 0.5), (rows, np.concatenate([self.bottom, self.top]))), shape=(k, n))


@dataclasses.dataclass(frozen=True, eq=False)
class Film:
    """A film on the printer's grid with its passive coat and deformation model.

    Parameters
    ----------
    shape : (nx, ny) ints
        Pixels along x and y.
    pixel : float [mm]
    h : float [mm]
        Film thickness.
    d : float [mm]
        Passive thickness of both faces' coat.
    model : DeformationModel, optional
        Default the paper's Eq. 3.
    mask : (nx, ny) bool array, optional
        Where the film is (default everywhere).

    Attributes
    ----------
    c0 : float
        Contraction of a free face, ``model.contraction(d, h)``.
    base : Design
        The film uncoated (every cell free on both faces), on which relaxed designs are made.
    centre : (2,) float array [mm]
        The film rectangle's centre in design coordinates.
    mid : MidSurface
    ij : (m, 2) int array
        Pixel of every cell.
    """

    shape: tuple
    pixel: float
    h: float
    d: float
    model: object = None
    mask: np.ndarray | None = None

    def __post_init__(self):
        nx, ny = (int(v) for v in self.shape)
        if nx < 2 or ny < 2:
            raise GdfeError(f"film: expected at least 2 x 2 pixels, got {nx} x {ny} (make the pixel smaller)")
        object.__setattr__(self, "shape", (nx, ny))
        object.__setattr__(self, "pixel", check_positive("pixel", self.pixel))
        object.__setattr__(self, "h", check_positive("h", self.h))
        object.__setattr__(self, "d", check_positive("d", self.d))
        object.__setattr__(self, "model", as_model(self.model) or paper_model())
        if self.mask is not None:
            m = check_array("mask", self.mask, shape=(nx, ny), dtype=bool)
            if m.sum() < 4:
                raise GdfeError("mask: expected a film of at least 4 pixels")
            object.__setattr__(self, "mask", m)

    @functools.cached_property
    def c0(self) -> float:
        return float(self.model.contraction(self.d, self.h))

    @functools.cached_property
    def base(self):
        none = np.zeros(self.shape, bool)
        return from_masks(none, none, self.pixel, h=self.h, film=self.mask, d=self.d, model=self.model)

    @property
    def centre(self):
        return 0.5 * self.pixel * np.array(self.shape, float)

    @functools.cached_property
    def ij(self):
        return self.base.mesh.cell_ij

    @functools.cached_property
    def cell_centres(self):
        """Flat centres of the cells ``(m, 2)`` [mm], from the film's centre."""
        return (self.ij + 0.5) * self.pixel - self.centre

    @functools.cached_property
    def mid(self) -> MidSurface:
        return MidSurface.of(self.base, self.centre)

    @property
    def n_cells(self) -> int:
        return self.base.n_cells

    def relaxed(self, rho):
        """The relaxed design of coating fractions ``rho`` ``(m, 2)`` (top, bottom) in [0, 1]."""
        rho = np.asarray(rho, float)
        c = self.c0 * (1.0 - np.clip(rho, 0.0, 1.0))
        return dataclasses.replace(self.base, contraction=c, meta={**self.base.meta, "kind": "relaxed coating"})

    def grid(self, values):
        """Per-cell values ``(m, ...)`` on the pixel grid ``(nx, ny, ...)`` (NaN where there is no film)."""
        values = np.asarray(values, float)
        out = np.full(self.shape + values.shape[1:], np.nan)
        out[self.ij[:, 0], self.ij[:, 1]] = values
        return out

    def cells(self, grid):
        """Values on the pixel grid ``(nx, ny, ...)`` at the film's cells ``(m, ...)``."""
        return np.asarray(grid)[self.ij[:, 0], self.ij[:, 1]]

    def printable(self, top, bottom):
        """The design printed from the masks ``top``, ``bottom`` ``(nx, ny)`` bool (True = coated)."""
        top = np.asarray(top, bool)
        bottom = np.asarray(bottom, bool)
        if self.mask is not None:
            top, bottom = top & self.mask, bottom & self.mask
        return from_masks(top, bottom, self.pixel, h=self.h, film=self.mask, d=self.d, model=self.model)
