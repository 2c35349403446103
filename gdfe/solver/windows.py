"""Windows of the print where a shape is provably embedded: the crossing test's broad phase.

Most pairs of boundary triangles that a search by distance finds lie on one face of the film,
a pixel or two apart in the print. Such a pair cannot cross while the face between them is not
folded onto itself, and that can be proved window by window.

The boundary triangles that lie in one plane of the print facing one way (the top, the bottom,
the levels of the coatings) are cut into blocks of :data:`BLOCK_CELLS` x :data:`BLOCK_CELLS`
pixels; a **window** is 2 x 2 blocks (so every two blocks that touch share one). The shape maps
a window's print ``W`` (a plane region, its coordinates ``x``) to space piecewise linearly,
with the 3 x 2 gradient ``F_t`` on triangle ``t``. When ``W`` is a rectangle (convex), for any
``x != y`` in it

    f(x) - f(y) = F_bar (x - y),   F_bar a convex combination of the F_t met along the segment,

so if some 3 x 2 matrix ``A`` has ``||F_t - A|| < sigma_min(A)`` for every ``t`` in ``W``, then
``|f(x) - f(y)| >= (sigma_min(A) - max_t ||F_t - A||) |x - y| > 0``: the window's surface is
embedded, and no two of its triangles cross. Such a window is **good**; two triangles that
lie in one good window are left out of the crossing test. The test takes ``A`` the window's
area-weighted mean gradient and bounds ``||F_t - A||`` (Frobenius, an upper bound of the
2-norm) by the block's ``max ||F_t - A_b|| + ||A_b - A||``; it asks the bound below
:data:`GOOD_MARGIN` times ``sigma_min(A)``, so that round-off never decides.

A window is a rectangle when its triangles' print area equals that of their bounding box
(boundary faces of one plane facing one way never overlap); one at a hole or an edge of the
film is not, and its triangles are tested as before. So are the triangles of the other
faces (the film's sides, the steps of the coatings), and every pair from blocks that share
no good window. The proof needs the shape continuous across a window, one vertex at each place
of the print, as gdfe's meshes have; on a mesh with two vertices at one place no window is good.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from gdfe.solver import nearby

__all__ = ["BLOCK_CELLS", "GOOD_MARGIN", "EmbeddedWindows"]

#: Pixels along each side of a block; a window is 2 x 2 blocks. At the converged 10^5-cell
#: corrugation and Figure 8 twist 100 % and 99.9 % of the windows of 8 x 8 pixels were good; blocks
#: of 3, 6 or 8 pixels made the check no faster, of 2 slower (docs/solver_history.md).
BLOCK_CELLS = 4
#: A window is good when its bound on ``||F_t - A||`` is below this fraction of ``sigma_min(A)``.
GOOD_MARGIN = 0.99
# the four windows of a block: it is their block (0, 0), (1, 0), (0, 1) or (1, 1)
_WINDOW_OFFSETS = ((0, 0), (1, 0), (0, 1), (1, 1))


def _one_vertex_per_place(print_points, tris, level, origin, pixel):
    """Whether no two vertices of ``tris`` share a place of the print (its level and pixel corner).

    The proof needs the shape continuous across a window: a surface cut along an edge, its two
    sides with vertices of their own, could pass through itself there. gdfe's meshes have one
    vertex per lattice point (:func:`gdfe.mesh.sheet_mesh`); a mesh made otherwise proves nothing.
    Points off the lattice round to a place another may share, which also proves nothing.
    """
    used = np.zeros(len(print_points), bool)
    used[tris.ravel()] = True
    v = np.nonzero(used)[0]
    ij = np.rint((print_points[v, :2] - origin) / pixel).astype(np.int64)
    if ij.min() < 0:
        return False
    span = ij.max(axis=0) + 1
    place = (level[v].astype(np.int64) * span[0] + ij[:, 0]) * span[1] + ij[:, 1]
    return bool(np.bincount(place).max() <= 1)


def _unkey(keys, span):
    """The plane and the ``(x, y)`` block coordinates of integer keys ``(plane * sx + x + 1) * sy + y + 1``."""
    xy, y = np.divmod(keys, span[1])
    plane, x = np.divmod(xy, span[0])
    return plane, np.column_stack([x - 1, y - 1])


class EmbeddedWindows:
    """The blocks and windows of a design's boundary triangles (the print's part, made once).

    Parameters
    ----------
    print_points : (n, 3) float array [mm]
        The flat print (``design.mesh.points``).
    tris : (t, 3) int array
        The boundary triangles (:func:`gdfe.solver.penetration.surface_triangles`).
    block_cells : int, optional
        :data:`BLOCK_CELLS`.

    Attributes
    ----------
    block : (t,) int array
        Each triangle's block; -1 for a triangle in no plane of the print facing up or down.
    n_blocks : int
    """

    def __init__(self, print_points, tris, block_cells=BLOCK_CELLS):
        self.tris = tris
        # a triangle lies in a plane of the print facing up or down when its corners share a level
        # of the print (exactly: two levels a round-off apart only make fewer blocks, never a wrong one)
        _, level = np.unique(print_points[:, 2], return_inverse=True)
        level = level.ravel().astype(np.int32)
        la = level[tris[:, 0]]
        flat = (la == level[tris[:, 1]]) & (la == level[tris[:, 2]])
        zt = np.nonzero(flat)[0]
        A, B, C = (print_points[tris[zt, k], :2] for k in range(3))  # their print corners (x, y)
        (ux, uy), (vx, vy) = (B - A).T, (C - A).T  # the print's edge vectors
        det = ux * vy - vx * uy  # twice the area, signed by the way the triangle faces
        keep = det != 0.0
        if not keep.all():  # a triangle of no area faces no way: tested as before
            zt, A, B, C, det = zt[keep], A[keep], B[keep], C[keep], det[keep]
            ux, uy, vx, vy = ux[keep], uy[keep], vx[keep], vy[keep]
        self.block = np.full(len(tris), -1, np.int32 if len(tris) < 2**31 else np.int64)
        if not zt.size:
            self.n_blocks, self._zt = 0, zt
            self.full, self._win = np.zeros(0, bool), np.zeros((0, len(_WINDOW_OFFSETS)), np.int64)
            return
        plane = 2 * la[zt].astype(np.int64) + (det > 0)  # its level and the way it faces
        lo2, hi2 = np.minimum(np.minimum(A, B), C), np.maximum(np.maximum(A, B), C)
        pixel = np.median(hi2 - lo2, axis=0)
        size = block_cells * pixel  # the pixel, times the block's cells
        b = np.floor(((A + B + C) / 3.0 - lo2.min(axis=0)) / size).astype(np.int64)
        # integer keys (plane, x, y), the coordinates shifted by one so that a window's (-1) fits
        span = b.max(axis=0) + 3
        key = (plane * span[0] + b[:, 0] + 1) * span[1] + b[:, 1] + 1
        used = np.zeros(int(key.max()) + 1, bool)  # small: planes x blocks; no sort
        used[key] = True
        ukeys = np.nonzero(used)[0]
        blk = (np.cumsum(used) - 1)[key]
        blk = blk.ravel()
        self.n_blocks = len(ukeys)
        self.block[zt] = blk
        order = np.argsort(blk, kind="stable")
        self._zt = zt[order]  # face triangles, block by block
        self._verts = tris[self._zt].astype(np.int32 if len(print_points) < 2**31 else np.int64)
        counts = np.bincount(blk, minlength=self.n_blocks)
        self._starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        self._plane, self._bxy = _unkey(ukeys, span)
        # the print's inverse edge matrices and areas, in block order
        ux, uy, vx, vy, det = ux[order], uy[order], vx[order], vy[order], det[order]
        # (E^-1)[j, l] with E = [u v] (columns): [[vy, -vx], [-uy, ux]] / det
        self._Einv = np.stack([vy, -vx, -uy, ux], axis=1).reshape(-1, 2, 2) / det[:, None, None]
        self._area = 0.5 * np.abs(det)
        del ux, uy, vx, vy, det
        area_b = np.add.reduceat(self._area, self._starts)
        # windows: each block is in four, by its lower-left block
        wkeys = np.concatenate([ukeys - (o[0] * span[1] + o[1]) for o in _WINDOW_OFFSETS])
        uw, win = np.unique(wkeys, return_inverse=True)
        self._win = win.ravel().reshape(len(_WINDOW_OFFSETS), self.n_blocks).T  # (blocks, 4)
        self._wplane, self._wxy = _unkey(uw, span)
        nw = len(uw)
        members = self._win.ravel()
        self._area_w = np.bincount(members, np.repeat(area_b, 4), minlength=nw)
        blo = np.minimum.reduceat(lo2[order], self._starts)
        bhi = np.maximum.reduceat(hi2[order], self._starts)
        wlo = np.full((nw, 2), np.inf)
        whi = np.full((nw, 2), -np.inf)
        np.minimum.at(wlo, members, np.repeat(blo, 4, axis=0))
        np.maximum.at(whi, members, np.repeat(bhi, 4, axis=0))
        box = np.prod(whi - wlo, axis=1)
        self.full = np.abs(self._area_w - box) <= 1e-9 * box  # the window's print is its bounding box
        self.full &= _one_vertex_per_place(print_points, tris[zt], level, lo2.min(axis=0), pixel)
        self._area_b = area_b

    # -- at one shape ---------------------------------------------------------------------------

    def good(self, X, lo, hi, chunk=262_144):
        """Which windows are good at the shape ``X`` ``(n, 3)`` [mm] (see the module docstring).

        ``lo``, ``hi`` are the triangles' boxes at the shape, ``(t, 3)`` each. Returns a bool
        array over the windows, and each block's box ``(lo, hi)`` (``(blocks, 3)`` arrays).
        """
        nb = self.n_blocks
        if not nb:
            return np.zeros(0, bool), (np.zeros((0, 3)), np.zeros((0, 3)))
        Ab = np.zeros((nb, 6))
        dev = np.zeros(nb)
        # whole blocks per chunk of about ``chunk`` triangles (bounded memory at 10^6 cells)
        edges = sorted({int(e) for e in np.searchsorted(self._starts, np.arange(0, len(self._zt), chunk))} | {nb})
        for b0, b1 in zip(edges[:-1], edges[1:]):
            s0 = self._starts[b0]
            s1 = self._starts[b1] if b1 < nb else len(self._zt)
            v = self._verts[s0:s1]
            e0, e1 = X[v[:, 1]] - X[v[:, 0]], X[v[:, 2]] - X[v[:, 0]]
            Ei = self._Einv[s0:s1]
            F = np.empty((s1 - s0, 6))  # the gradient's columns, (x, y, z) each
            F[:, :3] = e0 * Ei[:, 0, 0, None] + e1 * Ei[:, 1, 0, None]
            F[:, 3:] = e0 * Ei[:, 0, 1, None] + e1 * Ei[:, 1, 1, None]
            starts = self._starts[b0:b1] - s0
            Ab[b0:b1] = np.add.reduceat(F * self._area[s0:s1, None], starts) / self._area_b[b0:b1, None]
            F -= np.repeat(Ab[b0:b1], np.diff(np.append(starts, s1 - s0)), axis=0)
            dev[b0:b1] = np.sqrt(np.maximum.reduceat(np.einsum("ki,ki->k", F, F), starts))
        box = (np.minimum.reduceat(lo[self._zt], self._starts), np.maximum.reduceat(hi[self._zt], self._starts))
        members = self._win.ravel()
        blocks = np.repeat(np.arange(nb), 4)
        nw = len(self.full)
        Aw = np.column_stack([np.bincount(members, Ab[blocks, c] * self._area_b[blocks], minlength=nw)
                              for c in range(6)]) / self._area_w[:, None]
        spread = dev[blocks] + np.linalg.norm(Ab[blocks] - Aw[members], axis=1)
        bound = np.zeros(nw)
        np.maximum.at(bound, members, spread)
        p = np.einsum("ki,ki->k", Aw[:, :3], Aw[:, :3])
        q = np.einsum("ki,ki->k", Aw[:, :3], Aw[:, 3:])
        r = np.einsum("ki,ki->k", Aw[:, 3:], Aw[:, 3:])
        smallest = 0.5 * (p + r) - np.sqrt(0.25 * (p - r) ** 2 + q * q)  # of A^T A
        sigma = np.sqrt(np.maximum(smallest, 0.0))
        return self.full & (bound < GOOD_MARGIN * sigma), box

    def covered(self, good, bp, bq):
        """Whether blocks ``bp[k]`` and ``bq[k]`` (-1: none) lie in one good window (``good`` of :meth:`good`)."""
        out = np.zeros(len(bp), bool)
        ok = (bp >= 0) & (bq >= 0)
        if not ok.any():
            return out
        p, q = bp[ok], bq[ok]
        hit = np.zeros(p.size, bool)
        for c in range(len(_WINDOW_OFFSETS)):
            w = self._win[p, c]
            d = self._bxy[q] - self._wxy[w]
            hit |= good[w] & (self._wplane[w] == self._plane[q]) & np.all((d >= 0) & (d <= 1), axis=1)
        out[ok] = hit
        return out

    def involved(self, good, boxes, lo, hi):
        """The triangles whose crossings the test must still look at, as a bool array over all triangles.

        ``boxes`` is :meth:`good`'s block boxes; ``lo``, ``hi`` the triangles' boxes ``(t, 3)``
        at the shape. A triangle in a block is involved when its block's box overlaps the box of
        a block not covered with it by a good window, or of a triangle in no block; those are
        always involved, and so is every triangle of a block none of whose windows is good.
        Only a pair with a box not yet involved can add one, so only those pairs are searched
        (a block with a good window against every box), in parts of bounded size
        (:mod:`gdfe.solver.nearby`).
        """
        t = len(self.tris)
        loose = np.nonzero(self.block < 0)[0]
        nb = self.n_blocks
        plo = np.concatenate([boxes[0], lo[loose]])
        phi = np.concatenate([boxes[1], hi[loose]])
        blocks = np.concatenate([np.arange(nb), np.full(loose.size, -1)])
        centre, half = 0.5 * (plo + phi), 0.5 * np.linalg.norm(phi - plo, axis=1)
        r = 2.0 * float(half.max(initial=0.0))
        hit = np.ones(len(plo), bool)  # the other triangles are always tested
        hit[:nb] = ~good[self._win].any(axis=1)  # a block is covered with itself where one of its windows is good

        def mark(i, j):  # pairs of boxes that involve both: apart by no good window, boxes that overlap
            todo = ~(hit[i] & hit[j])  # two involved already add nothing
            i, j = i[todo], j[todo]
            meet = np.all((plo[i] <= phi[j]) & (plo[j] <= phi[i]), axis=1)
            i, j = i[meet], j[meet]
            near = ~self.covered(good, blocks[i], blocks[j])
            hit[i[near]] = True
            hit[j[near]] = True
        ask = np.nonzero(~hit)[0]
        if ask.size:
            for u, v in nearby.within(cKDTree(centre[ask]), r):
                mark(ask[u], ask[v])
            rest = np.nonzero(hit)[0]
            ask = ask[~hit[ask]]  # those the pairs among them left uninvolved, against the others
            if ask.size and rest.size:
                for u, v in nearby.between(cKDTree(centre[ask]), cKDTree(centre[rest]), r):
                    mark(ask[u], rest[v])
        out = np.zeros(t, bool)
        out[self._zt] = hit[self.block[self._zt]]
        out[loose] = True
        return out
