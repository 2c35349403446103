"""The predictive content of a model file: parameter covariance, noise, and the weighted named set.

From a diagnosis (:func:`from_diagnosis`): every model of its named set
(:attr:`gdfe.diagnosis.Diagnosis.named`, the models the data cannot tell from the chosen one)
becomes a member of the model file, each with

* the covariance of its fitted parameters at the optimum, ``s^2 (J^T W J)^-1`` with ``J`` the
  derivatives of its predicted angles (complex step through the diagnosis's own closed form),
  ``W`` the tests' weights (mean 1) and ``s^2 = sum w r^2 / (n - k)``;
* the noise of a new test about it, with ``n - k`` degrees of freedom: the leave-one-out
  mean squared error less the parameters' mean share of it (``s^2 mean(h_ii)``, which each
  prediction adds back for its own specimen), never below ``s^2``. The residual scatter
  ``s`` alone understates the error of a model chosen among many on the same tests;
* its fitted reading offset where it has one (a measured angle is the fold plus it; the
  model of the part leaves it out, :meth:`gdfe.DeformationModel.from_effect_fit`);
* a weight by **stacking** of its leave-one-out predictive densities
  (:func:`gdfe.stacking.stacking_weights`; why stacking and not pseudo-BMA is said there).
  The leave-one-out density of test ``i`` under member ``k`` is Student's t with ``n - k``
  degrees of freedom about the member's leave-one-out prediction, with scale
  ``sqrt(noise^2 + s^2 h_ii)`` (``h_ii`` the leverage of the test: the parameters' share).

A calibration's model (:meth:`gdfe.DeformationModel.from_calibration`) carries its reading's
covariance and noise the same way. Angles in radians, lengths in mm.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from gdfe._validation import GdfeError, check_choice
from gdfe.model import WEIGHTINGS, DeformationModel, Member, Uncertainty
from gdfe.stacking import pseudo_bma_weights, stacking_weights

__all__ = ["from_diagnosis", "fit_uncertainty", "loo_log_density"]

log = logging.getLogger(__name__)


def _inputs(diag, fit):
    """The tests' inputs and weights as ``fit`` was fitted to them."""
    t = diag.tests
    cols = diag.columns
    x = cols.process[fit.model.process] if getattr(fit.model, "process", None) else None
    g = fit.model.group_index(cols.groups[fit.model.group]) if getattr(fit.model, "group", None) else None
    sigma = diag.noise.sigma if diag.noise is not None else None
    w = None
    if sigma is not None and np.size(sigma) == len(t) and np.ptp(sigma) > 0:
        w = 1.0 / np.asarray(sigma, float) ** 2
        w = w / w.mean()
    return t.L, t.d, t.h, x, g, (np.ones(len(t)) if w is None else w)


def _jacobian(fit, L, d, h, x, g):
    """(n, k) derivatives of ``fit``'s predicted angles in its parameters (complex step)."""
    p = np.asarray(fit.params, float)
    k = p.size
    P = fit.model.predict((p[:, None] + 1j * 1e-20 * np.eye(k))[:, :, None], L, d, h, x, g)
    J = np.asarray(P.imag / 1e-20).T
    if J.shape != (L.size, k) or not np.all(np.isfinite(J)):
        raise GdfeError(f"{fit.name}: the derivatives of its predictions are not finite at the fitted parameters")
    return J


