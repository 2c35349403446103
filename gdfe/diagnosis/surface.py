"""Surfaces: the boundary of a simulated shape, sampled and queried for exact closest points.

Each boundary quadrilateral ``p_0 .. p_3`` of the hex mesh is sampled at ``per_edge^2``
interior points of its bilinear map (a k-d tree of them finds the candidate faces of a
query) and split into four triangles ``(p_i, p_{i+1}, c)`` around its centre ``c``. The closest
point of ``x`` on a triangle ``a + v (b - a) + w (c - a)`` solves the 2 x 2 normal equations

    [d00 d01; d01 d11] [v; w] = [(x - a).(b - a); (x - a).(c - a)]

(``d00 = |b - a|^2``, ``d01 = (b - a).(c - a)``, ``d11 = |c - a|^2``) when ``v, w >= 0`` and
``v + w <= 1``; else it is the closest of the clamped projections onto the three edges.

Lengths in mm.
"""

from __future__ import annotations

import numpy as np

from gdfe._triangles import Triangles
from gdfe._validation import check_array, check_instance, check_int
from gdfe.design import Design

__all__ = ["Surface"]


class Surface:
    """The boundary of a simulated shape, for exact closest-point queries.

    Each boundary quadrilateral of the hex mesh is split into four triangles around its
    centre (within about 1e-3 of the cell size of the bilinear face); a query finds the
    faces of the ``k`` nearest of a few interior samples per face and the exact closest
    point on their triangles (inside, or on one of the three edges).

    Parameters
    ----------
    points : (n, 3) float array [mm]
        Vertices of the shape (``n`` the design's vertices).
    design : Design
    cells : (c,) int array, optional
        Only the boundary faces of these cells.
    per_edge : int
        Samples per face edge (``per_edge^2`` per face) for the candidate search.
    faces : ((f, 4) int array, (f,) int array), optional
        The design's boundary faces and their cells (:func:`gdfe.io.surface_faces`), if known.

    Attributes
    ----------
    P : (f, 4, 3) float array [mm]
        Corners of the boundary faces.
    owner : (f,) int array
        Cell of each face.
    samples : (f * per_edge^2, 3) float array [mm]
        The interior samples of the faces.
    """

    def __init__(self, points, design, cells=None, per_edge=3, faces=None):
        from scipy.spatial import cKDTree

        from gdfe.io import surface_faces

        check_instance("design", design, Design)
        points = check_array("points", points, shape=(design.mesh.n_points, 3))
        per_edge = check_int("per_edge", per_edge, minimum=1)
        faces, owner = surface_faces(design) if faces is None else faces
        if cells is not None:
            keep = np.isin(owner, cells)
            faces, owner = faces[keep], owner[keep]
        self.P = points[faces]  # (f, 4, 3)
        self.owner = owner
        u = (np.arange(per_edge) + 0.5) / per_edge
        uu, vv = [a.ravel() for a in np.meshgrid(u, u)]
        w = np.stack([(1 - uu) * (1 - vv), uu * (1 - vv), uu * vv, (1 - uu) * vv], 1)
        samples = np.einsum("sk,fkc->fsc", w, self.P).reshape(-1, 3)
        self.sample_face = np.repeat(np.arange(len(self.P)), len(uu))
        self.tree = cKDTree(samples)
        self.samples = samples

        # four triangles per face, fanned around its centre, (4f, 3) each, with what a query needs
        c = self.P.mean(axis=1, keepdims=True)
        tri = np.concatenate([np.concatenate([self.P[:, [i, (i + 1) % 4]], c], axis=1) for i in range(4)])
        self._tri = Triangles(tri[:, 0], tri[:, 1], tri[:, 2])
        self._nf = len(self.P)

    def closest(self, X, k=4):
        """Closest surface points of query points.

        Parameters
        ----------
        X : (q, 3) float array [mm]
        k : int
            Nearest samples (hence candidate faces) searched per point.

        Returns
        -------
        points : (q, 3) float array [mm]
        distances : (q,) float array [mm]
        cells : (q,) int array
            The cell owning each closest point's face.
        """
        X = check_array("X", X, shape=(-1, 3))
        k = min(check_int("k", k, minimum=1), len(self.samples))
        _, nn = self.tree.query(X, k=k)
        F = self.sample_face[nn.reshape(len(X), -1)]
        T = np.concatenate([F + i * self._nf for i in range(4)], axis=1)  # (q, 4k) candidates
        C, dist, t, _ = self._tri.closest(X, T)
        return C, dist, self.owner[t % self._nf]
