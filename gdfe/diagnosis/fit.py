"""Least-squares fits of the effect models, their uncertainty, held-out errors and the choice.

Every model is fitted by (weighted) least squares from a grid of starts: Levenberg-Marquardt
iterated on all starts at once, each parameter held inside its physical bounds by a smooth
change of variable (logistic between two bounds, exponential above one; ``E_ratio`` and the
group scales on a log scale), then the best polished by ``scipy.optimize.least_squares``
with the bounds. With more than :data:`START_ROWS` tests the starts are iterated on a
seeded random subset of that many and only the polish sees every test, so the cost of a fit
grows linearly with the tests. Derivatives are by complex step (exact to rounding).

Uncertainty: from the Jacobian ``J`` of the predictions at the optimum, the covariance
``s^2 (J^T W J)^-1`` with ``s^2 = sum w r^2 / (n - k)``, standard errors and 95 %
t-intervals. A model whose column-scaled ``sqrt(W) J`` has a singular value below
:data:`RANK_TOL` times its largest cannot identify its parameters from the data (``lambda``
and ``K`` when every ``L`` is equal): it is marked and never chosen.

Held-out errors refit the model without the held-out tests, starting from the full fit and
keeping the full data's bounds:

* leave-one-out (LOO) for up to :data:`LOO_EXACT` tests, else :data:`FOLDS`-fold
  cross-validation (tests assigned to folds by a seeded permutation): each test predicted by
  the model fitted without it;
* leave-one-group-out (LOGO): each test predicted by the model fitted without its group
  (with more than :data:`FOLDS` groups, the groups are dealt into that many folds). A batch
  effect, whose scale of a group is only known from that group, has no LOGO error.

The information criterion is the corrected AIC of a least-squares fit with Gaussian errors,
``AICc = n ln(RSS / n) + 2k + 2k (k + 1) / (n - k - 1)`` with ``k`` the model's
parameters plus one for the noise variance.

Weights ``w`` (from per-test noise ``sigma_i``, ``w_i`` proportional to ``1 / sigma_i^2``,
mean 1) weight the fits and the held-out comparisons; without them every test weighs 1.
Angles in radians.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from gdfe._validation import GdfeError, describe
from gdfe.diagnosis.effects import Model

__all__ = ["EffectFit", "fit_params", "evaluate", "select", "compare", "mark_equal", "aicc", "robust_fit",
           "STEP_SE", "RANK_TOL", "EQUAL_TOL", "LOO_EXACT", "FOLDS", "START_ROWS"]

log = logging.getLogger(__name__)

#: Largest number of tests with exact leave-one-out refits; more get FOLDS-fold cross-validation.
LOO_EXACT = 250
#: Folds of the cross-validation (and of grouped folds when there are more groups).
FOLDS = 10
#: Tests the multi-start iterations see at most (a seeded random subset); the polish sees all.
START_ROWS = 2000
#: Relative singular value of the scaled Jacobian below which a parameter direction is not
#: identified by the data (about the square root of the machine epsilon: round-off).
RANK_TOL = 1e-7
#: RMS difference of fitted angles, relative to the RMS measured angle, below which a model's
#: predictions equal a simpler model's (an effect fitted to nothing).
EQUAL_TOL = 1e-6
#: Standard errors by which the best model with one more effect must beat the current choice:
#: one (the one-standard-error rule) to name an effect at all, two (about the 5 % level of a
#: one-sided paired test) to name a pair, of which many are tried on as few as 18 tests.
STEP_SE = (1.0, 2.0)


@dataclasses.dataclass
class EffectFit:
    """A fitted model, its uncertainty and its errors.

    Attributes
    ----------
    model : Model
    params : (k,) float array
        Least-squares parameters, in the order of ``model.param_names``.
    predicted, residuals : (n,) float arrays [rad]
        Fitted angles and measured minus fitted.
    rmse : float [rad]
    loo_predicted : (n,) float array [rad]
        Held-out predictions within the data: leave-one-out, or ``FOLDS``-fold
        cross-validation for more than ``LOO_EXACT`` tests (see :attr:`cv`).
    loo_rmse : float [rad]
    logo_predicted : (n,) float array or None [rad]
        Leave-one-group-out predictions (when groups are given; None for a batch effect).
    logo_rmse : float or None [rad]
    aicc : float
    at_bound : list of str
        Parameters that ended on a bound of their physical range (their errors assume an
        interior optimum: read them as the edge of what the range allows).
    success : bool
        Whether the optimiser reported convergence for the full fit.
    se : (k,) float array
        Standard errors of the parameters (inf where not identifiable).
    ci95 : (k, 2) float array
        95 % t-intervals ``params +- t se``.
    identifiable : bool
        Whether the data determine every parameter (see :data:`RANK_TOL`).
    unidentified : list of str
        Parameters in the directions the data do not determine.
    condition : float
        Largest over smallest singular value of the column-scaled Jacobian.
    equals : str or None
        The simpler model whose fitted angles this one's equal (see :data:`EQUAL_TOL`).
    cv : str
        ``"leave-one-out"`` or ``"10-fold"`` (what :attr:`loo_predicted` is).
    logo_scheme : str or None
        ``"leave-one-group-out"`` or ``"10 folds of groups"``.
    implausible : list of dict
        Parameters outside their physical range (:meth:`Model.implausible`: ``name``,
        ``value``, ``range``, ``unit``, ``why``); empty for a plausible fit.
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
    se: np.ndarray = None
    ci95: np.ndarray = None
    identifiable: bool = True
    unidentified: list = dataclasses.field(default_factory=list)
    condition: float = 1.0
    equals: str | None = None
    cv: str = "leave-one-out"
    logo_scheme: str | None = None
    implausible: list = dataclasses.field(default_factory=list)

    @property
    def plausible(self) -> bool:
        """Whether every parameter is inside its physical range (:mod:`gdfe.physical_ranges`)."""
        return not self.implausible

    @property
    def name(self) -> str:
        return self.model.name

    @property
    def usable(self) -> bool:
        """Whether this model may be chosen: identifiable, and not equal to a simpler one."""
        return self.identifiable and self.equals is None

    def held_out(self, kind="loo"):
        """Held-out predictions of ``kind`` (``"loo"`` or ``"logo"``)."""
        return self.loo_predicted if kind == "loo" else self.logo_predicted

    def held_out_rmse(self, kind="loo"):
        """Held-out RMSE [rad] of ``kind`` (``"loo"`` or ``"logo"``)."""
        return self.loo_rmse if kind == "loo" else self.logo_rmse

    def param_dict(self) -> dict:
        return {n: float(v) for n, v in zip(self.model.param_names, self.params)}

    def se_dict(self) -> dict:
        """Standard error of every parameter, by name."""
        return {n: float(v) for n, v in zip(self.model.param_names, self.se)}

    def ci_dict(self) -> dict:
        """95 % interval ``(lo, hi)`` of every parameter, by name."""
        return {n: (float(a), float(b)) for n, (a, b) in zip(self.model.param_names, self.ci95)}

    def parameters(self) -> list:
        """Every parameter as a dict: name, value, se, ci95, unit, meaning, at_bound."""
        out = []
        for p, v, s, ci in zip(self.model.parameters(), self.params, self.se, self.ci95):
            out.append({"name": p.name, "value": float(v), "se": _finite(s), "ci95": [_finite(c) for c in ci],
                        "unit": p.unit, "meaning": p.meaning, "at_bound": p.name in self.at_bound})
        return out


