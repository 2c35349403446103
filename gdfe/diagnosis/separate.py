"""Indistinguishable models, and the tests that would tell them apart.

On one set of folding tests several models of the catalogue can fit equally well: at Table
1's single film thickness a thicker cured coat, a film that thickens and an elastic coat all
soften the dependence on ``d`` alike. The diagnosis then names them all rather than one
picked by the noise (:func:`indistinguishable`), and says which further test would
separate them (:func:`separating_test`).

**Indistinguishable** from the chosen model are the usable models (identifiable, not equal
to a simpler one) with no more effects than it that the data do not tell apart from it:

* on held-out tests: the chosen model does not beat its held-out error by more than
  ``step`` standard errors of the paired per-test difference (the one-standard-error rule
  that names an effect at all, :data:`gdfe.diagnosis.fit.STEP_SE`); or
* with a known noise ``sigma_i``, by their fitted angles: ``D = sum_i ((p_i - q_i) /
  sigma_i)^2``, the chi^2 by which the one model's fitted angles ``p`` miss the other's
  ``q``, is below the ``1 - LEVEL`` quantile of chi^2 on one degree of freedom
  (:data:`gdfe.diagnosis.verdict.LEVEL`): even if one model were exactly true, the other
  would be expected to fit the data worse by less than a significant amount.

With a known noise and the chosen model within it, a model must also be within the noise
itself (a model the lack-of-fit test rejects is told apart by the data). The set is listed
with the fewest effects first, then the fewest parameters, then the smallest held-out error.

**Every kind.** The set is drawn from the whole catalogue, measurement artefacts (a reading
offset) and models with implausible parameters included: a single cause is named only when
the data rule the others out. When the chosen model fits only with implausible parameters and
a model of the set is plausible, the plausible one with the fewest effects is chosen instead
(:func:`prefer_plausible`): the data cannot tell them apart, the physics can.

**Separating test**: each model of the set, with its fitted parameters, predicts tests like
the data's with one input (``L``, ``d`` or ``h``) moved over a range (from half its smallest
to 1.5 times its largest value in the data, the data's value when it is the same in every
test), the other inputs, process columns and groups of each test kept. The test where the
predictions spread most (largest minus smallest, among predictions between 0 and pi) is
named, with each model's prediction there and the spread on the tests made.

Angles in radians, lengths in mm.
"""

from __future__ import annotations

import math

import numpy as np

from gdfe.diagnosis.fit import compare
from gdfe.diagnosis.verdict import LEVEL

__all__ = ["indistinguishable", "separating_test", "prefer_plausible", "SEPARATION_VALUES", "SEPARATION_RANGE"]

#: Values of the moved input tried by :func:`separating_test`.
SEPARATION_VALUES = 11
#: The moved input's range: these factors of its smallest and largest value in the data.
SEPARATION_RANGE = (0.5, 1.5)
_INPUTS = (("L_mm", "hinge width L"), ("d_mm", "passive coat d"), ("h_mm", "film thickness h"))


def indistinguishable(chosen, fits, alpha, kind_of, within_of=None, step=1.0, weights=None, sigma=None):
    """The models the data cannot tell from ``chosen``, ``chosen`` among them (ordered as in Returns).

    Parameters
    ----------
    chosen : EffectFit
    fits : list of EffectFit
        The other fitted models (the baseline may be among them; it is never added to the
        set of a model with effects, which beat it to be chosen).
    alpha : (n,) float array [rad]
        Measured angles.
    kind_of : callable
        ``kind_of(fit) -> "loo" | "logo"``: the held-out error each model is ranked by; two
        models are compared on ``"logo"`` only when both have it.
    within_of : callable, optional
        ``within_of(fit) -> bool | None``: whether a model is within a known noise (its
        lack-of-fit test); ``None`` or a noise-free call leaves the lack of fit out.
    step : float
        Standard errors by which the chosen model must beat another to be told apart.
    weights : (n,) float array, optional
    sigma : (n,) float array, optional
        The known noise of each test [rad]: enables the comparison of fitted angles.

    Returns
    -------
    list of EffectFit
        Ordered by number of effects, then parameters, then held-out RMSE; ``chosen`` is among
        them (the first when it is the simplest).
    """
    if not chosen.model.effects:
        return [chosen]
    from scipy import stats

    alpha = np.asarray(alpha, float)
    check_within = within_of is not None and bool(within_of(chosen))
    d_max = float(stats.chi2.ppf(1.0 - LEVEL, 1))
    out = [chosen]
    for f in fits:
        if f is chosen or f.model == chosen.model or not f.model.effects or not f.usable:
            continue
        if f.model.level > chosen.model.level:
            continue
        if check_within and not within_of(f):
            continue
        if sigma is not None and float(np.sum(((f.predicted - chosen.predicted) / sigma) ** 2)) < d_max:
            out.append(f)
            continue
        kind = "logo" if kind_of(f) == kind_of(chosen) == "logo" else "loo"
        better, mean, _ = compare(chosen, f, alpha, kind, step, weights)
        if not better and not math.isnan(mean):
            out.append(f)

    def key(f):
        return (f.model.level, f.model.n_params, f.held_out_rmse("loo"), f.name)

    return sorted(out, key=key)


