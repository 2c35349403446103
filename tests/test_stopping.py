"""The Newton stopping test: rigid motions left out, tol from the part's size, drift reported."""

import logging

import numpy as np
import pytest

import gdfe
from gdfe.solver import SHAPE_ACCURACY, STEP_TOL_FACTOR, Solver, auto_method, default_tol
from gdfe.solver.newton import DRIFT_WINDOW, _solve_free, deformation, solve_newton
from studies.bench import mask_sheet


def _expmap(w):
    th = np.linalg.norm(w)
    k = w / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def test_deformation_removes_an_infinitesimal_rigid_motion_and_keeps_the_rest():
    rng = np.random.default_rng(3)
    V = rng.uniform(-5, 5, (200, 3))
    omega, t = np.array([1e-7, -2e-7, 3e-7]), np.array([1e-6, 0.0, -2e-6])
    rigid = (V - V.mean(0)) @ (_expmap(omega) - np.eye(3)).T + t
    # a finite rotation leaves its second-order part, |omega|^2 |r| (r up to 5 sqrt(3) mm)
    assert np.abs(deformation(rigid, V)).max() < np.linalg.norm(omega) ** 2 * 10.0
    bend = np.zeros_like(V)
    bend[:, 2] = 1e-6 * V[:, 0] ** 2
    d = deformation(bend + rigid, V)
    # what is left is the bend less its own best rigid fit: removing the rigid part again changes nothing
    np.testing.assert_allclose(deformation(d, V), d, atol=1e-18)
    np.testing.assert_allclose(d, deformation(bend, V), atol=1e-12)


def test_default_tol_scales_with_the_part():
    small = gdfe.hinge(1.0, d=0.33)
    big = gdfe.from_masks(*mask_sheet(2500), 0.1, 0.7, nz=1)
    for des in (small, big):
        size = np.linalg.norm(np.ptp(des.mesh.points, axis=0))
        assert default_tol(des, "newton-cg") == pytest.approx(SHAPE_ACCURACY * size / (STEP_TOL_FACTOR * des.h))
    assert default_tol(small, "plain") == default_tol(big, "anderson") == 1e-7
    # "auto" is the method simulate picks (a Newton method for both), not the alternation's 1e-7
    for des in (small, big):
        assert default_tol(des, "auto") == default_tol(des, auto_method(des)) != 1e-7
    with pytest.raises(gdfe.GdfeError, match="method"):
        default_tol(small, "newton-gc")


def test_default_stop_is_within_the_stated_accuracy_of_a_tight_solve():
    des = gdfe.from_masks(*mask_sheet(900), 0.1, 0.7, nz=1)
    size = np.linalg.norm(np.ptp(des.mesh.points, axis=0))
    loose = gdfe.simulate(des).check()
    tight = gdfe.simulate(des, tol=1e-10).check()
    assert loose.tol == pytest.approx(default_tol(des, "newton-cg"))
    assert loose.error_estimate_mm <= SHAPE_ACCURACY * size
    assert gdfe.shape_distance(tight.points, loose.points)["max"] <= SHAPE_ACCURACY * size
    assert loose.iterations <= tight.iterations
    assert loose.drift is None and loose.summary()["drift"] is None


def test_drift_between_near_equal_states_is_reported_or_stops(caplog):
    des = gdfe.hinge(1.0, d=0.33, cell_size=0.125, width=0.25)
    s = Solver(des)
    ref = gdfe.simulate(des, tol=1e-10).check()
    V0 = ref.points + 1e-6 * des.h * np.random.default_rng(0).standard_normal(ref.points.shape)

    def creeping(Q, S, grad, res, extra=None, error=None, target=None):
        # a hundredth of the plain step (-L^-1 grad / 2): the energy, near its minimum, falls by
        # far less than 1e-6 of itself over ten iterations and the steps hardly shrink
        return lambda mu: (-0.005 * _solve_free(s, grad), 0)

    with caplog.at_level(logging.WARNING, logger="gdfe.solver.newton"):
        warn = solve_newton(s, V0, 1.0, 1e-12, 3 * DRIFT_WINDOW, creeping, on_drift="warn")
    assert not warn.converged and warn.iterations == 3 * DRIFT_WINDOW
    # the random perturbation's stiff part goes within the first window; the drift comes after
    assert warn.drift is not None and warn.drift["detected_at"] in (DRIFT_WINDOW, 2 * DRIFT_WINDOW)
    assert warn.drift["energy_change"] < 1e-6 and warn.drift["moved_mm"] > 0
    assert warn.drift["iterations"] == warn.iterations - warn.drift["since_iteration"]
    assert caplog.text.count("drifting between near-equal states") == 1
    stop = solve_newton(s, V0, 1.0, 1e-12, 3 * DRIFT_WINDOW, creeping, on_drift="stop")
    assert stop.drift["detected_at"] == warn.drift["detected_at"]
    assert not stop.converged and stop.iterations == stop.drift["detected_at"] + 1


def test_newton_steps_towards_the_solution_do_not_count_as_drift():
    des = gdfe.hinge(1.0, d=0.33, cell_size=0.125, width=0.25)
    res = gdfe.simulate(des, tol=1e-12, max_iter=3 * DRIFT_WINDOW)
    assert res.drift is None


def test_bad_on_drift():
    with pytest.raises(ValueError, match=r"on_drift: expected one of 'warn', 'stop', got 'ignore'"):
        gdfe.simulate(gdfe.hinge(1.0, d=0.33), on_drift="ignore")
