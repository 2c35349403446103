"""The coarse space augmented by recycled Newton directions (gdfe.solver.recycling)."""

import numpy as np
import scipy.sparse as sp

from gdfe.solver.recycling import TURN_SHARE, AugmentedCoarse, mostly_turn
from gdfe.solver.rigid import without_turn


def _problem(n=30, k=6, seed=0):
    """A symmetric positive definite H on (n, 3) arrays, a grid space Z (n x k) and its Galerkin factor."""
    rng = np.random.default_rng(seed)
    G = rng.standard_normal((3 * n, 3 * n))
    H = G @ G.T / (3 * n) + 0.05 * np.eye(3 * n)
    Z = sp.csr_matrix(np.abs(rng.standard_normal((n, k))) * (rng.random((n, k)) < 0.5))
    Z3 = sp.kron(Z, sp.eye(3)).toarray()  # (Zt @ r).ravel() of an (n, 3) r is Z3^T r.ravel()
    A = Z3.T @ H @ Z3
    Ainv = np.linalg.inv(A)

    def apply_H(v):
        return (H @ v.ravel()).reshape(-1, 3)
    return rng, H, Z, Z3, (lambda b: Ainv @ b), apply_H


def _galerkin(H, W, r):
    return (W @ np.linalg.solve(W.T @ H @ W, W.T @ r.ravel())).reshape(-1, 3)


def test_augmented_coarse_solve_is_the_galerkin_solve_on_the_grid_and_the_directions():
    rng, H, Z, Z3, solve, apply_H = _problem()
    U = [rng.standard_normal((30, 3)) for _ in range(2)]
    aug = AugmentedCoarse(solve, Z, Z.T.tocsr(), apply_H, U)
    assert aug.rank == 2
    W = np.column_stack([Z3] + [u.ravel() for u in U])
    r = rng.standard_normal((30, 3))
    np.testing.assert_allclose(aug(r), _galerkin(H, W, r), rtol=1e-9, atol=1e-12)
    # without directions: the grid's solve alone
    plain = AugmentedCoarse(solve, Z, Z.T.tocsr(), apply_H, [])
    np.testing.assert_allclose(plain(r), _galerkin(H, Z3, r), rtol=1e-9, atol=1e-12)


def test_a_recycled_direction_that_solves_the_system_makes_the_coarse_solve_exact():
    """The coarse solution of H x = b is x itself when x is among the directions: a Newton step
    along a recycled soft mode needs no CG iteration for that mode."""
    rng, H, Z, Z3, solve, apply_H = _problem(seed=1)
    x = rng.standard_normal((30, 3))
    b = apply_H(x)
    aug = AugmentedCoarse(solve, Z, Z.T.tocsr(), apply_H, [x])
    np.testing.assert_allclose(aug(b), x, rtol=1e-8, atol=1e-10)


def test_directions_the_grid_holds_or_that_repeat_are_left_out():
    rng, H, Z, Z3, solve, apply_H = _problem(seed=2)
    inside = (Z3 @ rng.standard_normal(Z3.shape[1])).reshape(-1, 3)
    u = rng.standard_normal((30, 3))
    aug = AugmentedCoarse(solve, Z, Z.T.tocsr(), apply_H, [inside, u, 2.0 * u])
    assert aug.rank == 1
    W = np.column_stack([Z3, u.ravel()])
    r = rng.standard_normal((30, 3))
    np.testing.assert_allclose(aug(r), _galerkin(H, W, r), rtol=1e-8, atol=1e-10)


def test_a_direction_of_negative_curvature_is_left_out():
    """With a Hessian that is not positive along a direction, that direction stays out, so the
    coarse matrix stays positive definite."""
    rng, H, Z, Z3, solve, apply_H = _problem(seed=3)
    u = rng.standard_normal(90)
    u -= Z3 @ np.linalg.lstsq(Z3, u, rcond=None)[0]  # outside the grid: the grid's matrix is unchanged
    A = Z3.T @ H @ Z3
    Hu = H @ u
    schur = float(u @ Hu) - Hu @ Z3 @ np.linalg.solve(A, Z3.T @ Hu)
    Hn = H - 2.0 * schur / float(u @ u) ** 2 * np.outer(u, u)  # the Schur complement along u now negative
    Ainv = np.linalg.inv(Z3.T @ Hn @ Z3)
    aug = AugmentedCoarse(lambda b: Ainv @ b, Z, Z.T.tocsr(), lambda v: (Hn @ v.ravel()).reshape(-1, 3),
                          [u.reshape(-1, 3)])
    assert aug.rank == 0
    r = rng.standard_normal((30, 3))
    np.testing.assert_allclose(aug(r), (Z3 @ Ainv @ Z3.T @ r.ravel()).reshape(-1, 3), rtol=1e-9)


