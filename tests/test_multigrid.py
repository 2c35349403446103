"""Geometric multigrid for the assembly matrix: interpolation, symmetry, solves, same shapes."""

import sys

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh

import gdfe
import gdfe.solver.energy  # noqa: F401  (the module; gdfe.solver.energy is also a function)
from gdfe.solver import Solver
from gdfe.solver.multigrid import JACOBI_TOP, Multigrid, chebyshev2, lattice, prolongation
from studies.bench import mask_sheet


def _disc(n=40, nz=2, slot=False):
    """A striped disc of ``n`` x ``n`` pixels; with ``slot``, a slot cut through its middle."""
    x = (np.arange(n) + 0.5) / n - 0.5
    X, Y = np.meshgrid(x, x, indexing="ij")
    film = np.hypot(X, Y) <= 0.5
    if slot:
        film &= ~((np.abs(X) < 0.1) & (np.abs(Y) < 0.3))
    top = np.mod(np.arange(n), 6)[:, None] * np.ones((1, n), int) >= 2
    return gdfe.from_masks(top, np.ones((n, n), bool), 0.1, 0.7, nz=nz, film=film)


def _contraction(cycle, A, b, cycles=10):
    """The mean contraction per cycle of the stationary iteration ``x += cycle(b - A x)`` from zero."""
    x = np.zeros_like(b)
    for _ in range(cycles):
        x += cycle(b - A @ x)
    return (np.linalg.norm(b - A @ x) / np.linalg.norm(b)) ** (1.0 / cycles)


def test_prolongation_is_exact_for_affine_fields_on_each_layer():
    des = _disc()
    ijk = lattice(des.mesh)
    P, cijk = prolongation(ijk)
    coarse = 0.3 * 2 * cijk[:, 0] - 1.7 * 2 * cijk[:, 1] + 5.0 * cijk[:, 2] + 0.25
    fine = 0.3 * ijk[:, 0] - 1.7 * ijk[:, 1] + 5.0 * ijk[:, 2] + 0.25
    np.testing.assert_allclose(P @ coarse, fine, atol=1e-12)
    np.testing.assert_allclose(P.sum(axis=1).A.ravel(), 1.0)


def test_prolongation_through_the_layers_is_exact_for_affine_fields():
    """Coarsened 2 x 2 x 2 (three layers of cells: four of vertices, the even ones and the last kept)."""
    des = _disc(nz=3)
    ijk = lattice(des.mesh)
    P, cijk = prolongation(ijk, layers=True)
    assert sorted(set(cijk[:, 2])) == [0, 1, 2]
    kf = np.array([0, 2, 3])  # the fine layer of each coarse one
    coarse = 0.3 * 2 * cijk[:, 0] - 1.7 * 2 * cijk[:, 1] + 5.0 * kf[cijk[:, 2]] + 0.25
    fine = 0.3 * ijk[:, 0] - 1.7 * ijk[:, 1] + 5.0 * ijk[:, 2] + 0.25
    np.testing.assert_allclose(P @ coarse, fine, atol=1e-12)
    two, _ = prolongation(lattice(_disc(nz=1).mesh), layers=True)  # two layers of vertices become one
    np.testing.assert_allclose(two.sum(axis=1).A.ravel(), 1.0)


def test_vcycle_contraction_does_not_grow_with_the_levels():
    """Stationary V-cycles on a 10^4-cell sheet coarsened to 100 unknowns (four levels).

    Measured: 0.23 per cycle with the layers coarsened (MG_ASPECT), 0.66 with the plane alone;
    the bound 0.3 is that measurement with a margin.
    """
    des = gdfe.from_masks(*mask_sheet(10_000), 0.1, 0.7, nz=1)
    s = Solver(des)
    b = np.random.default_rng(0).standard_normal(len(s.free))
    mg = Multigrid(s.L_ff, lattice(des.mesh)[s.free], coarsest=100, smoothing=2)
    assert len(mg.levels) >= 4
    rho = _contraction(mg.vcycle, mg.levels[0][0], b)
    assert rho < 0.3, f"V-cycle contraction {rho:.3f} per cycle"


