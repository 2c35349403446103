"""Readings of the paper's Eq. 1 fitted to folding tests (used by ``fig02`` and ``gdfe calibrate``).

Every reading says the fold angle grows in proportion to the hinge width ``L``, so Eq. 2
turns each into a contraction ratio ``R(d, h) = 1 - alpha h / L`` (a reading of Eq. 3):

==========  =============================  ==========================  ============================
model       fold angle                     parameters                  Eq. 3 reading
==========  =============================  ==========================  ============================
``eq1``     ``K sqrt(h/d^3) L`` (printed)  K (dimensionless)           ``1 - K (h/d)^1.5``
``eq1-d1``  ``K sqrt(h/d) L``              K [1/mm]                    ``1 - K h (h/d)^0.5``
``power``   ``c (L/h) (h/d)^p``            c (dimensionless), p        ``1 - c (h/d)^p``
==========  =============================  ==========================  ============================

``eq1`` and ``eq1-d1`` are fitted by least squares through the origin, ``power`` by least
squares in ``alpha`` (``c`` in closed form for each ``p``, ``p`` by a bounded 1-D search).
R² is reported about the mean (``r2``) and about zero (``r2_uncentered``). Confidence
intervals are 95 % percentile bootstraps over the tests.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

MODELS = ("eq1", "eq1-d1", "power")

DESCRIPTIONS = {
    "eq1": "alpha = K sqrt(h/d^3) L (Eq. 1 as printed)",
    "eq1-d1": "alpha = K sqrt(h/d) L (d to the first power)",
    "power": "alpha = c (L/h) (h/d)^p (exponent of d fitted)",
}


@dataclasses.dataclass
class ModelFit:
    """A fitted reading of Eq. 1.

    Attributes
    ----------
    model : str
    K : float
        ``K`` of ``eq1``/``eq1-d1``; ``c`` of ``power``.
    p : float
        Exponent of ``h/d`` (1.5 for ``eq1``, 0.5 for ``eq1-d1``, fitted for ``power``).
    r2, r2_uncentered, rmse : float
        Fit quality (rmse in rad).
    n : int
    K_ci, p_ci : (2,) tuples
        95 % bootstrap intervals (``p_ci`` equals ``(p, p)`` where p is fixed).
    residuals : (n,) float array [rad]
        Measured minus fitted.
    """

    model: str
    K: float
    p: float
    r2: float
    r2_uncentered: float
    rmse: float
    n: int
    K_ci: tuple
    p_ci: tuple
    residuals: np.ndarray

    @classmethod
    def reading(cls, model, K, p):
        """The reading ``model`` with given ``K`` and ``p`` and no fit behind it (fit fields empty)."""
        return cls(model=model, K=K, p=p, r2=np.nan, r2_uncentered=np.nan, rmse=np.nan, n=0,
                   K_ci=(K, K), p_ci=(p, p), residuals=np.zeros(0))

    def alpha(self, L, d, h):
        """Fold angle [rad] of this reading."""
        return self.slope(d, h) * np.asarray(L, float)

    def slope(self, d, h):
        """``alpha / L`` [rad/mm] of this reading."""
        d = np.asarray(d, float)
        h = np.asarray(h, float)
        if self.model == "eq1-d1":
            return self.K * np.sqrt(h / d)
        return self.K / h * (h / d) ** self.p

    def ratio(self, d, h):
        """Eq. 3 of this reading: ``R = 1 - alpha h / L`` (may be <= 0 for thin passive layers)."""
        return 1.0 - self.slope(d, h) * np.asarray(h, float)

    def d_min(self, h):
        """Passive thickness [mm] below which this reading's Eq. 3 gives R <= 0."""
        if self.model == "eq1-d1":
            return h * (self.K * h) ** 2
        return h * self.K ** (1.0 / self.p)

    def as_dict(self):
        return {"model": self.model, "description": DESCRIPTIONS[self.model], "K": self.K, "p": self.p,
                "K_ci95": list(self.K_ci), "p_ci95": list(self.p_ci), "r2": self.r2,
                "r2_uncentered": self.r2_uncentered, "rmse": self.rmse, "n": self.n,
                "residuals": np.asarray(self.residuals).tolist()}


