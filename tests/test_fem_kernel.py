"""Element kernels: consistency of forces and tangents, invariants of the assembled operators."""

import numpy as np
import pytest

from reference_fem import BilayerMaterial, hinge_mesh
from reference_fem._kernel import (Discretisation, element_fields, linear_system,
                                   neohookean_state, svk_state)


@pytest.fixture(scope="module")
def small():
    strip = hinge_mesh(1.0, 0.33, 0.29, element_size=0.5, width=0.5, layers_per_ply=2,
                       junction_size=0.5, z_ratio=1.0)
    mat = BilayerMaterial(E_active=3000, E_passive=1000, nu_active=0.3, nu_passive=0.4,
                   eigenstrain=(-0.2, -0.1, 0.05))
    return strip, mat


@pytest.mark.parametrize("element", ["hex1", "hex2"])
@pytest.mark.parametrize("state", [svk_state, neohookean_state])
def test_force_is_energy_gradient_and_tangent_is_force_gradient(small, element, state):
    strip, mat = small
    disc = Discretisation(strip, element)
    lam, mu, G, _ = element_fields(strip, mat, disc)
    rng = np.random.default_rng(0)
    u = 0.01 * rng.standard_normal(disc.ndofs)
    e, f, K = state(disc, u, lam, mu, G)
    du = 1e-6 * rng.standard_normal(disc.ndofs)
    e_p, f_p, _ = state(disc, u + du, lam, mu, G, tangent=False)
    e_m, f_m, _ = state(disc, u - du, lam, mu, G, tangent=False)
    assert (e_p - e_m) / (2 * f @ du) == pytest.approx(1.0, abs=1e-6)
    assert np.linalg.norm(f_p - f_m - 2 * K @ du) <= 1e-6 * np.linalg.norm(2 * K @ du)
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()


@pytest.mark.parametrize("state", [svk_state, neohookean_state])
def test_tangent_without_eigenstrain_is_the_linear_stiffness(small, state):
    strip, mat = small
    disc = Discretisation(strip, "hex2")
    lam, mu, G, eps = element_fields(strip, mat, disc, scale=0.0)
    K0, f0 = linear_system(disc, lam, mu, eps)
    e, f, K = state(disc, np.zeros(disc.ndofs), lam, mu, G)
    assert abs(K - K0).max() <= 1e-12 * abs(K0).max()
    assert e == 0.0 and np.abs(f).max() == 0.0 and np.abs(f0).max() == 0.0


def test_linear_stiffness_is_symmetric_with_rigid_motions_in_its_null_space(small):
    strip, mat = small
    disc = Discretisation(strip, "hex2")
    lam, mu, _, eps = element_fields(strip, mat, disc)
    K, f = linear_system(disc, lam, mu, eps)
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    X = disc.X
    scale = abs(K).max()
    for c in range(3):
        t = np.zeros_like(X)
        t[:, c] = 1.0
        assert np.abs(K @ t.ravel()).max() <= 1e-10 * scale
        assert abs(f @ t.ravel()) <= 1e-10 * np.abs(f).sum()  # self-equilibrated load
    w = np.array([0.3, -0.2, 0.5])
    rot = np.cross(w, X)
    assert np.abs(K @ rot.ravel()).max() <= 1e-10 * scale * np.abs(X).max()


@pytest.mark.parametrize("state", [svk_state, neohookean_state])
def test_energy_is_invariant_under_a_rigid_rotation(small, state):
    strip, mat = small
    disc = Discretisation(strip, "hex2")
    lam, mu, G, _ = element_fields(strip, mat, disc)
    rng = np.random.default_rng(1)
    u = 0.01 * rng.standard_normal(disc.ndofs)
    x = disc.X + u.reshape(-1, 3)
    a = 1.1
    Q = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    u_rot = (x @ Q.T - disc.X).ravel()
    e, _, _ = state(disc, u, lam, mu, G, tangent=False)
    e_rot, _, _ = state(disc, u_rot, lam, mu, G, tangent=False)
    assert e_rot == pytest.approx(e, rel=1e-10)
