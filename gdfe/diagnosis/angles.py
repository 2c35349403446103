"""Diagnosis of fold-angle data: is there a gap to the calibrated GDFE hinge, and what explains it?

:func:`diagnose` takes folding tests (a table like the paper's Table 1, with any further
columns) and

1. reads its **columns**: ``sigma_rad`` (the noise of each test), numeric columns (a monotone
   dependence on one is ``partial_activation`` when its role is declared a process, else a
   factor, ``factor[COLUMN]``; :mod:`gdfe.diagnosis.columns`) and text columns with repeated
   labels (groups, for leave-one-group-out, a per-group contraction, ``batch`` for a declared
   group role, else ``factor[COLUMN]``, and the residual structure by group); a column
   confounded with the design is said (:mod:`gdfe.diagnosis.confounding`); fold angles are
   magnitudes, and a negative one beyond the noise is an error unless they are declared signed;
2. finds the **noise** (:mod:`gdfe.diagnosis.verdict`): given, a ``sigma_rad`` column,
   replicate rows, or unknown;
3. fits the **baseline**, by default the paper's deformation principle refitted to the data:
   the GDFE hinge with the contraction ratio of Eq. 3, whose converged fold is Eq. 2's
   ``(1 - R) L / h``, i.e. Eq. 1, ``alpha = K sqrt(h / d**3) L``, with ``K`` by least
   squares (the closed form is checked against GDFE solves of the same tests); or another
   form of the law (:mod:`gdfe.diagnosis.baselines`); every form is fitted, and the report
   says how much of the gap lies in the form and how much beyond it;
4. fits every **effect** of the catalogue (:mod:`gdfe.diagnosis.effects`) and every pair, and
   measures each on tests the fit did not see: leave-one-out (k-fold for many tests), and
   leave-one-group-out when the tests carry a group column, which then ranks them; a model
   whose parameters the data cannot identify, or whose predictions equal a simpler model's,
   is never chosen (:mod:`gdfe.diagnosis.fit`);
5. names the **best**, climbing from the baseline one effect at a time while the held-out
   error drops significantly (:func:`gdfe.diagnosis.fit.select`), then tries a ``batch``
   effect on each group column on top of it (judged on leave-one-out: a group's own
   contraction cannot be predicted for a group left out) and drops any effect the batch
   makes unnecessary;
6. with a known **noise**: the baseline within it is the best (there is nothing to
   explain); a chosen model (the baseline included) that the lack-of-fit test rejects gives
   way to one within the noise that the held-out errors do not rule out
   (:func:`within_noise_step`);
7. **names** every model the data cannot tell from the best, and the test that would tell
   them apart (:mod:`gdfe.diagnosis.separate`): at Table 1's single film thickness, for
   one, several effects soften the dependence on ``d`` alike;
8. says **where** the residuals of the baseline and of the best lie, and whether any
   structure is left (:mod:`gdfe.diagnosis.where`);
9. gives the **verdict** (``no_gap``, ``explained``, ``partly_explained``,
   ``not_explained``; :func:`gdfe.diagnosis.verdict.decide`), naming all the
   indistinguishable models; ``structure_remains`` in place of ``no_gap`` where the
   residuals show a strong trend the family-wise test cannot confirm
   (:func:`gdfe.diagnosis.where.strong_trends`); a factor is said to be no physical cause,
   and a confounded column to be confounded.

The cost grows linearly with the tests (k-fold cross-validation above
:data:`gdfe.diagnosis.fit.LOO_EXACT` tests, multi-start iterations on a subset above
:data:`gdfe.diagnosis.fit.START_ROWS`); measured timings are in the blind-diagnosis study's
output. Angles in radians, lengths in mm.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from gdfe._validation import GdfeError, GdfeTypeError, check_choice, data_float, is_finite_number
from gdfe.calibration import FoldingTests, load_folding_tests
from gdfe.diagnosis.attribution import attribute
from gdfe.diagnosis.artefacts import screen as screen_artefacts
from gdfe.diagnosis.artefacts import with_relative_noise
from gdfe.diagnosis.baselines import BASELINES, DESCRIPTIONS, baseline_model, form_shares
from gdfe.diagnosis.columns import ROLES, ColumnRoles, check_roles, rename
from gdfe.diagnosis.confounding import confounded
from gdfe.diagnosis.effects import EFFECTS, Model, catalogue
from gdfe.diagnosis.fit import STEP_SE, EffectFit, compare, evaluate, mark_equal, select
from gdfe.diagnosis.separate import indistinguishable, prefer_plausible, separating_test
from gdfe.diagnosis.verdict import LEVEL, MEANINGFUL, Noise, Verdict, decide, gap, lack_of_fit, noise_of
from gdfe.diagnosis.where import TREND_LEVEL, TREND_RHO, group_analysis, residual_analysis, strong_trends, structure

__all__ = ["Diagnosis", "Columns", "diagnose", "within_noise_step", "numeric_columns", "read_columns",
           "SIGMA_COLUMN", "CHECK_TESTS"]

log = logging.getLogger(__name__)

BASELINE_MODEL = "gdfe_hinge_eq3"
#: The column of per-test noise [rad].
SIGMA_COLUMN = "sigma_rad"
#: Most tests simulated by the GDFE check of the closed forms (evenly spread in predicted angle).
CHECK_TESTS = 24


@dataclasses.dataclass
class Columns:
    """What the diagnosis makes of a table's extra columns.

    Attributes
    ----------
    process : dict of str -> (n,) float array
        Numeric columns that vary: the process columns of ``partial_activation``.
    groups : dict of str -> (n,) str array
        Text columns whose labels repeat (at least two groups, at most half as many groups as
        tests): the group columns (``batch`` effect, residual structure by group).
    logo : str or None
        The group column held out group by group.
    sigma : (n,) float array or None [rad]
        The ``sigma_rad`` column.
    ignored : dict of str -> str
        Columns left out, and why.
    roles : ColumnRoles
        The declared roles (:mod:`gdfe.diagnosis.columns`): a numeric column is a process
        column of ``partial_activation`` only when declared a process role, else its effect is
        a factor; a group column's ``batch`` is a group factor unless declared a group role.
    """

    process: dict
    groups: dict
    logo: str | None
    sigma: np.ndarray | None
    ignored: dict
    roles: ColumnRoles = dataclasses.field(default_factory=ColumnRoles)

    def as_dict(self):
        return {"process": list(self.process), "groups": {k: sorted(set(v.tolist())) for k, v in self.groups.items()},
                "leave_one_group_out": self.logo, "sigma_column": self.sigma is not None,
                "ignored": self.ignored,
                "roles": {k: {"role": self.roles.roles.get(k), "kind": self.roles.kind(k) or "undeclared",
                              "effect": self.roles.words(k, numeric=k in self.process)}
                          for k in [*self.process, *self.groups]}}


def _as_float(values):
    try:
        x = np.array([data_float(s) for s in values])
    except (TypeError, ValueError):
        return None
    return x if np.all(np.isfinite(x)) else None


def numeric_columns(tests):
    """Extra columns of ``tests`` whose every value is a finite number, as float arrays."""
    out = {}
    for k, v in tests.extra.items():
        x = _as_float(v)
        if x is not None:
            out[k] = x
    return out


def _angle_again(x, alpha):
    """The factor ``c`` where the column ``x`` is ``c`` times the measured angles (to 1e-3 of its largest value,
    the rounding of an angle written in degrees), else None."""
    alpha = np.asarray(alpha, float)
    aa = float(alpha @ alpha)
    if aa == 0.0 or np.ptp(alpha) == 0.0:
        return None
    c = float(x @ alpha) / aa
    scale = float(np.max(np.abs(x)))
    return c if c != 0.0 and np.max(np.abs(x - c * alpha)) <= 1e-3 * scale else None


def _not_finite_rows(values):
    """Rows (CSV numbering) of a column whose values all read as numbers or are empty, where a
    value is empty or not finite; None when the column holds text."""
    bad = []
    for i, v in enumerate(values):
        v = str(v).strip()
        if not v:
            bad.append(i)
            continue
        try:
            x = data_float(v)
        except ValueError:
            return None
        if not math.isfinite(x):
            bad.append(i)
    return bad


def read_columns(tests, group=None, process=None, roles=None):
    """Sort the extra columns of ``tests`` into noise, process and group columns.

    A column of numbers with an empty, ``nan`` or infinite value in some row is an error
    naming those rows (it is neither a numeric column nor labels), unless it is the group
    column or declared a group role: then its values are labels.

    Parameters
    ----------
    tests : FoldingTests
    group : str, optional
        The column to hold out group by group (its values are labels even when numeric).
        Default: ``group`` when there is such a column, else the first group column.
    process : sequence of str, optional
        The numeric columns ``partial_activation`` may use (default: every numeric column
        that varies; ``()`` for none).
    roles : dict of str -> str, optional
        Declared roles of columns (:data:`gdfe.diagnosis.columns.ROLES`).

    Returns
    -------
    Columns
    """
    n = len(tests)
    extra = tests.extra
    known = ColumnRoles(check_roles(roles, list(extra)))
    if group is not None:
        if not isinstance(group, str):
            raise GdfeTypeError(f"group: expected a column name, got {group!r}")
        if group not in extra:
            raise GdfeError(f"group: no column {group!r} in the tests; columns besides L_mm, d_mm, "
                            f"h_mm, alpha_rad: {', '.join(extra) or 'none'}")
    sigma = None
    if SIGMA_COLUMN in extra:
        sigma = _as_float(extra[SIGMA_COLUMN])
        bad = [i for i, s in enumerate(extra[SIGMA_COLUMN])
               if sigma is None or not sigma[i] > 0]
        if bad:
            i = bad[0]
            raise GdfeError(f"row {i + 2}, column {SIGMA_COLUMN}: expected a positive noise in rad, "
                            f"got {str(extra[SIGMA_COLUMN][i])!r}")
    numeric, groups, ignored = {}, {}, {}
    for k, v in extra.items():
        if k == SIGMA_COLUMN:
            continue
        labelled = k == group or known.is_group(k)
        x = _as_float(v)
        bad = None if x is not None or labelled else _not_finite_rows(v)
        if bad and len(bad) < len(v):
            rows = ", ".join(str(i + 2) for i in bad[:8]) + (", ..." if len(bad) > 8 else "")
            raise GdfeError(f"column {k}: expected a finite number in every row of a numeric column, got "
                            f"{str(v[bad[0]])!r} in row{'s' if len(bad) > 1 else ''} {rows}; fill or drop "
                            f"{'those rows' if len(bad) > 1 else 'that row'}, or declare {k} a group column "
                            f"(--group {k}, or a group role, --role {k}=batch) to read its values as labels")
        if x is None and known.is_process(k):
            raise GdfeError(f"roles: column {k!r} is declared {known.roles[k]}, a process role, so it must be "
                            f"numeric; got {str(v[0])!r} in row 2")
        if x is not None and not labelled:
            again = _angle_again(x, tests.alpha)
            if again is not None:  # the measured angle in other units: it would "explain" every residual
                ignored[k] = f"the measured angle again ({again:.4g} x alpha_rad), not a cause"
            elif np.ptp(x) > 0:
                numeric[k] = x
            else:
                ignored[k] = "numeric, but the same in every test"
            continue
        labels = np.asarray(v).astype(str)
        m = np.unique(labels).size
        if labelled and m < 2:
            log.info("group column %r has a single value: no leave-one-group-out", k)
            ignored[k] = "a single group"
        elif labelled or 2 <= m <= n // 2:
            groups[k] = labels
        else:
            ignored[k] = ("a single group" if m < 2 else
                          f"text with {m} different values in {n} tests: not groups")
    if process is None:
        proc = numeric
    else:
        if isinstance(process, str):
            process = [process]
        proc = {}
        for k in process:
            if k not in numeric:
                raise GdfeError(f"process: expected a numeric column that varies ({', '.join(numeric) or 'none'}), "
                                f"got {k!r}")
            proc[k] = numeric[k]
        for k in numeric:
            if k not in proc:
                ignored[k] = "numeric, not among the process columns asked for"
    logo = group if group in groups else ("group" if "group" in groups else next(iter(groups), None))
    return Columns(process=proc, groups=groups, logo=logo, sigma=sigma, ignored=ignored, roles=known)


@dataclasses.dataclass
class Diagnosis:
    """Result of :func:`diagnose`.

    Attributes
    ----------
    tests : FoldingTests
    groups : (n,) array or None
        Group label of each test in the leave-one-group-out column.
    held_out : str
        ``"loo"`` or ``"logo"``: the held-out error the group-free models are ranked by.
    baseline : EffectFit
    fits : list of EffectFit
        Every effect model fitted (single effects, pairs, batch steps), best held-out error first.
    best : EffectFit
        The chosen model (the baseline when no effect earns its parameters, or when the
        baseline is within a known noise; with a known noise, a model within it in place of
        a held-out choice the lack-of-fit test rejects, :func:`within_noise_step`). Its
        ``model.effects``, ``model.param_names``, ``params``, ``se`` and ``ci95`` (or
        ``param_dict()``, ``se_dict()``, ``ci_dict()``, ``parameters()``) say what was found; :data:`gdfe.diagnosis.EFFECTS` says what each
        parameter means.
    selected : EffectFit
        The model the held-out errors alone choose (``best`` unless the baseline is within
        the noise, or the lack-of-fit test rejected it for a model within the noise).
    named : list of EffectFit
        The models the data cannot tell from ``best`` (``best`` among them; fewest effects
        first), :func:`gdfe.diagnosis.separate.indistinguishable`; one model when the
        choice is clear.
    separation : dict or None
        Where the models of ``named`` would disagree most
        (:func:`gdfe.diagnosis.separate.separating_test`); None for one model.
    candidates : list of str
        Models within one standard error of the chosen model's held-out error, or below it.
    where, where_best : list of dict
        Residual analysis of the baseline and of the best model (numeric inputs, then groups).
    regime, regime_best : str
        Where the error concentrates, in words.
    inputs : dict of str -> (n,) float array
        The numeric inputs the residuals were analysed against.
    columns : Columns
    noise : Noise
    verdict : Verdict
    lack_of_fit : dict
        :func:`gdfe.diagnosis.verdict.lack_of_fit` of ``baseline`` and ``best``.
    structure, structure_best : list of dict
        Structure in the residuals of the baseline and of the best
        (:func:`gdfe.diagnosis.where.structure`).
    excluded : list of dict
        Models never chosen, and why (parameters not identifiable, equal to a simpler model).
    warnings : list of str
    check : dict or None
        Closed form against GDFE solves (:func:`gdfe.diagnosis.forward.gdfe_check`) for
        the baseline and the best model.
    baseline_name : str
        The baseline the gap is measured against (:data:`gdfe.diagnosis.baselines.BASELINES`).
    baseline_form : dict or None
        How much of the gap to Eq. 1 lies in the form of the law and how much beyond it
        (:func:`gdfe.diagnosis.baselines.form_shares`).
    confounded : list of dict
        Extra columns confounded with the design variables
        (:func:`gdfe.diagnosis.confounding.confounded`).
    trends : list of dict
        Strong residual trends of the baseline that the family-wise structure test does not
        confirm (:func:`gdfe.diagnosis.where.strong_trends`).
    signed : bool
        Whether the angles were read as signed and taken as magnitudes.
    renames : dict of str -> str
        Fitted name -> reported name of effects on columns that are factors
        (``partial_activation[C]`` -> ``factor[C]``, ``batch[C]`` -> ``factor[C]``);
        the fits keep their fitted names, the text and the JSON report the others.
    """

    tests: FoldingTests
    groups: np.ndarray | None
    held_out: str
    baseline: EffectFit
    fits: list
    best: EffectFit
    candidates: list
    where: list
    regime: str
    where_best: list
    regime_best: str
    inputs: dict
    columns: Columns = None
    noise: Noise = None
    verdict: Verdict = None
    selected: EffectFit = None
    lack_of_fit: dict = None
    structure: list = dataclasses.field(default_factory=list)
    structure_best: list = dataclasses.field(default_factory=list)
    excluded: list = dataclasses.field(default_factory=list)
    warnings: list = dataclasses.field(default_factory=list)
    check: dict | None = None
    named: list = dataclasses.field(default_factory=list)
    separation: dict | None = None
    artefacts: object = None  # gdfe.diagnosis.artefacts.Artefacts
    baseline_name: str = "eq1"
    baseline_form: dict | None = None
    confounded: list = dataclasses.field(default_factory=list)
    trends: list = dataclasses.field(default_factory=list)
    signed: bool = False
    renames: dict = dataclasses.field(default_factory=dict)

    def display(self, fit):
        """The reported name of a fit (or fitted name): a factor's effect as ``factor[C]``."""
        return rename(fit if isinstance(fit, str) else fit.name, self.renames)

    def effect_kinds(self, fit):
        """The kind of each effect of ``fit`` (:meth:`gdfe.diagnosis.columns.ColumnRoles.effect_kinds`)."""
        return self.columns.roles.effect_kinds(fit.model)

    def term_kinds(self, fit):
        """``[(term, kind)]`` of ``fit``: each term of its reported name (``"cure_depth"``,
        ``"factor[T_C]"``) with its kind (:meth:`effect_kinds`)."""
        return list(zip(self.display(fit).split("+"), self.effect_kinds(fit))) if fit.model.effects else []

    def attribution(self):
        """The cause the diagnosis credits, or the alternatives it leaves open
        (:func:`gdfe.diagnosis.attribution.attribute`)."""
        why = []
        if self.best.model.effects and not getattr(self.best, "plausible", True):
            why.append("it fits only with implausible parameters")
        if self.best.model.effects and (self.lack_of_fit or {}).get("best", {}).get("within") is False:
            why.append("what it leaves is above the noise")
        if self.structure_best:
            why.append("structure remains after it")
        named = self.named or [self.best]
        return attribute(self.verdict.verdict, self.display(self.best), [self.display(f) for f in named],
                         {self.display(f): self.term_kinds(f) for f in [self.best, *named]},
                         why_open=" and ".join(why) or None)

    def credit(self, fit):
        """What each column effect of ``fit`` says, and whether its column is confounded."""
        out = []
        conf = {c["column"]: c for c in self.confounded}
        for col, numeric in ((fit.model.process, True), (fit.model.group, False)):
            if not col:
                continue
            words = self.columns.roles.words(col, numeric=numeric)
            if col in conf:
                names = ", ".join(w.split("_")[0] for w in conf[col]["with"])
                words += (f"; confounded with {names}: its effect cannot be told from a dependence on {names} "
                          f"the catalogue lacks")
            out.append({"column": col, "text": words, "confounded": col in conf})
        return out

    def _kind(self, fit, kind=None):
        kind = kind or self.held_out
        return "loo" if fit.held_out_rmse(kind) is None else kind

    def held_out_rmse(self, fit, kind=None):
        """Held-out RMSE [rad] of ``fit`` (LOO for a batch effect, which has no LOGO)."""
        return fit.held_out_rmse(self._kind(fit, kind))

    def shrink(self, fit, kind=None):
        """Fraction of the baseline's held-out RMSE that ``fit`` removes."""
        kind = self._kind(fit, kind)
        b = self.baseline.held_out_rmse(kind)
        return float(1.0 - fit.held_out_rmse(kind) / b) if b else 0.0

    def as_dict(self) -> dict:
        """The JSON layout of ``gdfe diagnose --json``: the verdict and the noise first."""
        ranked_by = "leave-one-group-out" if self.held_out == "logo" else self.baseline.cv
        out = {
            "verdict": self.verdict.verdict,
            "verdict_text": self.verdict.text,
            "noise": self.noise.as_dict(),
            "angles": ("signed: taken as magnitudes |alpha|" if self.signed else
                       "magnitudes, positive towards the uncoated face"),
            "confounded": self.confounded,
            "baseline_form": self.baseline_form,
            "n_tests": len(self.tests),
            "held_out": ranked_by,
            "columns": self._columns_entry(),
            "baseline": self._baseline_entry(),
            "lack_of_fit": self.lack_of_fit,
            "gap_removed": self.verdict.removed,
            "structure": {"baseline": self.structure, "best": self.structure_best, "strong_trends": self.trends},
            "where": self.where,
            "regime": self.regime,
            "residuals": self._residual_rows(),
            "effects": self._effect_entries(),
            "best": self.best.name,
            "named": [f.name for f in self.named] or [self.best.name],
            "attribution": self.attribution().as_dict(),
            "separation": self.separation,
            "selected": self.selected.name,
            "best_detail": {**self._fit_entry(self.best), "where": self.where_best, "regime": self.regime_best},
            "selection": _selection_rule(ranked_by),
            "verdict_rules": {"level": LEVEL, "meaningful": MEANINGFUL},
            "candidates": self.candidates,
            "excluded": self.excluded,
            "warnings": self.warnings,
            "catalogue": {e.name: e.as_dict() for e in EFFECTS.values()},
            "artefacts": None if self.artefacts is None else self.artefacts.as_dict(),
        }
        if self.check is not None:
            out["gdfe_check"] = self.check
        return self._reported(out)

    def _columns_entry(self):
        """The JSON of the columns, with every role a column could be declared."""
        return {**self.columns.as_dict(),
                "available_roles": {r: {"kind": k, "what": w} for r, (k, w) in ROLES.items()}}

    def _baseline_entry(self):
        """The JSON of the baseline: its form, parameters and errors."""
        b = self.baseline
        base = {"model": BASELINE_MODEL if self.baseline_name == "eq1" else b.name, "form": self.baseline_name,
                "description": DESCRIPTIONS[self.baseline_name],
                "params": b.param_dict(), "se": {k: _num(v) for k, v in b.se_dict().items()},
                "rmse": b.rmse, "loo_rmse": b.loo_rmse, "cv": b.cv, "aic": b.aicc,
                "r2": _r2(self.tests.alpha, b.predicted)}
        if self.held_out == "logo":
            base["logo_rmse"] = b.logo_rmse
        return base

    def _residual_rows(self):
        """One JSON row per test: its inputs and columns, what the baseline and the best predict, and
        their residuals, fitted and held out."""
        t, b, best = self.tests, self.baseline, self.best
        rows = []
        for i in range(len(t)):
            row = {"row": i + 2, "L_mm": float(t.L[i]), "d_mm": float(t.d[i]), "h_mm": float(t.h[i]),
                   "measured": float(t.alpha[i]), "predicted": float(b.predicted[i]),
                   "residual": float(b.residuals[i]), "loo_residual": float(t.alpha[i] - b.loo_predicted[i]),
                   "best_predicted": float(best.predicted[i]),
                   "best_residual": float(best.residuals[i]),
                   "best_loo_residual": float(t.alpha[i] - best.loo_predicted[i])}
            if self.groups is not None:
                row["group"] = str(self.groups[i])
            for k, v in t.extra.items():
                row.setdefault(k, str(v[i]))
            rows.append(row)
        return rows

    def _effect_entries(self):
        """The JSON of every fitted model with its rank by held-out error, the chosen model first."""
        effects = [{**self._fit_entry(f), "rank": rank} for rank, f in enumerate(self.fits, start=1)]
        # the chosen model first, the others by held-out error
        effects.sort(key=lambda e: (e["name"] != self.best.name, e["rank"]))
        return effects

    def _fit_entry(self, f):
        """The JSON of one fitted model: its parameters, errors and identifiability, and its columns."""
        e = {"name": f.name, "effects": list(f.model.effects), "effect_kinds": self.effect_kinds(f),
             "params": f.param_dict(),
             "se": {k: _num(v) for k, v in f.se_dict().items()},
             "ci95": {k: [_num(a), _num(b)] for k, (a, b) in f.ci_dict().items()},
             "parameters": f.parameters(),
             "n_params": f.model.n_params, "rmse": f.rmse, "loo_rmse": f.loo_rmse, "cv": f.cv,
             "shrink": self.shrink(f, "loo"), "aic": f.aicc, "at_bound": f.at_bound,
             "identifiable": f.identifiable, "unidentified": f.unidentified,
             "condition": _num(f.condition), "equals": f.equals, "converged": f.success,
             "plausible": getattr(f, "plausible", True), "implausible": getattr(f, "implausible", [])}
        if f.model.process:
            e["process_column"] = f.model.process
        if f.model.group:
            e["group_column"] = f.model.group
            e["group_labels"] = list(f.model.labels)
        if f.model.process or f.model.group:
            e["credit"] = self.credit(f)
        if self.held_out == "logo":
            e.update(logo_rmse=f.logo_rmse,
                     shrink_logo=self.shrink(f, "logo") if f.logo_rmse is not None else None)
        return e

    def _reported(self, out):
        """``out`` with the reported names of the fits (``factor[C]``), each model's entry saying the
        name it was fitted as (e.g. for ``--effect``)."""
        out = _renamed(out, self.renames)
        names = {rename(f.name, self.renames): f.name for f in [self.baseline] + list(self.fits)}
        for e in out["effects"] + [out["best_detail"]]:
            e["fitted_as"] = names.get(e["name"], e["name"])
        return out

    def text(self) -> str:
        """A human-readable summary, the verdict first."""
        b = self.baseline
        ho = "LOGO" if self.held_out == "logo" else ("LOO" if b.cv == "leave-one-out" else "CV")
        lines = [f"verdict: {self.verdict.verdict} -- {self.verdict.text}",
                 f"noise: {self.noise.text()}",
                 f"{len(self.tests)} folding tests; held-out error: {ho} RMSE"
                 + (f" by {self.columns.logo}" if self.held_out == "logo" else "")
                 + ("" if b.cv == "leave-one-out" else f"; LOO column: {b.cv} cross-validation"),
                 (f"baseline (Eq. 1-3 refitted): " if self.baseline_name == "eq1" else
                  f"baseline ({self.baseline_name}: {DESCRIPTIONS[self.baseline_name]}): ")
                 + ", ".join(f"{k} = {v:.4g} +- {e:.2g}" for (k, v), e in zip(b.param_dict().items(), b.se))
                 + f", RMSE {b.rmse:.3f} rad, "
                 f"{ho} {self.held_out_rmse(b):.3f} rad, R^2 {_r2(self.tests.alpha, b.predicted):.3f}"]
        if self.signed:
            lines.append("angles: signed in the data, taken as magnitudes |alpha| (--signed)")
        if self.baseline_form is not None:
            lines.append("baseline form: " + self.baseline_form["text"])
        roles = self.columns.roles
        if self.columns.process or self.columns.groups:
            lines.append("columns: " + "; ".join(
                [f"{k} ({roles.roles[k]})" if k in roles.roles else f"{k} (undeclared: a factor)"
                 for k in self.columns.process]
                + [f"{k} ({roles.roles[k]})" if k in roles.roles else f"{k} (undeclared: a group factor)"
                   for k in self.columns.groups]))
        for c in self.confounded:
            lines.append(f"confounded: {c['what it means']} ({c['measure']} {c['value']:.2f} >= {c['threshold']:g})")
        if self.check is not None and self.check.get("baseline"):
            c = self.check["baseline"]
            lines.append(f"  closed form vs GDFE solves ({c['cells']} cells/hinge, {c['n_tests']} tests): "
                         f"max |diff| {c['max_abs_diff']:.4f} rad")
        lines.append("where: " + self.regime)
        lines.append(f"{'model':44s} {'k':>2s} {'RMSE':>7s} {'LOO':>7s}"
                     + (f" {'LOGO':>7s}" if self.held_out == "logo" else "") + f" {'shrink':>7s} {'AICc':>8s}")
        for f in [b] + self.fits:
            flag = ("  <- best" if f is self.best else "  (not identifiable)" if not f.identifiable
                    else f"  (= {f.equals})" if f.equals else "")
            logo = f.logo_rmse
            lines.append(f"{self.display(f):44s} {f.model.n_params:2d} {f.rmse:7.3f} {f.loo_rmse:7.3f}"
                         + ((f" {logo:7.3f}" if logo is not None else f" {'-':>7s}")
                            if self.held_out == "logo" else "")
                         + f" {100 * self.shrink(f):6.1f}% {f.aicc:8.2f}" + flag)
        bp = ", ".join(f"{p['name']} = {p['value']:.4g}" + (f" +- {p['se']:.2g}" if p["se"] is not None else "")
                       + (" (at bound)" if p["at_bound"] else "") for p in self.best.parameters())
        lines.append(f"best: {self.best.name} ({bp}); {ho} RMSE {self.held_out_rmse(b):.3f} -> "
                     f"{self.held_out_rmse(self.best):.3f} rad ({100 * self.shrink(self.best):.0f} % less)")
        if self.selected is not self.best and not self.best.model.effects:
            lines.append(f"  (held-out errors alone would name {self.selected.name}; the baseline is within the "
                         f"noise, so it is not needed)")
        elif self.selected is not self.best:
            lines.append(f"  (held-out errors alone would name {self.selected.name}, which the lack-of-fit test "
                         f"rejects; {self.best.name} is within the noise)")
        if len(self.named) > 1:
            lines.append("the data cannot tell apart: " + ", ".join(
                f.name + ("" if getattr(f, "plausible", True) else " (implausible parameters)") for f in self.named))
            if self.separation is not None:
                lines.append("  " + self.separation["text"])
        for c in self.credit(self.best):
            lines.append(f"  {c['text']}")
        lines.append("after the best model: " + self.regime_best)
        lines += [f"measurement: {w}" for w in ([] if self.artefacts is None else self.artefacts.sentences())]
        lines += [f"warning: {w}" for w in self.warnings]
        return rename("\n".join(lines), self.renames)