def _finite(v):
    return float(v) if np.isfinite(v) else None


def aicc(rss, n, k):
    """Corrected Akaike information criterion of a least-squares fit (``k`` fitted parameters)."""
    k = k + 1  # the noise variance
    rss = max(float(rss), 1e-300)
    base = n * math.log(rss / n) + 2 * k
    return base + (2 * k * (k + 1) / (n - k - 1) if n - k - 1 > 0 else math.inf)


@dataclasses.dataclass(frozen=True)
class _Data:
    """Tests as the fits use them: inputs, measured angles and weights (mean 1)."""

    L: np.ndarray
    d: np.ndarray
    h: np.ndarray
    alpha: np.ndarray
    x: np.ndarray | None
    g: np.ndarray | None
    w: np.ndarray

    @classmethod
    def of(cls, L, d, h, alpha, x=None, group=None, weights=None):
        L, d, h, alpha = (np.asarray(a, float) for a in (L, d, h, alpha))
        x = None if x is None else np.asarray(x, float)
        g = None if group is None else np.asarray(group, int)
        w = np.ones(alpha.size) if weights is None else np.asarray(weights, float)
        if w.shape != alpha.shape or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise GdfeError(f"weights: expected {alpha.size} positive finite weights, got {describe(w)}")
        return cls(L, d, h, alpha, x, g, w / w.mean())

    def subset(self, idx):
        pick = (lambda a: None if a is None else a[idx])
        return _Data(self.L[idx], self.d[idx], self.h[idx], self.alpha[idx], pick(self.x), pick(self.g),
                     self.w[idx])

    def predict(self, model, params):
        return model.predict(params, self.L, self.d, self.h, self.x, self.g)


