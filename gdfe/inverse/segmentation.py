"""Sketch segmentation: a freeform polyline as a chain of couples and sharp turns (paper Sec. 4.2, Fig. 10).

The tangent-angle graph ``tau(s)`` of the polyline (:func:`tangent_graph`; ``tau_i`` the
direction of ``p_{i+1} - p_{i-1}``, unwrapped, ``s_i`` the length from ``p_0``) is split into
straight pieces by minimising

    F = sum_j eps_j + m * penalty

exactly, ``eps_j`` being the summed (weighted) squared residual of the least-squares line of
piece ``j`` and ``m`` the number of pieces: dynamic programming over breakpoints at the
vertices, ``best[b] = min_a best[a] + C[a, b] + penalty`` (:func:`fit_segments`), with the
costs ``C[a, b]`` of every run of vertices from prefix sums (:func:`segment_cost_matrix`).
Each piece ``tau = k s + c`` from ``s_a`` to ``s_b`` is one couple ``(s_b - s_a, 1/k)``, and the
jumps of ``tau`` between pieces are sharp turns that a maximum-curvature hinge approximates
(:func:`fit_sketch`, :func:`gdfe.inverse.with_hinges`).

All lengths in millimetres, angles in radians.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gdfe._validation import GdfeError, check_array, check_int, check_number
from gdfe.inverse.couples import Couple, arc_points

__all__ = ["tangent_graph", "Segmentation", "segment_cost_matrix", "fit_segments", "SketchFit", "fit_sketch"]


def tangent_graph(points):
    """Tangent-angle graph of a polyline (paper Sec. 4.2, steps 1-2).

    ``tau_i`` is the direction of ``p_{i+1} - p_{i-1}`` (one-sided at the ends), unwrapped
    so that it is continuous; ``s_i`` is the length of the polyline from ``p_0`` to ``p_i``.

    Parameters
    ----------
    points : (n, 2) float array [mm], n >= 3

    Returns
    -------
    s : (n,) float array [mm]
    tau : (n,) float array [rad]

    Raises
    ------
    GdfeError
        Fewer than three points, non-finite coordinates, or two consecutive points that coincide.
    """
    P = check_array("points", points, shape=(-1, 2))
    if len(P) < 3:
        raise GdfeError(f"points: expected a sketch of at least 3 points, got {len(P)}")
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    if np.any(seg <= 0):
        i = int(np.nonzero(seg <= 0)[0][0])
        raise GdfeError(f"points: consecutive points {i} and {i + 1} coincide (zero-length edge)")
    s = np.concatenate([[0.0], np.cumsum(seg)])
    D = np.empty_like(P)
    D[1:-1] = P[2:] - P[:-2]
    D[0] = P[1] - P[0]
    D[-1] = P[-1] - P[-2]
    tau = np.unwrap(np.arctan2(D[:, 1], D[:, 0]))
    return s, tau


@dataclasses.dataclass
class Segmentation:
    """A piecewise-linear fit of ``tau(s)``: segment ``j`` covers vertices ``start[j]:stop[j]``.

    Attributes
    ----------
    start, stop : (m,) int arrays
        Vertex ranges (``stop`` exclusive); together they partition the vertices.
    slope : (m,) float array [rad/mm]
        Fitted ``dtau/ds`` of each segment: the couple's curvature.
    intercept : (m,) float array [rad]
        Fitted ``tau`` at ``s = 0`` of each segment's line.
    eps : (m,) float array [rad^2]
        Summed squared residual of each segment.
    penalty : float
        The penalty per segment the fit was made with.
    cost : float
        ``sum(eps) + m * penalty``.
    """

    start: np.ndarray
    stop: np.ndarray
    slope: np.ndarray
    intercept: np.ndarray
    eps: np.ndarray
    penalty: float
    cost: float

    @property
    def m(self) -> int:
        return int(self.start.size)


def _check_graph(s, tau, weights):
    """``s``, ``tau`` and the weights (default 1) as float arrays of one length."""
    s = check_array("s", s, ndim=1)
    tau = check_array("tau", tau, shape=s.shape)
    w = np.ones(s.size) if weights is None else check_array("weights", weights, shape=s.shape)
    return s, tau, w


def _line_fit(s, tau, w):
    """Weighted least-squares line through (s, tau): slope, intercept, summed weighted squared residual."""
    W = w.sum()
    ms = (w * s).sum() / W
    mt = (w * tau).sum() / W
    sxx = (w * (s - ms) ** 2).sum()
    sxy = (w * (s - ms) * (tau - mt)).sum()
    slope = sxy / sxx if sxx > 0 else 0.0
    res = tau - mt - slope * (s - ms)
    return slope, mt - slope * ms, float((w * res * res).sum())


def segment_cost_matrix(s, tau, weights=None):
    """``C[a, b]``: summed squared residual of the least-squares line through vertices ``a .. b-1``.

    Computed for every pair at once from prefix sums (entries with ``b <= a`` are inf).

    Parameters
    ----------
    s, tau : (n,) float arrays
        The tangent graph (:func:`tangent_graph`).
    weights : (n,) float array, optional
        Weight of each vertex's squared residual (default 1).

    Returns
    -------
    (n + 1, n + 1) float array
    """
    s, tau, w = _check_graph(s, tau, weights)
    return _cost_matrix(s, tau, w)


def _cost_matrix(s, tau, w):
    n = s.size
    # centre for accuracy of the prefix-sum formulas
    s = s - s.mean()
    tau = tau - tau.mean()

    def csum(x):
        return np.concatenate([[0.0], np.cumsum(x)])

    S0, S1, S2 = csum(w), csum(w * s), csum(w * s * s)
    T1, T2, ST = csum(w * tau), csum(w * tau * tau), csum(w * s * tau)
    a = np.arange(n + 1)[:, None]
    b = np.arange(n + 1)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        W = S0[b] - S0[a]
        s1, s2 = S1[b] - S1[a], S2[b] - S2[a]
        t1, t2, st = T1[b] - T1[a], T2[b] - T2[a], ST[b] - ST[a]
        sxx = s2 - s1 * s1 / W
        syy = t2 - t1 * t1 / W
        sxy = st - s1 * t1 / W
        C = np.where(sxx > 1e-12 * np.maximum(s2, 1e-300), syy - sxy * sxy / sxx, syy)
    C = np.where(b > a, np.maximum(C, 0.0), np.inf)
    return C


def fit_segments(s, tau, penalty, min_points=2, weights=None):
    """Exact minimiser of ``F = sum_j eps_j + m * penalty`` over segmentations of ``tau(s)``.

    Breakpoints lie at the vertices: the segments partition the vertices into runs of at
    least ``min_points`` consecutive vertices, and each run gets its own least-squares
    line (consecutive lines need not meet: a jump is a sharp turn). ``eps_j`` is the
    summed squared residual of run ``j`` (weighted by ``weights`` if given). Dynamic
    programming over the last breakpoint finds the global minimum in O(n^2).

    Parameters
    ----------
    s, tau : (n,) float arrays
        The tangent graph (:func:`tangent_graph`).
    penalty : float
        Cost of one more segment (paper's Delta), >= 0, in the units of ``eps``.
    min_points : int
        Fewest vertices in a segment (>= 1).
    weights : (n,) float array, optional
        Weight of each vertex's squared residual (default 1: the plain sum).

    Returns
    -------
    Segmentation
    """
    s, tau, w = _check_graph(s, tau, weights)
    n = s.size
    if n < 2:
        raise GdfeError(f"s: expected at least 2 vertices to fit a line, got {n}")
    penalty = check_number("penalty", penalty, minimum=0.0, what="a non-negative number")
    min_points = check_int("min_points", min_points, minimum=1)
    if n < min_points:
        raise GdfeError(f"s: expected at least min_points={min_points} vertices for one segment, got {n}")
    C = _cost_matrix(s, tau, w)
    best = np.full(n + 1, np.inf)
    best[0] = 0.0
    prev = np.zeros(n + 1, int)
    for b in range(min_points, n + 1):
        a = np.arange(0, b - min_points + 1)
        cand = best[a] + C[a, b] + penalty
        k = int(np.argmin(cand))
        best[b], prev[b] = cand[k], a[k]
    if not np.isfinite(best[n]):
        raise GdfeError(f"s, tau: no segmentation with at least {min_points} vertices per segment")
    cuts = [n]
    while cuts[-1] > 0:
        cuts.append(int(prev[cuts[-1]]))
    cuts = cuts[::-1]
    start, stop = np.array(cuts[:-1]), np.array(cuts[1:])
    fits = [_line_fit(s[a:b], tau[a:b], w[a:b]) for a, b in zip(start, stop)]
    slope = np.array([f[0] for f in fits])
    icpt = np.array([f[1] for f in fits])
    eps = np.array([f[2] for f in fits])
    return Segmentation(start=start, stop=stop, slope=slope, intercept=icpt, eps=eps, penalty=penalty,
                        cost=float(eps.sum() + penalty * start.size))


@dataclasses.dataclass
class SketchFit:
    """Couples fitted to a sketch (paper Sec. 4.2, steps 3-5).

    Attributes
    ----------
    couples : list of Couple
        One per segment of ``tau(s)``.
    turns : (m,) float array [rad]
        Jump of the fitted ``tau`` just before each couple (``turns[0] = 0``).
    heading : float [rad]
        Fitted tangent direction at the start.
    start : (2,) float array [mm]
        The sketch's first point.
    segmentation : Segmentation
    s, tau : (n,) float arrays
        The tangent graph.
    boundaries : (m+1,) float array [mm]
        Arc lengths where segments meet (midway between their end vertices).
    """

    couples: list
    turns: np.ndarray
    heading: float
    start: np.ndarray
    segmentation: Segmentation
    s: np.ndarray
    tau: np.ndarray
    boundaries: np.ndarray

    def curve(self, ds=0.02):
        """The fitted shape: the couples' arcs with the sharp turns, from the sketch's start."""
        return arc_points(self.couples, ds=ds, start=self.start, heading=self.heading, turns=self.turns)[0]


def fit_sketch(points, penalty, min_points=2, weights=None, straight_tol=1e-9):
    """Segment a sketch's tangent graph and turn each segment into a couple.

    The segments of :func:`fit_segments` meet midway between their end vertices; a
    segment from ``s_a`` to ``s_b`` on the fitted line ``tau = k s + c`` is the couple
    ``(L, r) = (s_b - s_a, 1/k)`` (``r = 0`` where ``|k| <= straight_tol``). The lines'
    jumps at the meeting points are the sharp turns.

    Parameters
    ----------
    points : (n, 2) float array [mm], n >= 3
    penalty : float
        Penalty per segment (Delta).
    min_points : int
        Fewest vertices in a segment (>= 1).
    weights : {None, "length"} or (n,) float array
        None: plain sum of squared residuals; "length": each vertex weighted by its share
        of the polyline's length (the sum then approximates the mean of the squared
        residual over the curve and does not grow with the number of points).
    straight_tol : float [1/mm]
        Fitted curvatures this small make straight couples.

    Returns
    -------
    SketchFit
    """
    s, tau = tangent_graph(points)
    P = np.asarray(points, float)
    straight_tol = check_number("straight_tol", straight_tol, minimum=0.0)
    if isinstance(weights, str):
        if weights != "length":
            raise GdfeError(f"weights: expected None, 'length' or an array, got {weights!r}")
        ds = np.diff(s)
        w = np.concatenate([[ds[0]], ds[:-1] + ds[1:], [ds[-1]]]) / (2.0 * s[-1])
    else:
        w = weights
    seg = fit_segments(s, tau, penalty, min_points=min_points, weights=w)
    b = np.concatenate([[s[0]], 0.5 * (s[seg.stop[:-1] - 1] + s[seg.start[1:]]), [s[-1]]])
    couples = []
    turns = np.zeros(seg.m)
    for j in range(seg.m):
        L = b[j + 1] - b[j]
        k = seg.slope[j]
        couples.append(Couple(L, 0.0 if abs(k) <= straight_tol else 1.0 / k))
        if j > 0:
            turns[j] = (seg.slope[j] * b[j] + seg.intercept[j]) - (seg.slope[j - 1] * b[j] + seg.intercept[j - 1])
    heading = float(seg.slope[0] * b[0] + seg.intercept[0])
    return SketchFit(couples=couples, turns=turns, heading=heading, start=P[0].copy(), segmentation=seg,
                     s=s, tau=tau, boundaries=b)
