"""The multilevel preconditioner on the Hessian, the forcing sequence and the array-module (GPU) path.

No GPU is needed: the GPU code paths run with an array module that is NumPy under another
name (:class:`_NumpyModule`), so every branch taken for CuPy (products on the module, the
polar decomposition by batched SVD, the V-cycle's smoothers) runs here on the CPU.
"""

import types

import numpy as np
import pytest

import gdfe
from gdfe.solver import Solver
from gdfe.solver import amg, device
from gdfe.solver import newton as nw
from gdfe.solver.energy import rotations

pyamg = pytest.importorskip("pyamg")


def _NumpyModule():
    """NumPy's functions under a module that is not ``numpy`` itself (takes the GPU branches)."""
    mod = types.ModuleType("numpy_as_device")
    for name in ("asarray", "einsum", "matmul", "linalg", "sign", "where", "zeros", "float64"):
        setattr(mod, name, getattr(np, name))
    return mod


def _disc(n=20, nz=1):
    x = (np.arange(n) + 0.5) / n - 0.5
    film = np.hypot(*np.meshgrid(x, x, indexing="ij")) <= 0.5
    top = np.mod(np.arange(n), 6)[:, None] * np.ones((1, n), int) >= 2
    return gdfe.from_masks(top, np.ones((n, n), bool), 0.1, 0.7, nz=nz, film=film)


def _state(des):
    sv = Solver(des)
    V = sv.linearised_start(des.mesh.points.copy())
    return sv, V, sv.orient(V), sv.rest(1.0), sv.reduced_hessian


def test_assembled_blocks_are_the_hessian():
    """The block assembly equals ReducedHessian.matrix (sparse J^T J) off the pinned vertex; identity on it."""
    sv, V, o, rest, hs = _state(_disc(n=12, nz=2))
    mu = 1e-3
    lin = hs.linearise(o.Q, o.S, rest, floor=1.0)
    A = amg.hessian_blocks(hs, lin, rest, mu, hs.block_pattern)
    H = hs.matrix(o.Q, o.S, rest, mu=mu)
    free = np.ones(3 * sv.n, bool)
    free[3 * sv.pin:3 * sv.pin + 3] = False
    Ad, Hd = A.toarray(), H.toarray()
    scale = np.abs(Hd).max()
    np.testing.assert_allclose(Ad[np.ix_(free, free)], Hd[np.ix_(free, free)], rtol=0, atol=1e-12 * scale)
    np.testing.assert_array_equal(Ad[~free][:, ~free], np.eye(3))
    assert np.abs(Ad[~free][:, free]).max() == 0 and np.abs(Ad[free][:, ~free]).max() == 0
    np.testing.assert_allclose(Ad, Ad.T, rtol=0, atol=1e-12 * scale)


def test_translations_are_in_the_null_space_and_rotations_are_rigid_modes():
    sv, V, o, rest, hs = _state(_disc())
    lin = hs.linearise(o.Q, o.S, rest, floor=1.0)
    A = amg.hessian_blocks(hs, lin, rest, 0.0, hs.block_pattern)
    B = amg.rigid_modes(V)
    # away from the pinned vertex and its neighbours (their rows lost the pin's column)
    near = np.unique(sv.cells[np.any(sv.cells == sv.pin, axis=1)])
    rows = np.setdiff1d(np.arange(sv.n), near)
    out = (A @ B[:, :3]).reshape(sv.n, 3, 3)[rows]
    assert np.abs(out).max() <= 1e-10 * np.abs(A.data).max()
    # the rotations: omega x (V - c), unit axes; orthogonal to the translations
    r = V - V.mean(axis=0)
    size = np.sqrt(np.mean(np.sum(r * r, axis=1)))
    np.testing.assert_allclose(B[:, 5].reshape(-1, 3), np.cross([0.0, 0.0, 1.0], r) / size)
    np.testing.assert_allclose(B[:, :3].T @ B[:, 3:], 0.0, atol=1e-9 * sv.n)
    assert np.all(amg.rigid_modes(V, sv.pin).reshape(sv.n, 3, 6)[sv.pin] == 0)