def fit_uncertainty(fit, diag):
    """:class:`Uncertainty` of a fitted model of a diagnosis, and its parameters' variance at each test.

    Returns
    -------
    Uncertainty
    param_var : (n,) float array [rad^2]
        ``s^2 h_ii``, ``h_ii = w_i J_i (J^T W J)^-1 J_i^T`` the leverage of test ``i``.
    """
    L, d, h, x, g, w = _inputs(diag, fit)
    n = L.size
    if fit.residuals.size != n:
        raise GdfeError(f"{fit.name}: fitted to {fit.residuals.size} tests, the diagnosis has {n}")
    J = _jacobian(fit, L, d, h, x, g)
    k = J.shape[1]
    dof = n - k
    if dof < 1:
        raise GdfeError(f"{fit.name}: {k} parameters on {n} tests leave no degrees of freedom for the noise")
    s2 = float(np.sum(w * fit.residuals**2)) / dof
    A = np.linalg.pinv(J.T @ (w[:, None] * J))
    cov = s2 * A
    cov = 0.5 * (cov + cov.T)
    lev = w * np.einsum("ij,jk,ik->i", J, A, J)
    names = tuple(fit.model.param_names)
    offset = float(dict(zip(names, fit.params)).get("offset", 0.0))
    # the held-out scatter less the parameters' share of it (added back for each specimen), never
    # below the residual scatter: residuals understate the error of a model chosen among many
    held = float(np.mean(w * (diag.tests.alpha - fit.loo_predicted) ** 2))
    noise2 = max(s2, held - s2 * float(np.mean(lev))) if np.isfinite(held) else s2
    u = Uncertainty(names=names, covariance=cov, noise_rad=float(np.sqrt(noise2)), dof=dof, reading_offset_rad=offset,
                    noise_source=(f"held-out scatter less the parameters' share, max(RSS / (n - k), "
                                  f"MSE_held_out - mean(h_ii) RSS / (n - k)) with n = {n}, k = {k}"))
    return u, s2 * lev


def loo_log_density(fit, u, param_var, alpha):
    """Log leave-one-out predictive density of every test under ``fit`` (Student's t, see the module)."""
    from scipy import stats

    scale = np.sqrt(u.noise_rad**2 + np.clip(param_var, 0.0, None))
    return stats.t.logpdf((np.asarray(alpha, float) - fit.loo_predicted) / scale, u.dof) - np.log(scale)


def from_diagnosis(diag, fit=None, *, data=None, weighting="stacking", members=None):
    """The model file of a diagnosis: ``fit`` (default the chosen model) with its uncertainty, and,
    when it is the chosen model, every model of the named set weighted by held-out performance.

    Parameters
    ----------
    diag : gdfe.diagnosis.Diagnosis
    fit : EffectFit, optional
        A fitted model of the diagnosis to save (``gdfe diagnose --effect``): then it alone,
        unless it is among the named set.
    data : path, optional
        The CSV the diagnosis read (its name and sha256 go into the model).
    weighting : {"stacking", "pseudo-bma"}
    members : list of EffectFit, optional
        The fits to weigh instead of the named set (``fit`` among them).

    Returns
    -------
    DeformationModel
    """
    check_choice("weighting", weighting, [w for w in WEIGHTINGS if w != "single"])
    fit = diag.best if fit is None else fit
    named = [f for f in (members or diag.named or [diag.best]) if _is_hinge_model(f)]
    if fit not in named:
        named = [fit] if members is None else [fit] + named
    n = len(diag.tests)
    models, logd, kept = [], [], []
    for f in named:
        kind = diag.held_out if f.held_out_rmse(diag.held_out) is not None else "loo"
        m = DeformationModel.from_effect_fit(f, data=data, n_tests=n, held_out=kind)
        try:
            u, par = fit_uncertainty(f, diag)
        except GdfeError as exc:  # too few tests for its noise: the model without predictive content
            if f is not fit:
                log.warning("%s left out of the named set's predictions: %s", f.name, exc)
                continue
            return dataclasses.replace(m, warnings=m.warnings + (f"no predictive content: {exc}",))
        models.append(dataclasses.replace(m, uncertainty=u))
        logd.append(loo_log_density(f, u, par, diag.tests.alpha))
        kept.append(f)
    top = models[kept.index(fit)]
    if len(models) == 1:
        return top
    lp = np.column_stack(logd)
    w = stacking_weights(lp) if weighting == "stacking" else pseudo_bma_weights(lp)
    w = np.where(w < 1e-9, 0.0, w)
    w = w / w.sum()
    members = tuple(Member(float(wk), m) for wk, m in zip(w, models))
    log.info("named set weighted by %s: %s", weighting,
             ", ".join(f"{m.model.name} {m.weight:.3f}" for m in members))
    return dataclasses.replace(top, ensemble=members, weighting=weighting)


def _is_hinge_model(fit):
    """Whether ``fit`` is a model of the GDFE hinge (the catalogue's), not another baseline form."""
    return hasattr(fit.model, "effects") and hasattr(fit.model, "process")