def test_chebyshev2_is_the_least_degree_2_polynomial_on_its_interval():
    """``1 - a mu + c mu^2`` equioscillates on ``[top / ratio, top]`` at +-1 / T2(sigma) (9/41 for the default
    ratio 4, against 2/3 for one Jacobi sweep), and stays below 1 in size on ``(0, a / c)``."""
    for ratio in (4.0, 2.5, 10.0):
        a, c = chebyshev2(ratio)
        lo, top = 4.0 / 3.0 / ratio, 4.0 / 3.0
        sigma = (top + lo) / (top - lo)
        bound = 1.0 / (2.0 * sigma ** 2 - 1.0)
        f = lambda mu: 1.0 - a * mu + c * mu * mu  # noqa: E731
        mu = np.linspace(lo, top, 2001)
        assert np.abs(f(mu)).max() == pytest.approx(bound, rel=1e-12)
        assert f(lo) == pytest.approx(bound) and f(top) == pytest.approx(bound)
        assert f((lo + top) / 2) == pytest.approx(-bound)
        inside = np.linspace(0.0, a / c, 2001)[1:-1]
        assert np.all(np.abs(f(inside)) < 1.0)
    assert 1.0 / (2.0 * (5.0 / 3.0) ** 2 - 1.0) == pytest.approx(9.0 / 41.0)


def test_chebyshev2_takes_the_setting_when_called_and_refuses_an_empty_interval(monkeypatch):
    """``MG_SOLVE_RATIO`` changed at run time is the one used (a default bound at import would ignore it), and a
    ratio that leaves no interval, or a top that is not positive, is an error naming it."""
    monkeypatch.setattr(sys.modules["gdfe.solver.multigrid"], "MG_SOLVE_RATIO", 10.0)
    assert chebyshev2() == chebyshev2(10.0) != chebyshev2(4.0)
    for ratio in (1.0, 0.5, -2.0, float("nan")):
        with pytest.raises(gdfe.GdfeError, match="ratio"):
            chebyshev2(ratio)
    with pytest.raises(gdfe.GdfeError, match="top"):
        chebyshev2(4.0, top=0.0)


def test_the_solve_cycle_contracts_faster_than_the_preconditioner_cycle():
    """Stationary cycles on the 10^4-cell sheet's four levels. Measured: 0.243 per cycle with the Chebyshev
    smoothing of :meth:`Multigrid.solve_cycle` below the finest level, 0.182 with it on every level, 0.379 with
    the Jacobi V(1,1) of :meth:`Multigrid.vcycle` (0.231 with V(2,2))."""
    des = gdfe.from_masks(*mask_sheet(10_000), 0.1, 0.7, nz=1)
    s = Solver(des)
    b = np.random.default_rng(0).standard_normal(len(s.free))
    mg = Multigrid(s.L_ff, lattice(des.mesh)[s.free], coarsest=100)
    assert len(mg.levels) >= 4
    rho = {name: _contraction(cycle, mg.levels[0][0], b) for name, cycle in (("solve", mg.solve_cycle),
                                                                           ("vcycle", mg.vcycle))}
    assert rho["solve"] < 0.27 and rho["solve"] < 0.7 * rho["vcycle"], rho


def test_every_level_spectrum_lies_below_the_top_the_smoothings_assume():
    """The damped-Jacobi weight and the solve cycle's Chebyshev polynomial both take ``1.05`` times the power
    iteration's estimate of ``lambda_max(D^-1 A)`` for the top of the spectrum; the polynomial keeps the cycle
    positive definite up to 1.25 times that top. Measured, the true largest eigenvalue over that top, by level:
    0.959, 0.997, 0.975, 0.979 on this slotted disc of three layers of cells; 0.956-0.958, 0.991-0.997 on the 10^5
    benchmark sheets."""
    des = _disc(60, nz=3, slot=True)
    s = Solver(des)
    mg = Multigrid(s.L_ff, lattice(des.mesh)[s.free], coarsest=100)
    assert len(mg.levels) >= 3
    a, c = mg.chebyshev
    # the polynomial's interval ends where the weight puts the top
    assert mg.chebyshev == chebyshev2(top=JACOBI_TOP)
    for A, _, wd in mg.levels:
        d = A.diagonal()
        np.testing.assert_allclose(wd * d, (wd * d)[0], rtol=1e-14)  # one weight over the diagonal
        assumed = JACOBI_TOP / (wd * d)[0]  # the top the weight JACOBI_TOP / top was made for
        scaled = sp.diags(1.0 / np.sqrt(d)) @ A @ sp.diags(1.0 / np.sqrt(d))
        true = eigsh(scaled, k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0]
        assert true < assumed and true * JACOBI_TOP / assumed < a / c, (true, assumed)