_LOG_PARAMS = ("E_ratio",)


def _is_log(name):
    return name in _LOG_PARAMS or name.startswith("scale[")


class _Transform:
    """Maps unbounded variables ``y`` to parameters inside their bounds (and back).

    ``(lo, hi)``: ``lo + (hi - lo) sigmoid(y)``; ``(lo, inf)``: ``lo + exp(y)``; ``E_ratio``
    and group scales are mapped on a log scale. A fit in ``y`` runs unconstrained and can
    never leave the physical range.
    """

    def __init__(self, model, lo, hi):
        self.log = np.array([_is_log(n) for n in model.param_names], bool)
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


def _lm(model, tr, Y, data, W, max_iter=200, tol=1e-12):
    """Levenberg-Marquardt on a batch of weighted problems at once.

    Problem ``b`` minimises ``sum_i W[b, i] (model(y_b)_i - alpha_i)**2`` over the unbounded
    variables ``y_b`` (rows of ``Y``, shape ``(B, k)``); ``W`` is ``(B, n)`` (weights times
    0/1 masks that leave tests out). Derivatives by complex step; Marquardt's diagonal
    scaling; each problem keeps its own damping and stops when a step lowers its cost by
    less than ``tol`` relatively.

    Returns
    -------
    Y : (B, k) float array
    cost : (B,) float array
        Weighted residual sums of squares.
    """
    Y = np.array(Y, float)  # updated in place below: the caller's array is left as it was
    B, k = Y.shape
    sw = np.sqrt(W)
    eye = np.eye(k)
    hstep = 1e-20
    alpha = data.alpha

    def residuals(Y, sw):
        with np.errstate(all="ignore"):
            r = sw * (data.predict(model, tr.external(Y.T)[..., None]) - alpha)
        return np.where(np.isfinite(r), r, 1e3)

    def jacobian(Y, sw):
        Yc = Y[:, None, :] + 1j * hstep * eye[None]  # (B, k, k): row j perturbs variable j
        with np.errstate(all="ignore"):
            P = data.predict(model, tr.external(np.moveaxis(Yc, 2, 0))[..., None])  # (B, k, n)
        J = np.moveaxis(P.imag / hstep, 1, 2) * sw[:, :, None]  # (B, n, k)
        return np.where(np.isfinite(J), J, 0.0)

    r = residuals(Y, sw)
    cost = np.einsum("bi,bi->b", r, r)
    mu = np.full(B, 1e-3)
    active = np.ones(B, bool)
    for _ in range(max_iter):
        # only the problems still iterating are evaluated: the others keep their Y, r and cost
        a = np.flatnonzero(active)
        if a.size == 0:
            break
        Ya, ra, ca, mua = Y[a], r[a], cost[a], mu[a]
        J = jacobian(Ya, sw[a])
        A = np.einsum("bik,bil->bkl", J, J)
        g = np.einsum("bik,bi->bk", J, ra)
        diag = np.einsum("bkk->bk", A) + 1e-12
        step = -np.linalg.solve(A + (mua[:, None] * diag)[:, :, None] * eye, g[..., None])[..., 0]
        Yt = Ya + step
        rt = residuals(Yt, sw[a])
        ct = np.einsum("bi,bi->b", rt, rt)
        better = ct < ca
        gain = np.where(better, (ca - ct) / np.maximum(ca, 1e-300), 0.0)
        Ya = np.where(better[:, None], Yt, Ya)
        Y[a], r[a], cost[a] = Ya, np.where(better[:, None], rt, ra), np.where(better, ct, ca)
        mu[a] = np.where(better, np.maximum(mua / 3.0, 1e-12), np.minimum(mua * 4.0, 1e12))
        active[a] = ~((better & (gain < tol)) | (mu[a] >= 1e12)
                      | (np.abs(step).max(axis=1) < 1e-12 * (1 + np.abs(Ya).max(axis=1))))
    return Y, cost


