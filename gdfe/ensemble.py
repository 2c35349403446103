"""Ensembles through the simulator: one part folded by draws of a deformation model's predictive content.

A model file with predictive content (:mod:`gdfe.predictive`: each member's parameter covariance,
the members' stacking weights) says how sure its fold of a test is. Carried to a part, that
uncertainty is a distribution of shapes: :func:`fold_ensemble` draws ``n`` models
(:func:`gdfe.predict.draw_models`: a member by its weight, its parameters from their covariance),
applies each to the part's cells (:meth:`gdfe.DeformationModel.apply`) and folds it, every draw
started from the nominal fold (the given-positions start of :func:`gdfe.simulate`): a draw moves
the shape a little, so Newton's method starts close to its answer. The draws run in parallel
(:func:`gdfe.parallel.parallel_map`: local processes or a Dask cluster).

The :class:`Ensemble` gives central intervals at ``level`` of the fold angles and of any other
measure of the part (the quantiles of the converged draws), the probability that a measure falls
below a threshold (with its Wilson interval: 32 draws estimate a probability to about +-0.15), and
the per-vertex spread: the root of the summed variances of each vertex's coordinates over the
draws, after each draw is aligned to the nominal shape by the rigid motion that fits it best
(Kabsch), so the spread is of the shape, not of where the solver left it in space.

A draw's start can do better than the nominal fold. The first :data:`PILOT` draws are folded
from it; each later draw starts from the **secant prediction** of its shape: its cells'
contractions ``c`` (of each cell's top and bottom face) are written as
the least-squares combination ``c - c0 = sum_j a_j (c_j - c0)`` of the pilots' (``c0`` the
nominal model's), and its start is ``x0 + sum_j a_j (x_j - x0)``, the same combination of the
pilots' folds (each aligned rigidly to the nominal ``x0`` first). Exact where the fold is linear
in the contractions and the draws span no more directions than the pilots; near it otherwise
(a few parameters per member, each draw a small step from the nominal model). A start only
changes where Newton's method begins: every draw meets the same stopping test.

The noise of a test is not in it: it is the scatter of one measured hinge, not of a part's every
hinge at once. Draws that do not converge are counted and left out of the intervals, and said so.
So are intervals at a level the converged draws cannot resolve (fewer than one draw beyond each
end, ``n (1 - level) / 2 < 1``: :func:`draws_for`), which are narrower than their level says.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from gdfe._validation import GdfeError, check_int, check_number
from gdfe.measure import rigid_align

__all__ = ["LEVEL", "PILOT", "Ensemble", "fold_ensemble", "secant_starts", "has_predictive_content", "align_rigidly",
           "draws_for", "wilson_interval", "write_spread", "plot_band"]

#: Default level of the intervals.
LEVEL = 0.9

#: Solver options a draw inherits from the nominal solve (its start is the nominal shape, in one frame).
DRAW_OPTIONS = ("method", "tol", "max_iter", "contact", "on_drift")
#: Draws folded from the nominal shape before the later ones start from the secant prediction.
PILOT = 4
#: Largest combination coefficient a secant prediction may use (beyond it: the nominal start).
MAX_COEFFICIENT = 3.0
STARTS = ("predicted", "nominal", "solver")


def has_predictive_content(model):
    """Whether ``model`` carries a parameter covariance or an ensemble of members to draw from."""
    if model is None:
        return False
    return getattr(model, "uncertainty", None) is not None or bool(getattr(model, "ensemble", ()))


def align_rigidly(points, reference):
    """``points`` moved by the rotation and translation that bring them closest (least squares) to
    ``reference``: :func:`gdfe.measure.rigid_align` applied."""
    Q, t = rigid_align(points, reference)
    return np.asarray(points, float) @ Q.T + t


def draws_for(level):
    """The fewest draws whose central interval at ``level`` has a draw beyond each end, ``n (1 - level) / 2 >= 1``:
    20 for 0.9, 40 for 0.95; with fewer, the interval's ends lie within the range of the draws, and it is narrower
    than the level says."""
    return math.ceil(round(2.0 / (1.0 - level), 6))  # 2 / (1 - 0.9) is 20.000000000000004 in floating point


def wilson_interval(k, n, level=LEVEL):
    """Wilson score interval of a probability from ``k`` successes in ``n`` trials."""
    from scipy.stats import norm

    if n == 0:
        return (0.0, 1.0)
    z = float(norm.ppf(0.5 + level / 2))
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


@dataclasses.dataclass
class Ensemble:
    """The folds of one part under ``n`` draws of its model.

    Attributes
    ----------
    n : int
        Draws asked for.
    level : float
        Level of the intervals.
    labels : list of str
        One label per fold angle (``"hinge"``, ``"panels 0-1"``, ``"crease 3"``, ...).
    nominal_angles : (k,) float array [rad]
        The fold angles of the nominal model's fold.
    angles : (m, k) float array [rad]
        The fold angles of the ``m`` converged draws.
    nominal_measures, measures : dict of float, dict of (m,) float arrays
        The part's other measures (``end_gap_mm``, ``turn_rad``, ``rms_mm``, ...), nominal and per draw.
    nominal_points : (p, 3) float array [mm]
    points : (m, p, 3) float array [mm]
        The converged draws' shapes, each aligned to the nominal one (:func:`align_rigidly`).
    spread_mm : (p,) float array [mm]
        Per vertex: sqrt of the summed variances of its coordinates over the converged draws.
    converged : (n,) bool array
    iterations : (n,) int array
        Solver iterations of each draw.
    seconds : float
        Wall time of the ensemble (all draws, in parallel).
    draw_seconds, draw_cpu_seconds : (n,) float array
        The solve time of each draw on its worker, wall and CPU (the worker process's, all its threads).
    models : list of str
        The member each draw came from.
    """

    n: int
    level: float
    labels: list
    nominal_angles: np.ndarray
    angles: np.ndarray
    nominal_measures: dict
    measures: dict
    nominal_points: np.ndarray
    points: np.ndarray
    spread_mm: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    seconds: float
    draw_seconds: np.ndarray
    models: list
    start: str = "the nominal fold"
    draw_cpu_seconds: np.ndarray = None

    @property
    def n_converged(self):
        return int(self.converged.sum())

    def interval(self, values):
        """Central interval at :attr:`level` of ``values`` (NaN, NaN where there are none)."""
        v = np.asarray(values, float)
        if v.size == 0:
            return (math.nan, math.nan)
        lo, hi = np.quantile(v, [(1 - self.level) / 2, (1 + self.level) / 2])
        return (float(lo), float(hi))

    @property
    def warnings(self):
        """Sentences on what the intervals cannot say: too few converged draws for :attr:`level`
        (:func:`draws_for`)."""
        need, m = draws_for(self.level), self.n_converged
        if not 0 < m < need:
            return []
        return [f"{m} converged draws cannot resolve {100 * self.level:g} % intervals: their ends lie within the "
                f"range of the draws, so the intervals are narrower than the level says (and may miss the nominal "
                f"value); that level needs at least {need} draws (or a lower level)"]

    def probability_below(self, name, threshold):
        """``(p, (lo, hi))``: the share of converged draws whose measure ``name`` is at most ``threshold``, with
        its Wilson interval at :attr:`level`."""
        v = np.asarray(self.measures[name], float)
        k = int(np.sum(v <= threshold))
        return (k / v.size if v.size else math.nan), wilson_interval(k, v.size, self.level)

    def within(self, name, threshold):
        """The JSON of the probability that measure ``name`` is at most ``threshold``: ``{"threshold",
        "probability", "interval"}`` (the Wilson interval at :attr:`level`)."""
        p, (lo, hi) = self.probability_below(name, threshold)
        return {"measure": name, "threshold": float(threshold), "probability": p, "interval": [lo, hi],
                "draws": self.n_converged}

    def as_dict(self):
        """The JSON of ``"uncertainty"``: intervals of the fold angles and measures, draws, time, and
        :attr:`warnings`."""
        angles = [{"label": lab, "fold_angle_rad": float(self.nominal_angles[j]),
                   "interval_rad": list(self.interval(self.angles[:, j])),
                   "sd_rad": float(np.std(self.angles[:, j], ddof=1)) if len(self.angles) > 1 else math.nan}
                  for j, lab in enumerate(self.labels)]
        measures = {}
        for name, v in self.measures.items():
            measures[name] = {"nominal": float(self.nominal_measures[name]), "interval": list(self.interval(v))}
        counts = {}
        for m in self.models:
            counts[m] = counts.get(m, 0) + 1
        return {"n": self.n, "level": self.level, "n_converged": self.n_converged,
                "fold_angles": angles, "measures": measures,
                "spread_mm": {"max": float(self.spread_mm.max()) if self.spread_mm.size else math.nan,
                              "mean": float(self.spread_mm.mean()) if self.spread_mm.size else math.nan},
                "members_drawn": counts, "seconds": self.seconds,
                "draw_seconds_median": float(np.median(self.draw_seconds)),
                "draw_cpu_seconds_total": float(np.sum(self.draw_cpu_seconds)),
                "iterations_median": float(np.median(self.iterations)),
                "start": self.start, "warnings": self.warnings}

    def text(self):
        """A few lines for a command's text output."""
        lines = [f"  uncertainty: {self.n} draws of the model ({self.n_converged} converged), "
                 f"{100 * self.level:g} % intervals, {self.seconds:.1f} s"]
        if self.n_converged < self.n:
            lines.append(f"    {self.n - self.n_converged} draws did NOT converge and are left out of the intervals")
        lines += [f"    WARNING: {w}" for w in self.warnings]
        for j, lab in enumerate(self.labels[:8]):
            lo, hi = self.interval(self.angles[:, j])
            lines.append(f"    {lab}: {self.nominal_angles[j]:.4f} rad, interval {lo:.4f} to {hi:.4f} rad")
        if len(self.labels) > 8:
            lines.append(f"    and {len(self.labels) - 8} more fold angles (in the JSON)")
        for name, v in self.measures.items():
            lo, hi = self.interval(v)
            lines.append(f"    {name}: {self.nominal_measures[name]:.4g}, interval {lo:.4g} to {hi:.4g}")
        if self.spread_mm.size:
            lines.append(f"    vertex spread (sd over the draws): max {self.spread_mm.max():.3g} mm, "
                         f"mean {self.spread_mm.mean():.3g} mm")
        return "\n".join(lines)


def _fold_one(item):
    """One draw: its design folded from ``start``, measured. Module-level, for the worker processes."""
    import gdfe

    design, start, options, measure = item
    t0, c0 = time.perf_counter(), time.process_time()
    res = gdfe.simulate(design, init=start, steps=1, **options)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    angles, measures = measure(res)
    return {"points": np.asarray(res.points, float), "angles": [float(a) for a in angles],
            "measures": {k: float(v) for k, v in measures.items()}, "converged": bool(res.converged),
            "iterations": int(res.iterations), "seconds": seconds, "cpu_seconds": cpu}


def _contractions(design):
    """A design's cell contractions as one vector: each cell's top and bottom face
    (:meth:`Design.face_contraction`, the explicit per-face contraction of a mechanism where a
    member sets one, else from ``R``), the same length for every member of a model."""
    return np.concatenate(design.face_contraction())


def secant_starts(c0, x0, pilot_c, pilot_x, targets):
    """Starts of the draws of contractions ``targets`` from the pilots' folds (see the module's text).

    Parameters
    ----------
    c0 : (m,) float array
        The nominal model's contractions.
    x0 : (v, 3) float array
        The nominal fold.
    pilot_c : (P, m) float array
    pilot_x : (P, v, 3) float array
        The pilots' contractions and folds, aligned rigidly to ``x0``.
    targets : (N, m) float array

    Returns
    -------
    (N, v, 3) float array
        Each draw's start; the nominal fold where a draw is no combination of the pilots with
        coefficients within :data:`MAX_COEFFICIENT` (it would be an extrapolation).
    """
    A = (np.asarray(pilot_c, float) - c0).T  # (m, P)
    B = np.asarray(targets, float) - c0  # (N, m)
    if A.size == 0 or not np.any(A):
        return np.broadcast_to(x0, (len(B),) + x0.shape).copy()
    coef = np.linalg.lstsq(A, B.T, rcond=1e-10)[0].T  # (N, P)
    dx = np.asarray(pilot_x, float) - x0  # (P, v, 3)
    out = x0 + np.einsum("np,pvk->nvk", coef, dx)
    wild = np.abs(coef).max(axis=1) > MAX_COEFFICIENT
    out[wild] = x0
    return out


def fold_ensemble(design, model, n, *, nominal, measure, labels=None, level=LEVEL, seed=0, process=None,
                  options=None, start="predicted", n_jobs=None, scheduler=None, progress=None):
    """Fold ``design`` under ``n`` draws of ``model``'s predictive content.

    Parameters
    ----------
    design : Design
        The part, its cells carrying the passive thickness ``d`` they are printed with.
    model : DeformationModel
        With predictive content (:func:`has_predictive_content`).
    n : int
        Draws.
    nominal : Result
        The part folded by the nominal model: every draw starts from its final shape.
    measure : callable
        ``measure(result) -> (angles, measures)``: the fold angles [rad] (a list, the same length for every
        draw) and a dict of other measures. Module-level (it travels to the workers).
    labels : list of str, optional
        A label per fold angle (default ``"angle 0"``, ...).
    level : float
        Level of the intervals (default 0.9).
    seed : int
        Seed of the draws (an integer >= 0).
    process : dict, optional
        The part's process variables for the model.
    options : dict, optional
        Solver options of the draws (:data:`DRAW_OPTIONS`; others are ignored).
    start : {"predicted", "nominal", "solver"}
        Where each draw's solve starts: the secant prediction from :data:`PILOT` draws folded
        from the nominal fold (default; see the module's text), the nominal fold, or the
        solver's own start (:func:`gdfe.simulate`'s ``init="auto"``), for comparison.
    n_jobs, scheduler, progress
        As :func:`gdfe.parallel.parallel_map`.

    Returns
    -------
    Ensemble
    """
    from gdfe.parallel import parallel_map
    from gdfe.predict import draw_models

    n = check_int("n", n, minimum=2)
    level = check_number("level", level, minimum=0.0)
    if not 0 < level < 1:
        raise GdfeError(f"level: expected a number between 0 and 1, got {level:g}")
    if not has_predictive_content(model):
        raise GdfeError(f"model {getattr(model, 'name', model)!r}: expected a model with predictive content (a "
                        f"parameter covariance or an ensemble: gdfe diagnose or gdfe calibrate --model-out) to draw "
                        f"from")
    draws = draw_models(model, n, seed=seed)  # first: it checks the seed
    opts = {k: v for k, v in (options or {}).items() if k in DRAW_OPTIONS and v is not None}
    if start not in STARTS:
        raise GdfeError(f"start: expected one of {', '.join(map(repr, STARTS))}, got {start!r}")
    how = start
    init = "auto" if how == "solver" else np.asarray(nominal.points, float)
    start = np.asarray(nominal.points, float)
    nominal_angles, nominal_measures = measure(nominal)
    k = len(nominal_angles)
    labels = list(labels) if labels is not None else [f"angle {j}" for j in range(k)]
    if len(labels) != k:
        raise GdfeError(f"labels: expected {k} (one per fold angle), got {len(labels)}")
    designs = [m.apply(design, process) for m in draws]
    pilots = PILOT if how == "predicted" and n > PILOT else n

    def run(items):
        return parallel_map(_fold_one, items, n_jobs=n_jobs, desc="ensemble", progress=progress, scheduler=scheduler)

    t0 = time.perf_counter()
    out = run([(d, init, opts, measure) for d in designs[:pilots]])
    if pilots < n:
        ok_pilots = [i for i in range(pilots) if out[i]["converged"]]
        starts = secant_starts(_contractions(model.apply(design, process)), start,
                               [_contractions(designs[i]) for i in ok_pilots],
                               [align_rigidly(out[i]["points"], start) for i in ok_pilots],
                               [_contractions(d) for d in designs[pilots:]])
        out += run([(d, x, opts, measure) for d, x in zip(designs[pilots:], starts)])
    seconds = time.perf_counter() - t0
    ok = np.array([o["converged"] for o in out])
    good = [o for o in out if o["converged"]]
    for o in good:
        if len(o["angles"]) != k:
            raise GdfeError(f"the part's draws measure {len(o['angles'])} fold angles against the nominal fold's {k}: "
                            f"the draws fold it into a different shape, whose angles cannot be paired")
    pts = np.array([align_rigidly(o["points"], start) for o in good]) if good else np.zeros((0,) + start.shape)
    spread = (np.sqrt(pts.var(axis=0, ddof=1).sum(axis=1)) if len(pts) > 1
              else np.full(start.shape[0], math.nan))
    return Ensemble(n=n, level=level, labels=labels, nominal_angles=np.asarray(nominal_angles, float),
                    angles=np.array([o["angles"] for o in good], float).reshape(len(good), k),
                    nominal_measures={a: float(b) for a, b in nominal_measures.items()},
                    measures={name: np.array([o["measures"][name] for o in good]) for name in nominal_measures},
                    nominal_points=start, points=pts, spread_mm=spread, converged=ok,
                    iterations=np.array([o["iterations"] for o in out]), seconds=seconds,
                    draw_seconds=np.array([o["seconds"] for o in out]), models=[m.name for m in draws],
                    start={"predicted": f"the nominal fold for {pilots} draws, then their secant prediction",
                           "nominal": "the nominal fold", "solver": "the solver's own"}[how],
                    draw_cpu_seconds=np.array([o["cpu_seconds"] for o in out]))


def write_spread(result, ensemble, out_dir, name):
    """Rewrite the last frame of ``NAME``'s VTU series (:func:`gdfe.io.write_series`) with the point field
    ``spread_mm`` of ``ensemble`` beside ``displacement``. Returns the VTU's path."""
    from pathlib import Path

    from gdfe.io import write_vtu

    last = len(result.frames) - 1
    pts = np.asarray(result.frames[-1], float)
    path = Path(out_dir) / f"{name}_{last:03d}.vtu"
    return write_vtu(path, pts, result.design, {"displacement": pts - result.design.mesh.points,
                                                "spread_mm": np.nan_to_num(ensemble.spread_mm)})


def plot_band(ensemble, path, title=None, threshold=None):
    """The picture with the band: left, each fold angle's draws, nominal value and interval (a part without fold
    angles: its first measure's draws, with ``threshold`` ``(name, value)`` marked); right, the draws' shapes seen
    from the front (x-z), a grey band, over the nominal shape coloured by each vertex's spread. Returns the path."""
    from gdfe._plotting import pyplot

    plt = pyplot()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.5), gridspec_kw={"width_ratios": [1, 1.4]})
    k = len(ensemble.labels)
    shown = range(min(k, 24))
    rng = np.random.default_rng(0)
    for j in shown:
        lo, hi = ensemble.interval(ensemble.angles[:, j])
        ax.fill_betweenx([j - 0.35, j + 0.35], lo, hi, color="C0", alpha=0.25,
                         label=f"{100 * ensemble.level:g} % interval" if j == 0 else None)
        ax.plot(ensemble.angles[:, j], j + rng.uniform(-0.25, 0.25, len(ensemble.angles)), ".", color="C0", ms=3)
        ax.plot([ensemble.nominal_angles[j]], [j], "k|", ms=14, mew=2, label="nominal model" if j == 0 else None)
    if k:
        ax.set_yticks(list(shown), [ensemble.labels[j] for j in shown])
        ax.set_xlabel("fold angle [rad]")
    elif ensemble.measures:
        name, v = next(iter(ensemble.measures.items()))
        ax.hist(v, bins=max(5, len(v) // 3), color="C0", alpha=0.6)
        ax.axvspan(*ensemble.interval(v), color="C0", alpha=0.2, label=f"{100 * ensemble.level:g} % interval")
        ax.axvline(ensemble.nominal_measures[name], color="k", lw=2, label="nominal model")
        if threshold is not None:
            ax.axvline(threshold[1], color="r", ls="--", label=f"{threshold[0]} {threshold[1]:.3g}")
        ax.set_xlabel(name)
        ax.set_ylabel("draws")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{ensemble.n_converged} of {ensemble.n} draws")
    p = ensemble.nominal_points
    for q in ensemble.points:
        bx.scatter(q[:, 0], q[:, 2], s=1, color="0.6", alpha=min(0.3, 3.0 / max(len(ensemble.points), 1)),
                   linewidths=0)
    sc = bx.scatter(p[:, 0], p[:, 2], c=np.nan_to_num(ensemble.spread_mm), s=2, cmap="viridis")
    fig.colorbar(sc, ax=bx, label="vertex spread (sd) [mm]")
    bx.set_aspect("equal")
    bx.set_xlabel("x [mm]")
    bx.set_ylabel("z [mm]")
    bx.set_title("draws (grey) and the nominal shape, coloured by spread", fontsize=10)
    if title:
        fig.suptitle(title if len(title) <= 100 else title[:97] + "...", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
