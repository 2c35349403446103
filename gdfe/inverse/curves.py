"""Curves: comparing a planar curve with a target after the best rigid motion of the plane.

The best proper rotation ``Q`` and translation ``t`` taking points ``a_i`` onto ``b_i``
(weights ``w_i``, summing to 1) minimise ``sum_i w_i |Q a_i + t - b_i|^2``; with the
weighted centroids ``c_a``, ``c_b`` and ``H = sum_i w_i (a_i - c_a)(b_i - c_b)^T``, the
angle is

    phi = atan2(H_01 - H_10, H_00 + H_11),    t = c_b - Q c_a

(:func:`align_2d`; rotations only, so a mirrored curve is not aligned onto its image).
:func:`compare_curves` starts from corresponding arc lengths and iterates closest points on
the target polyline (:func:`closest_on_polyline`), then reports the symmetric Hausdorff
distance between the polylines.

All lengths in millimetres, angles in radians.
"""

from __future__ import annotations

import math

import numpy as np

from gdfe._validation import check_array, check_int

__all__ = ["align_2d", "closest_on_polyline", "compare_curves"]


def align_2d(source, target, weights=None):
    """Best proper rotation and translation of the plane taking ``source`` onto ``target``.

    Only rotations (det +1) are allowed, so a mirrored curve is not aligned onto its image.

    Parameters
    ----------
    source, target : (k, 2) float arrays [mm]
        Corresponding points.
    weights : (k,) float array, optional
        Weight of each pair (default: equal).

    Returns
    -------
    Q : (2, 2) float array
    t : (2,) float array [mm]
        ``source @ Q.T + t`` is aligned with ``target``.
    """
    A = check_array("source", source, shape=(-1, 2), min_size=1)
    B = check_array("target", target, shape=(len(A), 2))
    w = np.ones(len(A)) if weights is None else check_array("weights", weights, shape=(len(A),))
    return _align_2d(A, B, w)


def _align_2d(A, B, w):
    w = w / w.sum()
    ca, cb = w @ A, w @ B
    H = ((A - ca) * w[:, None]).T @ (B - cb)
    ang = math.atan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
    Q = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    return Q, cb - ca @ Q.T


def closest_on_polyline(points, polyline):
    """Distance from each point to a polyline, and the closest point on it.

    Parameters
    ----------
    points : (k, 2) float array [mm]
    polyline : (m, 2) float array [mm], m >= 2
        Vertices of the polyline, in order.

    Returns
    -------
    dist : (k,) float array [mm]
    closest : (k, 2) float array [mm]
    """
    P = check_array("points", points, shape=(-1, 2))
    poly = check_array("polyline", polyline, shape=(-1, 2), min_size=2)
    return _closest_on_polyline(P, poly)


def _closest_on_polyline(P, poly, chunk=2048):
    """:func:`closest_on_polyline` of checked arrays, ``chunk`` points at a time."""
    a = poly[:-1]
    d = poly[1:] - a
    dd = np.maximum((d * d).sum(1), 1e-300)
    dist = np.empty(len(P))
    close = np.empty_like(P)
    for lo in range(0, len(P), chunk):
        p = P[lo:lo + chunk]
        t = np.clip(((p[:, None, :] - a[None]) * d[None]).sum(-1) / dd[None], 0.0, 1.0)
        q = a[None] + t[..., None] * d[None]
        e = ((p[:, None, :] - q) ** 2).sum(-1)
        j = e.argmin(1)
        dist[lo:lo + chunk] = np.sqrt(e[np.arange(len(p)), j])
        close[lo:lo + chunk] = q[np.arange(len(p)), j]
    return dist, close


def compare_curves(points, target, s=None, s_target=None, icp=30):
    """Deviation of a curve from a target curve after the best rigid motion of the plane.

    The curves are first aligned by corresponding arc lengths (``s`` on ``points``,
    ``s_target`` on ``target``, when both are given; else by normalised arc length), then by
    iterated closest points on the target polyline (rotations only, no mirror).

    Parameters
    ----------
    points : (k, 2) float array [mm]
        The curve to measure (e.g. a simulated strip's mid-line).
    target : (m, 2) float array [mm]
        The target curve, densely sampled.
    s : (k,) float array [mm], optional
        Arc length of each of ``points``, on the scale of ``s_target``.
    s_target : (m,) float array [mm], optional
        Arc length of each of ``target``'s points.
    icp : int
        Most closest-point iterations.

    Returns
    -------
    dict
        ``max`` (symmetric Hausdorff distance between the two polylines [mm]), ``rms``
        (of the points' distance to the target [mm]), ``max_to_target`` and
        ``max_from_target`` (the two one-sided distances [mm]), ``aligned`` (the points
        moved onto the target), ``end_gap_mm`` (distance between the aligned curve's
        ends minus the target's).
    """
    P = check_array("points", points, shape=(-1, 2), min_size=2)
    T = check_array("target", target, shape=(-1, 2), min_size=2)
    icp = check_int("icp", icp, minimum=0)

    def arclen(X):
        return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(X, axis=0), axis=1))])

    sT_all = arclen(T)
    if s is None or s_target is None:
        sp = arclen(P)
        sq = sp / sp[-1] * sT_all[-1]
    else:
        s = check_array("s", s, shape=(len(P),))
        s_target = check_array("s_target", s_target, shape=(len(T),))
        sq = np.interp(s, s_target, sT_all)
    corr = np.column_stack([np.interp(sq, sT_all, T[:, 0]), np.interp(sq, sT_all, T[:, 1])])
    Q, t = _align_2d(P, corr, np.ones(len(P)))
    A = P @ Q.T + t
    for _ in range(icp):
        _, close = _closest_on_polyline(A, T)
        Q2, t2 = _align_2d(A, close, np.ones(len(A)))
        A_new = A @ Q2.T + t2
        moved = np.abs(A_new - A).max()
        A = A_new
        if moved < 1e-9:
            break
    d_to, _ = _closest_on_polyline(A, T)
    d_from, _ = _closest_on_polyline(T, A)
    return {"max": float(max(d_to.max(), d_from.max())), "rms": float(np.sqrt((d_to ** 2).mean())),
            "max_to_target": float(d_to.max()), "max_from_target": float(d_from.max()),
            "aligned": A, "end_gap_mm": float(np.linalg.norm(A[-1] - A[0]) - np.linalg.norm(T[-1] - T[0]))}