def _selection_rule(ranked_by):
    """How the effects are ordered and the best and the named models chosen, in words, with
    ``ranked_by`` the held-out error that ranks them."""
    return ("effects: the best first, then the others by rank, the order of their "
            + ranked_by
            + " RMSE; best: climbing from the baseline, the best single effect is named if "
            f"its held-out mean squared error is lower by more than {STEP_SE[0]:g} standard "
            "error(s) of the paired per-test difference, the best pair if lower than that "
            f"by more than {STEP_SE[1]:g}; models whose parameters the data cannot identify or "
            "whose predictions equal a simpler model's are never chosen; a batch effect is then "
            "tried on the chosen model on leave-one-out error; with a known noise and the "
            "baseline within it, the best is the baseline; with a known noise and the chosen "
            "model rejected by the lack-of-fit test, a model within the noise takes its place "
            f"(no more effects and not beaten by {STEP_SE[0]:g} standard error(s), or more effects "
            f"and better by {STEP_SE[0]:g}); named: the models the best does not beat by "
            f"{STEP_SE[0]:g} standard error(s) with no more effects (and within the noise when "
            "the best is), fewest effects first")


def _num(v):
    return float(v) if v is not None and math.isfinite(v) else None


def _renamed(obj, renames):
    """``obj`` (JSON-like) with every fitted name of ``renames`` in its strings and keys replaced."""
    if not renames:
        return obj
    if isinstance(obj, str):
        return rename(obj, renames)
    if isinstance(obj, dict):
        return {_renamed(k, renames): _renamed(v, renames) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_renamed(v, renames) for v in obj]
    return obj


