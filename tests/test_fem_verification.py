"""The reference FEM against closed forms: Timoshenko curvature, linear/nonlinear agreement, arcs."""

import numpy as np
import pytest

from reference_fem import (BilayerMaterial, curvature, fold_angle, hinge_mesh, layered_strip, strip_mesh,
                           solve_linear, solve_nonlinear, timoshenko_check, timoshenko_curvature,
                           arc_check, turning_angle)


def test_trilinear_strip_converges_to_timoshenko_at_the_observed_rate():
    check = timoshenko_check("hex1")
    errors = [r["rel_error"] for r in check["rows"]]
    sizes = [r["element_size_mm"] for r in check["rows"]]
    assert len(errors) >= 3
    rate = np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert rate == pytest.approx(check["rate"])
    # bending locking: the parasitic shear of a trilinear element is of order kappa * element
    # length, so the curvature error falls as size^2 (reference_fem.verify); halving the size
    # four times gives errors 0.11, 0.030, 0.0078, 0.0020 (rate 1.95)
    assert 1.8 < rate < 2.2, f"observed rate {rate:.2f}, expected about 2 (bending locking)"
    assert errors[-1] < 0.01, f"finest error {errors[-1]:.2e} not within 1 %"
    assert all(a > b for a, b in zip(errors, errors[1:]))


def test_triquadratic_strip_reproduces_timoshenko_on_every_mesh():
    check = timoshenko_check("hex2")
    errors = [r["rel_error"] for r in check["rows"]]
    assert len(errors) >= 3
    # the element contains the closed-form field u_z = -kappa (x^2 + y^2) / 2, so no
    # discretisation error of the size^2 kind remains (hex1 has 0.11 at 0.3 mm); observed at most
    # 7.5e-6, on the coarsest mesh
    assert max(errors) < 1e-4, f"errors {errors}"


def test_wide_plate_follows_the_biaxial_formula_with_unequal_poisson_ratios():
    h, d = 0.29, 0.33
    mat = BilayerMaterial(E_active=3000, E_passive=1500, nu_active=0.45, nu_passive=0.1, eigenstrain=-1e-3)
    k = curvature(solve_linear(strip_mesh(6.0, h, d, width=6.0, element_size=0.3), mat))
    kw = dict(nu_active=0.45, nu_passive=0.1)
    biaxial = timoshenko_curvature(h, d, 3000, 1500, -1e-3, state="biaxial", **kw)
    beam = timoshenko_curvature(h, d, 3000, 1500, -1e-3, state="beam", **kw)
    assert k == pytest.approx(biaxial, rel=5e-3)  # observed 1.7e-3
    # the two closed forms differ by 4.3 % here (E' = E / (1 - nu): n' = n 0.9 / 0.55), so the
    # FEM, within 0.5 % of the biaxial value, tells them apart
    assert abs(k / beam - 1) > 0.03


def test_nonlinear_agrees_with_linear_at_small_eigenstrain():
    strip = hinge_mesh(1.6, 0.33, 0.29, resolution="coarse")
    mat = BilayerMaterial.from_ratio(5.0, -1e-4)
    lin, nl = solve_linear(strip, mat), solve_nonlinear(strip, mat)
    assert nl.converged and lin.converged
    # the geometric terms are of the order of the strains and rotations (~1e-4 here);
    # observed 1e-5 (angle) and 6e-5 (curvature)
    assert fold_angle(nl) == pytest.approx(fold_angle(lin), rel=5e-3)
    assert curvature(nl) == pytest.approx(curvature(lin), rel=5e-3)
    assert fold_angle(lin) > 0  # folds towards the free (top) face


def test_large_eigenstrain_curls_a_strip_into_the_arc_kappa_L():
    arc = arc_check(eigenstrain=-0.05, turn=2.5)
    assert arc["converged"]
    assert arc["turning_angle_rad"] > 2.0
    assert arc["rel_error"] < 0.02, f"turn {arc['turning_angle_rad']:.4f} vs kappa L {arc['kappa_L_rad']:.4f}"
    assert arc["circle_rms_over_radius"] < 1e-3


def test_no_eigenstrain_leaves_the_shape_as_it_is():
    strip = hinge_mesh(1.0, 0.2, resolution="coarse")
    mat = BilayerMaterial(eigenstrain=0.0)
    for res in (solve_linear(strip, mat), solve_nonlinear(strip, mat)):
        assert res.converged
        assert np.abs(res.displacement).max() < 1e-12


def test_sandwich_panel_shrinks_without_bending():
    strip = layered_strip([(4.0, "both")], 0.29, 0.2, element_size=0.5)
    res = solve_nonlinear(strip, BilayerMaterial.from_ratio(1.0, -0.1))
    assert res.converged
    assert abs(turning_angle(res)) < 1e-8
    u = res.displacement
    end = np.argmax(res.points[:, 0])
    assert u[end, 0] < -0.01  # the panel shrinks along x


def test_free_face_decides_the_fold_direction():
    mat = BilayerMaterial.from_ratio(5.0, -0.05)
    up = solve_linear(hinge_mesh(1.0, 0.2, resolution="coarse", free_face="top"), mat)
    down = solve_linear(hinge_mesh(1.0, 0.2, resolution="coarse", free_face="bottom"), mat)
    assert fold_angle(up) == pytest.approx(fold_angle(down), rel=1e-9)
    assert fold_angle(up) > 0
    # towards +z for a free top face, towards -z for a free bottom face
    zu = up.deformed[np.argmax(up.points[:, 0]), 2] - up.points[np.argmax(up.points[:, 0]), 2]
    zd = down.deformed[np.argmax(down.points[:, 0]), 2] - down.points[np.argmax(down.points[:, 0]), 2]
    assert zu > 0 > zd


def test_fold_beyond_a_right_angle_is_unwrapped():
    # thin coat, soft film: a 5 mm hinge folds past pi/2
    strip = hinge_mesh(5.0, 0.14, resolution="coarse")
    res = solve_nonlinear(strip, BilayerMaterial.from_ratio(7.7, -0.17))
    assert res.converged
    alpha = fold_angle(res)
    assert np.pi / 2 < alpha < 2 * np.pi
    # the linear angle is the same order: the unwrapped nonlinear angle did not jump by 2 pi
    assert abs(alpha - fold_angle(solve_linear(strip, res.material))) < 0.5
