"""Couples: the circular arcs a planar curve is built of (paper Sec. 4.2-4.3, Fig. 9).

A planar curve is described by *couples* ``(L_i, r_i)``: circular arcs of length ``L_i``
[mm] and signed radius ``r_i`` [mm], joined tangentially (``r = 0`` is a straight piece,
as in the paper's Fig. 9; ``r > 0`` turns anticlockwise, ``r < 0`` clockwise). A couple
turns by

    alpha = L / r.

A fully contracting hinge of thickness ``h`` and contraction ratio ``R`` turns by
``(1 - R) L_c / h`` (Eq. 2), so the couple needs the contracting length

    L_c = |alpha| h / (1 - R),

and no strip bends tighter than the curvature ``(1 - R) / h``.

The points of a chain follow from the heading ``theta`` at the start of each couple: an arc
of curvature ``k`` from ``theta_0`` to ``theta_1 = theta_0 + k L`` steps by
``((sin theta_1 - sin theta_0) / k, (cos theta_0 - cos theta_1) / k)``, a straight couple
by ``L (cos theta_0, sin theta_0)``.

All lengths in millimetres, angles in radians.
"""

from __future__ import annotations

import dataclasses
import math
import numbers

import numpy as np

from gdfe._validation import GdfeError, GdfeTypeError, check_array, check_number, check_positive
from gdfe.calibration import DEFAULT_H
from gdfe.paper import R_ROUNDED

__all__ = ["Couple", "as_couples", "check_open_ratio", "contracting_length", "max_curvature", "arc_points"]


@dataclasses.dataclass(frozen=True)
class Couple:
    """A circular arc of length ``L`` [mm] and signed radius ``r`` [mm] (0: straight).

    ``r > 0`` turns anticlockwise, ``r < 0`` clockwise (paper Fig. 9); an infinite radius
    is straight too.

    Raises
    ------
    GdfeError
        ``L`` not a positive finite number, or ``r`` NaN (a :class:`GdfeTypeError` for
        what is not a number).
    """

    L: float
    r: float = 0.0

    def __post_init__(self):
        L = check_number("L", self.L, minimum=0.0, include_minimum=False, what="a positive segment length in mm")
        r = self.r
        if not (isinstance(r, numbers.Real) and math.isinf(r)):  # an infinite radius is straight
            r = check_number("r", r, what="a radius in mm (0 for straight)")
        object.__setattr__(self, "L", L)
        object.__setattr__(self, "r", float(r))

    @property
    def curvature(self) -> float:
        """Signed curvature ``1/r`` [1/mm]; 0 for a straight couple."""
        return 0.0 if self.r == 0 or math.isinf(self.r) else 1.0 / self.r

    @property
    def angle(self) -> float:
        """Signed turning angle ``L / r`` [rad]."""
        return self.L * self.curvature


def as_couples(couples):
    """A list of :class:`Couple` from couples or ``(L, r)`` pairs.

    Raises
    ------
    GdfeError
        If there is none, or a couple's length is not positive (naming the couple).
    GdfeTypeError
        If ``couples`` is not a sequence, or an entry is not an ``(L, r)`` pair.
    """
    if isinstance(couples, Couple):
        couples = [couples]
    try:
        items = list(couples)
    except TypeError:
        raise GdfeTypeError(f"couples: expected a sequence of (L, r) pairs, got {couples!r}") from None
    if not items:
        raise GdfeError("couples: expected at least one (L, r) couple, got none")
    out = []
    for i, c in enumerate(items):
        if isinstance(c, Couple):
            out.append(c)
            continue
        try:
            L, r = c
        except (TypeError, ValueError):
            raise GdfeTypeError(f"couples[{i}]: expected an (L, r) pair, got {c!r}") from None
        try:
            out.append(Couple(L, r))
        except GdfeError as exc:
            raise type(exc)(f"couples[{i}]: {exc}") from None
    return out


def check_open_ratio(R):
    """A contraction ratio for design: finite and strictly between 0 and 1 (returned as float)."""
    return check_number("R", R, minimum=0.0, maximum=1.0, include_minimum=False, include_maximum=False,
                        what="a contraction ratio strictly between 0 and 1")


def contracting_length(angle, h=DEFAULT_H, R=R_ROUNDED):
    """Length [mm] of contracting cells that turns by ``angle`` [rad]: ``|angle| h / (1 - R)``."""
    h = check_positive("h", h)
    R = check_open_ratio(R)
    return np.abs(np.asarray(angle, float)) * h / (1.0 - R)


def max_curvature(h=DEFAULT_H, R=R_ROUNDED):
    """Largest curvature [1/mm] a fully contracting strip reaches: ``(1 - R) / h``."""
    return (1.0 - check_open_ratio(R)) / check_positive("h", h)


def _chain(couples, turns, heading, start):
    """Start point, start heading and length of every couple of a chain."""
    n = len(couples)
    turns = np.zeros(n) if turns is None else check_array("turns", turns, shape=(n,))
    P = np.zeros((n + 1, 2))
    th = np.zeros(n + 1)
    P[0] = start
    th[0] = heading
    th_in = np.zeros(n)
    for i, c in enumerate(couples):
        t0 = th[i] + turns[i]
        th_in[i] = t0
        k = c.curvature
        if k == 0:
            step = c.L * np.array([math.cos(t0), math.sin(t0)])
        else:
            t1 = t0 + c.L * k
            step = np.array([math.sin(t1) - math.sin(t0), math.cos(t0) - math.cos(t1)]) / k
        P[i + 1] = P[i] + step
        th[i + 1] = t0 + c.L * k
    return P, th_in, th


def arc_points(couples, s=None, ds=0.05, start=(0.0, 0.0), heading=0.0, turns=None):
    """Points of the curve of a chain of couples.

    Parameters
    ----------
    couples : sequence of Couple or (L, r)
    s : (k,) float array [mm], optional
        Arc lengths at which to evaluate (clipped to the curve). Default: every ``ds``,
        with the ends of every couple.
    ds : float [mm]
        Spacing when ``s`` is not given.
    start : (2,) float [mm]
        First point.
    heading : float [rad]
        Direction of the tangent at the start (0: along +u).
    turns : (n,) float array [rad], optional
        Sharp turns of the tangent just before each couple (``turns[0]`` adds to ``heading``).

    Returns
    -------
    points : (k, 2) float array [mm]
    s : (k,) float array [mm]
    """
    couples = as_couples(couples)
    start = check_array("start", start, shape=(2,))
    heading = check_number("heading", heading)
    P, th_in, _ = _chain(couples, turns, heading, start)
    lengths = np.array([c.L for c in couples])
    ends = np.concatenate([[0.0], np.cumsum(lengths)])
    if s is None:
        ds = check_positive("ds", ds)
        parts = [np.linspace(ends[i], ends[i + 1], max(2, int(math.ceil(lengths[i] / ds)) + 1))
                 for i in range(len(couples))]
        s = np.unique(np.concatenate(parts))
    s = np.clip(check_array("s", s), 0.0, ends[-1])
    idx = np.clip(np.searchsorted(ends, s, side="right") - 1, 0, len(couples) - 1)
    t = s - ends[idx]
    k = np.array([c.curvature for c in couples])[idx]
    t0 = th_in[idx]
    straight = np.abs(k) < 1e-15
    ks = np.where(straight, 1.0, k)
    du = np.where(straight, t * np.cos(t0), (np.sin(t0 + k * t) - np.sin(t0)) / ks)
    dv = np.where(straight, t * np.sin(t0), (np.cos(t0) - np.cos(t0 + k * t)) / ks)
    return P[idx] + np.column_stack([du, dv]), s