def _r2(y, p):
    y, p = np.asarray(y, float), np.asarray(p, float)
    ss = float(((y - y.mean()) ** 2).sum())
    return float(1.0 - ((y - p) ** 2).sum() / ss) if ss > 0 else float("nan")


def _check_subset(pred, n=CHECK_TESTS):
    """Indices of at most ``n`` tests evenly spread over the predicted angles."""
    order = np.argsort(pred, kind="stable")
    if order.size <= n:
        return np.sort(order)
    return np.sort(order[np.unique(np.linspace(0, order.size - 1, n).round().astype(int))])


def diagnose(tests, *, group=None, sigma=None, process=None, pairs=True, check=None, models=None, roles=None,
             baseline="eq1", signed=False, screen=True, relative_sigma=None):
    """Diagnose the gap between folding tests and the calibrated GDFE hinge.

    Parameters
    ----------
    tests : FoldingTests or str or Path
        The tests, or the path of a CSV with columns ``L_mm, d_mm, h_mm, alpha_rad`` (and
        any others; bad rows are reported by row number and column).
    group : str, optional
        Column holding a group label (batch, print job, ...) held out group by group, which
        then ranks the group-free models. Default: the column ``group``, else the first text
        column whose labels repeat.
    sigma : float, optional
        The noise of the measured angles [rad] (standard deviation); overrides a ``sigma_rad``
        column and replicate rows.
    process : sequence of str, optional
        The numeric columns ``partial_activation`` may use (default every numeric column that
        varies; ``()`` for none).
    pairs : bool
        Also fit every pair of effects.
    check : {"coarse", "default", "fine"}, optional
        Simulate (at most :data:`CHECK_TESTS` of) the tests with GDFE at this resolution and
        compare with the closed forms of the baseline and the best model.
    models : list of Model, optional
        Models to compare instead of the catalogue (the baseline is always fitted).
    screen : bool
        Look for measurement artefacts (failed specimens, gross outliers, noise growing with
        the angle; :func:`gdfe.diagnosis.artefacts.screen`), repeating the diagnosis without
        flagged rows and, when the noise grows with the angle, weighted by the noise each test's
        angle implies (:func:`gdfe.diagnosis.artefacts.relative_noise`).
    relative_sigma : (n,) float array, optional
        Each test's noise relative to the RMS noise (mean square 1): weights
        ``1 / relative_sigma^2`` (set by the screen).
    roles : dict of str -> str, optional
        What extra columns are (:data:`gdfe.diagnosis.columns.ROLES`), e.g.
        ``{"T_C": "oven_temperature"}``. A monotone dependence on a numeric column is
        ``partial_activation[COLUMN]`` only for a process role, else ``factor[COLUMN]``; a
        group column's own contraction is ``batch[COLUMN]`` only for a group role, else
        ``factor[COLUMN]`` too (:mod:`gdfe.diagnosis.columns`).
    baseline : {"eq1", "eq1-d1", "power", "timoshenko"}
        The form of the law the gap is measured against
        (:data:`gdfe.diagnosis.baselines.BASELINES`); every form is fitted, and the report
        says how much of the gap to Eq. 1 lies in the form and how much beyond it.
    signed : bool
        The angles are signed (their sign a direction): they are taken as magnitudes
        ``|alpha|``, and the report says so. Without it a negative angle is an error.

    Returns
    -------
    Diagnosis

    Raises
    ------
    GdfeError
        Fewer than 5 tests, a group or process column that is not there, a bad ``sigma`` or a
        bad ``sigma_rad`` value (naming its row), a numeric column with a missing or
        non-finite value (naming its rows), a role that is not in the registry, negative
        angles without ``signed`` (naming their rows).
    """
    diag = _diagnose(tests, group=group, sigma=sigma, process=process, pairs=pairs, check=check, models=models,
                     roles=roles, baseline=baseline, signed=signed, screen=screen, relative_sigma=relative_sigma)
    said = diag.attribution().text
    diag.verdict = dataclasses.replace(diag.verdict, text=diag.verdict.text.rstrip() + " " + said[0].upper() + said[1:]
                                       + ".")
    return diag


