"""Pairs of points within a distance of each other, made in parts of bounded size.

The crossing test's broad phase (:mod:`gdfe.solver.windows`, :mod:`gdfe.solver.penetration`)
lists the pairs of boxes or triangles whose centres lie within a distance and tests each pair.
On a film the pairs are few: a triangle is within reach of the few dozen around it. A shape
that has passed through itself many times is another matter. A contact-free solve of the
10 m hinge strip (``gdfe.hinge(1e4, d=0.33)``) rolled it into a 5.8 mm cube: 180 044 boxes,
each within reach of some 17 700 others, 1.6 x 10^9 pairs. SciPy lists a pair in 24 bytes
(38 GiB), and the search ended in ``MemoryError: std::bad_alloc``.

The searches here bound their pairs first, from a grid of cubes as wide as the search's
distance (:func:`point_bounds`: two points within it lie in cubes at most one apart on each
axis), then, where that does not clear the search, from the cubes that come within the distance
of each point; a :class:`Tree` keeps its grids for the searches made against it. A film's
searches are cleared and made whole, as before. A search over :data:`PAIR_BUDGET` is cut into
contiguous parts of its query points whose bounds sum to at most the budget; where that would
make parts of fewer than :data:`PART_POINTS` points, its pairs are counted
(:meth:`scipy.spatial.cKDTree.count_neighbors`, which keeps none of them), and it is cut by each
point's own count. A single point is a part however many pairs it has. The parts come one at a
time, in the order of the query points, so that memory holds one part and a test that needs one
crossing can end at the first part that has one. Every pair is in exactly one part.
"""

from __future__ import annotations

import math
import threading

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["FEW", "PAIR_BUDGET", "PART_POINTS", "Tree", "between", "point_bounds", "within"]

#: The most pairs a part holds: 8.4 million, 200 MiB as SciPy lists them (two indices and a
#: distance, 24 bytes a pair), about as much again while the caller tests them. Of the 10^5-cell
#: corrugation's searches none is cut; of the Figure 8 twist's, the search for vertices inside
#: cells, whose bound is loose (16 million for 65 536 vertices, against 270 000 pairs); of the
#: 10^6-cell dome's, that one and the windows' (97 808 blocks, more than 8.4 million pairs).
PAIR_BUDGET = 1 << 23


def _budget(budget):
    return PAIR_BUDGET if budget is None else int(budget)


_OFFSETS = [(dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)]


def _with_neighbours(table, step):
    """``table[k] + table[k - step] + table[k + step]`` for every entry ``k``, modulo the table's size."""
    s = step % table.size
    out = 3 * table if s == 0 else table.copy()
    if s:
        out[s:] += table[:-s]
        out[:s] += table[-s:]
        out[:-s] += table[s:]
        out[-s:] += table[:s]
    return out


