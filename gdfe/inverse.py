"""One-dimensional inverse design (paper Sec. 4.2-4.3): couples, patterns, segmentation.

A planar curve is described by *couples* ``(L_i, r_i)``: circular arcs of length ``L_i``
[mm] and signed radius ``r_i`` [mm], joined tangentially (``r = 0`` is a straight piece,
as in the paper's Fig. 9; ``r > 0`` turns anticlockwise, ``r < 0`` clockwise). A couple
turns by ``alpha = L / r``; a fully contracting hinge turns by ``(1 - R) L_c / h``
(Eq. 2), so the couple needs the contracting length

    L_c = |alpha| h / (1 - R),

which is spread uniformly over the couple as contracting cells alternated with rigid
ones (:func:`strip_pattern`). A printer that cannot print features narrower than
``w_min`` quantises the contracting cells to blocks of width ``w_min``.

The pattern is printed on a straight strip along x and the strip curls in the x-z
plane. Seen from -y (x to the right, z up) a ``CONTRACT_TOP`` cell turns the strip
anticlockwise, so ``r > 0`` maps to ``CONTRACT_TOP`` and ``r < 0`` to ``CONTRACT_BOTTOM``,
and a curve's 2-D coordinates ``(u, v)`` are the strip's ``(x, z)``.

For a freeform sketch (Sec. 4.2, Fig. 10) the tangent-angle graph ``tau(s)`` of the
polyline is split into straight pieces by minimising ``sum_j eps_j + m * penalty``
exactly (dynamic programming over breakpoints at the vertices,
:func:`fit_segments`); each piece is one couple, and the jumps of ``tau`` between pieces
are sharp turns that a maximum-curvature hinge approximates.

All lengths in millimetres, angles in radians.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gdfe._validate import check_positive
from gdfe.calibration import DEFAULT_H
from gdfe.design import Material, grid_design

__all__ = [
    "Couple", "as_couples", "check_open_ratio", "contracting_length", "max_curvature",
    "arc_points", "StripPattern", "strip_pattern", "with_hinges",
    "bent_start", "simulate_strip", "strip_midline", "align_2d", "compare_curves",
    "tangent_graph", "Segmentation", "fit_segments", "SketchFit", "fit_sketch",
]


# -- couples -------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Couple:
    """A circular arc of length ``L`` [mm] and signed radius ``r`` [mm] (0: straight).

    ``r > 0`` turns anticlockwise, ``r < 0`` clockwise (paper Fig. 9).
    """

    L: float
    r: float = 0.0

    def __post_init__(self):
        L, r = float(self.L), float(self.r)
        if not math.isfinite(L) or L <= 0:
            raise ValueError(f"L: expected a positive segment length in mm, got {self.L!r}")
        if not math.isfinite(r) and not math.isinf(r):
            raise ValueError(f"r: expected a radius in mm (0 for straight), got {self.r!r}")
        object.__setattr__(self, "L", L)
        object.__setattr__(self, "r", r)

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
    ValueError
        If there is none, or a couple's length is not positive (naming the couple).
    """
    if isinstance(couples, Couple):
        couples = [couples]
    try:
        items = list(couples)
    except TypeError:
        raise TypeError(f"couples: expected a sequence of (L, r) pairs, got {couples!r}") from None
    if not items:
        raise ValueError("couples: expected at least one (L, r) couple, got none")
    out = []
    for i, c in enumerate(items):
        if isinstance(c, Couple):
            out.append(c)
            continue
        try:
            L, r = c
        except (TypeError, ValueError):
            raise TypeError(f"couples[{i}]: expected an (L, r) pair, got {c!r}") from None
        try:
            out.append(Couple(L, r))
        except ValueError as exc:
            raise ValueError(f"couples[{i}]: {exc}") from None
    return out


def check_open_ratio(R):
    """A contraction ratio for design: finite and strictly between 0 and 1."""
    if isinstance(R, (str, bytes)) or R is None:
        raise TypeError(f"R: expected a number, got {R!r}")
    R = float(R)
    if not (0.0 < R < 1.0):
        raise ValueError(f"R: expected a contraction ratio strictly between 0 and 1, got {R:g}")
    return R