def prefer_plausible(chosen, named):
    """``chosen``, or the first plausible model of ``named`` when ``chosen`` fits only with
    implausible parameters (:attr:`gdfe.diagnosis.fit.EffectFit.plausible`)."""
    if getattr(chosen, "plausible", True) or not chosen.model.effects:
        return chosen
    return next((f for f in named if f.model.effects and getattr(f, "plausible", True)), chosen)


def separating_test(fits, L, d, h, x_of, group_of, sigma=None):
    """The test, near the data's, where the fitted models of ``fits`` disagree most.

    Parameters
    ----------
    fits : list of EffectFit
        Two or more fitted models.
    L, d, h : (n,) float arrays [mm]
        The tests made.
    x_of, group_of : callable
        ``x_of(model)``: its process column (None without ``partial_activation``);
        ``group_of(model)``: its group index of every test (None without ``batch``).
    sigma : float, optional
        The noise [rad]: the spreads are also given in units of it.

    Returns
    -------
    dict or None
        None for fewer than two models. Else ``on_data`` (largest spread of the fitted angles
        on the tests made [rad]), ``input`` (``"L_mm"``, ``"d_mm"`` or ``"h_mm"``), ``value``
        [mm], ``row`` (the data row, counted from 2 as in the CSV, whose other inputs the
        test keeps), ``test`` (its ``L_mm, d_mm, h_mm``), ``predictions`` (model name ->
        angle [rad]), ``spread`` [rad], ``sigmas`` (spread over the noise, or None) and
        ``text``; ``input`` is None when no moved test gives valid predictions of every
        model.
    """
    if len(fits) < 2:
        return None
    L, d, h = (np.asarray(a, float) for a in (L, d, h))
    base = {"L_mm": L, "d_mm": d, "h_mm": h}

    def predict(ins):
        P = []
        for f in fits:
            with np.errstate(all="ignore"):
                p = f.model.predict(f.params, ins["L_mm"], ins["d_mm"], ins["h_mm"], x_of(f.model),
                                    group_of(f.model))
            P.append(np.broadcast_to(np.real(p), ins["L_mm"].shape))
        return np.array(P)  # (m, n)

    def spread(P):
        ok = np.all(np.isfinite(P) & (P >= 0.0) & (P <= math.pi), axis=0)
        s = np.where(ok, P.max(axis=0) - P.min(axis=0), -np.inf)
        return s

    on_data = spread(predict(base))
    on_data = float(np.max(on_data)) if np.isfinite(on_data).any() else math.nan
    best = None
    for name, _ in _INPUTS:
        v = base[name]
        lo, hi = SEPARATION_RANGE[0] * float(v.min()), SEPARATION_RANGE[1] * float(v.max())
        for value in np.linspace(lo, hi, SEPARATION_VALUES):
            ins = {**base, name: np.full(v.shape, value)}
            P = predict(ins)
            s = spread(P)
            i = int(np.argmax(s))
            if np.isfinite(s[i]) and (best is None or s[i] > best[0]):
                best = (float(s[i]), name, float(value), i, P[:, i], ins)
    names = [f.name for f in fits]
    out = {"models": names, "on_data": on_data, "input": None, "value": None, "row": None, "test": None,
           "predictions": None, "spread": None, "sigmas": None}
    if best is None:
        out["text"] = "no test near the data's gives valid predictions of every model"
        return out
    s, name, value, i, p, ins = best
    noun = dict(_INPUTS)[name]
    test = {k: float(ins[k][i]) for k in ("L_mm", "d_mm", "h_mm")}
    sig = None if not sigma else s / float(sigma)
    out.update(input=name, value=value, row=i + 2, test=test,
               predictions={n: float(v) for n, v in zip(names, p)}, spread=s, sigmas=sig)
    k = np.argsort(p)
    lo_n, hi_n = names[k[0]], names[k[-1]]
    same = "" if np.ptp(base[name]) > 0 else f" (every test so far has {name} = {float(base[name][0]):.3g} mm)"
    out["text"] = (f"a test at {noun} = {value:.3g} mm{same}, like row {i + 2} otherwise (L = {test['L_mm']:.3g}, "
                   f"d = {test['d_mm']:.3g}, h = {test['h_mm']:.3g} mm), would separate them: {lo_n} predicts "
                   f"{p[k[0]]:.3f} rad, {hi_n} {p[k[-1]]:.3f} rad"
                   + (f" ({sig:.1f} sigma apart)" if sig is not None else "")
                   + f"; on the tests made they differ by at most {on_data:.3f} rad")
    return out
