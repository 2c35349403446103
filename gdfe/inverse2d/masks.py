"""From coating fractions to printable masks: the density filter, halftoning and w_min.

The relaxed design gives each cell and face a coating fraction ``rho`` in [0, 1]; a printer
coats a pixel or not. The masks here respect the printer's narrowest feature ``w_min``: the
pixels are grouped in square blocks of ``b = ceil(w_min / pixel)`` pixels a side, and each
block is coated or free as a whole, so every coated region and every gap on a face is a union
of ``w_min x w_min`` squares (a mask equal to its morphological opening, and its complement to
its own; :func:`min_feature_ok` checks it).

- :func:`halftone`: error diffusion (Floyd and Steinberg's weights 7, 3, 5, 1 / 16, serpentine
  scan) of the block means of ``rho``: the fraction of coated blocks follows ``rho`` over a few
  blocks, which is what the relaxation's linear interpolation assumes (every GDFE cell has the
  same stiffness, so a fine pattern contracts by its mean);
- :func:`threshold`: blocks whose mean ``rho`` is at least 1/2 are coated (the projection of
  topology optimisation; it keeps only the large features and loses graded coatings);
- :func:`density_filter`: the linear cone filter of topology optimisation,
  ``rho~_i = sum_j w_ij rho_j / sum_j w_ij`` with ``w_ij = max(0, r - |x_i - x_j|)``: applied to
  the optimiser's variables, it keeps the relaxed coating smooth over the scale a halftone can
  reproduce.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from gdfe._validation import GdfeError, check_array, check_choice, check_positive

__all__ = ["PROJECTIONS", "block_size", "density_filter", "halftone", "nested_halftone", "threshold", "project",
           "min_feature_ok"]

#: The projections of :func:`project`.
PROJECTIONS = ("halftone", "nested", "threshold")


def block_size(w_min, pixel):
    """Pixels per block side, ``ceil(w_min / pixel)`` (at least 1)."""
    w_min, pixel = check_positive("w_min", w_min), check_positive("pixel", pixel)
    return max(1, int(np.ceil(w_min / pixel - 1e-9)))


def density_filter(centres, radius):
    """The cone filter on points ``centres`` ``(m, 2)`` [mm] with ``radius`` [mm]: a sparse ``(m, m)`` matrix.

    Rows sum to 1; a radius below the spacing gives the identity.
    """
    from scipy.spatial import cKDTree

    X = check_array("centres", centres, shape=(-1, 2))
    radius = float(radius)
    m = len(X)
    if radius <= 0:
        return sp.identity(m, format="csr")
    pairs = cKDTree(X).query_pairs(radius, output_type="ndarray")
    i = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(m)])
    j = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(m)])
    w = np.maximum(radius - np.linalg.norm(X[i] - X[j], axis=1), 0.0)
    F = sp.csr_matrix((w, (i, j)), shape=(m, m))
    s = np.asarray(F.sum(axis=1)).ravel()
    return sp.diags(1.0 / s) @ F


def _blocks(grid, b, present):
    """Block means ``(Bx, By)`` of a pixel grid over the film's pixels, and the blocks' film fraction."""
    nx, ny = grid.shape
    Bx, By = -(-nx // b), -(-ny // b)
    g = np.zeros((Bx * b, By * b))
    p = np.zeros((Bx * b, By * b))
    g[:nx, :ny] = np.where(present, np.nan_to_num(grid), 0.0)
    p[:nx, :ny] = present
    gs = g.reshape(Bx, b, By, b).sum(axis=(1, 3))
    ps = p.reshape(Bx, b, By, b).sum(axis=(1, 3))
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(ps > 0, gs / ps, 0.0)
    return mean, ps > 0


def _expand(blocks, b, shape):
    return np.kron(blocks, np.ones((b, b), bool)).astype(bool)[:shape[0], :shape[1]]


def _error_diffusion(g, present):
    """Floyd-Steinberg error diffusion of ``g`` (values in [0, 1]) on the present cells, serpentine."""
    g = np.array(g, float)
    out = np.zeros(g.shape, bool)
    H, W = g.shape
    for i in range(H):
        fwd = i % 2 == 0
        cols = range(W) if fwd else range(W - 1, -1, -1)
        d = 1 if fwd else -1
        for j in cols:
            if not present[i, j]:
                continue
            o = g[i, j] >= 0.5
            out[i, j] = o
            e = g[i, j] - o
            for di, dj, wgt in ((0, d, 7 / 16), (1, -d, 3 / 16), (1, 0, 5 / 16), (1, d, 1 / 16)):
                a, c = i + di, j + dj
                if 0 <= a < H and 0 <= c < W and present[a, c]:
                    g[a, c] += e * wgt
    return out


def halftone(grid, b, present=None):
    """A mask ``(nx, ny)`` bool whose coated fraction follows ``grid`` (coating fractions in [0, 1]).

    Blocks of ``b x b`` pixels are coated or free as a whole (error diffusion of their means).
    """
    grid = np.asarray(grid, float)
    present = np.ones(grid.shape, bool) if present is None else np.asarray(present, bool)
    mean, pb = _blocks(np.clip(grid, 0.0, 1.0), b, present)
    return _expand(_error_diffusion(mean, pb), b, grid.shape) & present


def threshold(grid, b, present=None):
    """A mask ``(nx, ny)`` bool: the blocks of ``b x b`` pixels whose mean coating fraction is at least 1/2."""
    grid = np.asarray(grid, float)
    present = np.ones(grid.shape, bool) if present is None else np.asarray(present, bool)
    mean, pb = _blocks(grid, b, present)
    return _expand((mean >= 0.5) & pb, b, grid.shape) & present


def nested_halftone(rho_top, rho_bottom, b, present=None):
    """Masks ``(top, bottom)`` whose coats are nested: the less coated face's blocks lie within the other's.

    In every block the face with the larger fraction ``hi`` is halftoned; the other face is
    coated on a share ``lo / hi`` of those blocks (error diffusion of that ratio over them).
    Blocks coated on one face only are then a fraction ``|rho_top - rho_bottom|``, all bending
    the way the relaxed design bends, where independent halftones of the two faces coat one
    face only on ``rho_t (1 - rho_b) + rho_b (1 - rho_t)`` of the blocks, bending both ways.
    """
    rt = np.clip(np.asarray(rho_top, float), 0.0, 1.0)
    rb = np.clip(np.asarray(rho_bottom, float), 0.0, 1.0)
    present = np.ones(rt.shape, bool) if present is None else np.asarray(present, bool)
    mt, pb = _blocks(rt, b, present)
    mb, _ = _blocks(rb, b, present)
    hi, lo = np.maximum(mt, mb), np.minimum(mt, mb)
    first = _error_diffusion(hi, pb)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(hi > 0, lo / np.where(hi > 0, hi, 1.0), 0.0)
    second = _error_diffusion(ratio, first)
    top_more = mt >= mb
    top_b = np.where(top_more, first, second)
    bottom_b = np.where(top_more, second, first)
    return _expand(top_b, b, rt.shape) & present, _expand(bottom_b, b, rt.shape) & present


def project(rho_top, rho_bottom, b, present=None, method="halftone"):
    """The masks ``(top, bottom)`` of two faces' coating fractions ``(nx, ny)`` by ``method`` (:data:`PROJECTIONS`):
    independent halftones, nested ones (:func:`nested_halftone`) or the threshold."""
    check_choice("projection", method, PROJECTIONS)
    if method == "nested":
        return nested_halftone(rho_top, rho_bottom, b, present)
    fn = halftone if method == "halftone" else threshold
    return fn(rho_top, b, present), fn(rho_bottom, b, present)


def min_feature_ok(mask, b, present=None):
    """Whether every coated region and every gap of ``mask`` is a union of ``b x b`` squares of pixels.

    Outside the film (``present`` False, or beyond the grid) counts as either: a feature may be
    cut by the film's edge.
    """
    mask = np.asarray(mask, bool)
    if b <= 1:
        return True
    present = np.ones(mask.shape, bool) if present is None else np.asarray(present, bool)
    if mask.shape != present.shape:
        raise GdfeError(f"mask: expected shape {present.shape}, got {mask.shape}")
    return _union_of_squares(mask | ~present, b, mask) and _union_of_squares(~mask | ~present, b, ~mask & present)


def _union_of_squares(allowed, b, need):
    """Whether every ``need`` pixel lies in a ``b x b`` square of ``allowed`` pixels."""
    nx, ny = allowed.shape
    pad = np.ones((nx + 2 * b, ny + 2 * b), bool)  # beyond the film's rectangle: either
    pad[b:b + nx, b:b + ny] = allowed
    # fits[i, j]: the square with lower corner (i, j) (padded coordinates) lies in allowed
    c = np.cumsum(np.cumsum(pad.astype(np.int64), 0), 1)
    c = np.pad(c, ((1, 0), (1, 0)))
    fits = (c[b:, b:] - c[:-b, b:] - c[b:, :-b] + c[:-b, :-b]) == b * b  # (nx + b + 1, ny + b + 1)
    covered = np.zeros_like(pad)
    for di in range(b):
        for dj in range(b):
            covered[di:di + fits.shape[0], dj:dj + fits.shape[1]] |= fits[:pad.shape[0] - di, :pad.shape[1] - dj]
    return bool(np.all(covered[b:b + nx, b:b + ny][need]))
