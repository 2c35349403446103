"""GDFE simulations of folding tests with the catalogue's effects built into the simulation.

Each effect enters the simulated specimen (:func:`gdfe.hinge`) physically, not through the
closed form the diagnoser fits:

``cure_depth``
    the hinge's contraction ratio comes from the deformation principle at the cured
    thickness ``d + delta``;
``hinge_length``
    the meshed hinge is ``L + lambda`` wide;
``passive_stiffness``
    the contraction ratio comes from Timoshenko's bilayer curvature, ``R = 1 - h kappa``;
``film_thickening``
    the film is meshed at its thickness after shrinking, ``h (1 + beta (1 - R))``;
``saturation``
    the contraction is applied over time, and the rate at which the free face contracts
    falls with the fold already reached, ``da/dt = 1 - (alpha(a) / alpha_max)**2`` (the
    face turning away from the heat), where ``alpha(a)`` is measured on the simulated shape
    at activation ``a``. ``alpha(a)`` is sampled by GDFE solves at a few activations
    (warm-started one from the other) and interpolated by a cubic spline; the ODE is
    integrated on it, and the final shape is a GDFE solve at the activation reached.

The same functions show that the diagnoser's closed forms equal the converged GDFE hinge
(:func:`gdfe_check`).

Lengths in mm, angles in radians.
"""

from __future__ import annotations

import logging

import numpy as np

from gdfe._validation import GdfeError, GdfeTypeError
from gdfe.diagnosis.effects import Model

__all__ = ["simulate_fold", "simulate_model", "gdfe_check", "CELLS"]

log = logging.getLogger(__name__)

#: Cells across the hinge and activation samples of the saturation ramp, per resolution.
CELLS = {"coarse": (16, 4), "default": (24, 6), "fine": (32, 8)}
#: Columns of cells in each rigid panel (the panels' length does not change the fold).
PANEL_CELLS = 4
#: Strip width [mm]: the core's narrow strip, or two cells where that is narrower (the fold
#: of so narrow a strip does not depend on its width: < 0.001 rad).
NARROW = 0.5
#: Largest cell [mm]: two rows across the 0.5 mm strip keep the cells' aspect below 1.5.
MAX_CELL = 0.36


def _cells(resolution):
    if resolution not in CELLS:
        raise GdfeError(f"resolution: expected one of {', '.join(CELLS)}, got {resolution!r}")
    return CELLS[resolution]


def simulate_fold(L, R, h, *, alpha_max=None, resolution="coarse"):
    """Fold angle of one GDFE hinge specimen.

    Parameters
    ----------
    L : float [mm]
        Meshed hinge width.
    R : float
        Contraction ratio of the hinge's free face, in (0, 1].
    h : float [mm]
        Meshed film thickness.
    alpha_max : float [rad], optional
        Switches on the exposure-limited activation (``saturation``): the activation rate
        is ``1 - (alpha / alpha_max)**2`` with ``alpha`` the fold of the current shape.
    resolution : {"coarse", "default", "fine"}
        Cells across the hinge (16, 24, 32, more where a cell would exceed ``MAX_CELL``) and
        samples of the activation ramp (4, 6, 8).

    Returns
    -------
    dict
        ``alpha`` [rad], ``converged``, ``iterations``, ``activation`` (the activation
        reached, 1 without saturation), ``seconds``.
    """
    import time

    import gdfe

    cells, steps = _cells(resolution)
    t0 = time.perf_counter()
    cell = min(L / cells, MAX_CELL)
    design = gdfe.hinge(L, R=R, h=h, cell_size=cell, panel_length=PANEL_CELLS * cell,
                        width=min(NARROW, 2 * cell))
    if alpha_max is None:
        res = gdfe.simulate(design)
        return {"alpha": gdfe.fold_angle(res), "converged": bool(res.converged),
                "iterations": int(res.iterations), "activation": 1.0,
                "seconds": time.perf_counter() - t0}
    if not alpha_max > 0:
        raise GdfeError(f"alpha_max: expected a positive angle in rad, got {alpha_max}")
    solver = gdfe.Solver(design)
    flat = design.mesh.points.copy()
    V, ok_all, its = None, True, 0

    def solve(a):
        nonlocal V, ok_all, its
        V0 = solver.linearised_start(flat, a) if V is None else V
        stats = solver.solve(V0, a)
        V, ok, it = stats.points, stats.converged, stats.iterations
        ok_all, its = ok_all and ok, its + it
        return gdfe.fold_angle(V, design)

    # the fold as a function of activation, from GDFE solves at `nodes` activations
    nodes = np.linspace(0.0, 1.0, steps + 1)
    folds = np.array([0.0] + [solve(a) for a in nodes[1:]])
    from scipy.interpolate import CubicSpline
    from scipy.integrate import solve_ivp

    fold = CubicSpline(nodes, folds)
    ode = solve_ivp(lambda t, a: [max(0.0, 1.0 - (float(fold(min(a[0], 1.0))) / alpha_max) ** 2)],
                    (0.0, 1.0), [0.0], rtol=1e-10, atol=1e-12)
    a_end = float(np.clip(ode.y[0, -1], 0.0, 1.0))
    V = None  # the final shape: a fresh solve at the activation reached
    alpha = solve(a_end) if a_end > 0 else 0.0
    return {"alpha": alpha, "converged": ok_all, "iterations": its, "activation": a_end,
            "seconds": time.perf_counter() - t0}