def contracting_length(angle, h=DEFAULT_H, R=0.7):
    """Length [mm] of contracting cells that turns by ``angle`` [rad]: ``|angle| h / (1 - R)``."""
    h = check_positive("h", h)
    R = check_open_ratio(R)
    return np.abs(np.asarray(angle, float)) * h / (1.0 - R)


def max_curvature(h=DEFAULT_H, R=0.7):
    """Largest curvature [1/mm] a fully contracting strip reaches: ``(1 - R) / h``."""
    return (1.0 - check_open_ratio(R)) / check_positive("h", h)


def _chain(couples, turns, heading, start):
    """Start point, start heading and length of every couple of a chain."""
    n = len(couples)
    turns = np.zeros(n) if turns is None else np.asarray(turns, float)
    if turns.shape != (n,):
        raise ValueError(f"turns: expected {n} turns (one before each couple), got shape {turns.shape}")
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
    P, th_in, _ = _chain(couples, turns, heading, np.asarray(start, float))
    lengths = np.array([c.L for c in couples])
    ends = np.concatenate([[0.0], np.cumsum(lengths)])
    if s is None:
        ds = check_positive("ds", ds)
        parts = [np.linspace(ends[i], ends[i + 1], max(2, int(math.ceil(lengths[i] / ds)) + 1))
                 for i in range(len(couples))]
        s = np.unique(np.concatenate(parts))
    s = np.clip(np.asarray(s, float), 0.0, ends[-1])
    idx = np.clip(np.searchsorted(ends, s, side="right") - 1, 0, len(couples) - 1)
    t = s - ends[idx]
    k = np.array([c.curvature for c in couples])[idx]
    t0 = th_in[idx]
    straight = np.abs(k) < 1e-15
    ks = np.where(straight, 1.0, k)
    du = np.where(straight, t * np.cos(t0), (np.sin(t0 + k * t) - np.sin(t0)) / ks)
    dv = np.where(straight, t * np.sin(t0), (np.cos(t0) - np.cos(t0 + k * t)) / ks)
    return P[idx] + np.column_stack([du, dv]), s


# -- patterns ------------------------------------------------------------------------------

@dataclasses.dataclass
class StripPattern:
    """The printed pattern of a chain of couples on a straight strip along x.

    Attributes
    ----------
    material : (n,) int array
        :class:`gdfe.Material` of each column of cells along the strip.
    cell : float [mm]
        Column width (the simulation's cell size along x).
    segment : (n,) int array
        Couple that each column belongs to.
    couples : list of Couple
        The couples as asked for.
    h, R : float
        Film thickness [mm] and contraction ratio of the free faces.
    w_min : float or None [mm]
        Printer resolution the contracting blocks were quantised to (None: the cell).
    rounding : str
        How the number of contracting blocks was rounded.
    L_c : (k,) float array [mm]
        Contracting length each couple needs, ``|alpha| h / (1 - R)``.
    L_c_printed : (k,) float array [mm]
        Contracting length printed after quantisation.
    blocks : (k,) int array
        Contracting blocks per couple.
    angle : (k,) float array [rad]
        Turning angle each couple asks for.
    angle_printed : (k,) float array [rad]
        Turning angle of the printed contracting length by Eq. 2, ``(1 - R) L_c_printed / h``.
    clamped : (k,) bool array
        Couples tighter than the film can fold, printed fully contracting instead.
    """

    material: np.ndarray
    cell: float
    segment: np.ndarray
    couples: list
    h: float
    R: float
    w_min: float | None
    rounding: str
    L_c: np.ndarray
    L_c_printed: np.ndarray
    blocks: np.ndarray
    angle: np.ndarray
    angle_printed: np.ndarray
    clamped: np.ndarray

    @property
    def length(self) -> float:
        """Printed strip length [mm]."""
        return float(self.material.size * self.cell)

    def printed_couples(self):
        """Couples with the printed lengths and the turn of the printed contracting cells."""
        out = []
        for i in range(len(self.couples)):
            L = float((self.segment == i).sum() * self.cell)
            a = float(self.angle_printed[i])
            out.append(Couple(L, L / a if a != 0 else 0.0))
        return out

    def rows(self) -> str:
        """The pattern as one text row (``R``, ``T``, ``B``), as :func:`gdfe.from_rows` reads it."""
        chars = {int(Material.RIGID): "R", int(Material.CONTRACT_TOP): "T", int(Material.CONTRACT_BOTTOM): "B"}
        return "".join(chars[int(m)] for m in self.material)

    def design(self, width=0.5, ny=1, nz=1, isotropy=1.0):
        """The strip as a :class:`gdfe.Design` (regions ``seg0``, ``seg1``, ...).

        Parameters
        ----------
        width : float [mm]
            Strip width along y.
        ny : int
            Cells across the strip.
        nz : int
            Cell layers through the film.
        isotropy : float
            See :class:`gdfe.Design`.
        """
        width = check_positive("width", width)
        mat = np.repeat(self.material[:, None], ny, axis=1)
        regions = {f"seg{i}": np.repeat((self.segment == i)[:, None], ny, axis=1)
                   for i in range(len(self.couples))}
        meta = {"kind": "strip", "couples": [[c.L, c.r] for c in self.couples], "R": self.R,
                "cell_mm": self.cell, "w_min_mm": self.w_min, "rounding": self.rounding}
        return grid_design(mat, self.R, h=self.h, pixel=(self.cell, width / ny), nz=nz, isotropy=isotropy,
                           regions2d=regions, meta=meta)