#: The diagnosis's time against its number of tests, ``seconds = t0 (n / n0) ** p``, to say before a long
#: one starts: t0 at n0 = 10^4 rows from docs/diagnosis.md (its cost at 10,000 rows), p from it and
#: 2 000 rows of the same generator (12 s on 2 loaded cores; 500 rows 7.7 s, where fixed costs weigh).
_ROWS_AT, _SECONDS_AT_ROWS, _ROWS_EXPONENT = 1e4, 49.0, 0.87


def _read_tests(path):
    """Read the CSV of folding tests to diagnose: degenerate data refused or named, a long run announced."""
    from pathlib import Path

    from gdfe._validation import degenerate_tests
    from gdfe.resources import check_work

    tests = load_folding_tests(path)
    name = Path(path).name
    for note in degenerate_tests(name, tests.L, tests.d, tests.h, tests.alpha, single_point_is_error=True):
        log.warning("%s", note)
    n = len(tests)
    seconds = _SECONDS_AT_ROWS * (n / _ROWS_AT) ** _ROWS_EXPONENT
    check_work(name, 0.0, f"a diagnosis of {n:,} folding tests", "", seconds=seconds, logger=log)
    return tests


def _diagnose(tests, *, group=None, sigma=None, process=None, pairs=True, check=None, models=None, roles=None,
             baseline="eq1", signed=False, screen=True, relative_sigma=None):
    """:func:`diagnose` without the attribution sentence (the screen's reruns call it)."""
    tests = _checked_tests(tests, sigma=sigma, check=check, baseline=baseline, signed=signed)
    data = _prepare(tests, group=group, sigma=sigma, process=process, roles=roles, relative_sigma=relative_sigma)
    fitted = _fit_models(data, baseline=baseline, models=models, pairs=pairs)
    res_base = _residuals_of(fitted.base, data)
    choice = _choose(fitted, data, res_base)
    diag = _conclude(data, fitted, choice, res_base, baseline=baseline, signed=signed)
    if check:
        diag.check = _gdfe_check(diag, check)
        if not all(c["converged"] for c in diag.check.values()):
            diag.warnings.append("a GDFE solve of the check did not converge: its difference to the closed "
                                 "form is not a discretisation error")
    if screen:  # measurement artefacts: failed specimens, outliers, noise growing with the angle
        diag = screen_artefacts(diag, lambda t, relative_sigma=None, main=False: _diagnose(
            t, group=group, sigma=sigma, process=process, pairs=pairs, check=check if main else None, models=models,
            roles=roles, baseline=baseline, signed=signed, screen=False, relative_sigma=relative_sigma))
    diag.verdict = dataclasses.replace(diag.verdict, text=rename(diag.verdict.text, diag.renames))
    return diag