@pytest.mark.parametrize("module", ["numpy", "device"])
def test_vcycle_is_symmetric_positive_definite_and_preconditions_cg(module):
    """One V-cycle is an SPD operator (CG's requirement); with it CG solves the Hessian in few iterations."""
    sv, V, o, rest, hs = _state(_disc(n=28))
    mu = 1e-3
    xp = np if module == "numpy" else _NumpyModule()
    lin = hs.linearise(o.Q, o.S, rest, floor=1.0)
    A = amg.hessian_blocks(hs, lin, rest, mu, hs.block_pattern)
    ml = amg.HessianAMG(A, amg.rigid_modes(V, sv.pin), xp=xp, max_coarse=60)
    assert len(ml.sizes) >= 3 and ml.sizes[-1] <= 60 and 1.0 <= ml.complexity < 2.0
    rng = np.random.default_rng(5)
    x, y = rng.standard_normal((2, 3 * sv.n))
    Mx, My = ml.vcycle(x), ml.vcycle(y)
    assert y @ Mx == pytest.approx(x @ My, rel=1e-10)
    assert x @ Mx > 0 and y @ My > 0
    ops = hs.amg_operator(lin, rest, mu, ml, xp=xp)
    apply_H, apply_P = ops.apply_H, ops.apply_P
    b = rng.standard_normal((sv.n, 3))
    b[sv.pin] = 0.0
    s, k = nw.pcg(apply_H, apply_P, b, 1e-8, 300)
    unpre, k0 = nw.pcg(apply_H, lambda r: r.copy(), b, 1e-8, 3000)
    res = apply_H(s) - b
    assert np.linalg.norm(res) <= 1e-6 * np.linalg.norm(b)
    assert k < k0 / 4, f"AMG-CG took {k} iterations, plain CG {k0}"


def test_amg_products_on_the_device_module_match_numpy():
    """The Hessian product with J and L moved to the array module is the NumPy one."""
    sv, V, o, rest, hs = _state(_disc())
    lin = hs.linearise(o.Q, o.S, rest, floor=0.5)
    A = amg.hessian_blocks(hs, hs.linearise(o.Q, o.S, rest, floor=1.0), rest, 1e-3, hs.block_pattern)
    ml = amg.HessianAMG(A, amg.rigid_modes(V, sv.pin))
    v = np.random.default_rng(1).standard_normal((sv.n, 3))
    H_np = hs.amg_operator(lin, rest, 1e-3, ml).apply_H
    H_dev = hs.amg_operator(lin, rest, 1e-3, ml, xp=_NumpyModule()).apply_H
    np.testing.assert_allclose(H_dev(v), H_np(v), rtol=1e-12, atol=1e-14)
    H_two = hs.operator(lin, rest, 1e-3).apply_H
    np.testing.assert_allclose(H_np(v), H_two(v), rtol=1e-12, atol=1e-14 * np.abs(H_two(v)).max())


def test_polar_by_svd_matches_the_polar_iteration_and_handles_reflections():
    rng = np.random.default_rng(2)
    S = rng.standard_normal((200, 3, 3))
    S[:50] *= -1.0  # reflections among them
    Q = device.polar(S, np)
    Qi, _ = rotations(S)
    np.testing.assert_allclose(Q, Qi, atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(Q), 1.0, atol=1e-12)
    np.testing.assert_allclose(device.polar(S, _NumpyModule()), Q, atol=1e-14)


def test_device_choice_falls_back_to_the_cpu_and_refuses_a_missing_gpu(monkeypatch):
    monkeypatch.setattr(device, "_cupy", lambda: None)
    assert device.resolve("auto") == "cpu" and device.resolve("cpu") == "cpu"
    assert device.array_module("auto") is np
    assert not device.gpu_available()
    with pytest.raises(gdfe.GdfeError, match=r"device: expected 'auto' or 'cpu' here, got 'gpu'"):
        device.resolve("gpu")
    with pytest.raises(gdfe.GdfeError, match=r"device: expected one of"):
        device.resolve("tpu")
    with pytest.raises(gdfe.GdfeError, match="device"):
        Solver(_disc(), device="gpu")
    with pytest.raises(gdfe.GdfeError, match="preconditioner"):
        Solver(_disc(), preconditioner="ilu")
    assert Solver(_disc(), device="auto").preconditioner == "two-level"