_ROUNDING = {"nearest": lambda x: np.floor(x + 0.5), "floor": np.floor, "ceil": np.ceil,
             "carry": lambda x: np.floor(x + 0.5)}


def strip_pattern(couples, h=DEFAULT_H, R=0.7, cell=None, w_min=None, rounding="nearest", clamp=False):
    """Contracting and rigid cells along a strip that folds into the curve of the couples.

    Each couple gets ``round(L / cell)`` columns. Its contracting length
    ``L_c = |L / r| h / (1 - R)`` is printed as ``n_b`` blocks of width ``w_min``
    (``n_b = rounding(L_c / w_min)``; without a printer resolution a block is one cell),
    spread uniformly along the couple with rigid cells between them: block ``j`` is
    centred at ``(j + 1/2) / n_b`` of the couple. Contracting cells are ``CONTRACT_TOP``
    for ``r > 0`` (anticlockwise) and ``CONTRACT_BOTTOM`` for ``r < 0``.

    Parameters
    ----------
    couples : sequence of Couple or (L, r)
    h : float [mm]
        Film thickness.
    R : float
        Contraction ratio of the free face, strictly between 0 and 1.
    cell : float [mm], optional
        Column width. Default: 0.125 mm, or ``w_min`` divided into the fewest equal
        parts no wider than 0.125 mm.
    w_min : float [mm], optional
        Narrowest contracting feature the printer makes; must be a whole number of cells.
    rounding : {"nearest", "floor", "ceil", "carry"}
        How ``L_c / w_min`` is rounded to a number of blocks. "nearest" rounds each couple
        on its own (halves up). "carry" rounds to the nearest too, but adds to each couple the
        turn the couples before it lost or gained by rounding (as far as the couple can take
        it: never below zero blocks, never the opposite way, straight couples stay straight),
        so the printed strip's accumulated turn stays within half a block of the target's;
        couples shorter than a block, like the hinges of :func:`with_hinges`, then keep
        their turn.
    clamp : bool
        A couple tighter than the film can fold (``L_c > L``) raises ValueError unless
        ``clamp``, which prints it fully contracting (the maximum curvature, ``(1-R)/h``).

    Returns
    -------
    StripPattern
    """
    couples = as_couples(couples)
    h = check_positive("h", h)
    R = check_open_ratio(R)
    if rounding not in _ROUNDING:
        raise ValueError(f"rounding: expected one of {sorted(_ROUNDING)}, got {rounding!r}")
    if w_min is not None:
        if isinstance(w_min, (str, bytes)) or not math.isfinite(float(w_min)) or float(w_min) <= 0:
            raise ValueError(f"w_min: expected a positive printer resolution in mm, got {w_min!r}")
        w_min = float(w_min)
    if cell is None:
        cell = 0.125 if w_min is None else w_min / math.ceil(w_min / 0.125 - 1e-9)
    cell = check_positive("cell", cell)
    if w_min is None:
        b = 1
    else:
        b = int(round(w_min / cell))
        if b < 1 or abs(b * cell - w_min) > 1e-6 * w_min:
            raise ValueError(f"w_min: expected a whole number of cells ({cell:g} mm), got {w_min:g} mm")
    w = b * cell
    materials, segments = [], []
    k = len(couples)
    L_c = np.zeros(k)
    L_cp = np.zeros(k)
    blocks = np.zeros(k, int)
    clamped = np.zeros(k, bool)
    turn_per_block = w * (1.0 - R) / h
    debt = 0.0  # target minus printed accumulated turn [rad] ("carry")
    for i, c in enumerate(couples):
        n = max(1, int(round(c.L / cell)))
        L_c[i] = abs(c.angle) * h / (1.0 - R)
        want = L_c[i] / w
        if rounding == "carry" and c.angle != 0:
            want = max(0.0, math.copysign(1.0, c.angle) * (c.angle + debt)) / turn_per_block
        nb = int(_ROUNDING[rounding](want - 1e-12)) if want > 0 else 0
        if rounding == "carry" and L_c[i] <= n * cell:
            nb = min(nb, n // b)  # a carried turn never makes a feasible couple infeasible
        col = np.full(n, int(Material.RIGID))
        code = int(Material.CONTRACT_TOP if c.curvature > 0 else Material.CONTRACT_BOTTOM)
        if nb * b > n:
            if not clamp:
                rmin = h / (1.0 - R)
                raise ValueError(
                    f"couples[{i}]: radius {abs(c.r):g} mm needs a contracting length {L_c[i]:.4g} mm "
                    f"longer than the couple ({c.L:g} mm); the film folds no tighter than "
                    f"h/(1-R) = {rmin:.4g} mm (pass clamp=True to print it fully contracting)")
            clamped[i] = True
            col[:] = code
            nb = n // b if n >= b else 0
            L_cp[i] = n * cell
        else:
            for j in range(nb):
                centre = (j + 0.5) * n / nb
                s0 = int(np.clip(math.floor(centre - b / 2 + 0.5), 0, n - b))
                col[s0:s0 + b] = code
            L_cp[i] = float((col == code).sum() * cell) if nb else 0.0
        blocks[i] = nb
        debt += c.angle - math.copysign(1.0, c.angle) * (1.0 - R) * L_cp[i] / h
        materials.append(col)
        segments.append(np.full(n, i))
    angle = np.array([c.angle for c in couples])
    angle_p = np.sign(angle) * (1.0 - R) * L_cp / h
    return StripPattern(material=np.concatenate(materials), cell=cell, segment=np.concatenate(segments),
                        couples=couples, h=h, R=R, w_min=w_min, rounding=rounding, L_c=L_c,
                        L_c_printed=L_cp, blocks=blocks, angle=angle, angle_printed=angle_p,
                        clamped=clamped)


def with_hinges(couples, turns, h=DEFAULT_H, R=0.7, min_turn=1e-3):
    """Replace the sharp turns of a chain by maximum-curvature hinges (paper Sec. 4.2).

    A turn ``t`` before couple ``i`` becomes a fully contracting couple of length
    ``|t| h / (1 - R)`` and radius ``sign(t) h / (1 - R)`` inserted before it; turns
    smaller than ``min_turn`` [rad] are dropped. The first turn (at the start of the
    curve) only rotates the whole curve and is dropped too.

    Returns
    -------
    list of Couple
    """
    couples = as_couples(couples)
    h = check_positive("h", h)
    R = check_open_ratio(R)
    turns = np.asarray(turns, float)
    if turns.shape != (len(couples),):
        raise ValueError(f"turns: expected {len(couples)} turns, got shape {turns.shape}")
    rmin = h / (1.0 - R)
    out = []
    for i, c in enumerate(couples):
        t = turns[i]
        if i > 0 and abs(t) >= min_turn:
            out.append(Couple(abs(t) * rmin, math.copysign(rmin, t)))
        out.append(c)
    return out


# -- simulation and measurement of strips --------------------------------------------------

def _column_rates(design):
    """Signed curvature [1/mm] each column of a strip would take by Eq. 2 (mean over its cells)."""
    mesh = design.mesh
    ci = mesh.cell_ij[:, 0]
    ncol = int(ci.max()) + 1
    sign = np.where(design.material == Material.CONTRACT_TOP, 1.0,
                    np.where(design.material == Material.CONTRACT_BOTTOM, -1.0, 0.0))
    rate = sign * (1.0 - design.R) / design.h
    return np.bincount(ci, rate, ncol) / np.maximum(np.bincount(ci, minlength=ncol), 1)


def bent_start(design):
    """A starting shape for a strip: every column already turned as Eq. 2 says.

    The strip's flat mid-line is mapped onto the curve whose curvature in each column is
    the Eq. 2 rate of its contracting cells; every vertex keeps its offset from the
    mid-surface along the curve's normal. The solver then only corrects this guess,
    which takes far fewer iterations than starting from the flat print for strips that
    roll up by a full turn.

    Returns
    -------
    (n, 3) float array [mm]
    """
    mesh = design.mesh
    P = mesh.points
    dx = float(mesh.spacing[0])
    rate = _column_rates(design)
    ncol = rate.size
    th = np.concatenate([[0.0], np.cumsum(rate * dx)])
    step = np.where(np.abs(rate) < 1e-12, dx * np.cos(th[:-1]),
                    (np.sin(th[1:]) - np.sin(th[:-1])) / np.where(np.abs(rate) < 1e-12, 1.0, rate))
    stepz = np.where(np.abs(rate) < 1e-12, dx * np.sin(th[:-1]),
                     (np.cos(th[:-1]) - np.cos(th[1:])) / np.where(np.abs(rate) < 1e-12, 1.0, rate))
    cu = np.concatenate([[0.0], np.cumsum(step)])
    cv = np.concatenate([[0.0], np.cumsum(stepz)])
    x0 = P[:, 0].min()
    xb = x0 + np.arange(ncol + 1) * dx
    x = P[:, 0]
    t = np.interp(x, xb, th)
    u = np.interp(x, xb, cu)
    v = np.interp(x, xb, cv)
    off = P[:, 2] - design.h / 2
    return np.column_stack([x0 + u - off * np.sin(t), P[:, 1], design.h / 2 + v + off * np.cos(t)])


def simulate_strip(design, tol=1e-7, max_iter=400):
    """Simulate a strip design from :func:`bent_start` with the damped Newton solver.

    :func:`gdfe.simulate` with ``init=bent_start(design)``: same energy, same stopping
    criterion and same fixed point; only the starting shape differs (the flat print's
    linearised solution converges slowly for strips that roll up by a full turn).

    Returns
    -------
    gdfe.Result
        Check ``converged``.
    """
    from gdfe.solver import simulate

    return simulate(design, method="newton", init=bent_start(design), tol=tol, max_iter=max_iter)


def strip_midline(result, design=None):
    """Mid-line of a simulated strip: its two end faces' centroids and every column's centroid.

    Returns
    -------
    s : (c + 2,) float array [mm]
        Arc length of each point in the flat print, from the strip's start (0 and the strip
        length for the end faces, column centres between).
    uv : (c + 2, 2) float array [mm]
        The points' (x, z) coordinates: the curve in the plane the strip curls in.
    off_plane : float [mm]
        Largest spread of the points along y (0 for a strip that curls in a plane).
    """
    from gdfe.measure import _points_design, column_frames

    points, design = _points_design(result, design)
    cols, _, centre = column_frames(points, design)
    flat = design.mesh.points
    dx = float(design.mesh.spacing[0])
    x0, x1 = flat[:, 0].min(), flat[:, 0].max()
    tol = 1e-9 * max(1.0, abs(x1))
    first = points[np.abs(flat[:, 0] - x0) <= tol].mean(axis=0)
    last = points[np.abs(flat[:, 0] - x1) <= tol].mean(axis=0)
    pts = np.vstack([first, centre, last])
    s = np.concatenate([[0.0], (cols + 0.5) * dx, [x1 - x0]])
    return s, pts[:, [0, 2]], float(np.ptp(pts[:, 1]))


def align_2d(source, target, weights=None):
    """Best proper rotation and translation of the plane taking ``source`` onto ``target``.

    Only rotations (det +1) are allowed, so a mirrored curve is not aligned onto its image.

    Returns
    -------
    Q : (2, 2) float array
    t : (2,) float array [mm]
        ``source @ Q.T + t`` is aligned with ``target``.
    """
    A = np.asarray(source, float)
    B = np.asarray(target, float)
    w = np.ones(len(A)) if weights is None else np.asarray(weights, float)
    w = w / w.sum()
    ca, cb = w @ A, w @ B
    H = ((A - ca) * w[:, None]).T @ (B - cb)
    ang = math.atan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
    Q = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    return Q, cb - ca @ Q.T


def _closest_on_polyline(P, poly, chunk=2048):
    """Distance from each point of ``P`` (k, 2) to the polyline ``poly`` (m, 2), and the closest points."""
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

    Returns
    -------
    dict
        ``max`` (symmetric Hausdorff distance between the two polylines [mm]), ``rms``
        (of the points' distance to the target [mm]), ``max_to_target`` and
        ``max_from_target`` (the two one-sided distances [mm]), ``aligned`` (the points
        moved onto the target), ``end_gap_mm`` (distance between the aligned curve's
        ends minus the target's).
    """
    P = np.asarray(points, float)
    T = np.asarray(target, float)

    def arclen(X):
        return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(X, axis=0), axis=1))])

    sT_all = arclen(T)
    if s is None or s_target is None:
        sp = arclen(P)
        sq = sp / sp[-1] * sT_all[-1]
    else:
        sq = np.interp(np.asarray(s, float), np.asarray(s_target, float), sT_all)
    corr = np.column_stack([np.interp(sq, sT_all, T[:, 0]), np.interp(sq, sT_all, T[:, 1])])
    Q, t = align_2d(P, corr)
    A = P @ Q.T + t
    for _ in range(int(icp)):
        _, close = _closest_on_polyline(A, T)
        Q2, t2 = align_2d(A, close)
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


# -- sketch segmentation -------------------------------------------------------------------

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
    ValueError
        Fewer than three points, non-finite coordinates, or two consecutive points that coincide.
    """
    P = np.asarray(points, float)
    if P.ndim != 2 or P.shape[1] != 2:
        raise ValueError(f"points: expected an (n, 2) array of sketch points, got shape {P.shape}")
    if len(P) < 3:
        raise ValueError(f"points: a sketch needs at least 3 points, got {len(P)}")
    if not np.isfinite(P).all():
        raise ValueError("points: expected finite coordinates, got NaN or inf")
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    if np.any(seg <= 0):
        i = int(np.nonzero(seg <= 0)[0][0])
        raise ValueError(f"points: consecutive points {i} and {i + 1} coincide (zero-length edge)")
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
    """
    s = np.asarray(s, float)
    tau = np.asarray(tau, float)
    n = s.size
    w = np.ones(n) if weights is None else np.asarray(weights, float)
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
    s = np.asarray(s, float)
    tau = np.asarray(tau, float)
    if s.shape != tau.shape or s.ndim != 1:
        raise ValueError(f"s, tau: expected two 1-D arrays of the same length, got {s.shape} and {tau.shape}")
    n = s.size
    if n < 2:
        raise ValueError(f"s, tau: need at least 2 vertices to fit a line, got {n}")
    if isinstance(penalty, (str, bytes)) or not math.isfinite(float(penalty)) or float(penalty) < 0:
        raise ValueError(f"penalty: expected a non-negative number, got {penalty!r}")
    penalty = float(penalty)
    if int(min_points) < 1:
        raise ValueError(f"min_points: expected an integer >= 1, got {min_points!r}")
    min_points = int(min_points)
    if n < min_points:
        raise ValueError(f"s, tau: {n} vertices cannot hold one segment of min_points={min_points}")
    w = np.ones(n) if weights is None else np.asarray(weights, float)
    C = segment_cost_matrix(s, tau, w)
    best = np.full(n + 1, np.inf)
    best[0] = 0.0
    prev = np.zeros(n + 1, int)
    for b in range(min_points, n + 1):
        a = np.arange(0, b - min_points + 1)
        cand = best[a] + C[a, b] + penalty
        k = int(np.argmin(cand))
        best[b], prev[b] = cand[k], a[k]
    if not np.isfinite(best[n]):
        raise ValueError(f"s, tau: no segmentation with at least {min_points} vertices per segment")
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
    weights : {None, "length"} or (n,) float array
        None: plain sum of squared residuals; "length": each vertex weighted by its share
        of the polyline's length (the sum then approximates the mean of the squared
        residual over the curve and does not grow with the number of points).

    Returns
    -------
    SketchFit
    """
    P = np.asarray(points, float)
    s, tau = tangent_graph(P)
    if isinstance(weights, str):
        if weights != "length":
            raise ValueError(f"weights: expected None, 'length' or an array, got {weights!r}")
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
