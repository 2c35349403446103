"""Self-penetration of a film's shape: where its boundary surface passes through itself.

The check works with NumPy and SciPy alone, so every result carries it whether or not the
contact library is installed (:mod:`gdfe.solver.contact` needs it; this module does not).
It looks at the film's boundary surface, the boundary quadrilaterals of the hex mesh
(:func:`gdfe.io.surface_faces`) split into two triangles each (:func:`surface_triangles`),
and finds:

- **crossing triangles**: pairs of boundary triangles that share no vertex and intersect
  (an edge of one passes through the inside of the other: a segment-triangle test on the
  six edges of each candidate pair; touching is not crossing). Candidates are the pairs
  whose centroids lie within their radii summed (k-d trees, the triangles in two classes
  by size) and whose bounding boxes overlap, less the pairs that lie in one window of the
  print that the shape provably embeds (:mod:`gdfe.solver.windows`: most of a smooth film;
  the 10^5-cell twist's crossing test went from 5.7 M candidate pairs to those of 23 000
  triangles near its edges);
- **vertices inside the film elsewhere**: boundary vertices inside a cell that is not within
  one cell of them (each cell split into six tetrahedra along its 0-6 diagonal), by more
  than round-off from the film's surface (a vertex on it touches, and does not count);
- **the depth**: for those vertices, and for seven points along every crossing edge that
  lie inside the film elsewhere (two strips crossing like an X have no vertex in each
  other), the distance to the nearest boundary triangle that is not their neighbour - how
  far the point would have to move to leave that part of the film; the deepest is reported;
- **the gap**: the smallest distance from a boundary vertex to a boundary triangle that
  faces it (each lies in front of the other, by the triangle's normal and the vertex's
  area-weighted normal, the triangle's nearest point within the ball of radius ``r`` that
  touches the vertex and is centred on its normal: within 60 degrees of the normal at the
  search range ``r``, wider nearer) and is not its neighbour, within that range. Only the
  smallest is wanted: each chunk of vertices is searched only as far as the nearest facing pair
  the chunks before it found, and by the boundary's quadrilaterals rather than its triangles (on
  the converged 10^5-cell twist 3.2 million candidate pairs instead of 9.7 million; the answer is
  the same).

:meth:`PenetrationCheck.crosses` makes the first test alone: ``contact="auto"`` asks it of the
iterates of a contact-free solve, and the same check then checks the solved shape.

Every search by distance is made in parts of bounded size (:mod:`gdfe.solver.nearby`), so that
a shape that has passed through itself many times is checked in bounded memory too. The
searches run in chunks (bounded memory at 10^6 cells) on the solver's threads
(:func:`gdfe.solver.threads.workers`; 2 threads took the 10^5-cell twist's check 1.9 x faster on 2 cores);
the answer does not depend on either.

"Neighbours" are kept out of all of them: a vertex and a cell are neighbours when the cell
shares a vertex with a cell of that vertex (the film's own thickness and the next cells
along it are not contact).
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import threading

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from gdfe._validation import check_array, check_instance, check_positive
from gdfe.design import Design
from gdfe.io import surface_faces
from gdfe.solver import nearby
from gdfe.solver.threads import in_order
from gdfe.solver.windows import EmbeddedWindows

__all__ = ["GAP_RANGE_H", "Penetration", "PenetrationCheck", "check_penetration", "surface_triangles",
           "point_triangle_closest", "segments_cross_triangles"]

log = logging.getLogger(__name__)

#: Range of the gap search, in film thicknesses: facing parts of the surface further apart
#: than this are reported as "no gap within range" (``min_gap_mm`` None).
GAP_RANGE_H = 0.25

# how far inside (0, 1) a crossing's coordinates must be: touching within round-off is not crossing
_CROSS_EPS = 1e-9
# points tested along every crossing edge for the depth of a crossing
_EDGE_SAMPLES = 7
# candidate pairs are made and tested this many points (triangles) at a time: the memory of a
# check stays bounded on 10^6-cell films (at 10^5 cells all at once took 0.84 GiB)
_CHUNK = 65_536
# the gap search's chunk of vertices: fine pixels put ~80 triangles of a face within its range of
# every vertex (the Figure 8 plate at 25 um: 1.5 GiB for chunks of 65 536 vertices)
_GAP_CHUNK = 8_192
# pairs of a point and a cell tested this many at a time: a pair carries its cell's eight corners
# (192 bytes) and more through the test
_INSIDE_SLICE = 1 << 20
# the six tetrahedra of a hexahedron (VTK order) about its diagonal 0-6
_HEX_TETS = np.array([[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]])


def surface_triangles(design):
    """The film's boundary surface as triangles, oriented outwards.

    Every boundary quadrilateral ``(a, b, c, d)`` of :func:`gdfe.io.surface_faces` gives
    ``(a, b, c)`` and ``(a, c, d)``.

    Returns
    -------
    tris : (t, 3) int array
        Vertex indices into ``design.mesh.points``.
    owner : (t,) int array
        The cell each triangle bounds.
    """
    faces, owner = surface_faces(design)
    tris = np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])
    return tris, np.concatenate([owner, owner])


@dataclasses.dataclass(frozen=True)
class Penetration:
    """Where a shape passes through itself (:func:`check_penetration`).

    Attributes
    ----------
    intersecting_pairs : int
        Pairs of boundary triangles that share no vertex and intersect.
    penetrated_cells : int
        Cells that own a crossing triangle, hold a vertex of another part of the film, or
        have a vertex inside another part.
    depth_mm : float
        Deepest penetration [mm] (see the module docstring); 0 when none.
    min_gap_mm : float or None
        Smallest distance [mm] between facing, non-neighbouring parts of the boundary
        surface within ``gap_range_mm``; minus ``depth_mm`` where the film penetrates
        itself; None when no two facing parts are that close.
    gap_range_mm : float
        Range of the gap search [mm].
    """

    intersecting_pairs: int
    penetrated_cells: int
    depth_mm: float
    min_gap_mm: float | None
    gap_range_mm: float

    @property
    def found(self) -> bool:
        """Whether the film passes through itself anywhere."""
        return self.intersecting_pairs > 0 or self.depth_mm > 0.0

    def as_dict(self) -> dict:
        return {"found": self.found, "intersecting_pairs": int(self.intersecting_pairs),
                "penetrated_cells": int(self.penetrated_cells), "depth_mm": float(self.depth_mm),
                "min_gap_mm": None if self.min_gap_mm is None else float(self.min_gap_mm),
                "gap_range_mm": float(self.gap_range_mm)}

    def text(self) -> str:
        """One line for the command line."""
        gap = ("no facing parts within %.3g mm" % self.gap_range_mm if self.min_gap_mm is None
               else f"min gap {self.min_gap_mm:.4g} mm")
        if not self.found:
            return f"no self-penetration ({gap})"
        return (f"SELF-PENETRATION: {self.intersecting_pairs} crossing face pairs, {self.penetrated_cells} cells, "
                f"{self.depth_mm:.4g} mm deep")


# -- geometric kernels (vectorised over rows) -------------------------------------------------

def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def segments_cross_triangles(p0, p1, a, b, c):
    """Whether each segment ``p0 -> p1`` passes through triangle ``(a, b, c)``, row by row.

    Moller-Trumbore: the segment's parameter and the barycentric coordinates of its
    crossing of the triangle's plane must all lie inside (0, 1) by more than
    :data:`_CROSS_EPS` (round-off): touching at an end, an edge or a vertex is not
    crossing, nor is a segment in the plane.

    Parameters
    ----------
    p0, p1, a, b, c : (k, 3) float arrays [mm]

    Returns
    -------
    (k,) bool array
    """
    d = p1 - p0
    e1, e2 = b - a, c - a
    pvec = np.cross(d, e2)
    det = _dot(e1, pvec)
    scale = np.linalg.norm(d, axis=1) * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    ok = np.abs(det) > 1e-12 * np.maximum(scale, 1e-300)
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    t = p0 - a
    u = _dot(t, pvec) * inv
    q = np.cross(t, e1)
    v = _dot(d, q) * inv
    s = _dot(e2, q) * inv
    e = _CROSS_EPS
    return ok & (u > e) & (v > e) & (u + v < 1 - e) & (s > e) & (s < 1 - e)


def point_triangle_closest(p, a, b, c):
    """Closest point of triangle ``(a, b, c)`` to ``p``, row by row (by the Voronoi regions).

    Parameters
    ----------
    p, a, b, c : (k, 3) float arrays [mm]

    Returns
    -------
    (k, 3) float array [mm]
    """
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    bp = p - b
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    cp = p - c
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = vb / denom
        w = vc / denom
        out = a + v[:, None] * ab + w[:, None] * ac  # inside the face
        # edges
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    edge_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    edge_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    edge_bc = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
    out = np.where(edge_bc[:, None], b + t_bc[:, None] * (c - b), out)
    out = np.where(edge_ac[:, None], a + t_ac[:, None] * ac, out)
    out = np.where(edge_ab[:, None], a + t_ab[:, None] * ab, out)
    # vertices
    out = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, out)
    bad = ~np.isfinite(out).all(axis=1)  # degenerate triangle: its nearest vertex
    if bad.any():
        cand = np.stack([a[bad], b[bad], c[bad]], axis=1)
        k = np.argmin(np.linalg.norm(cand - p[bad, None], axis=2), axis=1)
        out[bad] = cand[np.arange(k.size), k]
    return out


def _inside_hexes(p, H):
    """Whether each point ``p`` (k, 3) is in hexahedron ``H`` (k, 8, 3), its boundary included, by six tetrahedra."""
    inside = np.zeros(len(p), bool)
    for tet in _HEX_TETS:
        a, b, c, d = (H[:, i] for i in tet)
        vol = _dot(np.cross(b - a, c - a), d - a)
        s = np.sign(vol)
        tol = -_CROSS_EPS * np.abs(vol)
        v0 = _dot(np.cross(b - p, c - p), d - p) * s
        v1 = _dot(np.cross(p - a, c - a), d - a) * s
        v2 = _dot(np.cross(b - a, p - a), d - a) * s
        v3 = _dot(np.cross(b - a, c - a), p - a) * s
        inside |= (s != 0) & (v0 >= tol) & (v1 >= tol) & (v2 >= tol) & (v3 >= tol)
    return inside


def _radius_classes(idx, cen, rad, split):
    """The items ``idx`` in two classes by their radius ``rad`` (at most ``split``, and above it):
    ``(indices, k-d tree of their centroids cen, largest radius)`` for each class that has any."""
    out = []
    for sel in (rad[idx] <= split, rad[idx] > split):
        part = idx[sel]
        if part.size:
            out.append((part, nearby.Tree(cen[part]), float(rad[part].max())))
    return out


def _halves_of_quadrilaterals(tris):
    """Whether triangles ``k`` and ``k + t/2`` of ``tris`` ``(t, 3)`` are the halves ``(a, b, c)`` and
    ``(a, c, d)`` of one quadrilateral ``(a, b, c, d)``, as :func:`surface_triangles` makes them."""
    tris = np.asarray(tris)
    q = len(tris) // 2
    return (2 * q == len(tris) and bool(np.array_equal(tris[:q, 0], tris[q:, 0]))
            and bool(np.array_equal(tris[:q, 2], tris[q:, 1])))


class PenetrationCheck:
    """The penetration check of one design's film, its topology prepared once.

    Parameters
    ----------
    design : Design
    gap_range : float, optional
        Range of the gap search [mm]; default :data:`GAP_RANGE_H` times h.

    Attributes
    ----------
    tris : (t, 3) int array
        Boundary triangles (:func:`surface_triangles`).
    owner : (t,) int array
        Their cells.
    surface : (s,) int array
        The boundary vertices.
    gap_range : float [mm]
    """

    def __init__(self, design, gap_range=None):
        check_instance("design", design, Design)
        self.design = design
        self.gap_range = GAP_RANGE_H * design.h if gap_range is None else float(check_positive("gap_range", gap_range))
        self.tris, self.owner = surface_triangles(design)
        self._quads = _halves_of_quadrilaterals(self.tris)
        self.windows = EmbeddedWindows(design.mesh.points, self.tris)
        cells = design.mesh.cells
        self.cells = cells
        self.n = design.mesh.n_points
        self.surface = np.nonzero(np.bincount(self.tris.ravel(), minlength=self.n))[0]
        # vertex pairs that share a cell, as sorted keys u * n + v: the pattern of C^T C, C the
        # cells' vertex incidence, made by SciPy (listing the 64 pairs of every cell and summing
        # them peaked at 494 MiB on the 2.5 x 10^5-cell corrugation and took 0.79 s; this 184 MiB, 0.27 s)
        m = cells.shape[0]
        C = sp.csr_matrix((np.ones(8 * m, np.int8), cells.ravel(), np.arange(0, 8 * m + 1, 8)), shape=(m, self.n))
        pattern = (C.T.tocsr() @ C).tocsr()
        del C
        pattern.sort_indices()
        self._near = np.repeat(np.arange(self.n, dtype=np.int64), np.diff(pattern.indptr)) * self.n + pattern.indices
        del pattern
        # cells of each vertex (CSR rows)
        order = np.argsort(cells.ravel(), kind="stable")
        self._vc_cells = np.repeat(np.arange(m), 8)[order]
        self._vc_ptr = np.concatenate([[0], np.cumsum(np.bincount(cells.ravel(), minlength=self.n))])

    def neighbours(self, p, c):
        """Whether vertex ``p[k]`` and cell ``c[k]`` are neighbours (the cell shares a vertex with a cell of ``p``).

        Parameters
        ----------
        p, c : (k,) int arrays

        Returns
        -------
        (k,) bool array
        """
        keys = p[:, None].astype(np.int64) * self.n + self.cells[c]
        idx = np.minimum(np.searchsorted(self._near, keys), self._near.size - 1)
        return (self._near[idx] == keys).any(axis=1)

    def _cells_of(self, verts):
        """The cells of each vertex in ``verts``, as (vertex, cell) index arrays."""
        starts, stops = self._vc_ptr[verts], self._vc_ptr[verts + 1]
        counts = stops - starts
        rows = np.repeat(np.arange(verts.size), counts)
        offs = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        return verts[rows], self._vc_cells[starts[rows] + offs]

    def __call__(self, points) -> Penetration:
        """Check the shape ``points`` ``(n, 3)`` [mm]; see the module docstring."""
        X = check_array("points", points, shape=(self.n, 3))
        owner = self.owner
        tri = self._triangles(X)
        bad_cells = []

        # 1. crossing triangles
        i, j, edges = self._crossing_pairs(X, tri)
        if i.size:
            bad_cells += [owner[i], owner[j]]

        # 2. boundary vertices, and points along the crossing edges, inside cells elsewhere in the film
        H = X[self.cells]
        hc = H.mean(axis=1)
        hrad = float(np.sqrt(np.max(np.sum((H - hc[:, None]) ** 2, axis=2))))
        cell_tree = nearby.Tree(hc, radius=hrad)
        surf = self.surface
        _stage("boundary vertices inside the film")
        d_vert, hosts = self._inside_depth(X, X[surf], surf, surf, H, cell_tree, hrad, tri)
        deep = d_vert > 0.0
        if deep.any():
            bad_cells += [hosts, self._cells_of(surf[deep])[1]]
        depth = float(d_vert.max(initial=0.0))
        edges = np.unique(np.sort(np.concatenate(edges), axis=1), axis=0)
        inside = np.zeros(self.n, bool)
        inside[surf[deep]] = True
        edges = edges[~(inside[edges[:, 0]] | inside[edges[:, 1]])]  # an end inside: measured there
        if edges.size:
            _stage("depth along the crossing edges")
            t = (np.arange(1, _EDGE_SAMPLES + 1) / (_EDGE_SAMPLES + 1))[None, :, None]
            pts = (X[edges[:, 0]][:, None] * (1 - t) + X[edges[:, 1]][:, None] * t).reshape(-1, 3)
            a, b = np.repeat(edges[:, 0], _EDGE_SAMPLES), np.repeat(edges[:, 1], _EDGE_SAMPLES)
            d_edge, _ = self._inside_depth(X, pts, a, b, H, cell_tree, hrad, tri)
            depth = max(depth, float(d_edge.max(initial=0.0)))

        # 3. the gap between facing parts of the surface
        found = i.size > 0 or bool(deep.any())
        gap = -depth if found else self._gap(X, tri)
        ncells = int(np.unique(np.concatenate(bad_cells)).size) if bad_cells else 0
        return Penetration(intersecting_pairs=int(i.size), penetrated_cells=ncells, depth_mm=float(depth),
                           min_gap_mm=gap, gap_range_mm=self.gap_range)

    def crosses(self, points) -> bool:
        """Whether the boundary surface of the shape ``points`` ``(n, 3)`` [mm] crosses itself.

        The first test of :meth:`__call__` alone (crossing triangles, not the vertices inside the
        film nor the gap): what ``contact="auto"`` asks of the shapes of a contact-free solve. It
        ends at the first part of the candidate pairs that has a crossing (:mod:`gdfe.solver.nearby`):
        a shape rolled through itself many times is answered without listing all its pairs.
        """
        X = check_array("points", points, shape=(self.n, 3))
        return self._crossing_pairs(X, self._triangles(X), first=True)[0].size > 0

    def _triangles(self, X):
        """The boundary triangles at the shape ``X`` (:class:`_Triangles`)."""
        tris = self.tris
        return _Triangles(X[tris[:, 0]], X[tris[:, 1]], X[tris[:, 2]], quads=self._quads)

    def _crossing_pairs(self, X, tri, first=False):
        """The crossing triangle pairs ``i``, ``j`` of the shape ``X`` and the ``(k, 2)`` edges that cross.

        The candidates are the pairs whose centroids are closer than their radii summed, less the
        pairs in one window of the print that the shape provably embeds (:mod:`gdfe.solver.windows`).
        With ``first``, the search ends at the first part of the candidates (:meth:`_Triangles.close_pairs`)
        that has a crossing: some crossings, not all (what :meth:`crosses` asks).
        """
        good, boxes = self.windows.good(X, tri.lo, tri.hi)
        involved = np.nonzero(self.windows.involved(good, boxes, tri.lo, tri.hi))[0]
        done = threading.Event()

        def crossings_of(pairs):
            found = []
            if done.is_set():
                return found
            for i, j in pairs():  # the next part is searched only after this test
                found.append(self._crossings(X, tri, good, i, j))
                if first and found[-1][0].size:
                    done.set()
                if done.is_set():
                    break
            return found
        found = [f for part in _map(crossings_of, tri.close_pairs(involved), "crossing triangles, chunk") for f in part]
        none = [np.zeros(0, np.int64)]  # no triangle left to test: every pair proved apart
        i = np.concatenate([f[0] for f in found] or none)
        j = np.concatenate([f[1] for f in found] or none)
        edges = [e for f in found for e in f[2]] or [np.zeros((0, 2), np.int64)]
        return i, j, edges

    def _crossings(self, X, tri, good, i, j):
        """The crossing pairs among candidate triangle pairs ``(i, j)``, and the edges that cross.

        Pairs in one good window (``good``, :meth:`EmbeddedWindows.good`), that share a vertex,
        or whose bounding boxes are apart, are dropped first; an edge of either triangle through
        the other is a crossing (:func:`segments_cross_triangles`). Returns the crossing pairs'
        ``i`` and ``j`` and a list of ``(k, 2)`` vertex-index arrays.
        """
        tris = self.tris
        block = self.windows.block
        apart = ~self.windows.covered(good, block[i], block[j])
        i, j = i[apart], j[apart]
        ti, tj = tris[i], tris[j]
        share = np.zeros(i.size, bool)
        for a in range(3):  # nine comparisons of columns: a (k, 3, 3) broadcast took 5 x longer
            for b in range(3):
                share |= ti[:, a] == tj[:, b]
        i, j = i[~share], j[~share]
        box = np.all((tri.lo[i] <= tri.hi[j]) & (tri.lo[j] <= tri.hi[i]), axis=1)
        i, j = i[box], j[box]
        hit = np.zeros(i.size, bool)
        edges = []
        for s, t in ((i, j), (j, i)):
            for e0, e1 in ((0, 1), (1, 2), (2, 0)):
                cross = segments_cross_triangles(X[tris[s, e0]], X[tris[s, e1]], tri.A[t], tri.B[t], tri.C[t])
                hit |= cross
                edges.append(np.column_stack([tris[s[cross], e0], tris[s[cross], e1]]))
        return i[hit], j[hit], edges

    def _inside_depth(self, X, P, a, b, H, cell_tree, hrad, tri):
        """How deep each point ``P[k]`` of the surface lies inside the film away from vertices ``a[k]``, ``b[k]``.

        A point on the edge ``a b`` (``a == b`` for a vertex) is inside another part of
        the film when it is in a cell that is neighbour to neither; its depth is then its
        distance to the nearest boundary triangle that is neighbour to neither (by more
        than round-off: a point on that surface touches it). Returns the depths ``(k,)``
        [mm], 0 where not inside, and the cells found holding the points.
        """
        if len(P) > _CHUNK:  # the points one chunk at a time: each point's answer is its own
            parts = _map(lambda s: self._inside_depth(X, P[s:s + _CHUNK], a[s:s + _CHUNK], b[s:s + _CHUNK], H,
                                                      cell_tree, hrad, tri), range(0, len(P), _CHUNK), "points inside")
            return np.concatenate([d for d, _ in parts]), np.concatenate([c for _, c in parts])
        out = np.zeros(len(P))

        def holding(pi, ci):  # the pairs of a point and a cell elsewhere in the film that holds it
            own = (self.cells[ci] == a[pi][:, None]).any(axis=1) | (self.cells[ci] == b[pi][:, None]).any(axis=1)
            pi, ci = pi[~own], ci[~own]
            inside = _inside_hexes(P[pi], H[ci])
            pi, ci = pi[inside], ci[inside]
            keep = ~(self.neighbours(a[pi], ci) | self.neighbours(b[pi], ci))
            return pi[keep], ci[keep]
        held = []
        for pi, ci in nearby.between(cKDTree(P), cell_tree, hrad):
            for s in range(0, max(pi.size, 1), _INSIDE_SLICE):
                held.append(holding(pi[s:s + _INSIDE_SLICE], ci[s:s + _INSIDE_SLICE]))
        pi, ci = (np.concatenate([h[c] for h in held]) for c in (0, 1))
        if not pi.size:
            return out, ci
        k = np.unique(pi)
        d = np.full(k.size, np.inf)
        todo = np.arange(k.size)
        for r in (0.5 * hrad, 2.0 * hrad):  # most points are near a surface: a small search first
            dd = np.full(todo.size, np.inf)
            for qi, tj in tri.pairs_with(P[k[todo]], r):
                kk = k[todo][qi]
                keep = ~(self.neighbours(a[kk], self.owner[tj]) | self.neighbours(b[kk], self.owner[tj]))
                qi, tj = qi[keep], tj[keep]
                if not qi.size:
                    continue
                p = P[k[todo]][qi]
                q = point_triangle_closest(p, tri.A[tj], tri.B[tj], tri.C[tj])
                np.minimum.at(dd, qi, np.linalg.norm(p - q, axis=1))
            d[todo] = np.minimum(d[todo], dd)
            # a distance within r is the nearest; beyond it a triangle further out may be nearer
            todo = todo[~(d[todo] <= r)]
            if not todo.size:
                break
        d[todo] = np.minimum(d[todo], 2.0 * hrad + tri.rmax)
        d[d <= _CROSS_EPS * hrad] = 0.0
        out[k] = d
        return out, ci[np.isin(pi, k[d > 0])]

    def _gap(self, X, tri):
        """Smallest distance [mm] between a boundary vertex and a facing boundary triangle within range.

        The candidates of a vertex ``p`` with unit normal ``n`` are the triangles near the ball of
        radius ``r`` about ``p + r n``, which holds every point within ``r`` of ``p`` in the
        cone about ``n`` whose half-angle is 60 degrees at distance ``r`` (wider nearer:
        ``acos(s / 2r)`` at distance ``s``). The vertex's own face, tangent to the ball at ``p``,
        stays out of it wherever its radius of curvature exceeds ``r``: on fine pixels a ball
        about ``p`` itself met every triangle of the face within ``r`` (~600 at 8 um).

        Only the smallest distance is wanted, so each chunk of vertices is searched only as far as
        the nearest facing pair the chunks before it found (``within`` of :meth:`_facing_search`):
        once a chunk finds one, the searches after it leave out most of each vertex's own face.
        The answer is that of a search of every pair to the full range, whatever the order in
        which the threads finish: the nearest pair is within every bound used, as each bound is
        the distance of a facing pair.
        """
        find = self._facing_search(X, tri)
        surf = self.surface
        parts = [surf[start:start + _GAP_CHUNK] for start in range(0, surf.size, _GAP_CHUNK)]
        found = [np.inf]  # the nearest facing pair so far, shared by the threads
        lock = threading.Lock()

        def nearest(part):
            with lock:
                bound = found[0]
            d = float(find(part, within=bound)[2].min(initial=np.inf))
            with lock:
                found[0] = min(found[0], d)
            return d
        best = min(_map(nearest, parts, "gap search"), default=np.inf)
        return best if np.isfinite(best) else None

    def _facing_search(self, X, tri):
        """The search of :meth:`_gap`: a function of boundary vertices ``part`` (and ``within``, a
        distance [mm], default the range) that returns the facing pairs from them within the range
        and within ``within``, as vertex, triangle and distance arrays."""
        r = self.gap_range
        flat = self.tris.ravel()  # area-weighted vertex normals, made unit
        vn = np.column_stack([np.bincount(flat, weights=np.repeat(tri.N[:, c], 3), minlength=self.n)
                              for c in range(3)])
        vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-300)
        offset = _dot(tri.A, tri.unit)  # each triangle's plane: x . unit = offset
        tri.search_classes()  # the k-d trees made here, once, not by the threads

        def facing(part, within=np.inf):
            g = min(float(within), r)
            Xp, Np = X[part], vn[part]
            found = [facing_pairs(part, Xp, Np, g, vi, tj) for vi, tj in tri.facing_candidates(Xp, Xp + r * Np, r, g)]
            return tuple(np.concatenate([f[c] for f in found]) for c in range(3))

        def facing_pairs(part, Xp, Np, g, vi, tj):  # the facing pairs among one part of the candidates
            u = tri.unit[tj]
            # cheap and necessary: the vertex in front of the triangle's plane and within range of
            # it (the plane is no further than the triangle, within round-off), and the ball about
            # p + r n meeting that plane (the vertex's own face, tangent to the ball at it, is dropped
            # here wherever its radius of curvature exceeds r: 99.2 % of the 10^5-cell twist's
            # pairs); the plane's distance first, the ball's on what is left
            s = _dot(Xp[vi], u) - offset[tj]
            keep = (s > 1e-9 * r) & (s <= g + 1e-9 * r)
            vi, tj, u, s = vi[keep], tj[keep], u[keep], s[keep]
            keep = np.abs(s + r * _dot(Np[vi], u)) <= r * (1.0 + 1e-6)  # the centre's distance to the plane
            vi, tj = vi[keep], tj[keep]
            p = Xp[vi]
            if not vi.size:
                return part[vi], tj, np.zeros(0)
            q = point_triangle_closest(p, tri.A[tj], tri.B[tj], tri.C[tj])
            dist = np.linalg.norm(p - q, axis=1)
            faces = ((_dot(p - q, tri.N[tj]) > 0) & (_dot(q - p, vn[part[vi]]) >= 0.5 * dist * dist / r)
                     & (dist <= g))
            vi, tj, dist = vi[faces], tj[faces], dist[faces]
            keep = ~self.neighbours(part[vi], self.owner[tj])
            return part[vi[keep]], tj[keep], dist[keep]
        return facing


def _stage(what, step=None, total=None):
    """Log the check's progress (debug; the command line shows it on long checks)."""
    if not log.isEnabledFor(logging.DEBUG):
        return
    log.debug("checking self-penetration: %s%s", what,
              "" if step is None else f" {step}" + ("" if total is None else f"/{total}"),
              extra={"progress": {"event": "stage", "stage": f"checking self-penetration: {what}", "step": step,
                                  "total": total}})


