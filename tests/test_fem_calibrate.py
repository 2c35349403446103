"""Least-squares calibration of (E ratio, eigenstrain) with leave-one-out error."""

import numpy as np
import pytest

from reference_fem import fit_to_table, timoshenko_curvature, unit_angles

L = np.array([1.5, 3.27, 1.8, 5.08, 3.14, 1.22, 2.6])
D = np.array([0.11, 0.15, 0.24, 0.24, 0.31, 0.51, 0.33])
H = np.full(L.size, 0.29)


def test_closed_form_fit_recovers_the_parameters_of_exact_data():
    ratio, eps = 5.0, -0.15
    alpha = timoshenko_curvature(H, D, 1.0, ratio, eps) * L
    fit = fit_to_table(L, D, H, alpha, model="timoshenko")
    assert fit.E_ratio == pytest.approx(ratio, rel=1e-3)
    assert fit.eigenstrain == pytest.approx(eps, rel=1e-4)
    assert fit.rmse < 1e-4 and fit.loo_rmse < 1e-3 and not fit.at_bound


def test_leave_one_out_error_is_larger_than_the_fit_error_on_noisy_data():
    rng = np.random.default_rng(3)
    alpha = timoshenko_curvature(H, D, 1.0, 5.0, -0.15) * L * (1 + 0.1 * rng.standard_normal(L.size))
    fit = fit_to_table(L, D, H, alpha, model="timoshenko")
    assert fit.loo_rmse > fit.rmse > 0
    assert fit.predicted.shape == alpha.shape and fit.loo_params.shape == (L.size, 2)


def test_fem_fit_on_a_grid_node_recovers_the_node():
    # unit angles from linear solves at four ratios; data made at the third one
    ratios = [0.5, 2.0, 8.0, 32.0]
    A = unit_angles(L[:4], D[:4], H[:4], ratios, resolution="coarse")
    assert np.all(A > 0)
    alpha = 0.12 * A[:, 2]
    fit = fit_to_table(L[:4], D[:4], H[:4], alpha, ratios=ratios, angles=A)
    assert fit.E_ratio == pytest.approx(8.0, rel=1e-3)
    assert fit.eigenstrain == pytest.approx(-0.12, rel=1e-3)


def test_fit_input_checks():
    with pytest.raises(ValueError, match=r"tests: expected at least 3 folding tests"):
        fit_to_table(L[:2], D[:2], H[:2], [1.0, 1.0], model="timoshenko")
    with pytest.raises(ValueError, match=r"d: expected positive lengths in mm"):
        fit_to_table(L, -D, H, L, model="timoshenko")
    with pytest.raises(ValueError, match=r"alpha: expected 7 finite angles"):
        fit_to_table(L, D, H, [1.0], model="timoshenko")
    with pytest.raises(ValueError, match=r"model: expected one of 'fem', 'timoshenko'"):
        fit_to_table(L, D, H, L, model="spline")
