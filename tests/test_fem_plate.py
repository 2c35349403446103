"""The reference FEM's plates meshed from designs: mesh, verification, solvers, files, command."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("skfem")

import gdfe  # noqa: E402
import reference_fem as rf  # noqa: E402
from gdfe._validation import GdfeError, GdfeTypeError  # noqa: E402
from reference_fem.mesh import BOTTOM_COAT, FILM, TOP_COAT  # noqa: E402
from reference_fem.plate_verify import plate_convergence, plate_strip_check, plate_timoshenko_check  # noqa: E402


# -- the mesh ----------------------------------------------------------------------------------------------


def test_plate_mesh_puts_the_coat_where_each_face_is_printed():
    # R: both faces, T: bottom coated (top free), B: top coated, S: none, .: no film
    des = gdfe.from_rows(["RT", "BS", ".R"], R=0.8, h=0.3, pixel=0.5)
    plate = rf.plate_mesh(des, d=0.2, refine=1, layers_per_ply=2)
    mat = plate.grid.material
    assert mat.shape == (2, 3)
    per_cell = {}
    for (i, j), ply in zip(map(tuple, plate.cell), plate.ply):
        per_cell.setdefault((i, j), []).append(int(ply))
    counts = {k: (v.count(BOTTOM_COAT), v.count(FILM), v.count(TOP_COAT)) for k, v in per_cell.items()}
    # rows are listed top (largest y) first: j = 2 is "RT", j = 1 "BS", j = 0 ".R"
    assert counts[(0, 2)] == (2, 2, 2)  # R
    assert counts[(1, 2)] == (2, 2, 0)  # T: bottom coat only
    assert counts[(0, 1)] == (0, 2, 2)  # B: top coat only
    assert counts[(1, 1)] == (0, 2, 0)  # S: bare film
    assert (0, 0) not in counts  # no film there
    assert counts[(1, 0)] == (2, 2, 2)
    z = plate.mesh.p[2]
    assert np.isclose(z.min(), -0.2) and np.isclose(z.max(), 0.3 + 0.2)


def test_plate_mesh_refines_and_takes_each_cells_coat_thickness():
    top = np.zeros((4, 2), bool)
    bottom = np.ones((4, 2), bool)
    des = gdfe.from_masks(top, bottom, 0.5, R=0.8, h=0.29, d=0.3)
    plate = rf.plate_mesh(des, refine=2, layers_per_ply=1)
    assert plate.n_elements == 4 * 2 * 4 * 2  # 2 x 2 per cell, film and bottom coat one layer each
    assert np.allclose(plate.in_plane_step, 0.25)
    # a thicker coat on one half: two node levels in the bottom coat, thicker elements kept only there
    des.d[des.mesh.cell_ij[:, 0] >= 2] = 0.5
    thick = rf.plate_mesh(des, refine=1, layers_per_ply=2)
    assert thick.meta["coat_levels_mm"]["bottom"] == [0.3, 0.5]
    lowest = thick.mesh.p[2, thick.mesh.t].min(axis=0)
    deep = thick.cell[np.isclose(lowest, -0.5), 0]
    assert deep.size and (deep >= 2).all()


def test_coarsen_takes_the_majority_material_of_each_block():
    # a lone S cell would vanish in its block: refused (a one-pixel hinge vanished so, silently)
    with pytest.raises(GdfeError, match="coarsen: expected a factor that keeps the film's extent and every region"):
        rf.plate_mesh(gdfe.from_rows(["TTRR", "TSRR", "RRRR", "RR.."], R=0.8, h=0.29, pixel=0.25), d=0.3, coarsen=2)
    rows = ["TTRR", "TTRR", "RRRR", "RR.."]
    des = gdfe.from_rows(rows, R=0.8, h=0.29, pixel=0.25)
    plate = rf.plate_mesh(des, d=0.3, coarsen=2, refine=1)
    mat = plate.grid.material
    assert mat.shape == (2, 2)
    assert np.allclose(plate.grid.pixel, 0.5)
    # the block of four T is T; the block with two film cells of four is still film
    assert mat[0, 1] == int(gdfe.Material.CONTRACT_TOP)
    assert mat[1, 1] == int(gdfe.Material.RIGID)
    assert mat[1, 0] == int(gdfe.Material.RIGID)


def test_plate_mesh_checks_its_input():
    des = gdfe.from_rows(["RT"], R=0.8, h=0.29, pixel=0.5)
    with pytest.raises(GdfeError, match="d: expected a passive coat thickness"):
        rf.plate_mesh(des)  # made from R alone: no coat thickness anywhere
    with pytest.raises(GdfeTypeError, match="design: expected a gdfe.Design"):
        rf.plate_mesh("plate.toml", d=0.3)
    with pytest.raises(GdfeError, match="refine"):
        rf.plate_mesh(des, d=0.3, refine=0)
    with pytest.raises(GdfeError, match="resolution"):
        rf.plate_mesh(des, d=0.3, resolution="ultra")
    many = gdfe.from_rows(["TTTT"], R=0.8, h=0.29, pixel=0.5)
    many.d = np.array([0.1, 0.2, 0.3, 0.4])
    with pytest.raises(GdfeError, match="at most 2 distinct bottom coat"):
        rf.plate_mesh(many, max_coat_levels=2)
    with pytest.raises(GdfeTypeError, match="plate: expected a reference_fem.Plate"):
        rf.solve_plate(des)
    with pytest.raises(GdfeError, match="support"):
        rf.solve_plate(rf.plate_mesh(des, d=0.3, resolution="coarse"), support="pinned")


# -- invariants --------------------------------------------------------------------------------------------


def _plate(rows=("RT", "SB"), pixel=0.5, refine=1):
    return rf.plate_mesh(gdfe.from_rows(list(rows), R=0.8, h=0.29, pixel=pixel), d=0.33, refine=refine,
                         layers_per_ply=2)


def test_tangent_is_symmetric_with_rigid_motions_in_its_null_space():
    from reference_fem._kernel import Discretisation, linear_system
    from reference_fem.linear_solvers import _rigid_modes
    from reference_fem.plate_solve import plate_fields

    plate = _plate()
    disc = Discretisation(plate, "hex2")
    lam, mu, _, eps = plate_fields(plate, rf.BilayerMaterial(), disc.n_el)
    K, _ = linear_system(disc, lam, mu, eps)
    assert abs(K - K.T).max() <= 1e-10 * abs(K).max()
    B = _rigid_modes(disc.X)
    assert np.abs(K @ B).max() <= 1e-8 * abs(K).max() * np.abs(B).max()


def test_no_eigenstrain_no_motion_and_a_sandwich_stays_flat():
    still = rf.solve_plate(_plate(), rf.BilayerMaterial(eigenstrain=0.0))
    assert still.converged and np.abs(still.displacement).max() < 1e-12
    sandwich = rf.solve_plate(_plate(("RR", "RR")), rf.BilayerMaterial())
    assert sandwich.converged
    X, x = rf.plate_measure.midsurface(sandwich)
    assert np.ptp(x[:, 2]) < 1e-9  # coated on both faces: it shrinks, it does not bend
    shrink = np.ptp(x[:, 0]) / np.ptp(X[:, 0]) - 1
    assert -0.16 < shrink < 0  # less than the free film's contraction: the coats resist it


def test_amg_and_direct_solvers_agree_and_report_their_cost():
    pytest.importorskip("pyamg")
    plate = _plate(refine=1)
    mat = rf.BilayerMaterial(eigenstrain=-0.05)
    a = rf.solve_plate(plate, mat, solver="direct", linear=True)
    b = rf.solve_plate(plate, mat, solver="amg", linear=True)
    assert a.converged and b.converged and b.solver == "amg"
    assert np.abs(a.displacement - b.displacement).max() < 1e-6 * np.abs(a.displacement).max()
    for res in (a, b):
        c = res.cost
        assert c["factorisations"] >= c["newton_iterations"] == 1
        assert c["limit_s"] > 0 and c["over_limit"] >= 0.5


def test_reused_factorisations_reach_the_same_shape_for_less():
    plate = _plate(refine=1)
    mat = rf.BilayerMaterial(eigenstrain=-0.1)
    # both well inside the stopping test, so that their difference is the solver's, not the tolerance's
    plain = rf.solve_plate(plate, mat, reuse=False, tol=1e-10)
    modified = rf.solve_plate(plate, mat, reuse=True, tol=1e-10)
    assert plain.converged and modified.converged
    assert np.abs(plain.displacement - modified.displacement).max() < 1e-6 * np.abs(plain.displacement).max()
    c = plain.cost
    assert c["factorisations"] == c["newton_iterations"] == plain.iterations  # one per iteration: the limit
    assert c["assemblies"] >= c["newton_iterations"]
    assert sum(c["iterations_per_step"]) <= plain.iterations
    m = modified.cost
    assert m["factorisations"] <= m["newton_iterations"]
    assert m["factorisations"] < c["factorisations"], (m["factorisations"], c["factorisations"])


def test_kept_factorisations_and_one_load_step_reach_the_shape_of_plain_newton():
    # inexact Newton (GMRES preconditioned by kept factorisations), all the eigenstrain in one step,
    # against plain Newton over four load steps with a factorisation every iteration: the same
    # stopping test, the same shape. Both well inside the default test (1e-8), so that their
    # difference is the solver's, not the tolerance's: GMRES's cap is measured in seconds, so on a
    # loaded machine the inexact path differs, and at 1e-8 its shape once lay 3.7e-5 of the
    # deflection from plain Newton's (5.7e-7 on a quiet machine; 7.5e-10 at 1e-10)
    plate = _plate(("RTS", "SBR"), refine=2)
    mat = rf.BilayerMaterial()  # the full calibrated eigenstrain: a strongly nonlinear curl
    fast = rf.solve_plate(plate, mat, steps=1, tol=1e-10)
    plain = rf.solve_plate(plate, mat, steps=4, reuse=False, tol=1e-10)
    assert fast.converged and plain.converged
    assert fast.residual < 1e-10 and plain.residual < 1e-10
    size = np.abs(plain.displacement).max()
    assert size > 0.1  # a large deflection, not a linear problem
    assert np.abs(fast.displacement - plain.displacement).max() < 1e-5 * size
    f, c = fast.cost, plain.cost
    assert c["factorisations"] == c["newton_iterations"]  # the limit: one per iteration
    assert f["krylov_iterations"] > 0 and f["krylov_solves"] > 0
    assert f["factorisations"] < f["newton_iterations"], f
    assert f["assemblies"] <= f["newton_iterations"]  # no tangent for a modified Newton step
    assert f["analyses"] == 1 or fast.solver != "pardiso"  # one pattern, analysed once
    parts = ("setup_s", "assembly_s", "residual_s", "analysis_s", "factor_s", "solve_s", "krylov_s", "other_s")
    assert sum(f[k] for k in parts) == pytest.approx(fast.seconds, rel=0.02)  # the split adds up
    assert 0.0 <= f["krylov_solve_s"] <= f["solve_s"]


def test_gmres_reaches_its_tolerance_on_the_true_residual():
    import scipy.sparse as sp

    from reference_fem.linear_solvers import LinearCost, SymmetricCSR, gmres

    rng = np.random.default_rng(3)
    n = 300
    R = sp.random(n, n, density=0.03, random_state=4)
    A = (R + R.T + sp.diags(np.full(n, 6.0))).tocsr()
    b = rng.standard_normal(n)
    M = np.linalg.inv((A + sp.diags(rng.uniform(0.0, 1.0, n))).toarray())  # a perturbed exact inverse
    cost = LinearCost()
    res = gmres(SymmetricCSR(sp.triu(A, format="csr")), b, lambda r, c: M @ r, cost, rtol=1e-9, maxiter=40)
    true = np.linalg.norm(A @ res.x - b) / np.linalg.norm(b)
    assert res.converged and true < 1e-9
    assert res.residual == pytest.approx(true, rel=1e-3, abs=1e-12)
    assert cost.krylov_iterations == res.iterations < 40
    short = gmres(A, b, lambda r, c: r, LinearCost(), rtol=1e-9, maxiter=3)  # no preconditioner, 3 steps
    assert not short.converged and short.iterations == 3
    assert short.residual == pytest.approx(np.linalg.norm(A @ short.x - b) / np.linalg.norm(b), rel=1e-6)


@pytest.mark.parametrize("law", ["neohookean", "svk"])
def test_tangent_assembled_on_the_free_upper_pattern_is_the_sliced_matrix(law):
    """The upper pattern scatters only each element matrix's own upper triangle (half its entries)."""
    import scipy.sparse as sp

    from reference_fem._kernel import STATES, Discretisation
    from reference_fem.linear_solvers import SymmetricCSR
    from reference_fem.plate_solve import fixed_dofs, plate_fields

    plate = _plate()
    disc = Discretisation(plate, "hex2")
    free = np.setdiff1d(np.arange(disc.ndofs), fixed_dofs(plate, disc.X))
    lam, mu, G, _ = plate_fields(plate, rf.BilayerMaterial(), disc.n_el, scale=0.5)
    u = 0.01 * np.random.default_rng(5).standard_normal(disc.ndofs)
    state = STATES[law]
    e, f, K = state(disc, u, lam, mu, G)
    pattern = disc.pattern(free, upper=True)
    n = 3 * disc.n_bf  # the upper triangles of the element matrices, diagonal included: n (n + 1) / 2 each
    assert pattern.scatter.shape[1] == disc.n_el * n * (n + 1) // 2
    e2, f2, U = state(disc, u, lam, mu, G, pattern=pattern)
    assert e2 == e and np.array_equal(f2, f)
    ref = sp.triu(K[free][:, free], format="csr")
    ref.sort_indices()
    assert np.array_equal(U.indptr, ref.indptr) and np.array_equal(U.indices, ref.indices)
    assert np.abs(U.data - ref.data).max() <= 1e-12 * np.abs(ref.data).max()
    x = np.random.default_rng(6).standard_normal(free.size)
    A = K[free][:, free]
    assert np.abs(SymmetricCSR(U).matvec(x) - A @ x).max() <= 1e-12 * np.abs(A @ x).max()


