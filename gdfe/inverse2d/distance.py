"""Distance between a folded film and its target surface, after rigid alignment.

Both are triangle surfaces: the film's mid-surface (:class:`gdfe.inverse2d.film.MidSurface`)
and the target's patch. The closest point of ``x`` on a triangle ``a + v (b - a) + w (c - a)``
solves ``[d00 d01; d01 d11] [v; w] = [(x - a).(b - a); (x - a).(c - a)]`` when ``v, w >= 0`` and
``v + w <= 1``, and is otherwise the closest of the clamped projections onto its three edges;
the candidate triangles of a query come from a k-d tree of points sampled on every triangle.

The alignment is the rigid motion of the film that minimises the symmetric mean squared
distance ``mean_film d(x, target)^2 + mean_target d(y, film)^2`` (iterative closest points
with both sets of pairs in one weighted Kabsch step), started from the correspondence of the
film's points with the target points they were designed for. Reported, in mm:

- ``rms_mm``, ``max_mm``: the distances of the film's mid-surface points to the target surface;
- ``hausdorff_mm``: the larger of ``max_mm`` and the largest distance of the target's points to
  the film, so a film that covers only part of the target does not pass for a good fold;
- ``target_rms_mm``: the RMS of the target's points to the film.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gdfe._triangles import Triangles
from gdfe._validation import GdfeError, check_array
from gdfe.measure import rigid_align

__all__ = ["TriangleSurface", "Distance", "surface_distance", "patch", "ALIGN_SAMPLES"]


class TriangleSurface:
    """A triangle mesh for exact closest-point queries.

    Parameters
    ----------
    vertices : (n, 3) float array [mm]
    triangles : (t, 3) int array
    samples : int
        Points sampled per triangle for the candidate search (its centroid and points towards
        its corners).
    """

    def __init__(self, vertices, triangles, samples=4):
        from scipy.spatial import cKDTree

        V = check_array("vertices", vertices, shape=(-1, 3))
        T = np.asarray(triangles, np.int64)
        if T.ndim != 2 or T.shape[1] != 3 or T.size == 0:
            raise GdfeError(f"triangles: expected a non-empty (t, 3) array, got shape {T.shape}")
        self.vertices, self.triangles = V, T
        a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
        bary = np.array([[1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
        bary = bary[:max(1, min(int(samples), 4))]
        pts = np.einsum("sj,tjc->tsc", bary, np.stack([a, b, c], axis=1)).reshape(-1, 3)
        self.sample_triangle = np.repeat(np.arange(len(T)), len(bary))
        self.tree = cKDTree(pts)
        self._tri = Triangles(a, b, c)

    def closest(self, X, k=6):
        """Closest points of ``X`` ``(q, 3)`` [mm] on the surface.

        Returns
        -------
        points : (q, 3) float array [mm]
        distances : (q,) float array [mm]
        triangles : (q,) int array
        barycentric : (q, 3) float array
            Of the closest point in its triangle.
        """
        X = np.asarray(X, float)
        k = min(int(k), len(self.sample_triangle))
        _, nn = self.tree.query(X, k=k)
        return self._tri.closest(X, self.sample_triangle[nn.reshape(len(X), -1)])


def patch(target, sigma, film_size, spacing, film_mask=None):
    """The target's patch as a triangle mesh: the image of the film's rectangle (or outline).

    Parameters
    ----------
    target : Target
    sigma : float
        The scale from film to conformal coordinates.
    film_size : (2,) floats [mm]
    spacing : float [mm]
        Grid spacing on the film (at most).
    film_mask : callable, optional
        ``film_mask(p)``: where the film is (the triangles with a corner there are kept).

    Returns
    -------
    TriangleSurface
    """
    Lx, Ly = (float(v) for v in film_size)
    nx = max(2, int(np.ceil(Lx / spacing)))
    ny = max(2, int(np.ceil(Ly / spacing)))
    x = np.linspace(-Lx / 2, Lx / 2, nx + 1)
    y = np.linspace(-Ly / 2, Ly / 2, ny + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    p = np.column_stack([X.ravel(), Y.ravel()])
    idx = np.arange(len(p)).reshape(nx + 1, ny + 1)
    q = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1, 4)
    tris = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    if film_mask is not None:
        keep = np.asarray(film_mask(p), bool)
        tris = tris[keep[tris].all(axis=1)]
        used = np.unique(tris)
        remap = np.full(len(p), -1)
        remap[used] = np.arange(len(used))
        p, tris = p[used], remap[tris]
    return TriangleSurface(target.point(p, sigma), tris)


@dataclasses.dataclass(frozen=True, eq=False)
class Distance:
    """Distance of a folded film from its target after rigid alignment.

    Attributes
    ----------
    rms_mm, max_mm : float
        Of the film's mid-surface points to the target surface.
    hausdorff_mm : float
        ``max(max_mm, largest distance of the target's points to the film)``.
    target_rms_mm : float
        RMS of the target's points to the film.
    per_point : (k,) float array [mm]
        Distance of every mid-surface point to the target.
    aligned : (k, 3) float array [mm]
        The mid-surface points moved onto the target.
    rotation : (3, 3) float array
    translation : (3,) float array [mm]
    """

    rms_mm: float
    max_mm: float
    hausdorff_mm: float
    target_rms_mm: float
    per_point: np.ndarray
    aligned: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray

    def as_dict(self):
        return {"rms_mm": self.rms_mm, "max_mm": self.max_mm, "hausdorff_mm": self.hausdorff_mm,
                "target_rms_mm": self.target_rms_mm}


def _weighted_kabsch(A, B, w):
    """Rotation and translation taking points ``A`` onto ``B`` with weights ``w`` (least squares)."""
    return rigid_align(A, B, weights=w)


#: The target's points paired with the film in the alignment's iterations, at most (a regular subset of
#: them; the reported distances use every point).
ALIGN_SAMPLES = 2000


def surface_distance(points, triangles, target_surface, designed=None, max_iter=60, tol=1e-8):
    """Distance of a folded mid-surface from a target surface after the best rigid motion.

    Parameters
    ----------
    points : (k, 3) float array [mm]
        The fold's mid-surface points.
    triangles : (t, 3) int array
        Their triangles.
    target_surface : TriangleSurface
    designed : (k, 3) float array [mm], optional
        The target points the mid-surface points were designed for: the alignment starts from
        their correspondence (else from the centroids and principal axes).
    max_iter : int
    tol : float
        The iteration stops when the symmetric mean squared distance falls by less than this
        fraction. It pairs the film's points with the target and at most :data:`ALIGN_SAMPLES`
        of the target's points (every k-th) with the film.

    Returns
    -------
    Distance
    """
    X = check_array("points", points, shape=(-1, 3))
    Y_all = target_surface.vertices
    Y = Y_all[::max(1, -(-len(Y_all) // ALIGN_SAMPLES))]
    if designed is not None:
        Q, t = rigid_align(X, check_array("designed", designed, shape=X.shape))
    else:
        cx, cy = X.mean(0), Y_all.mean(0)
        _, _, Vx = np.linalg.svd(X - cx, full_matrices=False)
        _, _, Vy = np.linalg.svd(Y_all - cy, full_matrices=False)
        Q = Vy.T @ Vx
        if np.linalg.det(Q) < 0:
            Q = Vy.T @ np.diag([1.0, 1.0, -1.0]) @ Vx
        t = cy - cx @ Q.T
    T = np.asarray(triangles, np.int64)
    wx, wy = 1.0 / len(X), 1.0 / len(Y)
    err = np.inf
    for _ in range(max_iter):
        A = X @ Q.T + t
        C, dx, _, _ = target_surface.closest(A)
        film = TriangleSurface(A, T, samples=1)
        D, dy, tri, bary = film.closest(Y)
        e = wx * float(np.sum(dx**2)) + wy * float(np.sum(dy**2))
        if e >= err * (1.0 - tol):
            break
        err = e
        # the target's points pair with the film points under them, which move with the film
        src = np.concatenate([X, np.einsum("qj,qjc->qc", bary, X[T[tri]])])
        dst = np.concatenate([C, Y])
        w = np.concatenate([np.full(len(X), wx), np.full(len(Y), wy)])
        Q, t = _weighted_kabsch(src, dst, w)
    A = X @ Q.T + t
    _, dx, _, _ = target_surface.closest(A)
    _, dy, _, _ = TriangleSurface(A, T, samples=1).closest(Y_all)
    return Distance(rms_mm=float(np.sqrt(np.mean(dx**2))), max_mm=float(dx.max()),
                    hausdorff_mm=float(max(dx.max(), dy.max())), target_rms_mm=float(np.sqrt(np.mean(dy**2))),
                    per_point=dx, aligned=A, rotation=Q, translation=t)