def simulate_model(model, params, L, d, h, *, x=None, group=None, resolution="coarse"):
    """GDFE fold angles of tests ``(L, d, h)`` with a model's effects built into the simulation.

    ``partial_activation`` and ``batch`` enter through the contraction ratio of each test's
    hinge, like the deformation principle.

    Parameters
    ----------
    model : Model or str
    params : (k,) float array
        In the order of ``model.param_names``.
    L, d, h : float or (n,) float arrays [mm]
    x : (n,) float array, optional
        The process column of ``partial_activation``.
    group : (n,) int array, optional
        Group index of each test (``batch``).

    Returns
    -------
    alpha : (n,) float array [rad]
        NaN where the principle gives no valid contraction ratio (``R <= 0``).
    converged : (n,) bool array
    """
    from gdfe.diagnosis.effects import model as model_by_name

    if isinstance(model, str):
        model = model_by_name(model)
    if not isinstance(model, Model):
        raise GdfeTypeError(f"model: expected a Model or a name, got {type(model).__name__}")
    L, d, h = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, float)) for a in (L, d, h)))
    p = dict(zip(model.param_names, np.asarray(params, float)))
    c = np.broadcast_to(model.contraction(np.asarray(params, float), d, h, x, group), L.shape)
    alpha = np.full(L.shape, np.nan)
    ok = np.zeros(L.shape, bool)
    for i in range(L.size):
        R = 1.0 - float(c[i])
        if not 0.0 < R <= 1.0:
            continue
        out = simulate_fold(float(L[i] + p.get("lambda", 0.0)), R,
                            float(h[i] * (1.0 + p.get("beta", 0.0) * c[i])),
                            alpha_max=p.get("alpha_max"), resolution=resolution)
        alpha[i], ok[i] = out["alpha"], out["converged"]
    return alpha, ok


def gdfe_check(model, params, L, d, h, *, x=None, group=None, resolution="coarse"):
    """Compare a model's closed form with the GDFE simulation of the same tests
    (``x``, ``group``: see :func:`simulate_model`).

    Returns
    -------
    dict
        ``closed_form`` and ``gdfe`` angles [rad], ``max_abs_diff`` and ``rms_diff`` [rad],
        ``converged`` (all solves), ``cells`` across the hinge, ``n_skipped`` (tests whose
        contraction ratio is not in (0, 1]).
    """
    from gdfe.diagnosis.effects import model as model_by_name

    if isinstance(model, str):
        model = model_by_name(model)
    L, d, h = (np.asarray(a, float) for a in (L, d, h))
    closed = model.predict(np.asarray(params, float), L, d, h, x, group)
    sim, ok = simulate_model(model, params, L, d, h, x=x, group=group, resolution=resolution)
    valid = np.isfinite(sim)
    diff = (sim - closed)[valid]
    return {
        "model": model.name, "resolution": resolution, "cells": _cells(resolution)[0],
        "closed_form": closed.tolist(), "gdfe": sim.tolist(),
        "max_abs_diff": float(np.abs(diff).max()) if diff.size else None,
        "rms_diff": float(np.sqrt(np.mean(diff**2))) if diff.size else None,
        "converged": bool(ok[valid].all()), "n_skipped": int((~valid).sum()),
    }