def test_pardiso_analyses_a_pattern_once_and_refuses_a_replaced_factorisation():
    pytest.importorskip("pypardiso")
    import scipy.sparse as sp

    from reference_fem.linear_solvers import LinearCost, SymmetricCSR, make_solver

    factor, method = make_solver("direct", 50)
    assert method == "pardiso"
    n = 50
    main = np.full(n, 4.0)
    A = sp.diags([main, -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1], format="csr")
    B = (A + sp.diags(np.linspace(0.0, 1.0, n))).tocsr()
    b = np.random.default_rng(7).standard_normal(n)
    cost = LinearCost()
    solve_a = factor(SymmetricCSR(sp.triu(A, format="csr")), cost)
    assert np.abs(A @ solve_a(b, cost) - b).max() < 1e-12
    solve_b = factor(B, cost)  # the same pattern: numerical factorisation only
    assert np.abs(B @ solve_b(b, cost) - b).max() < 1e-12
    assert (cost.analyses, cost.factorisations, cost.solves) == (1, 2, 2)
    with pytest.raises(RuntimeError, match="replaced"):
        solve_a(b, cost)


def test_clamped_edge_stays_put():
    plate = _plate(("TT", "TT"))
    res = rf.solve_plate(plate, rf.BilayerMaterial(eigenstrain=-0.05), support="clamped")
    assert res.converged
    X = res.points
    edge = np.isclose(X[:, 0], X[:, 0].min()) & (X[:, 2] >= -1e-12) & (X[:, 2] <= plate.h + 1e-12)
    assert np.abs(res.displacement[edge]).max() == 0.0
    assert np.abs(res.displacement).max() > 1e-3