def _checked_tests(tests, *, sigma, check, baseline, signed):
    """The tests to diagnose (read when given a path), with the arguments checked and the angles
    taken as magnitudes when ``signed``."""
    if not isinstance(tests, FoldingTests):
        tests = _read_tests(tests)
    n = len(tests)
    if n < 5:
        raise GdfeError(f"tests: need at least 5 folding tests to fit and hold out, got {n}")
    check_choice("baseline", baseline, BASELINES)
    if signed and np.any(tests.alpha < 0):
        tests = dataclasses.replace(tests, alpha=np.abs(tests.alpha))
    if sigma is not None and not (is_finite_number(sigma) and sigma > 0):
        raise GdfeError(f"sigma: expected a positive noise in rad, got {sigma!r}")
    if check is not None:
        from gdfe.diagnosis.forward import CELLS

        check_choice("check", check, CELLS)
    return tests


@dataclasses.dataclass(frozen=True)
class _Setup:
    """The tests as every fit sees them: their columns, noise, weights and held-out error.

    Attributes
    ----------
    tests : FoldingTests
    columns : Columns
    noise : Noise
    weights : (n,) float array or None
        Weights of the least squares (``1 / sigma^2`` of a noise that varies between tests), None
        for equal ones.
    groups : (n,) str array or None
        Group label of each test in the leave-one-group-out column.
    kind : str
        ``"logo"`` with a leave-one-group-out column, else ``"loo"``.
    inputs : dict of str -> (n,) float array
        The numeric inputs the residuals are analysed against (``L_mm``, ``d_mm``, ``h_mm``,
        the process columns).
    small_negative : list of int
        Rows (CSV numbering) of negative angles kept as the noise of small folds.
    """

    tests: FoldingTests
    columns: Columns
    noise: Noise
    weights: np.ndarray | None
    groups: np.ndarray | None
    kind: str
    inputs: dict
    small_negative: list

    def x_of(self, m):
        """The values of the process column of model ``m`` (None without one)."""
        return self.columns.process[m.process] if m.process else None

    def group_of(self, m):
        """The index of each test's group among the labels of model ``m`` (None without a group)."""
        return m.group_index(self.columns.groups[m.group]) if m.group else None

    def fit(self, m):
        """Model ``m`` fitted to the tests and held out (:func:`gdfe.diagnosis.fit.evaluate`)."""
        t = self.tests
        return evaluate(m, t.L, t.d, t.h, t.alpha, self.groups, x=self.x_of(m), group=self.group_of(m),
                        weights=self.weights)

    def kind_of(self, f):
        """The held-out error ``f`` is ranked by: ``"loo"`` where it has no LOGO error (a batch effect)."""
        return "loo" if f.held_out_rmse(self.kind) is None else self.kind


