"""Closest points on triangles, many queries against candidate triangles at once.

Used by the scan's surface (:mod:`gdfe.diagnosis.surface`) and the target's patch
(:mod:`gdfe.inverse2d.distance`): each finds a few candidate triangles per query point
through a k-d tree of its own samples, and this module picks the closest point among them.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Triangles"]


class Triangles:
    """Triangles ``(a, b, c)`` with what a closest-point query needs precomputed.

    Parameters
    ----------
    a, b, c : (t, 3) float arrays [mm]
        The corners. A degenerate triangle (zero area) is searched on its edges only.
    """

    def __init__(self, a, b, c):
        self.a, self.ab, self.ac, self.bc = a, b - a, c - a, c - b
        d00 = np.einsum("ij,ij->i", self.ab, self.ab)
        d01 = np.einsum("ij,ij->i", self.ab, self.ac)
        d11 = np.einsum("ij,ij->i", self.ac, self.ac)
        self.d = np.stack([d00, d01, d11, np.einsum("ij,ij->i", self.bc, self.bc)], 1)
        den = d00 * d11 - d01**2
        self.den = np.where(den > 0, den, np.inf)

    def closest(self, X, T):
        """The closest point to each ``X[q]`` on its candidate triangles ``T[q]``.

        Parameters
        ----------
        X : (q, 3) float array [mm]
        T : (q, k) int array
            Candidate triangles of each point.

        Returns
        -------
        points : (q, 3) float array [mm]
        distances : (q,) float array [mm]
        triangles : (q,) int array
            The triangle holding each closest point.
        barycentric : (q, 3) float array
            Of the closest point in its triangle (weights of a, b, c).
        """
        p = X[:, None, :]
        a, ab, ac, bc = self.a[T], self.ab[T], self.ac[T], self.bc[T]
        d00, d01, d11, dbc = (self.d[T, i] for i in range(4))
        ap = p - a
        d20 = np.einsum("qkc,qkc->qk", ap, ab)
        d21 = np.einsum("qkc,qkc->qk", ap, ac)
        den = self.den[T]
        v = (d11 * d20 - d01 * d21) / den
        w = (d00 * d21 - d01 * d20) / den
        inside = (v >= 0) & (w >= 0) & (v + w <= 1)
        # clamped projections onto the three edges
        tab = np.clip(d20 / np.where(d00 > 0, d00, 1.0), 0, 1)
        tac = np.clip(d21 / np.where(d11 > 0, d11, 1.0), 0, 1)
        tbc = np.clip(np.einsum("qkc,qkc->qk", ap - ab, bc) / np.where(dbc > 0, dbc, 1.0), 0, 1)
        # the four candidates' barycentric weights of b and c: inside, on ab, on ac, on bc
        vv = np.stack([np.where(inside, v, 0.0), tab, np.zeros_like(tab), 1.0 - tbc])
        ww = np.stack([np.where(inside, w, 0.0), np.zeros_like(tab), tac, tbc])
        cands = a[None] + vv[..., None] * ab[None] + ww[..., None] * ac[None]  # (4, q, k, 3)
        diff = cands - p[None]
        dist2 = np.einsum("sqkc,sqkc->sqk", diff, diff)
        dist2[0] = np.where(inside, dist2[0], np.inf)
        s_best = np.argmin(dist2, axis=0)  # (q, k)
        d2 = np.take_along_axis(dist2, s_best[None], 0)[0]
        j = np.argmin(d2, axis=1)
        rows = np.arange(len(X))
        s = s_best[rows, j]
        vb, wb = vv[s, rows, j], ww[s, rows, j]
        return cands[s, rows, j], np.sqrt(d2[rows, j]), T[rows, j], np.column_stack([1.0 - vb - wb, vb, wb])
