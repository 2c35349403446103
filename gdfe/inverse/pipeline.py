"""The 1-D design pipeline of the paper (Sec. 4.2): target curve -> couples -> printable strip -> check.

1. A **target** (:class:`TargetCurve`): a planar curve given as couples ``(L_i, r_i)``
   (:func:`target_from_couples`), as a letter of Figure 9 (:func:`target_from_letter`), or as
   a sketch whose tangent graph is segmented into couples and sharp turns
   (:func:`target_from_sketch`, steps 1-5 of Sec. 4.2).
2. A **plan** (:func:`plan_strip`): the sharp turns become maximum-curvature hinges
   (:func:`gdfe.inverse.with_hinges`); optionally every couple is printed ``|alpha| h / 2``
   longer so that the strip's mid-line, which a contracting cell shortens by ``(1 - R) / 2`` of
   its length, keeps the couple's length (:func:`midline_compensated`, not in the paper); the
   couples become a pattern of contracting and rigid cells (:func:`gdfe.inverse.strip_pattern`).
3. A **check** (:func:`check_strip`): the strip simulated with GDFE from its Eq. 2 start
   (:func:`gdfe.inverse.simulate_strip`) and its mid-line compared with the target
   (:func:`gdfe.inverse.strip_deviation`).

The studies of Figures 9 and 10 and ``gdfe design`` run these steps.

All lengths in millimetres, angles in radians.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gdfe._validation import GdfeError, check_array, check_choice, check_int, check_number, check_positive
from gdfe.calibration import DEFAULT_H
from gdfe.inverse.couples import Couple, arc_points, as_couples, check_open_ratio
from gdfe.inverse.patterns import ROUNDINGS, StripPattern, strip_pattern, with_hinges
from gdfe.inverse.segmentation import SketchFit, fit_sketch
from gdfe.model import as_model

__all__ = ["TargetCurve", "target_from_couples", "target_from_letter", "target_from_sketch", "midline_compensated",
           "StripPlan", "plan_strip", "StripCheck", "check_strip", "TARGET_KINDS", "TOLERANCE_FRACTION"]

#: Kinds of :class:`TargetCurve`.
TARGET_KINDS = ("couples", "letter", "sketch")

#: A strip's check reaches its target when the mid-line's RMS deviation is within this fraction of the
#: target's length. A strip's error accumulates along it (each couple, rounded to whole pixels, turns
#: all that follows), so the fraction is larger than a film's (:data:`gdfe.inverse2d.TOLERANCE_FRACTION`):
#: the Figure 9 letters at 0.125 mm pixels fold within 1.0-1.6 % of their lengths and the Figure 10 S
#: within 0.7 %, while a sketch that doubles back tighter than the film folds misses by several per cent.
TOLERANCE_FRACTION = 0.02


@dataclasses.dataclass
class TargetCurve:
    """A planar curve to fold a strip into, and the couples that describe it.

    Attributes
    ----------
    name : str
        A short name (file stem, letter).
    kind : {"couples", "letter", "sketch"}
    couples : list of Couple
        The curve's couples (for a sketch: fitted to it).
    turns : (m,) float array [rad]
        Sharp turn of the tangent just before each couple (``turns[0]`` only rotates the curve).
    heading : float [rad]
        Direction of the tangent at the start.
    start : (2,) float array [mm]
        First point.
    curve : (k, 2) float array [mm]
        The target's points: the couples' arcs densely sampled, or the sketch itself.
    s_curve : (k,) float array [mm] or None
        Arc length of each point of ``curve`` along the couples; None for a sketch, which is
        compared by normalised arc length.
    curve_segment : (k,) int array
        Couple each point of ``curve`` belongs to.
    fit : SketchFit or None
        The segmentation of a sketch.
    """

    name: str
    kind: str
    couples: list
    turns: np.ndarray
    heading: float
    start: np.ndarray
    curve: np.ndarray
    s_curve: np.ndarray | None
    curve_segment: np.ndarray
    fit: SketchFit | None = None

    def summary(self) -> dict:
        return {"name": self.name, "kind": self.kind, "couples": [[c.L, c.r] for c in self.couples],
                "turns_rad": self.turns.tolist(), "heading_rad": self.heading, "start_mm": self.start.tolist(),
                "length_mm": float(sum(c.L for c in self.couples))}


def _segment_of(s, lengths):
    """Index of the couple each arc length ``s`` falls in (the last couple keeps its end)."""
    ends = np.concatenate([[0.0], np.cumsum(lengths)])
    return np.clip(np.searchsorted(ends, s, side="right") - 1, 0, len(lengths) - 1)


def target_from_couples(couples, heading=0.0, start=(0.0, 0.0), turns=None, name="couples", kind="couples",
                        ds=0.02):
    """A target given by its couples.

    Parameters
    ----------
    couples : sequence of Couple or (L, r)
    heading : float [rad]
        Tangent direction at the start.
    start : (2,) float [mm]
    turns : (m,) float array [rad], optional
        Sharp turns before each couple (default none).
    name : str
    kind : {"couples", "letter"}
    ds : float [mm]
        Spacing of the sampled target curve.
    """
    couples = as_couples(couples)
    check_choice("kind", kind, ("couples", "letter"))
    heading = check_number("heading", heading)
    start = check_array("start", start, shape=(2,))
    tt = np.zeros(len(couples)) if turns is None else check_array("turns", turns, shape=(len(couples),))
    curve, s = arc_points(couples, ds=ds, heading=heading, start=start, turns=turns)
    seg = _segment_of(s, [c.L for c in couples])
    return TargetCurve(name=str(name), kind=kind, couples=couples, turns=tt, heading=float(heading), start=start,
                  curve=curve, s_curve=s, curve_segment=seg)


def target_from_letter(char, ds=0.02):
    """The target of one letter of Figure 9 (:data:`gdfe.inverse.LETTERS`)."""
    from gdfe.inverse.letters import glyph

    g = glyph(char)
    return target_from_couples(g.as_couples(), heading=g.heading, start=g.start, name=char, kind="letter", ds=ds)


def target_from_sketch(points, penalty=0.1, weights=None, min_points=2, name="sketch"):
    """A sketched curve, segmented on its tangent graph into couples and sharp turns (Sec. 4.2).

    Parameters
    ----------
    points : (n, 2) float array [mm], n >= 3
        The sketch's vertices, in order.
    penalty : float
        Penalty per segment Delta (the paper's levels: 1, 0.3, 0.1).
    weights, min_points :
        See :func:`gdfe.inverse.fit_sketch`.
    """
    P = check_array("points", points, shape=(-1, 2))
    fit = fit_sketch(P, penalty, min_points=min_points, weights=weights)
    seg = np.zeros(len(P), int)
    for j, (a, b) in enumerate(zip(fit.segmentation.start, fit.segmentation.stop)):
        seg[a:b] = j
    return TargetCurve(name=str(name), kind="sketch", couples=list(fit.couples), turns=fit.turns.copy(),
                  heading=fit.heading, start=fit.start.copy(), curve=P, s_curve=None, curve_segment=seg, fit=fit)


def midline_compensated(couples, h=DEFAULT_H):
    """Couples printed ``|alpha| h / 2`` longer with the same angle, so that the mid-line has length L.

    A contracting cell shortens the film's mid-line by ``(1 - R) / 2`` of its length while the
    coated face keeps its length; the printed rule of Sec. 4.2 therefore makes every couple's
    mid-line ``|alpha| h / 2`` shorter than ``L`` (see ``studies/fig09_letters.py`` for what
    this compensation removes of the deviation).
    """
    h = check_positive("h", h)
    out = []
    for c in as_couples(couples):
        a = c.angle
        L = c.L + abs(a) * h / 2
        out.append(Couple(L, L / a if a != 0 else 0.0))
    return out


@dataclasses.dataclass
class StripPlan:
    """A target turned into a printable strip pattern.

    Attributes
    ----------
    target : TargetCurve
    printed : list of Couple
        The couples printed along the strip: the target's, with a maximum-curvature hinge
        for each sharp turn (and the mid-line compensation, if asked for).
    source : (p,) int array
        For each printed couple, the target couple it prints, or -1 for a hinge.
    pattern : StripPattern
    h, R : float
        Film thickness [mm] and contraction ratio.
    compensate : bool
        Whether the couples were printed with the mid-line compensation.
    """

    target: TargetCurve
    printed: list
    source: np.ndarray
    pattern: StripPattern
    h: float
    R: float
    compensate: bool

    def design(self, width=0.5, ny=1, nz=1, isotropy=1.0):
        """The strip as a :class:`gdfe.Design` (see :meth:`gdfe.inverse.StripPattern.design`)."""
        des = self.pattern.design(width=width, ny=ny, nz=nz, isotropy=isotropy)
        des.meta.update(target=self.target.name, target_kind=self.target.kind, compensate=self.compensate)
        return des

    def printed_ends(self):
        """Arc lengths [mm] along the printed strip where each printed couple ends, from 0."""
        pat = self.pattern
        return np.concatenate([[0.0], np.cumsum([(pat.segment == i).sum() * pat.cell
                                                 for i in range(len(self.printed))])])

    def target_ends(self):
        """Arc lengths [mm] along the target where each printed couple ends (a hinge has none)."""
        lengths = [0.0 if j < 0 else self.target.couples[j].L for j in self.source]
        return np.concatenate([[0.0], np.cumsum(lengths)])

    def summary(self) -> dict:
        pat = self.pattern
        return {"printed_couples": [[c.L, c.r] for c in self.printed], "source": self.source.tolist(),
                "hinges": int((self.source < 0).sum()), "cell_mm": pat.cell, "w_min_mm": pat.w_min,
                "rounding": pat.rounding, "strip_mm": pat.length, "blocks": pat.blocks.tolist(),
                "angle_target_rad": pat.angle.tolist(), "angle_printed_rad": pat.angle_printed.tolist(),
                "clamped": pat.clamped.tolist(), "compensate": self.compensate, "rows": pat.rows()}


def plan_strip(target, h=DEFAULT_H, R=None, cell=None, w_min=None, rounding="nearest", clamp=False,
               compensate=False, min_turn=1e-3, model=None, d=None):
    """The printable strip pattern of a target.

    Parameters
    ----------
    target : TargetCurve
    h : float [mm]
        Film thickness.
    R : float, optional
        Contraction ratio of the free face, strictly between 0 and 1 (default 0.7, the
        paper's), or:
    model : DeformationModel or path of a model file, optional
        Plan with this deformation model at passive thickness ``d``
        (:func:`gdfe.inverse.strip_pattern`): its ratio at ``d`` sizes the hinges and blocks,
        and its geometric mechanisms choose the blocks of each couple.
    d : float [mm], optional
        Passive thickness, with ``model``.
    cell, w_min, rounding, clamp :
        See :func:`gdfe.inverse.strip_pattern` (the paper's rule: ``rounding="nearest"``).
    compensate : bool
        Print every couple ``|alpha| h / 2`` longer (:func:`midline_compensated`).
    min_turn : float [rad]
        Sharp turns smaller than this are dropped (:func:`gdfe.inverse.with_hinges`).

    Returns
    -------
    StripPlan
    """
    if not isinstance(target, TargetCurve):
        raise GdfeError(f"target: expected a gdfe.inverse.TargetCurve, got {type(target).__name__}")
    h = check_positive("h", h)
    model = as_model(model)
    if model is not None:
        if R is not None:
            raise GdfeError("R, model: expected a contraction ratio R or a deformation model, not both")
        if d is None:
            raise GdfeError("d: expected the passive thickness [mm] the model gives R from")
        R_plan = float(model.ratio(check_positive("d", d), h))
    else:
        R_plan = 0.7 if R is None else R
    R_plan = check_open_ratio(R_plan)
    check_choice("rounding", rounding, ROUNDINGS)
    printed = with_hinges(target.couples, target.turns, h=h, R=R_plan, min_turn=min_turn)
    source, j = [], 0
    for c in printed:  # with_hinges keeps the target's couples and inserts new ones for the turns
        if j < len(target.couples) and c is target.couples[j]:
            source.append(j)
            j += 1
        else:
            source.append(-1)
    if compensate:
        printed = midline_compensated(printed, h)
    if model is not None:
        pattern = strip_pattern(printed, h=h, cell=cell, w_min=w_min, rounding=rounding, clamp=clamp,
                                model=model, d=d)
    else:
        pattern = strip_pattern(printed, h=h, R=R_plan, cell=cell, w_min=w_min, rounding=rounding, clamp=clamp)
    return StripPlan(target=target, printed=printed, source=np.array(source, int), pattern=pattern, h=h, R=R_plan,
                     compensate=bool(compensate))


@dataclasses.dataclass
class StripCheck:
    """A plan's strip, simulated and measured against the target.

    Attributes
    ----------
    plan : StripPlan
    design : Design
        The simulated strip.
    result : gdfe.Result
        Check ``result.converged`` before reading ``deviation``.
    deviation : gdfe.inverse.Deviation or None
        The mid-line against the target; None when the solver did not converge.
    """

    plan: StripPlan
    design: object
    result: object
    deviation: object

    @property
    def converged(self) -> bool:
        return bool(self.result.converged)

    def default_tolerance(self) -> float:
        """:data:`TOLERANCE_FRACTION` of the target's length [mm]."""
        return TOLERANCE_FRACTION * float(sum(c.L for c in self.plan.target.couples))

    def reached(self, tolerance_mm) -> bool:
        """Whether the check converged with its mid-line's RMS deviation within ``tolerance_mm``."""
        tolerance_mm = check_positive("tolerance_mm", tolerance_mm)
        return self.deviation is not None and bool(self.deviation.rms <= tolerance_mm)


def check_strip(plan, design=None, width=0.5, ny=1, nz=1, tol=1e-7, max_iter=400):
    """Simulate a plan's strip and measure its mid-line against the target.

    Parameters
    ----------
    plan : StripPlan
    design : Design, optional
        The strip to simulate (e.g. read back from its printer masks); default
        ``plan.design(width, ny, nz)``. Its columns along x must be the pattern's.
    width : float [mm]
        Strip width, for the default design.
    ny, nz : int
        Cells across the strip and through the film, for the default design.
    tol, max_iter :
        Solver options (:func:`gdfe.inverse.simulate_strip`).

    Returns
    -------
    StripCheck
        ``deviation`` is None when the solver did not converge: a shape that is not an
        equilibrium is not measured.
    """
    from gdfe.inverse.deviation import strip_deviation
    from gdfe.inverse.strips import simulate_strip

    if not isinstance(plan, StripPlan):
        raise GdfeError(f"plan: expected a gdfe.inverse.StripPlan, got {type(plan).__name__}")
    if design is None:
        design = plan.design(width=width, ny=check_int("ny", ny), nz=check_int("nz", nz))
    ncol = int(design.mesh.cell_ij[:, 0].max()) + 1
    if ncol != plan.pattern.material.size or not math.isclose(float(design.mesh.spacing[0]), plan.pattern.cell):
        raise GdfeError(f"design: expected a strip of {plan.pattern.material.size} columns of "
                        f"{plan.pattern.cell:g} mm along x, got {ncol} of {float(design.mesh.spacing[0]):g} mm")
    res = simulate_strip(design, tol=tol, max_iter=max_iter)
    dev = strip_deviation(plan, res) if res.converged else None
    return StripCheck(plan=plan, design=design, result=res, deviation=dev)