def test_vcycle_is_symmetric_positive_definite_and_solve_matches_the_factor():
    des = _disc()
    s = Solver(des)
    mg = Multigrid(s.L_ff, lattice(des.mesh)[s.free], coarsest=200)
    assert len(mg.levels) >= 2
    rng = np.random.default_rng(7)
    x, y = rng.standard_normal((2, len(s.free)))
    assert x @ mg.vcycle(y) == pytest.approx(y @ mg.vcycle(x), rel=1e-10)
    assert x @ mg.vcycle(x) > 0
    assert x @ mg.solve_cycle(y) == pytest.approx(y @ mg.solve_cycle(x), rel=1e-10)
    assert x @ mg.solve_cycle(x) > 0
    np.testing.assert_allclose(mg.solve_cycle(np.column_stack([x, y]))[:, 1], mg.solve_cycle(y), rtol=1e-12)
    # in single precision: the same cycle to float32's round-off
    np.testing.assert_allclose(mg.vcycle(y, single=True), mg.vcycle(y), rtol=0, atol=1e-5 * np.abs(mg.vcycle(y)).max())
    b = rng.standard_normal((len(s.free), 3))
    np.testing.assert_allclose(mg.solve(b, rtol=1e-12), s.factor.solve(b), rtol=0, atol=1e-9 * np.abs(s.factor.solve(b)).max())


def test_multigrid_path_reaches_the_factorised_shape(monkeypatch):
    des = gdfe.from_masks(*mask_sheet(900), 0.1, 0.7, nz=1)
    ref = gdfe.simulate(des, tol=1e-9).check()
    monkeypatch.setattr(sys.modules["gdfe.solver.energy"], "MULTIGRID_CELLS", 100)
    monkeypatch.setattr(sys.modules["gdfe.solver.multigrid"], "MG_COARSEST", 150)
    s = Solver(des)
    assert s.uses_multigrid and len(s.multigrid.levels) >= 2
    res = gdfe.simulate(des, tol=1e-9).check()
    assert "multigrid" in res.timings and "factorise" not in res.timings
    size = np.linalg.norm(np.ptp(des.mesh.points, axis=0))
    assert gdfe.shape_distance(ref.points, res.points)["max"] < 1e-7 * size
    assert res.energy == pytest.approx(ref.energy, rel=1e-9)


def test_dropped_caches_are_made_again_with_the_same_solve(monkeypatch):
    """Solver.drop_caches frees the Newton Hessian's structures and the multigrid; the next solve remakes them."""
    monkeypatch.setattr(sys.modules["gdfe.solver.energy"], "MULTIGRID_CELLS", 100)
    monkeypatch.setattr(sys.modules["gdfe.solver.newton"], "RELEASE_POINTS", 0)  # and the heap is trimmed each step
    des = gdfe.from_masks(*mask_sheet(900), 0.1, 0.7, nz=1)
    s = Solver(des)
    V0 = s.linearised_start(des.mesh.points.copy())
    first = s.solve(V0, method="newton-cg", tol=1e-9)
    mg, rh = s.multigrid, s.reduced_hessian
    s.drop_caches()
    assert "multigrid" not in s.__dict__ and "reduced_hessian" not in s.__dict__
    again = s.solve(V0, method="newton-cg", tol=1e-9)
    assert s.multigrid is not mg and s.reduced_hessian is not rh
    assert np.array_equal(first.points, again.points) and first.iterations == again.iterations