def _prepare(tests, *, group, sigma, process, roles, relative_sigma):
    """The tests' columns and noise (steps 1 and 2 of the module docstring), with their signs checked
    and the weights the noise gives."""
    cols = read_columns(tests, group=group, process=process, roles=roles)
    noise = noise_of(tests.alpha, sigma=sigma, sigma_column=cols.sigma, keys=_replicate_keys(tests, cols))
    small_negative = _check_signs(tests.alpha, noise)
    weights = None
    if noise.source == "sigma_rad column" and np.ptp(noise.sigma) > 0:
        weights = 1.0 / noise.sigma**2
    if relative_sigma is not None:  # the noise grows with the angle (gdfe.diagnosis.artefacts)
        noise, weights = with_relative_noise(noise, relative_sigma)
    groups = cols.groups.get(cols.logo)
    return _Setup(tests=tests, columns=cols, noise=noise, weights=weights, groups=groups,
                  kind="logo" if groups is not None else "loo",
                  inputs={"L_mm": tests.L, "d_mm": tests.d, "h_mm": tests.h, **cols.process},
                  small_negative=small_negative)


def _replicate_keys(tests, cols):
    """(n, k) float array whose equal rows are replicates: the design, the process columns and
    the group columns (as codes)."""
    keys = [tests.L, tests.d, tests.h, *cols.process.values()]
    keys += [np.unique(v, return_inverse=True)[1].ravel().astype(float) for v in cols.groups.values()]
    return np.column_stack(keys)


@dataclasses.dataclass
class _Fitted:
    """The baseline and every model fitted to the tests, and the held-out choice among them.

    Attributes
    ----------
    base : EffectFit
    fits : list of EffectFit
        The models besides the baseline (batch steps included), best held-out error first.
    selected : EffectFit
        The model the held-out errors choose, the batch step included.
    candidates : list of str
        Models within one standard error of the held-out choice's error, or below it
        (:func:`gdfe.diagnosis.fit.select`).
    """

    base: EffectFit
    fits: list
    selected: EffectFit
    candidates: list


def _fit_models(data, *, baseline, models, pairs):
    """Fit the baseline and every model, and choose by held-out error (steps 3 to 5 of the module
    docstring)."""
    alpha, n = data.tests.alpha, len(data.tests)
    base = data.fit(baseline_model(baseline))
    if models is None:
        models = catalogue(pairs, process=list(data.columns.process))
    fits = [data.fit(m) for m in _fittable(models, baseline, n)]
    mark_equal([base] + fits, alpha)
    selected, cands = select([base] + fits, alpha, data.kind, weights=data.weights)
    selected, batch_fits = _batch_step(selected, fits, data.columns, data.fit, alpha, data.weights, n)
    fits += [f for f in batch_fits if f not in fits]
    mark_equal([base] + fits, alpha)
    fits.sort(key=lambda f: (f.held_out_rmse(data.kind) if f.held_out_rmse(data.kind) is not None
                             else f.loo_rmse))
    return _Fitted(base=base, fits=fits, selected=selected, candidates=cands)


@dataclasses.dataclass
class _Residuals:
    """What the residuals of one fit say (step 8 of the module docstring).

    Attributes
    ----------
    lack_of_fit : dict
        :func:`gdfe.diagnosis.verdict.lack_of_fit` against the noise.
    where : list of dict
        Residual analysis against the numeric inputs and the prediction.
    regime : str
        Where the error concentrates, in words.
    by_group : list of dict
        Residual analysis by group column.
    structure : list of dict
        Structure in ``where`` and ``by_group`` (:func:`gdfe.diagnosis.where.structure`).
    """

    lack_of_fit: dict
    where: list
    regime: str
    by_group: list
    structure: list


def _residuals_of(f, data):
    """Whether the residuals of fit ``f`` are within the noise, where they lie, and what structure
    is left in them."""
    groups = data.columns.groups
    lof = lack_of_fit(f.residuals, f.model.n_params, data.noise)
    where, regime = residual_analysis(f.residuals, {**data.inputs, "predicted": f.predicted}, groups)
    by_group = group_analysis(f.residuals, groups)
    return _Residuals(lack_of_fit=lof, where=where, regime=regime, by_group=by_group,
                      structure=structure(where + by_group))


@dataclasses.dataclass
class _Choice:
    """The best model and the models the data cannot tell from it (``best`` among them)."""

    best: EffectFit
    named: list


def _choose(fitted, data, res_base):
    """The best model against the noise, and those the data cannot tell from it (steps 6 and 7 of
    the module docstring)."""
    base, noise, alpha = fitted.base, data.noise, data.tests.alpha
    within = _lack_of_fit_test(noise)
    best = fitted.selected
    if noise.known and res_base.lack_of_fit["within"] and not res_base.structure:
        best = base  # within the noise: nothing to explain
    elif noise.known and not within(best):
        best = within_noise_step(best, fitted.fits, alpha, within, data.kind_of, data.weights)
    named = indistinguishable(best, [base] + fitted.fits, alpha, data.kind_of, within if noise.known else None,
                              STEP_SE[0], data.weights, sigma=noise.sigma if noise.known else None)
    return _Choice(best=prefer_plausible(best, named), named=named)