def regressor(model, L, d, h):
    """Abscissa of a through-origin reading: ``sqrt(h/d^3) L`` (eq1) or ``sqrt(h/d) L`` (eq1-d1)."""
    L, d, h = (np.asarray(v, float) for v in (L, d, h))
    if model == "eq1":
        return np.sqrt(h / d**3) * L
    if model == "eq1-d1":
        return np.sqrt(h / d) * L
    raise ValueError(f"model: {model!r} has no single regressor; expected 'eq1' or 'eq1-d1'")


def quality(y, fitted):
    """R² about the mean, R² about zero, rmse and residuals of ``fitted`` against ``y``."""
    res = y - fitted
    ss = float(res @ res)
    return (1.0 - ss / float(((y - y.mean()) ** 2).sum()), 1.0 - ss / float(y @ y),
            math.sqrt(ss / y.size), res)


def _power_fit(x_over_h, q, y):
    """Least squares of ``y = c * x_over_h * q**p`` over c (closed form) and p (bounded search)."""
    from scipy.optimize import minimize_scalar

    lq = np.log(q)

    def sse(p):
        z = x_over_h * np.exp(p * lq)
        c = (z @ y) / (z @ z)
        r = y - c * z
        return r @ r

    opt = minimize_scalar(sse, bounds=(-2.0, 5.0), method="bounded", options={"xatol": 1e-8})
    p = float(opt.x)
    z = x_over_h * np.exp(p * lq)
    return float((z @ y) / (z @ z)), p


def fit(tests, model="eq1", n_boot=2000, seed=0):
    """Fit one reading of Eq. 1 to folding tests.

    Parameters
    ----------
    tests : gdfe.FoldingTests or str or Path
        The tests, or a CSV with columns ``L_mm, d_mm, h_mm, alpha_rad``.
    model : {"eq1", "eq1-d1", "power"}
    n_boot : int
        Bootstrap resamples (0: no interval).
    seed : int

    Returns
    -------
    ModelFit
    """
    import gdfe

    if model not in MODELS:
        raise ValueError(f"model: expected one of {', '.join(MODELS)}, got {model!r}")
    if not isinstance(tests, gdfe.FoldingTests):
        tests = gdfe.load_folding_tests(tests)
    L, d, h, y = tests.L, tests.d, tests.h, tests.alpha
    n = y.size
    if n < (3 if model == "power" else 2):
        raise ValueError(f"tests: need at least {3 if model == 'power' else 2} folding tests for {model}, got {n}")
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, n, size=(int(n_boot), n)) if n_boot else np.zeros((0, n), int)
    if model == "power":
        K, p = _power_fit(L / h, h / d, y)
        fitted = K * (L / h) * (h / d) ** p
        boots = np.array([_power_fit((L / h)[i], (h / d)[i], y[i]) for i in idx]).reshape(-1, 2)
        K_ci = tuple(np.percentile(boots[:, 0], [2.5, 97.5]).tolist()) if n_boot else (K, K)
        p_ci = tuple(np.percentile(boots[:, 1], [2.5, 97.5]).tolist()) if n_boot else (p, p)
    else:
        x = regressor(model, L, d, h)
        K = float(x @ y / (x @ x))
        p = 1.5 if model == "eq1" else 0.5
        fitted = K * x
        xb, yb = x[idx], y[idx]
        Kb = (xb * yb).sum(1) / (xb * xb).sum(1)
        K_ci = tuple(np.percentile(Kb, [2.5, 97.5]).tolist()) if n_boot else (K, K)
        p_ci = (p, p)
    r2, r2u, rmse, res = quality(y, fitted)
    return ModelFit(model=model, K=float(K), p=float(p), r2=r2, r2_uncentered=r2u, rmse=rmse, n=int(n),
                    K_ci=K_ci, p_ci=p_ci, residuals=res)


def format_fit(f):
    """Human-readable lines of a fit (``gdfe calibrate``)."""
    unit = " 1/mm" if f.model == "eq1-d1" else ""
    lines = [f"model  {f.model}: {DESCRIPTIONS[f.model]}",
             f"K      {f.K:.4f}{unit}  (95 % bootstrap CI {f.K_ci[0]:.4f} .. {f.K_ci[1]:.4f})"]
    if f.model == "power":
        lines.append(f"p      {f.p:.4f}  (95 % bootstrap CI {f.p_ci[0]:.4f} .. {f.p_ci[1]:.4f})")
    lines += [f"r2     {f.r2:.4f}  (about the mean; {f.r2_uncentered:.4f} about zero)",
              f"rmse   {f.rmse:.4f} rad", f"n      {f.n}"]
    return "\n".join(lines)