def test_with_a_multigrid_L_is_not_kept_and_its_products_are_exact(monkeypatch):
    """A multigrid design keeps only L's blocks (L_ff, L_fp); apply_L and the property L give L exactly."""
    from gdfe.solver.energy import system_matrix

    monkeypatch.setattr(sys.modules["gdfe.solver.energy"], "MULTIGRID_CELLS", 100)
    des = gdfe.from_masks(*mask_sheet(900), 0.1, 0.7, nz=2)
    s = Solver(des)
    assert s.uses_multigrid and s._L is None
    L = system_matrix(des).tocsr()
    assert abs(s.L - L).max() == 0.0
    V = np.random.default_rng(1).standard_normal((s.n, 3))
    np.testing.assert_allclose(s.apply_L(V), L @ V, rtol=0, atol=1e-14 * np.abs(L @ V).max())


def test_solve_from_a_guess_meets_the_same_test_in_fewer_cycles():
    """Multigrid.solve(x0=...): the residual test is relative to b, as from zero; a near guess needs fewer V-cycles."""
    des = _disc()
    s = Solver(des)
    mg = Multigrid(s.L_ff, lattice(des.mesh)[s.free], coarsest=200)
    A = s.L_ff
    b = np.random.default_rng(3).standard_normal((len(s.free), 3))
    cycles = []
    vcycle = mg.vcycle

    def counted(r, *args, **kwargs):
        cycles[-1] += 1
        return vcycle(r, *args, **kwargs)
    near = mg.solve(b, rtol=1e-7)  # an answer to 1e-7, as a Newton solve's last iterate is near its plain step
    mg.vcycle = counted
    cycles.append(0)
    cold = mg.solve(b, rtol=1e-11)
    cycles.append(0)
    warm = mg.solve(b, rtol=1e-11, x0=near)
    for x in (cold, warm):
        assert np.all(np.linalg.norm(b - A @ x, axis=0) <= 1e-11 * np.linalg.norm(b, axis=0))
    assert cycles[1] <= 0.6 * cycles[0], cycles
    np.testing.assert_allclose(warm, cold, rtol=0, atol=1e-9 * np.abs(cold).max())
    cycles.append(0)
    one = mg.solve(b[:, 0], x0=near[:, 0])  # a vector and its guess
    assert one.shape == (len(s.free),) and cycles[2] <= 0.6 * cycles[0]
    with pytest.raises(ValueError, match=r"x0: expected the shape of b"):
        mg.solve(b, x0=near.T)


def _plain_cycle(mg, b, level, levels):
    """The V-cycle as its formula reads, each product and correction a new array: the reference of the in-place one."""
    if level == len(levels):
        return mg.coarse.solve(np.asfortranarray(b, dtype=np.float64)).astype(b.dtype, copy=False)
    A, P, wd = levels[level]
    wd = wd[:, None] if b.ndim == 2 else wd
    x = wd * b
    for _ in range(mg.smoothing - 1):
        x = x + wd * (b - A @ x)
    x = x + P @ _plain_cycle(mg, P.T @ (b - A @ x), level + 1, levels)
    for _ in range(mg.smoothing):
        x = x + wd * (b - A @ x)
    return x


@pytest.mark.parametrize("smoothing", [1, 2])
def test_vcycle_in_place_gives_the_bits_of_its_formula(smoothing):
    """The V-cycle reuses each residual's array for its Jacobi correction: the same numbers, in double and single."""
    des = _disc()
    s = Solver(des)
    mg = Multigrid(s.L_ff, lattice(des.mesh)[s.free], coarsest=200, smoothing=smoothing)
    b = np.random.default_rng(3).standard_normal((len(s.free), 3))
    assert np.array_equal(mg.vcycle(b), _plain_cycle(mg, b, 0, mg._double))
    single = _plain_cycle(mg, b.astype(np.float32), 0, mg._single)
    assert mg.vcycle_single(b).dtype == np.float32
    assert np.array_equal(mg.vcycle_single(b), single)
    assert np.array_equal(mg.vcycle(b, single=True), single.astype(np.float64))


