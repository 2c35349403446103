"""Fit the FEM's free parameters (``E_passive / E_active`` and the eigenstrain) to folding tests.

The linear hinge model's fold angle is exactly proportional to the eigenstrain,
``alpha_i = -eps* a_i(n)``, where ``a_i(n)`` is the angle per unit contraction of test ``i`` at
modulus ratio ``n = E_passive / E_active``. So for every ``n`` the best ``eps*`` is a closed-form
least-squares slope, and the fit is a one-dimensional search over ``log n``:

1. ``a_i(n)`` is computed on a grid of ratios (one linear FEM solve per test and ratio; or the
   Timoshenko formula ``a_i = kappa_T L_i`` for ``model="timoshenko"``),
2. interpolated in ``log n`` by a cubic spline per test,
3. the residual sum of squares, minimised over ``eps*`` in closed form, is minimised over ``log n``
   within the grid.

``eps*`` is bounded below by :data:`EIGENSTRAIN_FLOOR` (a film that contracts by 100 % vanishes): a
fit that stops there is flagged ``at_bound``, as one at the edge of the grid of ratios. A fit outside
the film's free shrink ``[-MAX_CONTRACTION, 0]`` (:mod:`gdfe.physical_ranges`), at the bound or not,
is warned of: the tests ask for a contraction that no film has (lengths in micrometres rather than
mm, a misread column).

Leave-one-out: each test is predicted by the parameters fitted to the other tests; the
leave-one-out RMSE is the root-mean-square of those prediction errors.

Angles in radians, lengths in mm.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np

from gdfe import _validation as v
from gdfe._validation import GdfeError
from gdfe.physical_ranges import MAX_CONTRACTION, RANGES, looks_like_micrometres
from .material import BilayerMaterial
from gdfe.timoshenko import timoshenko_curvature

__all__ = ["TableFit", "unit_angles", "fit_to_table", "DEFAULT_RATIOS"]

log = logging.getLogger(__name__)

#: Modulus ratios ``E_passive / E_active`` at which the hinge angles are computed.
DEFAULT_RATIOS = tuple(float(r) for r in np.geomspace(0.1, 100.0, 13))
_PROBE = -0.1  # eigenstrain of the linear solves (the angle is scaled to a unit contraction)
#: The lower bound of the fitted eigenstrain: a film that contracts by 100 % would vanish.
EIGENSTRAIN_FLOOR = -0.999


@dataclasses.dataclass
class TableFit:
    """Result of :func:`fit_to_table`.

    Attributes
    ----------
    model : str
        ``"fem"`` (linear hinge FEM) or ``"timoshenko"`` (``alpha = kappa_T L``).
    E_ratio : float
        Fitted ``E_passive / E_active``.
    eigenstrain : float
        Fitted free in-plane contraction of the film (< 0).
    rmse, loo_rmse : float [rad]
        Root-mean-square error of the fit, and of the leave-one-out predictions.
    r2 : float
        Coefficient of determination of the fit.
    at_bound : bool
        True when a parameter stopped at a bound of its fit: :attr:`E_ratio_at_bound` or
        :attr:`eigenstrain_at_bound`.
    E_ratio_at_bound : bool
        The best ratio is at the edge of the searched grid.
    eigenstrain_at_bound : bool
        The best eigenstrain is :data:`EIGENSTRAIN_FLOOR`, the bound of its fit.
    L, d, h, measured, predicted, loo_predicted : (n,) float arrays
        The tests [mm, mm, mm, rad] and the fitted / left-out predictions [rad].
    loo_params : (n, 2) float array
        ``(E_ratio, eigenstrain)`` fitted without each test.
    ratios, profile_rmse : (k,) float arrays
        The grid of ratios and the RMSE with the best eigenstrain at each.
    seconds : float
        Time spent [s].
    """

    model: str
    E_ratio: float
    eigenstrain: float
    rmse: float
    loo_rmse: float
    r2: float
    at_bound: bool
    L: np.ndarray
    d: np.ndarray
    h: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    loo_predicted: np.ndarray
    loo_params: np.ndarray
    ratios: np.ndarray
    profile_rmse: np.ndarray
    seconds: float
    settings: dict = dataclasses.field(default_factory=dict)
    E_ratio_at_bound: bool = False
    eigenstrain_at_bound: bool = False

    def material(self) -> BilayerMaterial:
        """The fitted :class:`BilayerMaterial` (Poisson's ratio as used in the fit)."""
        return BilayerMaterial.from_ratio(self.E_ratio, self.eigenstrain, nu=self.settings.get("nu", 0.35))

    def as_dict(self) -> dict:
        return {"model": self.model, "E_ratio": self.E_ratio, "eigenstrain": self.eigenstrain,
                "rmse_rad": self.rmse, "loo_rmse_rad": self.loo_rmse, "r2": self.r2,
                "at_bound": self.at_bound, "n_tests": int(self.L.size),
                "tests": [{"L_mm": a, "d_mm": b, "h_mm": c, "alpha_rad": m, "fit_rad": p,
                           "loo_rad": q}
                          for a, b, c, m, p, q in zip(self.L.tolist(), self.d.tolist(),
                                                      self.h.tolist(), self.measured.tolist(),
                                                      self.predicted.tolist(),
                                                      self.loo_predicted.tolist())],
                "loo_params": self.loo_params.tolist(),
                "profile": {"E_ratio": self.ratios.tolist(), "rmse_rad": self.profile_rmse.tolist()},
                "seconds": self.seconds, "settings": self.settings}


def _arrays(L, d, h, alpha=None):
    arrs = [np.atleast_1d(np.asarray(a, dtype=float)) for a in (L, d, h)]
    n = max(a.size for a in arrs)
    arrs = [np.broadcast_to(a, (n,)).copy() for a in arrs]
    for name, a in zip(("L", "d", "h"), arrs):
        if not np.all(np.isfinite(a)) or np.any(a <= 0):
            raise GdfeError(f"{name}: expected positive lengths in mm, got {a.tolist()}")
    if alpha is not None:
        al = np.atleast_1d(np.asarray(alpha, dtype=float))
        if al.shape != (n,) or not np.all(np.isfinite(al)):
            raise GdfeError(f"alpha: expected {n} finite angles in rad, got {al.tolist()}")
        arrs.append(al)
    return arrs


def unit_angles(L, d, h, ratios=DEFAULT_RATIOS, *, model="fem", nu=0.35, width=1.0,
                resolution="default", progress=False):
    """Fold angle per unit film contraction of each test at each modulus ratio.

    Parameters
    ----------
    L, d, h : (n,) float arrays [mm]
        Hinge width, coat and film thickness of each test.
    ratios : (k,) float array
        ``E_passive / E_active`` values.
    model : {"fem", "timoshenko"}
        Linear hinge FEM (:func:`~reference_fem.hinge_mesh` + :func:`~reference_fem.solve_linear`)
        or ``kappa_T L`` with Timoshenko's beam curvature.
    nu : float
        Poisson's ratio of both layers (FEM only; Timoshenko's beam formula has none).
    width : float [mm]
        Hinge width along the fold line (FEM only).
    resolution : {"coarse", "default", "fine"}
        Mesh preset (FEM only).
    progress : bool
        Show a progress bar.

    Returns
    -------
    (n, k) float array [rad]
        ``-alpha / eps*`` (positive: folds towards the free face).
    """
    L, d, h = _arrays(L, d, h)
    ratios = np.asarray(ratios, dtype=float)
    if ratios.ndim != 1 or ratios.size < 1 or np.any(~(ratios > 0)):
        raise GdfeError(f"ratios: expected positive E_passive/E_active values, got {ratios.tolist()}")
    v.check_choice("model", model, {"fem", "timoshenko"})
    if model == "timoshenko":
        return np.stack([timoshenko_curvature(h, d, 1.0, r, -0.5) * L / 0.5 for r in ratios],
                        axis=1)
    from gdfe.parallel import parallel_map

    jobs = [(i, float(L[i]), float(d[i]), float(h[i]), tuple(ratios.tolist()), nu, width, resolution)
            for i in range(L.size)]
    rows = parallel_map(_unit_row, jobs, desc="linear hinge solves", progress=progress)
    return np.array(rows).reshape(L.size, ratios.size)


def _unit_row(job):
    """One test's unit angles at every modulus ratio (one mesh, one linear solve per ratio)."""
    from .measure import fold_angle
    from .mesh import hinge_mesh
    from .solve import solve_linear

    i, L, d, h, ratios, nu, width, resolution = job
    strip = hinge_mesh(L, d, h, width=width, resolution=resolution)
    row = []
    for r in ratios:
        res = solve_linear(strip, BilayerMaterial.from_ratio(r, _PROBE, nu=nu))
        if not res.converged:
            raise RuntimeError(f"linear solve failed for test {i} at E_ratio {r}")
        row.append(fold_angle(res) / -_PROBE)
    return row


def _best_eps(a, alpha):
    """Least-squares eigenstrain for unit angles ``a`` and measured ``alpha``, at least
    :data:`EIGENSTRAIN_FLOOR`; returns (eps, rss)."""
    s = -(a @ alpha) / (a @ a)
    s = max(s, EIGENSTRAIN_FLOOR)
    r = alpha + s * a
    return s, float(r @ r)


def _fit_rows(logr, spline, alpha, rows):
    from scipy.optimize import minimize_scalar

    def rss(x):
        return _best_eps(spline(x)[rows], alpha[rows])[1]

    grid = np.array([rss(x) for x in logr])
    k = int(np.argmin(grid))
    lo, hi = logr[max(k - 1, 0)], logr[min(k + 1, logr.size - 1)]
    if lo == hi:
        x = lo
    else:
        x = minimize_scalar(rss, bounds=(lo, hi), method="bounded",
                            options={"xatol": 1e-6}).x
    eps = _best_eps(spline(x)[rows], alpha[rows])[0]
    ratio_at_bound = bool(np.isclose(x, logr[0], atol=1e-3) or np.isclose(x, logr[-1], atol=1e-3))
    return float(x), float(eps), (ratio_at_bound, bool(eps <= EIGENSTRAIN_FLOOR)), grid


def fit_to_table(L, d, h, alpha, *, model="fem", ratios=DEFAULT_RATIOS, nu=0.35, width=1.0,
                 resolution="default", angles=None, progress=False) -> TableFit:
    """Least-squares fit of ``(E_passive / E_active, eps*)`` to measured fold angles.

    Parameters
    ----------
    L, d, h, alpha : (n,) float arrays
        Hinge width [mm], coat thickness [mm], film thickness [mm], measured fold angle [rad],
        e.g. the paper's Table 1 (``gdfe.load_folding_tests``).
    model : {"fem", "timoshenko"}
        See :func:`unit_angles`.
    ratios : (k,) float array
        Grid of ratios searched (the fit interpolates between them), k >= 4.
    nu, width, resolution
        FEM settings, see :func:`unit_angles`.
    angles : (n, k) float array, optional
        Precomputed :func:`unit_angles` (skips the solves).
    progress : bool
        Show a progress bar over the solves.

    Returns
    -------
    TableFit
    """
    from scipy.interpolate import CubicSpline

    t0 = time.perf_counter()
    L, d, h, alpha = _arrays(L, d, h, alpha)
    if L.size < 3:
        raise GdfeError(f"tests: expected at least 3 folding tests to fit two parameters, got {L.size}")
    ratios = np.asarray(ratios, dtype=float)
    if ratios.size < 4:
        raise GdfeError(f"ratios: expected at least 4 values, got {ratios.size}")
    A = (unit_angles(L, d, h, ratios, model=model, nu=nu, width=width, resolution=resolution,
                     progress=progress) if angles is None else np.asarray(angles, dtype=float))
    if A.shape != (L.size, ratios.size):
        raise GdfeError(f"angles: expected shape {(L.size, ratios.size)}, got {A.shape}")
    logr = np.log(ratios)
    spline = CubicSpline(logr, A, axis=1)
    rows = np.arange(L.size)
    x, eps, (ratio_at_bound, eps_at_bound), grid = _fit_rows(logr, spline, alpha, rows)
    _warn_eigenstrain(eps, eps_at_bound, d, h)
    pred = -eps * spline(x)
    loo = np.empty(L.size)
    loo_params = np.empty((L.size, 2))
    for i in range(L.size):
        xi, ei, _, _ = _fit_rows(logr, spline, alpha, np.delete(rows, i))
        loo[i] = -ei * spline(xi)[i]
        loo_params[i] = (np.exp(xi), ei)
    res = alpha - pred
    r2 = 1.0 - float(res @ res) / float(((alpha - alpha.mean()) ** 2).sum())
    return TableFit(model=model, E_ratio=float(np.exp(x)), eigenstrain=eps,
                    rmse=float(np.sqrt(np.mean(res**2))),
                    loo_rmse=float(np.sqrt(np.mean((alpha - loo) ** 2))), r2=r2,
                    at_bound=ratio_at_bound or eps_at_bound, L=L, d=d, h=h, measured=alpha, predicted=pred,
                    loo_predicted=loo, loo_params=loo_params, ratios=ratios,
                    profile_rmse=np.sqrt(grid / L.size), seconds=time.perf_counter() - t0,
                    settings={"nu": nu, "width_mm": width, "resolution": resolution,
                              "probe_eigenstrain": _PROBE},
                    E_ratio_at_bound=ratio_at_bound, eigenstrain_at_bound=eps_at_bound)


def _warn_eigenstrain(eps, at_bound, d, h):
    """Warn of a fitted eigenstrain outside the film's free shrink ``[-MAX_CONTRACTION, 0]`` (or at the
    bound of its fit), naming the thicknesses that look like micrometres."""
    if -MAX_CONTRACTION <= eps <= 0.0 and not at_bound:
        return
    stop = (f" stopped at the bound {EIGENSTRAIN_FLOOR:g} of its fit (a film that contracts by 100 % vanishes) and"
            if at_bound else "")
    big = [(name, float(a.max())) for name, a in (("d", d), ("h", h))]
    um = [f"{name}_mm up to {v:g}" for name, v in big if looks_like_micrometres(name, v)]
    hint = (f"; {' and '.join(um)} look like micrometres: lengths are in mm "
            f"({', '.join(f'{n} in [{RANGES[n].lo:g}, {RANGES[n].hi:g}] mm' for n, _ in big)})" if um else "")
    log.warning("eigenstrain = %.4g%s is outside the physical range [%g, 0] of the film's free shrink "
                "(pre-strained polystyrene shrinks in-plane by at most 50-60 %%): the fit uses it to absorb "
                "something else, and its E_ratio and eigenstrain describe no film%s", eps, stop, -MAX_CONTRACTION,
                hint)