def _jacobian(model, params, data):
    """(n, k) derivatives of the predictions with respect to the parameters (complex step)."""
    k = len(params)
    P = data.predict(model, (np.asarray(params, float)[:, None] + 1j * 1e-20 * np.eye(k))[:, :, None])
    J = (P.imag / 1e-20).T
    return np.where(np.isfinite(J), J, 0.0)


def _fit(model, data, starts, bounds):
    from scipy.optimize import least_squares

    lo, hi = bounds
    tr = _Transform(model, lo, hi)
    n = data.alpha.size
    sub = data
    if n > START_ROWS:
        idx = np.sort(np.random.default_rng(0).choice(n, START_ROWS, replace=False))
        sub = data.subset(idx)
    Y0 = np.array([tr.internal(s) for s in starts])
    Y, cost = _lm(model, tr, Y0, sub, np.broadcast_to(sub.w, (len(Y0), sub.alpha.size)))
    x0 = np.real(tr.external(Y[int(np.argmin(cost))])).astype(float)
    sw = np.sqrt(data.w)

    def fun(x):
        with np.errstate(all="ignore"):
            r = sw * (data.predict(model, x) - data.alpha)
        return np.where(np.isfinite(r), r, 1e3)

    def jac(x):
        with np.errstate(all="ignore"):
            return sw[:, None] * _jacobian(model, x, data)

    x0 = np.clip(x0, lo, hi)
    cost0 = 0.5 * float(np.sum(fun(x0) ** 2))
    res = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                        xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=100)
    x = res.x if res.cost <= cost0 else x0
    rss = float(np.sum(fun(x) ** 2))
    return x, rss, bool(res.status > 0)


