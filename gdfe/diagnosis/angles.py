"""Diagnosis of fold-angle data: where the calibrated GDFE hinge misses, which effect explains it.

:func:`diagnose` takes folding tests (a table like the paper's Table 1) and

1. fits the **baseline**, the paper's deformation principle refitted to the data: the GDFE
   hinge with the contraction ratio of Eq. 3, whose converged fold is Eq. 2's
   ``(1 - R) L / h``, i.e. Eq. 1, ``alpha = K sqrt(h / d**3) L``, with ``K`` by least
   squares (the closed form is checked against GDFE solves of the same tests);
2. says **where** its residuals lie (:mod:`gdfe.diagnosis.where`);
3. fits every **effect** of the catalogue (:mod:`gdfe.diagnosis.effects`) and every pair,
   and measures each on tests the fit did not see: leave-one-out, and leave-one-group-out
   when the tests carry a group column;
4. ranks them by held-out error, reports how much of the baseline's held-out error each
   removes (``shrink``) and its AICc, and names the **best**, climbing from the baseline one
   effect at a time while the held-out error drops significantly
   (:func:`gdfe.diagnosis.fit.select`).

Angles in radians, lengths in mm.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from gdfe._validation import GdfeError
from gdfe.calibration import FoldingTests, load_folding_tests
from gdfe.diagnosis.effects import EFFECTS, Model, catalogue
from gdfe.diagnosis.fit import STEP_SE, EffectFit, evaluate, select
from gdfe.diagnosis.where import residual_analysis

__all__ = ["Diagnosis", "diagnose", "numeric_columns"]

log = logging.getLogger(__name__)

BASELINE_MODEL = "gdfe_hinge_eq3"


@dataclasses.dataclass
class Diagnosis:
    """Result of :func:`diagnose`.

    Attributes
    ----------
    tests : FoldingTests
    groups : (n,) array or None
        Group label of each test.
    held_out : str
        ``"loo"`` or ``"logo"``: the held-out error the models are ranked by.
    baseline : EffectFit
    fits : list of EffectFit
        Every effect model (single effects and pairs), best held-out error first.
    best : EffectFit
        The chosen model (may be the baseline: no effect earns its parameters).
    candidates : list of str
        Models within one standard error of the chosen model's held-out error, or below it.
    where, where_best : list of dict
        Residual analysis of the baseline and of the best model.
    regime, regime_best : str
        Where the error concentrates, in words.
    inputs : dict of str -> (n,) float array
        The inputs the residuals were analysed against.
    check : dict or None
        Closed form against GDFE solves (:func:`gdfe.diagnosis.forward.gdfe_check`) for
        the baseline and the best model.
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
    check: dict | None = None

    def held_out_rmse(self, fit):
        return fit.held_out_rmse(self.held_out)

    def shrink(self, fit, kind=None):
        """Fraction of the baseline's held-out RMSE that ``fit`` removes."""
        kind = kind or self.held_out
        b = self.baseline.held_out_rmse(kind)
        return float(1.0 - fit.held_out_rmse(kind) / b) if b else 0.0

    def as_dict(self) -> dict:
        """The JSON layout of ``gdfe diagnose --json``."""
        t = self.tests
        logo = self.held_out == "logo"

        def entry(f):
            e = {"name": f.name, "effects": list(f.model.effects), "params": f.param_dict(),
                 "n_params": f.model.n_params, "rmse": f.rmse, "loo_rmse": f.loo_rmse,
                 "shrink": self.shrink(f, "loo"), "aic": f.aicc, "at_bound": f.at_bound}
            if logo:
                e.update(logo_rmse=f.logo_rmse, shrink_logo=self.shrink(f, "logo"))
            return e

        effects = []
        for rank, f in enumerate(self.fits, start=1):
            effects.append({**entry(f), "rank": rank})
        # the chosen model first, the others by held-out error
        effects.sort(key=lambda e: (e["name"] != self.best.name, e["rank"]))
        b = self.baseline
        base = {"model": BASELINE_MODEL,
                "description": "GDFE hinge with the contraction ratio of Eq. 3 refitted to the data; "
                               "its converged fold is Eq. 1, alpha = K sqrt(h/d^3) L",
                "params": b.param_dict(), "rmse": b.rmse, "loo_rmse": b.loo_rmse, "aic": b.aicc,
                "r2": _r2(t.alpha, b.predicted)}
        if logo:
            base["logo_rmse"] = b.logo_rmse
        residuals = []
        for i in range(len(t)):
            row = {"row": i + 2, "L_mm": float(t.L[i]), "d_mm": float(t.d[i]), "h_mm": float(t.h[i]),
                   "measured": float(t.alpha[i]), "predicted": float(b.predicted[i]),
                   "residual": float(b.residuals[i]), "loo_residual": float(t.alpha[i] - b.loo_predicted[i]),
                   "best_predicted": float(self.best.predicted[i]),
                   "best_residual": float(self.best.residuals[i]),
                   "best_loo_residual": float(t.alpha[i] - self.best.loo_predicted[i])}
            if self.groups is not None:
                row["group"] = str(self.groups[i])
            for k, v in t.extra.items():
                row.setdefault(k, str(v[i]))
            residuals.append(row)
        out = {
            "n_tests": len(t),
            "held_out": "leave-one-group-out" if logo else "leave-one-out",
            "baseline": base,
            "where": self.where,
            "regime": self.regime,
            "residuals": residuals,
            "effects": effects,
            "best": self.best.name,
            "best_detail": {**entry(self.best), "where": self.where_best, "regime": self.regime_best},
            "selection": ("effects: the best first, then the others by rank, the order of their "
                          + ("leave-one-group-out" if logo else "leave-one-out")
                          + " RMSE; best: climbing from the baseline, the best single effect is named if "
                          f"its held-out mean squared error is lower by more than {STEP_SE[0]:g} standard "
                          "error(s) of the paired per-test difference, the best pair if lower than that "
                          f"by more than {STEP_SE[1]:g}"),
            "candidates": self.candidates,
            "catalogue": {e.name: {"stage": e.stage, "params": list(e.params), "units": list(e.units),
                                   "meaning": e.meaning} for e in EFFECTS.values()},
        }
        if self.check is not None:
            out["gdfe_check"] = self.check
        return out

    def text(self) -> str:
        """A human-readable summary."""
        b = self.baseline
        ho = "LOGO" if self.held_out == "logo" else "LOO"
        lines = [f"{len(self.tests)} folding tests; held-out error: {ho} RMSE",
                 f"baseline (Eq. 1-3 refitted): K = {b.params[0]:.4g}, RMSE {b.rmse:.3f} rad, "
                 f"{ho} {self.held_out_rmse(b):.3f} rad, R^2 {_r2(self.tests.alpha, b.predicted):.3f}"]
        if self.check is not None and self.check.get("baseline"):
            c = self.check["baseline"]
            lines.append(f"  closed form vs GDFE solves ({c['cells']} cells/hinge): max |diff| "
                         f"{c['max_abs_diff']:.4f} rad")
        lines.append("where: " + self.regime)
        lines.append(f"{'model':36s} {'k':>2s} {'RMSE':>7s} {'LOO':>7s}"
                     + (f" {'LOGO':>7s}" if self.held_out == "logo" else "") + f" {'shrink':>7s} {'AICc':>8s}")
        for f in [b] + self.fits:
            lines.append(f"{f.name:36s} {f.model.n_params:2d} {f.rmse:7.3f} {f.loo_rmse:7.3f}"
                         + (f" {f.logo_rmse:7.3f}" if self.held_out == "logo" else "")
                         + f" {100 * self.shrink(f):6.1f}% {f.aicc:8.2f}"
                         + ("  <- best" if f is self.best else ""))
        bp = ", ".join(f"{k} = {v:.4g}" for k, v in self.best.param_dict().items())
        lines.append(f"best: {self.best.name} ({bp}); {ho} RMSE {self.held_out_rmse(b):.3f} -> "
                     f"{self.held_out_rmse(self.best):.3f} rad ({100 * self.shrink(self.best):.0f} % less)")
        lines.append("after the best model: " + self.regime_best)
        return "\n".join(lines)