class _Grid:
    """The points of a k-d tree counted in cubes of side ``side`` (:func:`point_bounds`).

    The cubes' counts are kept in a table by the low bits of the cubes' numbers (cubes that share
    an entry only add to a bound), and again summed with the 26 cubes about each. Not made where
    the cubes cannot be numbered in 64-bit integers (``side`` not positive, or tiny against the
    points' spread): :attr:`table` is then None.
    """

    def __init__(self, tree, side):
        self.side, self.table = float(side), None
        self.lo = tree.mins
        if not self.side > 0.0 or np.prod((tree.maxes - tree.mins) / self.side + 5.0) > 2.0**62:
            return
        self.cubes = ((tree.maxes - tree.mins) // self.side).astype(np.int64) + 1  # along each axis
        # a cube's index shifted by two; a point outside the cubes is put in the cube beside them
        # (-1 or cubes, shifted 1 or cubes + 2); its neighbours' indices are then 0 to cubes + 3
        span = self.cubes + 4
        self.step = np.array([span[1] * span[2], span[2], 1])  # a cube's neighbour along x, y, z
        self.mask = (1 << int(2 * tree.n).bit_length()) - 1  # a table of a power of two entries, 2 a point or more
        self.table = np.bincount(self._keys(tree.data)[0] & self.mask, minlength=self.mask + 1).astype(np.int32)
        summed = self.table.astype(np.int64)  # 27 cubes' counts: over 2^31 from 80 million points
        for step in self.step[::-1]:  # a neighbour's entry is ``step`` further on, modulo the table's size
            summed = _with_neighbours(summed, int(step))
        self.summed = summed
        # distances are compared with this much to spare: a point on a cube's face may be binned beside it
        self.spare = 1e-9 * self.side + 1e-12 * float(np.max(np.abs(np.concatenate([tree.mins, tree.maxes]))))

    def _keys(self, p):
        """The points' cubes' numbers, where in its cube each point lies (0 to 1 along each axis),
        and which points lie outside the cubes."""
        t = (p - self.lo) / self.side
        k = np.floor(t)
        kc = np.clip(k, -1, self.cubes)
        outside = np.any(k != kc, axis=1)
        return (kc.astype(np.int64) + 2) @ self.step, t - kc, outside

    def bounds(self, p, r=None):
        """For each point ``p[k]``, the points in the 27 cubes about it (its own and the 26 next to it),
        or more; with ``r`` (<= :attr:`side`), only those of the cubes that come within ``r`` of it."""
        key, frac, outside = self._keys(p)
        if r is None:
            return self.summed[key & self.mask]
        reach = (r + self.spare) ** 2
        # each point's squared distance along each axis to the cube before its own, its own, the one after;
        # a point outside the cubes is near each cube about it
        inside = ~outside[:, None]
        gap = list(zip((inside * frac * self.side).T ** 2, np.zeros((3, len(p))), (inside * (1.0 - frac) * self.side).T ** 2))
        out = np.zeros(len(p), np.int64)
        for off in _OFFSETS:
            take = gap[0][off[0] + 1] + gap[1][off[1] + 1] + gap[2][off[2] + 1] <= reach
            out += take * self.table[(key + int(np.dot(off, self.step))) & self.mask]
        return out


class Tree(cKDTree):
    """A :class:`scipy.spatial.cKDTree` that keeps the grids of its points (:func:`point_bounds`) for the
    searches made against it, so that a search of few points against it costs their own cubes alone.

    Its grids have cubes whose sides are powers of two (a search's distance or up to twice it), at most
    :attr:`GRIDS` of them, the last made kept; a search at ``radius``, where given, has a grid of its
    own, of cubes of that side (the bounds of cubes up to twice the distance are up to eight times
    as loose).
    """

    GRIDS = 4
    _grids = None
    _making = threading.Lock()  # one grid made at a time, by whichever thread asks first

    def __init__(self, data, radius=None):
        super().__init__(data)
        self.radius = radius

    def grid(self, r):
        """The grid of cubes of side :attr:`radius` where ``r`` is it, else ``2^ceil(log2 r)``."""
        if not r > 0.0:
            return _Grid(self, r)
        side = r if r == self.radius else 2.0 ** math.ceil(math.log2(r))
        with self._making:
            if self._grids is None:
                self._grids = {}
            if side not in self._grids:
                while len(self._grids) >= self.GRIDS:
                    del self._grids[next(iter(self._grids))]
                self._grids[side] = _Grid(self, side)
            return self._grids[side]


def point_bounds(tree_a, tree_b, r, fine=False):
    """For each point of ``tree_a``, an upper bound of the points of ``tree_b`` within ``r`` of it.

    The points of ``tree_b`` are counted in cubes of side ``r`` (or up to twice it, where ``tree_b``
    is a :class:`Tree` that keeps its grids); two points within ``r`` lie in cubes at most one apart
    on each axis, so a point has at most the points of ``tree_b`` in the 27 cubes about its own.
    With ``fine``, only the cubes that come within ``r`` of the point are counted: tighter where the
    points lie in layers that the distance barely reaches across (the 10^5-cell Figure 8 twist's
    vertices against its cells' centres, cells of 25 um by 0.29 mm: 16 million for 65 536 vertices
    against 21 million, and 270 000 pairs), at 27 look-ups a point instead of one. None where the
    cubes cannot be numbered in 64-bit integers (``r`` not positive, or tiny against the points'
    spread). The cubes' counts are kept in a table by the low bits of their numbers: cubes that
    share an entry only add to the bound.
    """
    if not (tree_a.n and tree_b.n):
        return np.zeros(tree_a.n, np.int64)
    grid = tree_b.grid(r) if isinstance(tree_b, Tree) else _Grid(tree_b, r)
    return None if grid.table is None else grid.bounds(tree_a.data, r if fine else None)


#: A search over the budget is cut by its points' bounds where that makes parts of this many points
#: or more on average; else (a bound far above the budget, or none) its pairs are counted, and it is
#: cut by each point's own count (:meth:`scipy.spatial.cKDTree.query_ball_point`, twice a count's time).
PART_POINTS = 64
#: A search of a tree's points against this many times as many in a plain k-d tree (not a
#: :class:`Tree`, which keeps its grid) is counted rather than bounded: binning the many would cost more.
FEW = 8


def _sizes(tree_a, tree_b, r, budget, pairs):
    """None where the search of ``tree_a``'s points against ``tree_b``'s holds at most ``budget``
    pairs (``pairs`` turns ordered pairs into the search's), else each query point's pairs or more."""
    if pairs(tree_a.n * tree_b.n) <= budget:
        return None
    if (isinstance(tree_b, Tree) or tree_b.n <= FEW * tree_a.n) and (quick := point_bounds(tree_a, tree_b, r)) is not None:
        if pairs(int(quick.sum())) <= budget:
            return None
        bounds = point_bounds(tree_a, tree_b, r, fine=True)
        total = int(bounds.sum())
        if pairs(total) <= budget:
            return None
        if tree_a.n * budget >= PART_POINTS * total:
            return bounds
    if pairs(int(tree_a.count_neighbors(tree_b, r))) <= budget:
        return None
    return np.asarray(tree_b.query_ball_point(tree_a.data, r, return_length=True), np.int64)


def _cuts(sizes, budget):
    """``range(len(sizes))`` in contiguous parts whose ``sizes`` sum to at most ``budget`` (a single
    item over it is a part of its own)."""
    end = np.cumsum(sizes)
    out, start = [], 0
    while start < len(sizes):
        before = end[start - 1] if start else 0
        stop = max(int(np.searchsorted(end, before + budget, side="right")), start + 1)
        out.append((start, stop))
        start = stop
    return out


def _between_whole(tree_a, tree_b, r):
    m = tree_a.sparse_distance_matrix(tree_b, r, output_type="ndarray")
    return m["i"].astype(np.int64), m["j"].astype(np.int64)


def between(tree_a, tree_b, r, budget=None):
    """The pairs ``(i, j)`` with point ``i`` of ``tree_a`` within ``r`` of point ``j`` of ``tree_b``, in parts.

    Parameters
    ----------
    tree_a, tree_b : scipy.spatial.cKDTree
    r : float
    budget : int, optional
        The most pairs of a part (:data:`PAIR_BUDGET`).

    Yields
    ------
    (i, j) : int64 arrays
        One part of the pairs; its ``i`` lie in a range of ``tree_a``'s points after the last part's.
    """
    budget = _budget(budget)
    sizes = _sizes(tree_a, tree_b, r, budget, lambda c: c)
    if sizes is None:
        yield _between_whole(tree_a, tree_b, r)
        return
    for start, stop in _cuts(sizes, budget):
        i, j = _between_whole(cKDTree(tree_a.data[start:stop]), tree_b, r)
        yield i + start, j


def within(tree, r, budget=None):
    """The pairs ``(i, j)``, ``i < j``, of points of ``tree`` within ``r`` of each other, in parts.

    Parameters and parts as :func:`between`; each pair once. A search over the budget is cut
    into parts of its points, each searched against all and kept where ``i < j``.
    """
    budget = _budget(budget)
    n = tree.n
    # a search against itself finds each pair twice, and each point with itself
    sizes = _sizes(tree, tree, r, budget, lambda c: (c - n) // 2)
    if sizes is None:
        uv = tree.query_pairs(r, output_type="ndarray").astype(np.int64)
        yield uv[:, 0], uv[:, 1]
        return
    for start, stop in _cuts(sizes, budget):
        i, j = _between_whole(cKDTree(tree.data[start:stop]), tree, r)
        i += start
        keep = i < j
        yield i[keep], j[keep]