@pytest.mark.parametrize("multigrid", [False, True])
@pytest.mark.parametrize("sheet", [True, False])
def test_approx_solve_pinned_is_the_free_rows_solve_over_the_scale(monkeypatch, multigrid, sheet):
    """Newton-CG's n x n preconditioner by slices around the pinned vertex (inside the numbering on the
    sheet, the first vertex on the disc): the numbers of the index-array form."""
    if multigrid:
        monkeypatch.setattr(sys.modules["gdfe.solver.energy"], "MULTIGRID_CELLS", 100)
    s = Solver(gdfe.from_masks(*mask_sheet(900), 0.1, 0.7, nz=1) if sheet else _disc())
    assert s.uses_multigrid == multigrid and (0 < s.pin < s.n - 1 if sheet else s.pin == 0)
    r = np.random.default_rng(5).standard_normal((s.n, 3))
    r[s.pin] = 0.0
    want = np.zeros_like(r)
    want[s.free] = s.approx_solve_free(r[s.free]) / 2.5
    got = s.approx_solve_pinned(r, 2.5)
    assert got.dtype == np.float64 and np.array_equal(got, want)


def test_the_alternation_starts_each_multigrid_solve_near_its_answer(monkeypatch):
    """method="plain" above MULTIGRID_CELLS: each assembly step's solve starts from the last move repeated
    (after an Anderson mix, from the mixed iterate), to the same test: the factorised alternation's iterates,
    in fewer V-cycles than from zero."""
    from gdfe.solver.starts import flat_start

    des = gdfe.from_masks(*mask_sheet(900), 0.1, 0.7, nz=1)
    V0 = flat_start(des, 0)
    ref = {m: Solver(des).solve(V0, method=m, tol=1e-12, max_iter=12) for m in ("plain", "anderson")}
    monkeypatch.setattr(sys.modules["gdfe.solver.energy"], "MULTIGRID_CELLS", 100)
    monkeypatch.setattr(sys.modules["gdfe.solver.multigrid"], "MG_COARSEST", 150)
    size = np.linalg.norm(np.ptp(des.mesh.points, axis=0))
    for method in ("plain", "anderson"):
        s = Solver(des)
        assert s.uses_multigrid
        cycles, guesses = [], []
        solve, solve_cycle = s.multigrid.solve, s.multigrid.solve_cycle

        def counted(b, *args, x0=None, **kwargs):
            cycles.append(0)
            guesses.append(x0 is not None)
            return solve(b, *args, x0=x0, **kwargs)

        def cycle(r, *args, **kwargs):
            cycles[-1] += 1
            return solve_cycle(r, *args, **kwargs)
        s.multigrid.solve, s.multigrid.solve_cycle = counted, cycle
        st = s.solve(V0, method=method, tol=1e-12, max_iter=12)
        assert st.iterations == ref[method].iterations == 12 and all(guesses)
        if method == "plain":
            assert np.abs(st.points - ref[method].points).max() < 1e-9 * size
            np.testing.assert_allclose(st.energies, ref[method].energies, rtol=1e-9)
        else:
            # Anderson's least squares on the iterates' differences magnify any difference in the solves about
            # tenfold an iteration (measured, energies against the factorised run: 2e-13, 4e-13, 7e-12, 1e-10,
            # 6e-11, 9e-10 ... 5e-8 at the 10th; with the solves to 1e-13 instead of 1e-11, 1.3e-9), where the
            # plain alternation stays within 1e-12: its first six iterations are held to 1e-9, all to 1e-6
            assert np.abs(st.points - ref[method].points).max() < 1e-7 * size
            np.testing.assert_allclose(st.energies[:6], ref[method].energies[:6], rtol=1e-9)
            np.testing.assert_allclose(st.energies, ref[method].energies, rtol=1e-6)
        # the assembly system at the last answer's rotations solved from zero, against the solves from guesses
        o = s.orient(st.points)
        rhs = s.assemble(o.Q, V0[s.pin], solve=False).b[s.free] - s.L_fp @ V0[s.pin][None, :]
        n = len(cycles)
        counted(rhs)
        cold = cycles[n]
        # the first steps move the flat print most, and their guesses save little (measured 11, 11, 10, 9-10 against
        # 11-12 from zero); from the fifth on every solve must be shorter than that one from zero
        assert max(cycles[4:n]) < cold, (method, cycles)