def _r2(y, p):
    y, p = np.asarray(y, float), np.asarray(p, float)
    return float(1.0 - ((y - p) ** 2).sum() / ((y - y.mean()) ** 2).sum())


def numeric_columns(tests):
    """Extra columns of ``tests`` whose every value is a finite number, as float arrays."""
    out = {}
    for k, v in tests.extra.items():
        try:
            x = np.array([float(s) for s in v])
        except ValueError:
            continue
        if np.all(np.isfinite(x)):
            out[k] = x
    return out


def diagnose(tests, *, group=None, pairs=True, check=None, models=None):
    """Diagnose the gap between folding tests and the calibrated GDFE hinge.

    Parameters
    ----------
    tests : FoldingTests or str or Path
        The tests, or the path of a CSV with columns ``L_mm, d_mm, h_mm, alpha_rad`` (and
        any others; bad rows are reported by row number and column).
    group : str, optional
        Column holding a group label (batch, print job, ...): enables leave-one-group-out,
        which then ranks the models. Default: the column ``group`` when there is one.
    pairs : bool
        Also fit every pair of effects.
    check : {"coarse", "default", "fine"}, optional
        Simulate the tests with GDFE at this resolution and compare with the closed forms
        of the baseline and the best model.
    models : list of Model, optional
        Models to compare instead of the catalogue (the baseline is always fitted).

    Returns
    -------
    Diagnosis
    """
    if not isinstance(tests, FoldingTests):
        tests = load_folding_tests(tests)
    n = len(tests)
    if n < 5:
        raise GdfeError(f"tests: need at least 5 folding tests to fit and hold out, got {n}")
    groups = None
    if group is None and "group" in tests.extra:
        group = "group"
    if group is not None:
        if group not in tests.extra:
            raise GdfeError(f"group: no column {group!r} in the tests; columns besides L_mm, d_mm, "
                             f"h_mm, alpha_rad: {', '.join(tests.extra) or 'none'}")
        groups = np.asarray(tests.extra[group])
        if len(np.unique(groups)) < 2:
            log.info("group column %r has a single value: no leave-one-group-out", group)
            groups = None
    L, d, h, alpha = tests.L, tests.d, tests.h, tests.alpha
    base = evaluate(Model(()), L, d, h, alpha, groups)
    models = [m for m in (catalogue(pairs) if models is None else models) if m.effects]
    fits = []
    for m in models:
        if n - 1 <= m.n_params + 1:
            log.info("%s: %d parameters need more than %d tests; skipped", m.name, m.n_params, n)
            continue
        fits.append(evaluate(m, L, d, h, alpha, groups))
    kind = "logo" if groups is not None else "loo"
    best, cands = select([base] + fits, alpha, kind)
    fits.sort(key=lambda f: f.held_out_rmse(kind))
    inputs = {"L_mm": L, "d_mm": d, "h_mm": h, **numeric_columns(tests)}
    where, regime = residual_analysis(base.residuals, {**inputs, "predicted": base.predicted})
    where_b, regime_b = residual_analysis(best.residuals, {**inputs, "predicted": best.predicted})
    diag = Diagnosis(tests=tests, groups=groups, held_out=kind, baseline=base, fits=fits, best=best,
                     candidates=cands, where=where, regime=regime, where_best=where_b,
                     regime_best=regime_b, inputs=inputs)
    if check:
        from gdfe.diagnosis.forward import gdfe_check

        diag.check = {"baseline": gdfe_check(base.model, base.params, L, d, h, resolution=check)}
        if best is not base:
            diag.check["best"] = gdfe_check(best.model, best.params, L, d, h, resolution=check)
    return diag