def test_forcing_sequence_is_eisenstat_walker_choice_2_safeguarded():
    g, a = nw.EW_GAMMA, nw.EW_ALPHA
    assert nw.forcing_term(1.0, None, None) == nw.CG_RTOL_MAX
    # superlinear phase: the residual fell 10x, the previous term small: gamma (1/10)^alpha
    assert nw.forcing_term(1e-2, 1e-1, 1e-3) == pytest.approx(max(g * 0.1 ** a, nw.CG_RTOL_MIN))
    # the safeguard: the previous term large, the term does not drop below gamma eta_prev^alpha
    assert nw.forcing_term(1e-6, 1.0, 0.9) == pytest.approx(min(nw.CG_RTOL_MAX, g * 0.9 ** a))
    # clipped, and no tighter than the margin the stopping test still needs
    assert nw.forcing_term(1e-12, 1.0, 1e-3) == nw.CG_RTOL_MIN
    assert nw.forcing_term(1e-12, 1.0, 1e-3, target=1e-4, error=1e-3) == pytest.approx(nw.CG_TARGET_MARGIN * 0.1)
    # never looser than the square root of the plain step's residual (the stopping test reads the step)
    assert nw.forcing_term(2.0, 1.0, 0.5, plain=1e-4) == pytest.approx(1e-2)
    assert nw.forcing_term(2.0, 1.0, 0.5, plain=1e-4) <= nw.sqrt_forcing(1e-4)


def _sheet():
    from studies.bench import SHEET_PIXEL, SHEET_R, mask_sheet

    return gdfe.from_masks(*mask_sheet(200), SHEET_PIXEL, SHEET_R, h=0.29, nz=1)


@pytest.mark.parametrize("module", ["numpy", "device"])
def test_newton_cg_with_amg_reaches_the_two_level_answer(module, monkeypatch):
    """The same stopping test, the same answer: energy and shape of the AMG solve (on NumPy, and on
    the device branches run with NumPy) against the two-level preconditioner's."""
    des = _sheet()
    ref = Solver(des)
    V0 = ref.linearised_start(des.mesh.points.copy())
    a = ref.solve(V0, method="newton-cg", tol=1e-8)
    sv = Solver(des, preconditioner="amg")
    if module == "device":
        sv.xp = _NumpyModule()  # the orientation step's polar decomposition by SVD on the module
        monkeypatch.setattr(device, "array_module", lambda d="auto": _NumpyModule())
    b = sv.solve(V0, method="newton-cg", tol=1e-8)
    assert a.converged and b.converged
    assert b.energies[-1] == pytest.approx(a.energies[-1], rel=1e-9)
    # each within STEP_TOL_FACTOR tol h of the solution, after the rigid motion (a null mode) is taken out
    gap = gdfe.shape_distance(a.points, b.points)["max"]
    assert gap <= 2 * nw.STEP_TOL_FACTOR * 1e-8 * des.h, f"shapes differ by {gap:.2e} mm"
    assert b.cg_iterations > 0


def test_amg_preconditioner_without_pyamg_is_refused(monkeypatch):
    monkeypatch.setattr(amg, "available", lambda: False)
    sv = Solver(_disc(), preconditioner="amg")
    with pytest.raises(gdfe.GdfeError, match="preconditioner: expected 'two-level' here, got 'amg'"):
        sv.solve(sv.design.mesh.points.copy(), method="newton-cg")


def test_simulate_names_its_device(monkeypatch):
    monkeypatch.setattr(device, "_cupy", lambda: None)
    des = gdfe.hinge(1.6, d=0.33)
    with pytest.raises(gdfe.GdfeError, match=r"device: expected 'auto' or 'cpu' here, got 'gpu'"):
        gdfe.simulate(des, device="gpu")
    with pytest.raises(gdfe.GdfeError, match=r"device: expected one of"):
        gdfe.simulate(des, device="cuda")
    a, b = gdfe.simulate(des, device="cpu"), gdfe.simulate(des)  # "auto" is the CPU here
    assert a.converged and b.converged and a.energy == b.energy
    assert a.device == b.device == "cpu" and a.summary()["device"] == "cpu"


def test_vanishing_damping_keeps_the_answer_and_the_stopping_test():
    """With the damping's floor falling with the residual, the same converged shape as with it held."""
    des = _sheet()
    held = Solver(des, vanishing_damping=False)
    V0 = held.linearised_start(des.mesh.points.copy())
    a = held.solve(V0, method="newton-cg", tol=1e-8)
    b = Solver(des).solve(V0, method="newton-cg", tol=1e-8)
    assert a.converged and b.converged
    assert b.error_estimate <= nw.STEP_TOL_FACTOR * 1e-8 and b.residual <= 1e-8
    assert gdfe.shape_distance(a.points, b.points)["max"] <= 2 * nw.STEP_TOL_FACTOR * 1e-8 * des.h