def fit_params(model, L, d, h, alpha, starts=None, bounds=None, *, x=None, group=None, weights=None):
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
    x : (n,) float array, optional
        The process column (``partial_activation``).
    group : (n,) int array, optional
        Group index of each test (``batch``).
    weights : (n,) float array, optional
        Positive weights (normalised to mean 1).

    Returns
    -------
    params : (k,) float array
    rss : float
        Weighted residual sum of squares [rad^2] (the plain one without weights).
    success : bool
        Whether the polishing step reported convergence.
    """
    data = _Data.of(L, d, h, alpha, x, group, weights)
    lo, hi = model.bounds(data.L, data.d, data.alpha, data.x) if bounds is None else bounds
    if starts is None:
        starts = model.starts(data.L, data.d, data.h, data.alpha, data.x, data.g, data.w)
    return _fit(model, data, starts, (lo, hi))


def _uncertainty(model, params, data, residuals):
    """Standard errors, 95 % intervals, identifiability and condition at the optimum."""
    from scipy import stats

    n, k = data.alpha.size, len(params)
    J = np.sqrt(data.w)[:, None] * _jacobian(model, params, data)
    norms = np.linalg.norm(J, axis=0)
    zero = norms <= 1e-14 * max(float(norms.max()), 1e-300)
    Js = J / np.where(zero, 1.0, norms)
    Js[:, zero] = 0.0
    _, sv, Vt = np.linalg.svd(Js, full_matrices=False)
    rel = sv / sv[0] if sv[0] > 0 else np.zeros_like(sv)
    weak = rel < RANK_TOL
    names = model.param_names
    unident = set(np.array(names)[zero])
    for v in Vt[weak]:
        unident |= {names[i] for i in np.nonzero(np.abs(v) > 0.2)[0]}
    dof = n - k
    s2 = float(np.sum(data.w * residuals**2)) / dof if dof > 0 else np.nan
    se = np.full(k, np.inf)
    if not unident and dof > 0:
        cov = s2 * np.linalg.pinv(J.T @ J)
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    t = float(stats.t.ppf(0.975, dof)) if dof > 0 else np.inf
    ci = np.column_stack([params - t * se, params + t * se])
    cond = float(1.0 / rel[-1]) if rel[-1] > 0 else np.inf
    return se, ci, not unident, sorted(unident, key=names.index), cond


def _folds(n, n_folds=FOLDS, seed=0):
    """Fold of every test: a seeded permutation dealt into ``n_folds``."""
    f = np.empty(n, int)
    f[np.random.default_rng(seed).permutation(n)] = np.arange(n) % n_folds
    return f


def evaluate(model, L, d, h, alpha, groups=None, starts=None, *, x=None, group=None, weights=None):
    """Fit ``model`` and compute its uncertainty, held-out errors (LOO or k-fold, and LOGO)
    and AICc.

    Held-out fits start from the full fit and keep the full data's bounds.

    Parameters
    ----------
    model : Model
    L, d, h, alpha : (n,) float arrays [mm, mm, mm, rad]
    groups : (n,) array, optional
        Group label of each test; enables leave-one-group-out when there are >= 2 groups
        (not for a model with a batch effect).
    x : (n,) float array, optional
        The process column of ``partial_activation``.
    group : (n,) int array, optional
        The batch effect's group index of each test (:meth:`Model.group_index`).
    weights : (n,) float array, optional
        Positive weights, ``1 / sigma_i^2`` up to a factor.

    Returns
    -------
    EffectFit
    """
    data = _Data.of(L, d, h, alpha, x, group, weights)
    n = data.alpha.size
    lo, hi = model.bounds(data.L, data.d, data.alpha, data.x)
    tr = _Transform(model, lo, hi)
    if starts is None:
        starts = model.starts(data.L, data.d, data.h, data.alpha, data.x, data.g, data.w)
    params, rss, ok = _fit(model, data, starts, (lo, hi))
    pred = data.predict(model, params)
    res = data.alpha - pred
    se, ci, ident, unident, cond = _uncertainty(model, params, data, res)
    y = tr.internal(params)

    def held_out(masks):
        """Predictions of the tests left out by each mask row (True: left out)."""
        out = np.zeros(n)
        chunk = max(1, int(4e6 // (n * model.n_params)))
        for s in range(0, len(masks), chunk):
            m = masks[s:s + chunk]
            Y, _ = _lm(model, tr, np.repeat(y[None], len(m), 0), data, (~m) * data.w[None])
            with np.errstate(all="ignore"):
                P = data.predict(model, np.real(tr.external(Y.T))[..., None])  # (B, n)
            out += (P * m).sum(0)
        return out

    if n <= LOO_EXACT:
        cv = "leave-one-out"
        loo = held_out(np.eye(n, dtype=bool))
    else:
        cv = f"{FOLDS}-fold"
        f = _folds(n)
        loo = held_out(f[None, :] == np.arange(FOLDS)[:, None])
    logo, scheme = None, None
    if groups is not None and len(np.unique(groups)) >= 2 and "batch" not in model.effects:
        groups = np.asarray(groups)
        labels, inv = np.unique(groups, return_inverse=True)
        if labels.size > FOLDS:
            scheme = f"{FOLDS} folds of groups"
            inv = _folds(labels.size)[inv]
        else:
            scheme = "leave-one-group-out"
        masks = inv[None, :] == np.arange(inv.max() + 1)[:, None]
        logo = held_out(masks)
        small = (~masks).sum(1) <= model.n_params  # too few tests left to fit
        logo[masks[small].any(0)] = np.nan
    tol = 1e-6 * (1 + np.abs(params))
    at_bound = [nm for nm, v, a, b, t in zip(model.param_names, params, lo, hi, tol)
                if abs(v - a) <= t or abs(v - b) <= t]
    return EffectFit(
        model=model, params=params, predicted=pred, residuals=res,
        rmse=float(np.sqrt(np.mean(res**2))), loo_predicted=loo,
        loo_rmse=float(np.sqrt(np.mean((data.alpha - loo) ** 2))),
        logo_predicted=logo,
        logo_rmse=None if logo is None else float(np.sqrt(np.nanmean((data.alpha - logo) ** 2))),
        aicc=aicc(rss, n, model.n_params), at_bound=at_bound, success=ok,
        se=se, ci95=ci, identifiable=ident, unidentified=unident, condition=cond, cv=cv,
        logo_scheme=scheme, implausible=_implausible(model, params, data, se),
    )


def _implausible(model, params, data, se):
    """:meth:`Model.implausible` of a fit (with its standard errors when the model's check takes them)."""
    import inspect

    check = getattr(model, "implausible", None)
    if check is None:
        return []
    if "se" in inspect.signature(check).parameters:
        return check(params, data.L, data.d, data.h, data.x, data.g, se=se)
    return check(params, data.L, data.d, data.h, data.x, data.g)


def robust_fit(fit, L, d, h, alpha, scale, *, x=None, group=None, loss="soft_l1"):
    """Refit ``fit``'s model with a robust loss, so that gross outliers do not pull it.

    ``scipy.optimize.least_squares`` with ``loss`` on the residuals in units of ``scale``
    (``soft_l1``: quadratic within one unit, linear beyond), from the least-squares
    parameters and inside the model's bounds.

    Parameters
    ----------
    fit : EffectFit
    L, d, h, alpha : (n,) float arrays [mm, mm, mm, rad]
    scale : (n,) float array [rad]
        The noise of each test (or a robust estimate of it).
    x, group : (n,) arrays, optional
        As in :func:`evaluate`.
    loss : str

    Returns
    -------
    params : (k,) float array
    residuals : (n,) float array [rad]
        Measured minus robustly fitted angles.
    """
    from scipy.optimize import least_squares

    data = _Data.of(L, d, h, alpha, x, group)
    model = fit.model
    lo, hi = model.bounds(data.L, data.d, data.alpha, data.x)
    scale = np.broadcast_to(np.asarray(scale, float), data.alpha.shape)

    def fun(p):
        with np.errstate(all="ignore"):
            r = (data.predict(model, p) - data.alpha) / scale
        return np.where(np.isfinite(r), r, 1e3)

    def jac(p):
        with np.errstate(all="ignore"):
            return _jacobian(model, p, data) / scale[:, None]

    x0 = np.clip(np.asarray(fit.params, float), lo, hi)
    res = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", loss=loss, f_scale=1.0,
                        x_scale="jac", max_nfev=200)
    return res.x, data.alpha - data.predict(model, res.x)