# -- verification ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("nu, tol", [(0.0, 1e-3), (0.35, 3e-3)])
def test_uniformly_coated_plate_matches_timoshenko(nu, tol):
    check = plate_timoshenko_check(nu=nu)
    assert check["converged"]
    assert check["rel_error"] < tol, (f"plate curvature {check['kappa_fem_per_mm']:.6e} against Timoshenko "
                                      f"{check['kappa_timoshenko_per_mm']:.6e}: {check['rel_error']:.2e}")
    assert abs(check["k_xx_per_mm"] - check["k_yy_per_mm"]) < 1e-6 * abs(check["k_xx_per_mm"])
    assert abs(check["k_xy_per_mm"]) < 1e-6 * abs(check["k_xx_per_mm"])


@pytest.mark.slow
def test_strip_cut_from_a_plate_design_matches_the_strip_model():
    check = plate_strip_check()
    assert check["converged"]
    assert check["turn_plate_rad"] > 0.3  # it folds, towards its free top face
    assert check["turn_diff_rad"] < 1e-3 * check["turn_strip_rad"], check
    assert check["max_mm"] < 1e-4 * check["length_mm"], check


@pytest.mark.slow
def test_plate_shape_converges_at_the_observed_order():
    # a plate coated all over: a smooth solution; quadratic elements converge at order 2 or more
    smooth = plate_convergence(gdfe.from_rows(["TT"], R=0.8, h=0.29, pixel=1.0), (1, 2, 4), d=0.33)
    assert all(r["converged"] for r in smooth["rows"])
    assert smooth["order"] > 1.7, f"observed order {smooth['order']:.2f} (expected about 2)"
    # a hinge: the coat ends are re-entrant corners, the order drops, the differences still shrink
    hinge = plate_convergence(gdfe.from_rows(["RTTR"], R=0.8, h=0.29, pixel=0.5), (1, 2, 4),
                              rf.BilayerMaterial(eigenstrain=-0.02), d=0.33, steps=1)
    diffs = [r["diff_mm"] for r in hinge["rows"][:-1]]
    assert diffs[1] < diffs[0]
    assert hinge["order"] > 0.3, f"observed order {hinge['order']:.2f}"