def _map(fn, items, what):
    """``[fn(x) for x in items]``, on the solver's threads (:func:`gdfe.solver.threads.in_order`); progress logged as ``what``."""
    items = list(items)

    def run(k):
        _stage(what, k + 1, len(items))
        return fn(items[k])
    return in_order(run, range(len(items)))


class _Triangles:
    """Boundary triangles at one shape, with what the searches need: boxes, normals, radii, k-d trees.

    Triangles are kept in two classes by their radius (the side faces of a film thicker than
    its cells are long and thin), so that a search's range follows the triangles it meets.
    The normals and the classes of all triangles are made on first use: the crossing test
    (:meth:`PenetrationCheck.crosses`) searches only the triangles the windows leave it. Where the
    triangles are the halves of the boundary's quadrilaterals (``quads``, as the check makes them),
    the searches from points (the gap's and the depth's) go by the quadrilaterals
    (:attr:`quad_classes`): on the converged 10^5-cell twist the gap search's k-d trees gave
    1.6 million pairs of a vertex and a quadrilateral instead of 4.6 million of a vertex and a
    triangle.
    """

    def __init__(self, A, B, C, quads=False):
        self.A, self.B, self.C = A, B, C
        # triangles k and k + t/2 are the halves (a, b, c) and (a, c, d) of one quadrilateral (a, b, c, d)
        # (_halves_of_quadrilaterals, asked by the caller): the searches by distance then go by the quadrilaterals
        self.quads = bool(quads)
        self.lo = np.minimum(np.minimum(A, B), C)
        self.hi = np.maximum(np.maximum(A, B), C)
        cen = (A + B + C) / 3.0
        self.rad = np.sqrt(np.max([_dot(A - cen, A - cen), _dot(B - cen, B - cen), _dot(C - cen, C - cen)], axis=0))
        self.rmax = float(self.rad.max())
        self.cen = cen
        self.split = 1.5 * float(np.median(self.rad))

    @functools.cached_property
    def N(self):
        """Twice each triangle's area times its unit normal, ``(t, 3)``."""
        return np.cross(self.B - self.A, self.C - self.A)

    @functools.cached_property
    def unit(self):
        """Each triangle's unit normal, ``(t, 3)``."""
        return self.N / np.maximum(np.linalg.norm(self.N, axis=1, keepdims=True), 1e-300)

    @functools.cached_property
    def classes(self):
        """All triangles in their two classes (:meth:`_classes`)."""
        return self._classes(np.arange(len(self.cen)))

    @functools.cached_property
    def quad_classes(self):
        """The quadrilaterals (``quads``) in two classes by radius, as :meth:`_classes`: ``(indices, k-d tree
        of centroids, largest radius)`` each. Every point of a quadrilateral's two triangles is within its
        radius of its centroid (the distance from a point is convex, and largest at a corner). A pixel's
        quadrilateral has a smaller radius than either of its triangles (0.707 against 0.745 of its side)
        and there are half as many: a search by distance meets half as many candidates."""
        q = len(self.cen) // 2
        corners = (self.A[:q], self.B[:q], self.C[:q], self.C[q:])
        cen = sum(corners) / 4.0
        rad = np.sqrt(np.max([_dot(v - cen, v - cen) for v in corners], axis=0))
        return _radius_classes(np.arange(q), cen, rad, 1.5 * float(np.median(rad)))

    def search_classes(self):
        """What the searches by distance go by: the quadrilaterals' classes where there are
        quadrilaterals, else the triangles'; and the number of quadrilaterals (None for triangles)."""
        return (self.quad_classes, len(self.cen) // 2) if self.quads else (self.classes, None)

    @staticmethod
    def _as_triangles(k, idx, q):
        """Pairs ``(k, idx)`` of points and search items as pairs of points and triangles (with ``q``
        quadrilaterals, both halves of each)."""
        return (k, idx) if q is None else (np.concatenate([k, k]), np.concatenate([idx, idx + q]))

    def _classes(self, idx):
        """The triangles ``idx`` in their two classes: ``(indices, k-d tree of centroids, largest radius)`` each."""
        return _radius_classes(idx, self.cen, self.rad, self.split)

    def close_pairs(self, subset=None):
        """Pairs ``(i, j)``, ``i != j``, of triangles whose centroids are within their classes' radii summed.

        Among the triangles ``subset`` (an index array) where given, else among all. Returns a
        list of functions, each of which yields the pairs of its :data:`_CHUNK` triangles ``i``
        as index arrays ``(i, j)`` when called, in parts of at most :data:`gdfe.solver.nearby.PAIR_BUDGET`
        pairs (:mod:`gdfe.solver.nearby`); every pair is in one part, once.
        """
        classes = self.classes if subset is None else self._classes(np.asarray(subset, np.int64))

        def within(ta, tb, r, ia, ib):
            def pairs():
                for u, v in nearby.between(ta, tb, r):
                    yield ia[u], ib[v]
            return pairs

        def own(ta, r, ia):
            def pairs():
                for u, v in nearby.within(ta, r):
                    yield ia[u], ia[v]
            return pairs

        tasks = []
        for a, (ia, ta, ra) in enumerate(classes):
            for b, (ib, tb, rb) in enumerate(classes):
                r = ra + rb
                if b > a:  # the two classes: a chunk of one against the whole other
                    tasks += [within(cKDTree(ta.data[s:s + _CHUNK]), tb, r, ia[s:s + _CHUNK], ib)
                              for s in range(0, ia.size, _CHUNK)]
                elif b == a:  # one class: each chunk's own pairs, and each pair of chunks whose boxes come within r
                    parts = [(ia[s:s + _CHUNK], cKDTree(ta.data[s:s + _CHUNK])) for s in range(0, ia.size, _CHUNK)]
                    for x, (ix, tx) in enumerate(parts):
                        tasks.append(own(tx, r, ix))
                        tasks += [within(tx, ty, r, ix, iy) for iy, ty in parts[x + 1:]
                                  if np.all(tx.mins <= ty.maxes + r) and np.all(ty.mins <= tx.maxes + r)]
        return tasks

    def pairs_with(self, points, r):
        """Pairs ``(k, t)`` of points and triangles closer than ``r``, and others (by the centroids of the triangles, or
        of their quadrilaterals, with their class's radius), in parts (:meth:`_pairs_by_class`)."""
        tree = cKDTree(points)
        return self._pairs_by_class(lambda rad: (tree, r + rad))

    def facing_candidates(self, points, centres, r, g):
        """Pairs ``(k, t)``: every triangle that meets the ball of radius ``r`` about ``centres[k]``
        within ``g`` (<= ``r``) of ``points[k]``, and others.

        Such a triangle (or its quadrilateral, :attr:`quad_classes`) has its centroid within ``r``
        plus its class's radius of the centre, and within ``g`` plus it of the point: each class is
        searched about whichever covers less of a plane through the point tangent to the ball
        (``(g + rad)^2`` against ``2 r rad + rad^2``, the squared radii of the discs they cut from
        it), so a small ``g`` leaves out most of the point's own face. In parts (:meth:`_pairs_by_class`).
        """
        trees = {}

        def about(rad):
            if g * (g + 2.0 * rad) < 2.0 * r * rad:
                if "point" not in trees:
                    trees["point"] = cKDTree(points)
                return trees["point"], (g + rad) * (1.0 + 1e-9)  # a pair at exactly g kept
            if "centre" not in trees:
                trees["centre"] = cKDTree(centres)
            return trees["centre"], r + rad
        return self._pairs_by_class(about)

    def _pairs_by_class(self, about):
        """Pairs ``(k, t)`` of query points and triangles from the searches of :meth:`search_classes`'
        classes; ``about(rad)`` gives a class of radius ``rad`` the k-d tree of the query points and the
        search's radius. Yields them in parts, each from at most :data:`gdfe.solver.nearby.PAIR_BUDGET`
        pairs of a search (:func:`gdfe.solver.nearby.between`)."""
        classes, q = self.search_classes()
        for idx, t, rad in classes:
            tree, radius = about(rad)
            for u, v in nearby.between(tree, t, radius):
                yield self._as_triangles(u, idx[v], q)


def check_penetration(points, design, gap_range=None) -> Penetration:
    """Whether, where and how deep a shape of ``design`` passes through itself.

    Parameters
    ----------
    points : (n, 3) float array [mm]
        Vertex positions (e.g. ``result.points``).
    design : Design
    gap_range : float, optional
        Range of the gap search [mm]; default :data:`GAP_RANGE_H` times h.

    Returns
    -------
    Penetration

    See the module docstring for what is counted. For several shapes of one design make a
    :class:`PenetrationCheck` once and call it on each.
    """
    return PenetrationCheck(design, gap_range)(points)