def mark_equal(fits, alpha, tol=EQUAL_TOL):
    """Set ``equals`` of every fit whose fitted angles equal those of a fitted model with one
    effect fewer, to within ``tol`` times the RMS measured angle. Returns ``fits``."""
    alpha = np.asarray(alpha, float)
    scale = float(np.sqrt(np.mean(alpha**2))) or 1.0
    by_model = {f.model: f for f in fits}
    for f in sorted(fits, key=lambda f: f.model.level):
        for e in f.model.effects:
            sub = by_model.get(f.model.without(e))
            if sub is None:
                continue
            diff = float(np.sqrt(np.mean((f.predicted - sub.predicted) ** 2)))
            if diff <= tol * scale:
                f.equals = sub.equals or sub.name
                break
    return fits


def _paired(sq_a, sq_b):
    """Mean and standard error of the per-test difference of two held-out squared errors."""
    diff = sq_a - sq_b
    se = diff.std(ddof=1) / math.sqrt(diff.size) if diff.size > 1 else 0.0
    return float(diff.mean()), float(se)


def _sq(fit, alpha, kind, weights):
    w = 1.0 if weights is None else np.asarray(weights, float) / np.mean(weights)
    return w * (alpha - fit.held_out(kind)) ** 2


def compare(new, current, alpha, kind="loo", step=1.0, weights=None):
    """Whether ``new`` beats ``current`` on held-out error by more than ``step`` standard errors
    of the paired per-test difference (and by more than round-off).

    Returns
    -------
    better : bool
    mean, se : float
        Mean and standard error of the paired difference of (weighted) held-out squared errors
        [rad^2], negative where ``new`` is better.
    """
    alpha = np.asarray(alpha, float)
    a, b = _sq(new, alpha, kind, weights), _sq(current, alpha, kind, weights)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return False, math.nan, math.nan
    mean, se = _paired(a, b)
    tiny = 1e-9 * float(b.mean()) + 1e-300
    return bool(new.usable and mean < -step * se and mean < -tiny), mean, se


