"""The two-level preconditioner's coarse matrix solved by smoothed aggregation, and flexible CG.

``ReducedHessian.coarse_solver = "amg"`` keeps the coarse grid's spacing where a factorised
grid would be widened (more than ``ReducedHessian.coarse_cells`` coarse cells per layer) and
solves its matrix with a few smoothed-aggregation V-cycles (:class:`gdfe.solver.amg.CoarseAMG`).
The small plates here reach that regime by lowering ``coarse_cells`` and the hierarchy's
coarsest level, so that its V-cycles are not an exact solve.
"""

import numpy as np
import pytest
import scipy.sparse as sp

import gdfe
from gdfe.measure import rigid_align
from gdfe.solver import Solver
from gdfe.solver import amg
from gdfe.solver import newton as nw
from gdfe.solver.newton import ReducedHessian

pytest.importorskip("pyamg")


def _plate(n=40, nz=2):
    """An n x n plate of stripes (pixel 0.1 mm, h = 0.29 mm: the coarse grid 5 cells apart)."""
    top = np.mod(np.arange(n), 6)[:, None] * np.ones((1, n), int) >= 2
    return gdfe.from_masks(top, np.ones((n, n), bool), 0.1, 0.7, nz=nz)


def _system(des):
    sv = Solver(des)
    V = sv.linearised_start(des.mesh.points.copy())
    return sv, V, sv.orient(V), sv.rest(1.0), sv.reduced_hessian


@pytest.mark.parametrize("solver, spacing", [("factor", 9), ("amg", 5)])
def test_the_coarse_grid_is_widened_only_where_it_is_factorised(monkeypatch, solver, spacing):
    """At most ~``coarse_cells`` (here 20) cells per layer where the grid is factorised: 9 cells apart on
    this plate; smoothed aggregation keeps its spacing, 5 cells (0.4 h, at least 1.5 h on cells this coarse)."""
    monkeypatch.setattr(ReducedHessian, "coarse_cells", 20)
    monkeypatch.setattr(ReducedHessian, "coarse_solver", solver)
    hs = Solver(_plate()).reduced_hessian
    assert (hs.coarse.spacing, hs.coarse.solver) == (spacing, solver)


def test_the_coarse_amg_solve_without_pyamg_is_refused(monkeypatch):
    monkeypatch.setattr(ReducedHessian, "coarse_solver", "amg")
    monkeypatch.setattr(amg, "available", lambda: False)
    with pytest.raises(gdfe.GdfeError, match="coarse_solver: expected 'factor' here, got 'amg': it needs pyamg"):
        Solver(_plate()).reduced_hessian.coarse


def test_the_default_factorises_and_cg_is_not_flexible():
    """By default nothing changes: the grid is factorised, CG takes its plain form."""
    sv, V, o, rest, hs = _system(_plate())
    assert hs.coarse.solver == "factor" and hs.coarse.spacing == 5
    ops = hs.operator(hs.linearise(o.Q, o.S, rest), rest, 1e-6)
    assert not ops.flexible


def test_the_coarse_amg_solve_is_the_stationary_iteration_of_its_v_cycle(monkeypatch):
    """``CoarseAMG.solve`` with ``k`` cycles is ``sum_{j<k} (I - S A)^j S``, ``S`` one V-cycle (column by
    column against that polynomial); ``S`` is symmetric positive definite, so ``I - S A`` is
    self-adjoint in the energy norm and every cycle shrinks the error by its spectral radius ``rho``:
    ``|e_k|_A <= rho |e_k-1|_A``, with ``rho < 1`` (a convergent iteration); the hierarchy has more than
    one level, so that one cycle is not an exact solve (``rho > 0``)."""
    monkeypatch.setattr(ReducedHessian, "coarse_solver", "amg")
    sv, V, o, rest, hs = _system(_plate(n=60))
    lin = hs.linearise(o.Q, o.S, rest, floor=0.5)
    Hc = hs.coarse_matrix(lin, rest, 1e-6).toarray()
    k = Hc.shape[0]
    points = hs.coarse.points(V)

    def operator(cycles):
        solver = amg.CoarseAMG(sp.csr_matrix(Hc), points, cycles=cycles, max_coarse=60)
        assert len(solver.ml.sizes) >= 2, solver.ml.sizes
        return np.column_stack([solver.solve(e) for e in np.eye(k)])
    S = operator(1)
    scale = np.abs(S).max()
    np.testing.assert_allclose(S, S.T, rtol=0, atol=1e-10 * scale)
    assert np.linalg.eigvalsh(0.5 * (S + S.T)).min() > 0
    E = np.eye(k) - S @ Hc
    np.testing.assert_allclose(operator(3), S + E @ S + E @ E @ S, rtol=0, atol=1e-9 * scale)
    # the error propagation's spectral radius: eigenvalues of I - S^(1/2) A S^(1/2), similar to I - S A
    w, U = np.linalg.eigh(0.5 * (S + S.T))
    root = (U * np.sqrt(w)) @ U.T
    rho = float(np.abs(np.linalg.eigvalsh(np.eye(k) - root @ Hc @ root)).max())
    assert 0.0 < rho < 1.0, rho
    exact = np.linalg.solve(Hc, np.random.default_rng(0).standard_normal(k))
    b = Hc @ exact
    cycles = (0, 1, 2, 3, 6)
    errors = [float(np.sqrt(exact @ Hc @ exact))]  # from zero
    for c in cycles[1:]:
        e = amg.CoarseAMG(sp.csr_matrix(Hc), points, cycles=c, max_coarse=60).solve(b) - exact
        errors.append(float(np.sqrt(e @ Hc @ e)))
    for i in range(len(cycles) - 1):
        assert errors[i + 1] <= rho ** (cycles[i + 1] - cycles[i]) * errors[i] * (1.0 + 1e-9), (rho, errors)