def _lack_of_fit_test(noise):
    """``within(fit)``: whether a fit passes the lack-of-fit test against ``noise`` (None with the
    noise unknown), each fit tested once."""
    lofs = {}

    def within(f):
        """Whether ``f`` passes the lack-of-fit test (None with the noise unknown)."""
        if f.name not in lofs:
            lofs[f.name] = lack_of_fit(f.residuals, f.model.n_params, noise)
        return lofs[f.name]["within"]

    return within


def _conclude(data, fitted, choice, res_base, *, baseline, signed):
    """The :class:`Diagnosis` of the chosen model: its residuals, the verdict with what the columns
    add to it, the baseline forms and the warnings (steps 7 to 9 of the module docstring)."""
    t, cols, noise = data.tests, data.columns, data.noise
    base, fits, best, named = fitted.base, fitted.fits, choice.best, choice.named
    separation = (separating_test(named, t.L, t.d, t.h, data.x_of, data.group_of, sigma=noise.value)
                  if len(named) > 1 else None)
    res_best = _residuals_of(best, data)
    verdict = _decide(data, base, choice, res_base, res_best, separation)
    renames = cols.roles.renames([f.model for f in [base] + fits])
    conf = confounded({"L_mm": t.L, "d_mm": t.d, "h_mm": t.h}, numeric=cols.process, groups=cols.groups)
    trends = strong_trends(res_base.where)
    verdict = _amend(verdict, base=base, best=best, named=named, cols=cols, conf=conf, trends=trends,
                     structure_any=bool(res_base.structure or res_best.structure), n=len(t), renames=renames)
    forms = _baseline_forms(baseline, base, fits, data.fit, t.alpha, noise, best, renames)
    diag = Diagnosis(tests=t, groups=data.groups, held_out=data.kind, baseline=base, fits=fits, best=best,
                     candidates=fitted.candidates, where=res_base.where + res_base.by_group,
                     regime=res_base.regime, where_best=res_best.where + res_best.by_group,
                     regime_best=res_best.regime, inputs=data.inputs, columns=cols, noise=noise, verdict=verdict,
                     selected=fitted.selected,
                     lack_of_fit={"baseline": res_base.lack_of_fit, "best": res_best.lack_of_fit},
                     structure=res_base.structure, structure_best=res_best.structure, excluded=_excluded(fits),
                     named=named, separation=separation, baseline_name=baseline, baseline_form=forms,
                     confounded=conf, trends=trends, signed=bool(signed), renames=renames)
    diag.warnings = _warnings(diag) + _angle_warnings(data.small_negative, signed)
    return diag


def _decide(data, base, choice, res_base, res_best, separation):
    """The verdict on the gap (:func:`gdfe.diagnosis.verdict.decide`) from the baseline, the best
    and the named models and their residuals."""
    alpha, noise, best, named = data.tests.alpha, data.noise, choice.best, choice.named
    return decide(best_name=best.name, best_is_baseline=not best.model.effects, lof_base=res_base.lack_of_fit,
                  lof_best=res_best.lack_of_fit, structure_base=res_base.structure,
                  structure_best=res_best.structure,
                  gap_base=gap(alpha, base.loo_predicted, noise), gap_best=gap(alpha, best.loo_predicted, noise),
                  noise=noise, named=[f.name for f in named],
                  separation=None if separation is None else separation["text"],
                  implausible=getattr(best, "implausible", None), kinds=getattr(best.model, "kinds", None),
                  effects=best.model.effects,
                  named_implausible={f.name: [p["name"] for p in getattr(f, "implausible", [])] for f in named})


def _excluded(fits):
    """The models of ``fits`` never chosen, and why (parameters not identifiable, predictions equal
    to a simpler model's)."""
    return [{"name": f.name, "reason": (f"parameters not identifiable from these data "
                                        f"({', '.join(f.unidentified)})" if not f.identifiable else
                                        f"predictions equal those of {f.equals}")}
            for f in fits if not f.usable]


def _angle_warnings(small_negative, signed):
    """The warnings on how the angles were read: negative ones kept as noise (their rows), signed
    ones taken as magnitudes."""
    out = []
    if small_negative:
        out.append(f"rows {', '.join(map(str, small_negative))}: negative angles within "
                   f"{NEGATIVE_SIGMAS:g} standard deviations of the noise, kept as measured (the noise of "
                   f"small folds; angles are magnitudes, positive towards the uncoated face)")
    if signed:
        out.append("angles read as signed (--signed): the diagnosis uses their magnitudes |alpha|")
    return out


def _fittable(models, baseline, n):
    """The models of ``models`` to fit besides the baseline: not the baseline itself, and with
    enough tests (``n``) to fit and hold out their parameters."""
    out = []
    for m in models:
        if not m.effects or (baseline == "timoshenko" and m.effects == ("passive_stiffness",)):
            continue  # the baseline itself
        if n - 1 <= m.n_params + 1:
            log.info("%s: %d parameters need more than %d tests; skipped", m.name, m.n_params, n)
            continue
        out.append(m)
    return out


def _gdfe_check(diag, resolution):
    """GDFE solves of (at most :data:`CHECK_TESTS` of) the tests against the closed forms of the
    baseline and the chosen model (:func:`gdfe.diagnosis.forward.gdfe_check`)."""
    from gdfe.diagnosis.forward import gdfe_check

    t, cols, base, best = diag.tests, diag.columns, diag.baseline, diag.best
    idx = _check_subset(base.predicted)

    def sub(f):
        x = cols.process[f.model.process][idx] if f.model.process else None
        g = f.model.group_index(cols.groups[f.model.group])[idx] if f.model.group else None
        c = gdfe_check(f.model, f.params, t.L[idx], t.d[idx], t.h[idx], x=x, group=g, resolution=resolution)
        c["n_tests"] = int(idx.size)
        return c

    # a baseline form other than Eq. 1 has no GDFE hinge of its own to check
    out = {"baseline": sub(base)} if isinstance(base.model, Model) else {}
    if best is not base and isinstance(best.model, Model):
        out["best"] = sub(best)
    return out


#: Standard deviations of the noise within which a negative angle is read as the noise of a small fold.
NEGATIVE_SIGMAS = 2.0


def _check_signs(alpha, noise):
    """Fold angles are magnitudes, positive towards the uncoated face. A negative angle is an
    error naming its rows unless the noise is known and it lies within
    :data:`NEGATIVE_SIGMAS` of it (a small fold measured with noise: kept as measured, and
    the rows returned for a warning)."""
    negative = np.nonzero(alpha < 0)[0]
    if not negative.size:
        return []
    tol = NEGATIVE_SIGMAS * (noise.sigma[negative] if noise.known else 0.0)
    beyond = negative[alpha[negative] < -tol]
    if beyond.size:
        rows = ", ".join(str(i + 2) for i in beyond[:10]) + (", ..." if beyond.size > 10 else "")
        raise GdfeError(f"alpha_rad: expected fold angles as magnitudes (>= 0, positive towards the uncoated face), "
                        f"got {beyond.size} negative {'beyond twice the noise ' if noise.known else ''}in "
                        f"row{'s' if beyond.size > 1 else ''} {rows}; if the sign is a direction, say so "
                        f"(signed=True, --signed) to take |alpha|")
    return [int(i) + 2 for i in negative]