def select(fits, alpha, kind="loo", step_se=STEP_SE, weights=None):
    """The model to report, climbing from the baseline one effect at a time.

    Level 0 is the baseline, level 1 the single effects, level 2 the pairs. At each level the
    usable model (identifiable, not equal to a simpler one, see :attr:`EffectFit.usable`)
    with the smallest held-out mean squared error replaces the current choice only if it beats
    it by more than ``step_se[level - 1]`` standard errors of the paired per-test difference,
    and by more than round-off: a more complex model must earn its parameters on held-out
    data. Models whose held-out errors tie (to 1e-9 relatively) are ranked by their number of
    parameters, the simpler first. Models with a batch effect are not ranked here (they have
    no leave-one-group-out error; the diagnosis adds them in a step of their own).

    Parameters
    ----------
    fits : list of EffectFit
        Must include the baseline (no effect).
    alpha : (n,) float array [rad]
        The measured angles.
    kind : {"loo", "logo"}
    step_se : (2,) float
    weights : (n,) float array, optional
        Weights of the held-out squared errors (``1 / sigma_i^2`` up to a factor).

    Returns
    -------
    best : EffectFit
    candidates : list of str
        Usable models whose held-out error is within one standard error of the chosen one's,
        or below it (the alternatives the data cannot rule out), best first.
    """
    alpha = np.asarray(alpha, float)
    sq = {f.name: _sq(f, alpha, kind, weights) for f in fits if f.held_out(kind) is not None}
    ok = [f for f in fits if f.name in sq and np.all(np.isfinite(sq[f.name]))]
    base = [f for f in ok if not f.model.effects]
    if not base:
        raise GdfeError("fits: the baseline (no effect) must be among them with finite held-out errors")
    best = base[0]
    ok = [f for f in ok if f.usable and "batch" not in f.model.effects]

    def rank(f):
        m = float(sq[f.name].mean())
        return (round(m / (float(sq[best.name].mean()) + 1e-300), 9), f.model.n_params)

    for level in (1, 2):
        tier = [f for f in ok if f.model.level == level]
        if not tier:
            continue
        top = min(tier, key=rank)
        better, _, _ = compare(top, best, alpha, kind, step_se[level - 1], weights)
        if better:
            best = top
    tiny = 1e-6 * float(sq[best.name].mean())
    cands = [f for f in ok + ([best] if best not in ok else [])
             if _paired(sq[f.name], sq[best.name])[0] <= _paired(sq[f.name], sq[best.name])[1] + tiny]
    return best, [f.name for f in sorted(cands, key=lambda f: sq[f.name].mean())]