# -- files and the command ---------------------------------------------------------------------------------


def test_vtu_series_reads_back(tmp_path):
    meshio = pytest.importorskip("meshio")
    plate = _plate()
    res = rf.solve_plate(plate, rf.BilayerMaterial(eigenstrain=-0.05), keep_steps=True)
    pvd = rf.write_plate_series(res, tmp_path, "fem")
    text = pvd.read_text()
    n_frames = text.count("<DataSet")
    assert n_frames == 1 + sum(s["accepted"] for s in res.steps)
    last = meshio.read(tmp_path / f"fem_{n_frames - 1:03d}.vtu")
    nv = plate.mesh.p.shape[1]
    assert last.points.shape == (nv, 3)
    assert np.allclose(last.points, res.deformed[:nv])
    assert np.array_equal(last.cell_data["ply"][0], plate.ply)
    first = meshio.read(tmp_path / "fem_000.vtu")
    assert np.allclose(first.points, plate.mesh.p.T)


def test_fem_simulate_command(tmp_path, capsys):
    from gdfe.cli import main

    design = tmp_path / "plate.toml"
    design.write_text('[film]\nh = 0.29\nd = 0.33\n[layout]\npixel = 0.5\nrows = ["RTTR", "SBBR"]\n')
    out = tmp_path / "out"
    assert main(["fem", "simulate", str(design), "--out", str(out), "--resolution", "coarse",
                 "--eigenstrain=-0.05", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["converged"] is True
    assert summary["n_elements"] > 0 and summary["dofs"] > 0 and summary["seconds"] > 0
    assert summary["cost"]["newton_iterations"] >= 1
    assert (out / "fem.pvd").exists() and (out / "fem.json").exists()
    assert json.loads((out / "fem.json").read_text())["n_elements"] == summary["n_elements"]
    from gdfe.cli._vocabulary import known_keys

    assert not set(summary) - known_keys("fem simulate")
    # a design made from R alone needs --d
    bare = tmp_path / "bare.toml"
    bare.write_text('[film]\nh = 0.29\nR = 0.8\n[layout]\npixel = 0.5\nrows = ["RT"]\n')
    assert main(["fem", "simulate", str(bare), "--out", str(tmp_path / "o2"), "--resolution", "coarse"]) == 1
    assert "pass d" in capsys.readouterr().err


def test_superlu_serves_where_pardiso_is_not_installed(monkeypatch):
    import sys

    from reference_fem.linear_solvers import make_solver

    plate = _plate()
    mat = rf.BilayerMaterial(eigenstrain=-0.05)
    first = rf.solve_plate(plate, mat)
    monkeypatch.setitem(sys.modules, "pypardiso", None)  # an import of it now fails
    assert make_solver("direct", 10)[1] == "superlu"
    fallback = rf.solve_plate(plate, mat)
    assert fallback.solver == "superlu" and fallback.converged
    assert np.abs(first.displacement - fallback.displacement).max() < 1e-8
