"""One Timoshenko implementation (gdfe.timoshenko) for the diagnosis and the reference FEM."""

import numpy as np
import pytest

from gdfe.diagnosis import Model
from gdfe.timoshenko import bilayer_curvature, laminate_curvature, timoshenko_curvature


def test_equal_layers():
    # equal thickness and modulus: kappa = 3 delta / (2 t)
    assert bilayer_curvature(0.5, 0.5, 1.0, 0.01) == pytest.approx(0.015, rel=1e-12)


@pytest.mark.parametrize("h, d, E_ratio", [(0.29, 0.11, 0.3), (0.29, 0.51, 7.7), (0.2, 0.4, 1.0)])
def test_matches_force_moment_balance(h, d, E_ratio):
    """Timoshenko's formula against the laminate equations (force and moment balance)."""
    kappa, _ = laminate_curvature([d, h], [E_ratio, 1.0], [0.0, -0.02])  # coat at the bottom, film on top
    assert bilayer_curvature(h, d, E_ratio, 0.02) == pytest.approx(abs(kappa), rel=1e-10)


@pytest.mark.parametrize("h, d, E_ratio, mismatch", [(0.29, 0.11, 0.3, 0.05), (0.29, 0.51, 7.7, 0.16)])
def test_the_diagnosis_and_the_fem_conventions_are_one_formula(h, d, E_ratio, mismatch):
    # the diagnosis writes (E_coat / E_film, film contraction); the FEM writes (E_active,
    # E_passive, eigenstrain of the film): the same number, to the last bit
    assert bilayer_curvature(h, d, E_ratio, mismatch) == timoshenko_curvature(h, d, 1.0, E_ratio, -mismatch)
    # and the diagnosis's passive_stiffness contraction is h * kappa
    c = Model(("passive_stiffness",)).contraction([E_ratio, mismatch], d, h)
    assert float(c) == h * bilayer_curvature(h, d, E_ratio, mismatch)


def test_complex_steps_pass_through():
    """The diagnosis differentiates the formula by complex steps: no check may refuse them."""
    step = 1e-30
    k = bilayer_curvature(0.29, 0.33, 2.0 + 1j * step, 0.1)
    fd = (bilayer_curvature(0.29, 0.33, 2.0 + 1e-7, 0.1) - bilayer_curvature(0.29, 0.33, 2.0 - 1e-7, 0.1)) / 2e-7
    assert k.imag / step == pytest.approx(fd, rel=1e-6)


def test_the_formula_matches_the_finite_element_strip():
    """The reference FEM's free bilayer strip (triquadratic elements, nu = 0) bends as the
    diagnosis's passive-stiffness formula says, to the FEM's own discretisation error."""
    rf = pytest.importorskip("reference_fem")
    pytest.importorskip("skfem")
    h, d, E_ratio, eps = 0.29, 0.33, 0.5, -1e-3
    mat = rf.BilayerMaterial(E_active=3000.0, E_passive=E_ratio * 3000.0, nu_active=0.0, nu_passive=0.0,
                             eigenstrain=eps)
    k_fem = rf.curvature(rf.solve_linear(rf.strip_mesh(6.0, h, d, width=1.0, element_size=0.6), mat))
    # 7.5e-6 relative on this mesh (gdfe fem timoshenko-check, hex2 coarsest level)
    assert k_fem == pytest.approx(bilayer_curvature(h, d, E_ratio, -eps), rel=1e-4)
    assert np.sign(k_fem) == 1.0