def _baseline_forms(chosen, base, fits, fit, alpha, noise, best, renames):
    """:func:`gdfe.diagnosis.baselines.form_shares` of the data: every baseline form fitted
    (reusing the chosen baseline's and the catalogue's fits where they are the same model)."""
    from gdfe.diagnosis.baselines import FormModel

    out = {}
    for name in BASELINES:
        if name == chosen:
            out[name] = base
        elif name == "eq1":
            out[name] = next((f for f in fits if isinstance(f.model, Model) and not f.model.effects), None) \
                or fit(Model(()))
        elif name == "timoshenko":
            out[name] = next((f for f in fits if isinstance(f.model, Model)
                              and f.model.effects == ("passive_stiffness",)), None) or fit(FormModel(name))
        else:
            out[name] = fit(FormModel(name))
    gaps = {k: gap(alpha, f.loo_predicted, noise) for k, f in out.items()}
    rmse = {k: f.loo_rmse for k, f in out.items()}
    rmse["best_model"] = best.loo_rmse
    usable = [k for k, f in out.items() if f.usable and np.all(np.isfinite(f.loo_predicted))] or ["eq1"]
    best_form = min(usable, key=lambda k: gaps[k])
    return form_shares(gaps, rmse, best_form, (rename(best.name, renames), gap(alpha, best.loo_predicted, noise)),
                       chosen)


def _amend(verdict, *, base, best, named, cols, conf, trends, structure_any, n, renames):
    """The verdict with what the columns and the residuals add to it.

    * ``no_gap`` is never given when the residuals show structure: with family-wise structure
      (which :func:`gdfe.diagnosis.verdict.decide` already rules out), or with a strong trend
      that the family-wise test cannot confirm on these tests
      (:func:`gdfe.diagnosis.where.strong_trends`), the verdict is ``structure_remains``;
    * a chosen or named model with a factor (an effect on a column whose role was not
      declared) says that it is a factor, not a physical cause;
    * a chosen or named model on a confounded column says with what.
    Model names in the text are the reported ones (``factor[C]``).
    """
    if verdict.verdict == "no_gap" and (structure_any or trends):
        t = trends[0] if trends else None
        why = (f"{t['text']}, a strong trend (|rho| >= {TREND_RHO:g}, p < {TREND_LEVEL:g} on its own test) "
               f"that the family-wise test over every column cannot confirm with {n} tests" if t else
               "residual structure")
        verdict = dataclasses.replace(
            verdict, verdict="structure_remains",
            text=f"structure remains: no model of the catalogue earns its parameters and the baseline fits "
                          f"as well as can be told, but its residuals show {why}; neither a gap nor its absence is "
                          f"established: tests over a wider range of {t['input'] if t else 'the inputs'} would tell")
    notes = []
    if verdict.verdict in ("explained", "partly_explained"):
        seen = set()
        conf_by = {c["column"]: c for c in conf}
        for f in [best] + [g for g in named if g is not best]:
            for col, numeric in ((f.model.process, True), (f.model.group, False)):
                if not col or col in seen:
                    continue
                seen.add(col)
                kind = cols.roles.kind(col)
                if not ((numeric and kind == "process") or (not numeric and kind == "group")):
                    notes.append(f"{rename(f.name, renames)} is {cols.roles.words(col, numeric)}: a factor, "
                                 f"not a physical cause")
                if col in conf_by:
                    c = conf_by[col]
                    names = ", ".join(w.split("_")[0] for w in c["with"])
                    notes.append(f"{col} is confounded with {names} ({c['measure']} {c['value']:.2f}): the effect "
                                 f"of {rename(f.name, renames)} cannot be told from a dependence on {names} that the "
                                 f"catalogue lacks")
    else:
        seen = set()
    notes += [c["what it means"] for c in conf if c["column"] not in seen]
    text = rename(verdict.text, renames)
    if notes:
        text = text.rstrip(".") + ". " + ". ".join(notes) + "."
    return dataclasses.replace(verdict, text=text, named=[rename(m, renames) for m in verdict.named])


def _batch_step(best, fits, cols, fit, alpha, weights, n):
    """Add a batch effect on a group column to the chosen model when it lowers the
    leave-one-out error significantly; then drop any other effect it makes unnecessary.

    The batch effect alone (on the baseline) is fitted for every group column too, whatever
    is chosen, so that the later steps (a model within the noise, the named set) can weigh it
    against the chosen model with its effects."""
    tried = []
    if not cols.groups or "batch" in best.model.effects:
        return best, tried
    for col, labels in cols.groups.items():
        m = Model(("batch",), group=col, labels=np.unique(labels))
        if n - 1 > m.n_params + 1 and m != best.model:
            tried.append(next((g for g in fits if g.model == m), None) or fit(m))
    found = None
    for col, labels in cols.groups.items():
        m = best.model.with_effect("batch", group=col, labels=np.unique(labels))
        if n - 1 <= m.n_params + 1:
            continue
        f = next((g for g in fits if g.model == m), None) or fit(m)
        tried.append(f)
        better, mean, _ = compare(f, best, alpha, "loo", STEP_SE[min(best.model.level, 1)], weights)
        if better and (found is None or mean < found[1]):
            found = (f, mean)
    if found is None:
        return best, tried
    current = found[0]
    for e in [e for e in current.model.effects if e != "batch"]:
        simpler = current.model.without(e)
        f = next((g for g in tried if g.model == simpler), None) or fit(simpler)
        tried.append(f)
        better, _, _ = compare(current, f, alpha, "loo", STEP_SE[min(simpler.level, 1)], weights)
        if not better:
            current = f
    return current, tried


def within_noise_step(chosen, fits, alpha, within, kind_of, weights=None, step=STEP_SE[0]):
    """With a known noise, a chosen model that the lack-of-fit test rejects gives way to one
    within the noise.

    Candidates are the usable models within the noise with at most as many effects as
    ``chosen`` whose held-out error ``chosen`` does not beat by ``step`` standard errors (the
    data prefer neither on held-out tests, and only one of them fits), and those with more
    effects that beat ``chosen`` by ``step`` standard errors (the one-standard-error rule by
    which any effect is named). The one with the fewest effects, then the smallest held-out
    mean squared error, is returned; ``chosen`` when there is none.

    Parameters
    ----------
    chosen : EffectFit
        The held-out choice (the baseline when no effect earned its parameters: then only
        models that beat it by ``step`` standard errors are candidates).
    fits : list of EffectFit
    alpha : (n,) float array [rad]
    within : callable
        ``within(fit) -> bool``: the lack-of-fit test against the known noise.
    kind_of : callable
        ``kind_of(fit) -> "loo" | "logo"``.
    weights : (n,) float array, optional
    step : float
    """
    alpha = np.asarray(alpha, float)
    found = []
    for f in fits:
        if f is chosen or not f.model.effects or not f.usable or not within(f):
            continue
        k = "logo" if kind_of(f) == kind_of(chosen) == "logo" else "loo"
        if f.model.level <= chosen.model.level:
            beaten, mean, _ = compare(chosen, f, alpha, k, step, weights)
            ok = not beaten and math.isfinite(mean)
        else:
            ok, mean, _ = compare(f, chosen, alpha, k, step, weights)
        if ok:
            found.append((f.model.level, float(np.mean((alpha - f.held_out(k)) ** 2)), f.name, f))
    if not found:
        return chosen
    return min(found, key=lambda t: t[:3])[3]


def _warnings(diag):
    out = []
    best = diag.best
    if best.at_bound:
        out.append(f"{best.name}: {', '.join(best.at_bound)} ended on a bound of the physical range: the data "
                   f"push past what the effect allows, so read the value as that edge, not as a measurement")
    if not best.success:
        out.append(f"{best.name}: the optimiser did not report convergence of the fit")
    for e in diag.excluded:
        out.append(f"{e['name']} never chosen: {e['reason']}")
    for k, why in diag.columns.ignored.items():
        out.append(f"column {k!r} not used: {why}")
    if not diag.noise.known:
        out.append("the noise is unknown: give --sigma (or a sigma_rad column, or replicate rows) for a verdict "
                   "against the noise")
    return out