def _stripes(n=48):
    import gdfe

    top = np.mod(np.arange(n), 6)[:, None] * np.ones((1, n), int) >= 3
    return gdfe.from_masks(top, np.ones((n, n), bool), 0.1, 0.7, nz=1)


def test_newton_cg_with_and_without_recycling_reaches_one_shape(monkeypatch):
    """Recycling changes the path, not the answer: both converge to one energy and, up to a turn of
    the whole part, one shape within the stopping test's distance."""
    import gdfe
    from gdfe.solver.newton import STEP_TOL_FACTOR, ReducedHessian

    des = _stripes()
    out = {}
    for recycle in (0, 2):
        monkeypatch.setattr(ReducedHessian, "recycle", recycle)
        res = gdfe.simulate(des, method="newton-cg", contact="off")
        assert res.converged
        out[recycle] = res
    assert abs(out[2].energy - out[0].energy) <= 1e-10 * out[0].energy
    # the stopping test's distance, after a rigid alignment
    assert gdfe.shape_distance(out[0].points, out[2].points)["max"] <= STEP_TOL_FACTOR * out[0].tol * des.h


def test_a_turn_about_the_pinned_vertex_is_taken_out_of_a_direction():
    rng = np.random.default_rng(4)
    V = rng.standard_normal((40, 3))
    pin = 7
    r = V - V[pin]
    bend = rng.standard_normal((40, 3))
    bend[pin] = 0.0
    out = without_turn(bend + np.cross([0.3, -1.0, 2.0], r), V, pin)
    assert np.all(out[pin] == 0.0)
    np.testing.assert_allclose(np.cross(r, out).sum(axis=0), 0.0, atol=1e-12)  # no turn left in it
    np.testing.assert_allclose(out, without_turn(bend, V, pin), atol=1e-12)  # whatever turn was added
    np.testing.assert_allclose(without_turn(out, V, pin), out, atol=1e-12)
    np.testing.assert_allclose(without_turn(np.cross([1.0, 2.0, 3.0], r), V, pin), 0.0, atol=1e-12)
    line = np.outer(np.arange(5.0), [1.0, 2.0, 0.0])  # points on a line through the pin: returned as given
    u = rng.standard_normal((5, 3))
    u[0] = 0.0
    assert without_turn(u, line, 0) is u


def test_a_direction_that_is_nearly_all_a_turn_is_told_apart():
    rng = np.random.default_rng(5)
    V = rng.standard_normal((40, 3))
    pin = 3
    turn = np.cross([0.5, 1.0, -2.0], V - V[pin])
    bend = rng.standard_normal((40, 3))
    bend[pin] = 0.0
    bend = without_turn(bend, V, pin)
    bend *= np.linalg.norm(turn) / np.linalg.norm(bend)  # as long as the turn, and none of it a turn
    assert mostly_turn(turn, V, pin)
    assert mostly_turn(turn + 0.5 * TURN_SHARE * bend, V, pin)
    assert not mostly_turn(turn + 2.0 * TURN_SHARE * bend, V, pin)
    assert not mostly_turn(bend, V, pin)


def test_a_tight_solve_with_recycling_stops(monkeypatch):
    """Near round-off a Newton step can be a turn of the whole part about its pinned vertex, along
    which the energy does not change; recycled, the coarse solve resolved that turn exactly: steps
    that turned the part by 1e-4 mm, each followed by half of it back, and no stop after 200 steps
    (60 here). Such a direction is no longer recycled, and the tight solve stops."""
    import gdfe
    from gdfe.solver.newton import STEP_TOL_FACTOR, ReducedHessian
    from studies.bench import mask_sheet

    des = gdfe.from_masks(*mask_sheet(900), 0.1, 0.7, nz=1)
    out = {}
    for recycle in (0, 2):
        monkeypatch.setattr(ReducedHessian, "recycle", recycle)
        res = gdfe.simulate(des, tol=1e-10, max_iter=30, contact="off")
        assert res.converged, recycle
        out[recycle] = res
    # measured: 10 steps with recycling, 9 without; twice is the margin, far below the stall's 60+
    assert out[2].iterations <= 2 * out[0].iterations
    # and the answer of the tight solve without recycling, to its own stopping distance after a rigid turn
    # (the energy is second order in the distance to its minimum: equal to round-off, measured 2e-15)
    assert abs(out[2].energy - out[0].energy) <= 1e-12 * out[0].energy
    assert gdfe.shape_distance(out[2].points, out[0].points)["max"] <= STEP_TOL_FACTOR * 1e-10 * des.h


def test_a_bad_recycle_count_is_refused(monkeypatch):
    import gdfe
    from gdfe._validation import GdfeError
    from gdfe.solver.newton import ReducedHessian

    monkeypatch.setattr(ReducedHessian, "recycle", -1)
    with np.testing.assert_raises_regex(GdfeError, "recycle: expected an integer >= 0"):
        gdfe.simulate(_stripes(12), method="newton-cg", contact="off")
