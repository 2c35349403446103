"""Timoshenko's bimetal curvature and the layered-beam balance it comes from."""

import numpy as np
import pytest

from reference_fem import laminate_curvature, timoshenko_curvature


def test_equal_layers_give_three_halves_mismatch_over_thickness():
    # two equal layers of total thickness t: kappa = 3 delta / (2 t)
    for t in (0.2, 0.62, 1.0):
        assert timoshenko_curvature(t / 2, t / 2, 2.0, 2.0, -0.01) == pytest.approx(0.015 / t, rel=1e-12)


@pytest.mark.parametrize("h,d,Ea,Ep", [(0.29, 0.33, 3000, 1500), (0.29, 0.11, 1.0, 7.7),
                                       (0.1, 0.5, 5.0, 1.0)])
def test_formula_matches_force_and_moment_balance(h, d, Ea, Ep):
    # film at the bottom contracting: the stack curls towards its bottom (laminate kappa > 0)
    k_lam, _ = laminate_curvature([h, d], [Ea, Ep], [-0.02, 0.0])
    assert timoshenko_curvature(h, d, Ea, Ep, -0.02) == pytest.approx(k_lam, rel=1e-12)


def test_swapping_the_layers_leaves_the_magnitude():
    k1 = timoshenko_curvature(0.29, 0.2, 3.0, 1.0, -0.05)
    k_lam, _ = laminate_curvature([0.2, 0.29], [1.0, 3.0], [0.0, -0.05])
    assert abs(k_lam) == pytest.approx(k1, rel=1e-12)


def test_sign_and_linearity_in_the_eigenstrain():
    k = timoshenko_curvature(0.29, 0.33, 1.0, 1.0, np.array([-0.1, -0.05, 0.0, 0.05]))
    assert k[0] > 0 and k[2] == 0 and k[3] < 0
    assert k[0] == pytest.approx(2 * k[1], rel=1e-12)


def test_biaxial_correction_only_matters_for_unequal_poisson_ratios():
    kw = dict(h=0.29, d=0.33, E_active=3000, E_passive=1500, eigenstrain=-0.01)
    beam = timoshenko_curvature(**kw)
    same = timoshenko_curvature(**kw, nu_active=0.35, nu_passive=0.35, state="biaxial")
    assert same == pytest.approx(beam, rel=1e-12)
    # biaxial = beam formula with E -> E / (1 - nu)
    diff = timoshenko_curvature(**kw, nu_active=0.45, nu_passive=0.1, state="biaxial")
    manual = timoshenko_curvature(0.29, 0.33, 3000 / 0.55, 1500 / 0.9, -0.01)
    assert diff == pytest.approx(manual, rel=1e-12)
    # n' = n (1 - nu_p) / (1 - nu_a) = 2 * 0.9 / 0.55 instead of n = 2: kappa changes by -4.3 %
    assert abs(diff / beam - 1) > 0.03


def test_plane_strain_raises_the_mismatch_by_one_plus_nu():
    kw = dict(h=0.29, d=0.33, E_active=3000, E_passive=3000, eigenstrain=-0.01)
    beam = timoshenko_curvature(**kw)
    ps = timoshenko_curvature(**kw, nu_active=0.35, nu_passive=0.35, state="plane_strain")
    assert ps == pytest.approx(1.35 * beam, rel=1e-12)


@pytest.mark.parametrize("kwargs,match", [
    (dict(h=0.0), "h: expected a positive finite number, got 0"),
    (dict(d=-0.1), "d: expected a positive finite number, got -0.1"),
    (dict(E_active=0.0), "E_active: expected a positive finite number, got 0"),
    (dict(E_passive=-3.0), "E_passive: expected a positive finite number, got -3"),
    (dict(eigenstrain=-1.0), "eigenstrain: expected a strain > -1, got -1"),
    (dict(nu_active=0.5), r"nu_active: expected a Poisson's ratio in \(-1, 0\.5\), got 0\.5"),
    (dict(state="shell"), "state: expected one of 'beam', 'biaxial', 'plane_strain', got 'shell'"),
])
def test_bad_input_is_named(kwargs, match):
    args = dict(h=0.29, d=0.33, E_active=3000, E_passive=3000, eigenstrain=-0.1)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        timoshenko_curvature(**args)


def test_laminate_rejects_mismatched_layers():
    with pytest.raises(ValueError, match="thicknesses, moduli, eigenstrains: expected 1-D arrays of one length"):
        laminate_curvature([0.1, 0.2], [1.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="thicknesses: expected a positive finite number, got an array containing 0"):
        laminate_curvature([0.1, 0.0], [1.0, 1.0], [0.0, 0.0])
