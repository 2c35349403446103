"""Least-squares fits of the effect models, their held-out errors and the choice among them.

Every model is fitted by least squares from a grid of starts: Levenberg-Marquardt iterated
on all starts at once, each parameter held inside its physical bounds by a smooth change of
variable (logistic between two bounds, exponential above one; ``E_ratio`` on a log scale),
then the best polished by ``scipy.optimize.least_squares`` with the bounds. Derivatives are
by complex step (exact to rounding). Held-out errors refit the model without the held-out
tests, starting from the full fit and keeping the full data's bounds:

* leave-one-out (LOO): each test predicted by the model fitted to the other ``n - 1``;
* leave-one-group-out (LOGO): each test predicted by the model fitted without its group.

The information criterion is the corrected AIC of a least-squares fit with Gaussian errors,
``AICc = n ln(RSS / n) + 2k + 2k (k + 1) / (n - k - 1)`` with ``k`` the model's
parameters plus one for the noise variance.

Angles in radians.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from gdfe._validation import GdfeError
from gdfe.diagnosis.effects import Model

__all__ = ["EffectFit", "fit_params", "evaluate", "select", "aicc"]

log = logging.getLogger(__name__)

_LOG_PARAMS = ("E_ratio",)


@dataclasses.dataclass
class EffectFit:
    """A fitted model and its errors.

    Attributes
    ----------
    model : Model
    params : (k,) float array
        Least-squares parameters, in the order of ``model.param_names``.
    predicted, residuals : (n,) float arrays [rad]
        Fitted angles and measured minus fitted.
    rmse : float [rad]
    loo_predicted : (n,) float array [rad]
        Leave-one-out predictions.
    loo_rmse : float [rad]
    logo_predicted : (n,) float array or None [rad]
        Leave-one-group-out predictions (when groups are given).
    logo_rmse : float or None [rad]
    aicc : float
    at_bound : list of str
        Parameters that ended on a bound of their physical range.
    success : bool
        Whether the optimiser reported convergence for the full fit.
    """

    model: Model
    params: np.ndarray
    predicted: np.ndarray
    residuals: np.ndarray
    rmse: float
    loo_predicted: np.ndarray
    loo_rmse: float
    logo_predicted: np.ndarray | None
    logo_rmse: float | None
    aicc: float
    at_bound: list
    success: bool

    @property
    def name(self) -> str:
        return self.model.name

    def held_out(self, kind="loo"):
        """Held-out predictions of ``kind`` (``"loo"`` or ``"logo"``)."""
        return self.loo_predicted if kind == "loo" else self.logo_predicted

    def held_out_rmse(self, kind="loo"):
        """Held-out RMSE [rad] of ``kind`` (``"loo"`` or ``"logo"``)."""
        return self.loo_rmse if kind == "loo" else self.logo_rmse

    def param_dict(self) -> dict:
        return {n: float(v) for n, v in zip(self.model.param_names, self.params)}


def aicc(rss, n, k):
    """Corrected Akaike information criterion of a least-squares fit (``k`` fitted parameters)."""
    k = k + 1  # the noise variance
    rss = max(float(rss), 1e-300)
    base = n * math.log(rss / n) + 2 * k
    return base + (2 * k * (k + 1) / (n - k - 1) if n - k - 1 > 0 else math.inf)


class _Transform:
    """Maps unbounded variables ``y`` to parameters inside their bounds (and back).

    ``(lo, hi)``: ``lo + (hi - lo) sigmoid(y)``; ``(lo, inf)``: ``lo + exp(y)``; parameters
    in ``_LOG_PARAMS`` are mapped on a log scale. A fit in ``y`` runs unconstrained and
    can never leave the physical range.
    """

    def __init__(self, model, lo, hi):
        self.log = np.array([n in _LOG_PARAMS for n in model.param_names])
        self.lo = np.where(self.log, np.log(np.where(self.log, lo, 1.0)), lo)
        self.hi = np.where(self.log, np.log(np.where(self.log, hi, 1.0)), hi)
        self.finite = np.isfinite(self.hi)

    def external(self, y):
        """Parameters of unbounded variables ``y`` (first axis: the parameters; complex allowed)."""
        x = np.empty_like(y)
        for i in range(len(self.lo)):
            yi = y[i]
            if self.finite[i]:
                yi = np.clip(yi.real, -300.0, 300.0) + (1j * yi.imag if np.iscomplexobj(yi) else 0.0)
                xi = self.lo[i] + (self.hi[i] - self.lo[i]) / (1.0 + np.exp(-yi))
            else:
                yi = np.minimum(yi.real, 300.0) + (1j * yi.imag if np.iscomplexobj(yi) else 0.0)
                xi = self.lo[i] + np.exp(yi)
            x[i] = np.exp(xi) if self.log[i] else xi
        return x

    def internal(self, x):
        x = np.asarray(x, float)
        x = np.where(self.log, np.log(np.where(self.log, x, 1.0)), x)
        span = np.where(self.finite, self.hi - self.lo, 1.0)
        u = np.clip((x - self.lo) / span, 1e-9, 1 - 1e-9)
        return np.where(self.finite, np.log(u / (1 - u)), np.log(np.maximum(x - self.lo, 1e-12)))


def _lm(model, tr, Y, L, d, h, alpha, W, max_iter=200, tol=1e-12):
    """Levenberg-Marquardt on a batch of weighted problems at once.

    Problem ``b`` minimises ``sum_i W[b, i] (model(y_b)_i - alpha_i)**2`` over the unbounded
    variables ``y_b`` (rows of ``Y``, shape ``(B, k)``); ``W`` is ``(B, n)`` (0/1 weights leave
    tests out). Derivatives by complex step; Marquardt's diagonal scaling; each problem keeps
    its own damping and stops when a step lowers its cost by less than ``tol`` relatively.

    Returns
    -------
    Y : (B, k) float array
    cost : (B,) float array
        Weighted residual sums of squares.
    """
    B, k = Y.shape
    sw = np.sqrt(W)
    eye = np.eye(k)
    hstep = 1e-20

    def residuals(Y):
        r = sw * (model.predict(tr.external(Y.T)[..., None], L, d, h) - alpha)
        return np.where(np.isfinite(r), r, 1e3)

    def jacobian(Y):
        Yc = Y[:, None, :] + 1j * hstep * eye[None]  # (B, k, k): row j perturbs variable j
        P = model.predict(tr.external(np.moveaxis(Yc, 2, 0))[..., None], L, d, h)  # (B, k, n)
        J = np.moveaxis(P.imag / hstep, 1, 2) * sw[:, :, None]  # (B, n, k)
        return np.where(np.isfinite(J), J, 0.0)

    r = residuals(Y)
    cost = np.einsum("bi,bi->b", r, r)
    mu = np.full(B, 1e-3)
    active = np.ones(B, bool)
    for _ in range(max_iter):
        if not active.any():
            break
        J = jacobian(Y)
        A = np.einsum("bik,bil->bkl", J, J)
        g = np.einsum("bik,bi->bk", J, r)
        diag = np.einsum("bkk->bk", A) + 1e-12
        step = -np.linalg.solve(A + (mu[:, None] * diag)[:, :, None] * eye, g[..., None])[..., 0]
        Yt = np.where(active[:, None], Y + step, Y)
        rt = residuals(Yt)
        ct = np.einsum("bi,bi->b", rt, rt)
        better = active & (ct < cost)
        gain = np.where(better, (cost - ct) / np.maximum(cost, 1e-300), 0.0)
        Y = np.where(better[:, None], Yt, Y)
        r = np.where(better[:, None], rt, r)
        cost = np.where(better, ct, cost)
        mu = np.where(better, np.maximum(mu / 3.0, 1e-12), np.minimum(mu * 4.0, 1e12))
        active &= ~((better & (gain < tol)) | (mu >= 1e12)
                    | (np.abs(step).max(axis=1) < 1e-12 * (1 + np.abs(Y).max(axis=1))))
    return Y, cost


def fit_params(model, L, d, h, alpha, starts=None, bounds=None):
    """Least-squares parameters of ``model`` for tests ``(L, d, h)`` [mm] and angles ``alpha`` [rad].

    All starts are iterated together (:func:`_lm`, inside the bounds by change of variable);
    the best is polished by ``scipy.optimize.least_squares`` (trust region reflective with the
    bounds), which also lands exactly on a bound where the optimum lies there.

    Parameters
    ----------
    starts : list of (k,) float arrays, optional
        Starting points; default :meth:`Model.starts`.
    bounds : (lo, hi), optional
        Default :meth:`Model.bounds` of the data.

    Returns
    -------
    params : (k,) float array
    rss : float
        Residual sum of squares [rad^2].
    success : bool
        Whether the polishing step reported convergence.
    """
    from scipy.optimize import least_squares

    L, d, h, alpha = (np.asarray(a, float) for a in (L, d, h, alpha))
    lo, hi = model.bounds(L, d, alpha) if bounds is None else bounds
    tr = _Transform(model, lo, hi)
    if starts is None:
        starts = model.starts(L, d, h, alpha)
    Y0 = np.array([tr.internal(x) for x in starts])
    Y, cost = _lm(model, tr, Y0, L, d, h, alpha, np.ones((len(Y0), alpha.size)))
    x0 = np.real(tr.external(Y[int(np.argmin(cost))])).astype(float)
    k = len(lo)
    hstep = 1e-20 * np.eye(k)

    def fun(x):
        r = model.predict(x, L, d, h) - alpha
        return np.where(np.isfinite(r), r, 1e3)

    def jac(x):
        J = model.predict((x[:, None] + 1j * hstep)[:, :, None], L, d, h).imag / 1e-20
        return np.where(np.isfinite(J), J, 0.0).T

    x0 = np.clip(x0, lo, hi)
    res = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                        xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=100)
    x = res.x if res.cost <= 0.5 * float(np.min(cost)) else x0
    rss = float(np.sum(fun(x) ** 2))
    return x, rss, bool(res.status > 0)


def evaluate(model, L, d, h, alpha, groups=None, starts=None):
    """Fit ``model`` and compute its RMSE, LOO (and LOGO) held-out errors and AICc.

    Held-out fits start from the full fit and keep the full data's bounds.

    Parameters
    ----------
    model : Model
    L, d, h, alpha : (n,) float arrays [mm, mm, mm, rad]
    groups : (n,) array, optional
        Group label of each test; enables leave-one-group-out when there are >= 2 groups.

    Returns
    -------
    EffectFit
    """
    L, d, h, alpha = (np.asarray(a, float) for a in (L, d, h, alpha))
    n = alpha.size
    lo, hi = model.bounds(L, d, alpha)
    tr = _Transform(model, lo, hi)
    x, rss, ok = fit_params(model, L, d, h, alpha, starts, bounds=(lo, hi))
    pred = model.predict(x, L, d, h)
    y = tr.internal(x)

    def held_out(masks):
        """Predictions of the tests left out by each mask row (True: left out)."""
        Y, _ = _lm(model, tr, np.repeat(y[None], len(masks), 0), L, d, h, alpha, (~masks).astype(float))
        P = model.predict(np.real(tr.external(Y.T))[..., None], L, d, h)  # (B, n)
        return (P * masks).sum(0)

    loo = held_out(np.eye(n, dtype=bool))
    logo = None
    if groups is not None and len(np.unique(groups)) >= 2:
        groups = np.asarray(groups)
        labels = np.unique(groups)
        masks = groups[None, :] == labels[:, None]
        logo = held_out(masks)
        small = (~masks).sum(1) <= model.n_params  # too few tests left to fit
        logo[masks[small].any(0)] = np.nan
    tol = 1e-6 * (1 + np.abs(x))
    at_bound = [nm for nm, v, a, b, t in zip(model.param_names, x, lo, hi, tol)
                if abs(v - a) <= t or abs(v - b) <= t]
    return EffectFit(
        model=model, params=x, predicted=pred, residuals=alpha - pred,
        rmse=float(np.sqrt(rss / n)), loo_predicted=loo,
        loo_rmse=float(np.sqrt(np.mean((alpha - loo) ** 2))),
        logo_predicted=logo,
        logo_rmse=None if logo is None else float(np.sqrt(np.nanmean((alpha - logo) ** 2))),
        aicc=aicc(rss, n, model.n_params), at_bound=at_bound, success=ok,
    )


#: Standard errors by which the best model with one more effect must beat the current choice:
#: one (the one-standard-error rule) to name an effect at all, two (about the 5 % level of a
#: one-sided paired test) to name a pair, of which ten are tried on as few as 18 tests.
STEP_SE = (1.0, 2.0)


def _paired(sq_a, sq_b):
    """Mean and standard error of the per-test difference of two held-out squared errors."""
    diff = sq_a - sq_b
    se = diff.std(ddof=1) / math.sqrt(diff.size) if diff.size > 1 else 0.0
    return float(diff.mean()), float(se)


def select(fits, alpha, kind="loo", step_se=STEP_SE):
    """The model to report, climbing from the baseline one effect at a time.

    Level 0 is the baseline, level 1 the single effects, level 2 the pairs. At each level the
    model with the smallest held-out mean squared error replaces the current choice only if
    it beats it by more than ``step_se[level - 1]`` standard errors of the paired per-test
    difference: a more complex model must earn its parameters on held-out data.

    Parameters
    ----------
    fits : list of EffectFit
        Must include the baseline (no effect).
    alpha : (n,) float array [rad]
        The measured angles.
    kind : {"loo", "logo"}
    step_se : (2,) float

    Returns
    -------
    best : EffectFit
    candidates : list of str
        Models whose held-out error is within one standard error of the chosen one's, or
        below it (the alternatives the data cannot rule out), best first.
    """
    alpha = np.asarray(alpha, float)
    sq = {f.name: (alpha - f.held_out(kind)) ** 2 for f in fits}
    ok = [f for f in fits if np.all(np.isfinite(sq[f.name]))]
    levels = {}
    for f in ok:
        levels.setdefault(len(f.model.effects), []).append(f)
    if 0 not in levels:
        raise GdfeError("fits: the baseline (no effect) must be among them with finite held-out errors")
    best = levels[0][0]
    for level in (1, 2):
        if level not in levels:
            continue
        top = min(levels[level], key=lambda f: sq[f.name].mean())
        mean, se = _paired(sq[top.name], sq[best.name])
        if mean < -step_se[level - 1] * se:
            best = top
    tiny = 1e-6 * float(sq[best.name].mean())  # models that coincide (an effect at zero) tie
    cands = [f for f in ok if (lambda m, s: m <= s + tiny)(*_paired(sq[f.name], sq[best.name]))]
    return best, [f.name for f in sorted(cands, key=lambda f: sq[f.name].mean())]
