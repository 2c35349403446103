"""Reading shapes off a plate solution (:class:`~reference_fem.PlateResult`).

Shapes are read on the film's mid-plane (``z = h / 2``), a plane of nodes of every plate mesh, at
the vertices of the design's cells, the points GDFE's film also has: so the two models' shapes
are compared point for point. Lengths in mm, curvatures in 1/mm.
"""

from __future__ import annotations

import numpy as np

from gdfe._validation import GdfeError

__all__ = ["midsurface", "grid_vertices", "central_curvatures"]


def midsurface(result):
    """Every mid-plane degree of freedom of the film.

    Returns
    -------
    X : (k, 3) float array [mm]
        Reference positions (``z = h / 2``).
    x : (k, 3) float array [mm]
        Deformed positions.
    """
    plate = result.plate
    tol = 1e-9 * max(1.0, plate.size)
    on = np.abs(result.points[:, 2] - plate.z_mid) < tol
    return result.points[on], result.points[on] + result.displacement[on]


def grid_vertices(result):
    """The film's mid-plane at the vertices of the design's cells.

    Returns
    -------
    ij : (k, 2) int array
        Vertex index (i along x, j along y) on the design's grid, sorted by j then i.
    X : (k, 3) float array [mm]
        Reference positions.
    x : (k, 3) float array [mm]
        Deformed positions.
    """
    grid = result.plate.grid
    X, x = midsurface(result)
    g = (X[:, :2] - grid.origin) / grid.pixel
    on = np.all(np.abs(g - np.round(g)) < 1e-6, axis=1)
    ij = np.round(g[on]).astype(int)
    order = np.lexsort((ij[:, 0], ij[:, 1]))
    return ij[order], X[on][order], x[on][order]


def central_curvatures(X, x, centre, radius):
    """Curvatures of a deformed mid-surface near a point, from a quadratic fit.

    The deformed surface is rotated so that its fitted tangent plane at ``centre`` is horizontal,
    then ``w = c + (k_xx u^2 + 2 k_xy u v + k_yy v^2) / 2`` is fitted in the reference in-plane
    coordinates ``(u, v)`` within ``radius``. Positive curvature: the surface curls towards +z
    (its reference top side).

    Parameters
    ----------
    X, x : (k, 3) float arrays [mm]
        Reference and deformed mid-surface points.
    centre : (2,) float [mm]
        Reference in-plane point.
    radius : float [mm]

    Returns
    -------
    dict
        ``k_xx``, ``k_xy``, ``k_yy`` [1/mm], ``gaussian`` [1/mm^2], ``mean`` [1/mm], ``points``.
    """
    r = X[:, :2] - np.asarray(centre, float)
    near = np.hypot(r[:, 0], r[:, 1]) <= radius
    if near.sum() < 6:
        raise GdfeError(f"radius: expected six or more mid-surface points within {radius:g} mm of "
                        f"{tuple(centre)}, got {int(near.sum())}")
    r, y = r[near], x[near]
    A = np.column_stack([np.ones(len(r)), r])
    coef = np.linalg.lstsq(A, y, rcond=None)[0]  # y ~ y0 + a_u u + a_v v
    tu, tv = coef[1], coef[2]
    n = np.cross(tu, tv)
    n /= np.linalg.norm(n)
    w = (y - coef[0]) @ n
    Q = np.column_stack([np.ones(len(r)), r, 0.5 * r[:, 0] ** 2, r[:, 0] * r[:, 1], 0.5 * r[:, 1] ** 2])
    c = np.linalg.lstsq(Q, w, rcond=None)[0]
    kxx, kxy, kyy = c[3:]
    return {"k_xx": float(kxx), "k_xy": float(kxy), "k_yy": float(kyy),
            "gaussian": float(kxx * kyy - kxy**2), "mean": float(0.5 * (kxx + kyy)), "points": int(near.sum())}