def test_coarse_amg_refuses_what_it_cannot_solve():
    A = sp.identity(6, format="csr")
    with pytest.raises(gdfe.GdfeError, match="cycles: expected an integer >= 1, got 0"):
        amg.CoarseAMG(A, np.zeros((2, 3)), cycles=0)
    with pytest.raises(gdfe.GdfeError, match=r"A, points: expected a \(3k, 3k\) matrix and \(k, 3\) points, "
                                             r"got \(6, 6\) and \(3, 3\)"):
        amg.CoarseAMG(A, np.zeros((3, 3)))


def test_coarse_points_are_the_shape_where_the_grid_has_its_vertices():
    """On the flat print, the coarse vertices' points lie on the film's lattice (z on a layer, x and y
    the weighted mean of the vertices they interpolate to); a rigid motion of the shape moves them rigidly."""
    sv, V, o, rest, hs = _system(_plate())
    P = hs.coarse.points(sv.design.mesh.points)
    assert P.shape == (hs.coarse.Z.shape[1], 3)
    zs = np.unique(np.round(sv.design.mesh.points[:, 2], 12))
    assert np.all(np.min(np.abs(P[:, 2:3] - zs[None, :]), axis=1) < 1e-12)
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    moved = hs.coarse.points(V) @ R.T + [1.0, 2.0, 3.0]
    np.testing.assert_allclose(hs.coarse.points(V @ R.T + [1.0, 2.0, 3.0]), moved, atol=1e-12 * np.abs(moved).max())


def test_newton_cg_with_the_coarse_amg_solve_reaches_the_factorised_answer(monkeypatch):
    """The same converged shape and energy with the coarse matrix factorised and solved by V-cycles
    (a hierarchy of several levels); CG takes its flexible form with the V-cycles."""
    des = _plate(n=60)
    tol = 1e-7
    ref = Solver(des)
    V0 = ref.linearised_start(des.mesh.points.copy())
    a = ref.solve(V0, method="newton-cg", tol=tol)
    monkeypatch.setattr(ReducedHessian, "coarse_solver", "amg")
    monkeypatch.setattr(amg, "AMG_MAX_COARSE", 60)
    seen = []
    plain = nw.pcg

    def spy(*args, **kwargs):
        seen.append(kwargs.get("flexible"))
        return plain(*args, **kwargs)
    monkeypatch.setattr(nw, "pcg", spy)
    sv = Solver(des)
    b = sv.solve(V0, method="newton-cg", tol=tol)
    assert sv.reduced_hessian.coarse.solver == "amg"
    assert a.converged and b.converged, (a.iterations, b.iterations)
    assert seen and all(seen)
    assert b.energies[-1] == pytest.approx(a.energies[-1], rel=1e-9)
    # the pinned vertex holds only the translations: compare the shapes after a rigid alignment
    Q, t = rigid_align(b.points, a.points)
    np.testing.assert_allclose(b.points @ Q.T + t, a.points, rtol=0, atol=2 * nw.STEP_TOL_FACTOR * tol * des.h)


def _spd_system(seed, n=300):
    """A random symmetric positive definite ``A`` (condition ~10^3), its Jacobi preconditioner's
    diagonal ``d``, a right-hand side ``b`` ``(n, 1)`` and the generator."""
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((n, n)) / np.sqrt(n)
    A = B @ B.T + np.diag(np.linspace(0.01, 10.0, n))
    return A, 1.0 / np.diag(A), rng.standard_normal((n, 1)), rng


def test_flexible_cg_gives_the_iterates_of_cg_with_a_symmetric_preconditioner():
    """With a symmetric positive definite preconditioner, the Polak-Ribiere coefficient equals the
    Fletcher-Reeves one (the residuals are P-orthogonal): the same iterations and solution."""
    A, d, b, _ = _spd_system(1)
    out = [nw.pcg(lambda v: A @ v, lambda r: d[:, None] * r, b, 1e-10, 500, flexible=f) for f in (False, True)]
    (x0, k0), (x1, k1) = out
    assert abs(k0 - k1) <= 1
    np.testing.assert_allclose(x1, x0, rtol=0, atol=1e-8 * np.abs(x0).max())
    np.testing.assert_allclose(A @ x1, b, atol=1e-8 * np.abs(b).max())


def test_flexible_cg_converges_where_the_preconditioner_changes_between_iterations():
    """A preconditioner that is not a fixed operator (a randomly perturbed Jacobi): flexible CG still
    reaches the tolerance."""
    A, d, b, rng = _spd_system(2)

    def varying(r):
        return (d * (1.0 + 0.3 * rng.uniform(-1.0, 1.0, d.size)))[:, None] * r
    x, k = nw.pcg(lambda v: A @ v, varying, b, 1e-8, 1000, flexible=True)
    assert k < 1000
    assert np.linalg.norm(A @ x - b) <= 1e-6 * np.linalg.norm(b)
