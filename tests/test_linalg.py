"""The sparse factorisations (gdfe.solver.linalg): every backend solves alike, and a Factoriser keeps its analysis."""

import logging

import numpy as np
import pytest
import scipy.sparse as sp

import gdfe
from gdfe.solver import Solver
from gdfe.solver.linalg import FACTOR_BACKENDS, Factoriser, factor_backend, factorise, installed_backends
from studies.bench import mask_sheet


def _importable():
    """The backends whose modules import here, found apart from gdfe.solver.linalg's own test."""
    out = ["superlu"]
    for backend, module in (("cholmod", "sksparse.cholmod"), ("cvxopt", "cvxopt.cholmod")):
        try:
            __import__(module)
        except ImportError:
            continue
        out.append(backend)
    return out


def _spd(n=300, seed=0):
    rng = np.random.default_rng(seed)
    R = sp.random(n, n, density=0.02, random_state=rng)
    return (R @ R.T + n * sp.eye(n)).tocsc()


@pytest.mark.parametrize("backend", FACTOR_BACKENDS)
def test_every_backend_solves_vectors_and_blocks(backend):
    if backend not in _importable():
        pytest.skip(f"{backend} is not installed")
    A = Solver(gdfe.from_masks(*mask_sheet(400), 0.1, 0.7, nz=1)).L_ff
    b = np.random.default_rng(1).standard_normal((A.shape[0], 3))
    f = factorise(A, backend=backend)
    x = f.solve(b)
    assert x.shape == b.shape
    np.testing.assert_allclose(A @ x, b, rtol=0, atol=1e-9 * np.abs(b).max())
    np.testing.assert_allclose(f.solve(b[:, 1]), x[:, 1], rtol=0, atol=1e-12 * np.abs(x).max())
    np.testing.assert_allclose(f.solve(np.asfortranarray(b)), x, rtol=0, atol=1e-12 * np.abs(x).max())
    np.testing.assert_allclose(x, factorise(A, backend="superlu").solve(b), rtol=0, atol=1e-9 * np.abs(x).max())


def test_the_default_is_the_first_installed_and_the_environment_forces_one(monkeypatch):
    monkeypatch.delenv("GDFE_FACTOR", raising=False)
    assert factor_backend() == next(b for b in FACTOR_BACKENDS if b in _importable())
    assert installed_backends() == [b for b in FACTOR_BACKENDS if b in _importable()]
    monkeypatch.setenv("GDFE_FACTOR", "superlu")
    assert factor_backend() == "superlu" and Factoriser().backend == "superlu"


def test_a_factoriser_keeps_its_pattern_and_every_factor_stays_its_own():
    cholmod = pytest.importorskip("cvxopt.cholmod")
    options = dict(cholmod.options)
    A = _spd()
    fac = Factoriser("cvxopt")
    b = np.random.default_rng(2).standard_normal(A.shape[0])
    first = fac(A)
    pattern = fac._pattern
    x1 = first.solve(b)
    np.testing.assert_allclose(A @ x1, b, rtol=0, atol=1e-10 * np.abs(b).max())
    B = A.copy()
    B.data *= 2.0  # the same pattern, other values
    second = fac(B)
    assert fac._pattern is pattern
    np.testing.assert_allclose(second.solve(b), 0.5 * x1, rtol=1e-10, atol=0)
    np.testing.assert_allclose(first.solve(b), x1, rtol=1e-12, atol=0)  # unchanged by the second
    assert dict(cholmod.options) == options  # CVXOPT's options, shared by the process, given back
    C = _spd(seed=5)  # another pattern: made anew
    np.testing.assert_allclose(C @ fac(C).solve(b), b, rtol=0, atol=1e-10 * np.abs(b).max())
    assert fac._pattern is not pattern
    # a matrix not in canonical form (unsorted, duplicated entries) is the same matrix
    coo = A.tocoo()
    dup = sp.coo_matrix((np.concatenate([coo.data, 0.0 * coo.data[:5]]), (np.concatenate([coo.row, coo.row[:5]]),
                         np.concatenate([coo.col, coo.col[:5]]))), shape=A.shape).tocsc()
    np.testing.assert_allclose(fac(dup).solve(b), x1, rtol=1e-10, atol=0)


@pytest.mark.parametrize("backend", ["cholmod", "cvxopt"])
def test_cholmod_falls_back_to_superlu_on_an_indefinite_matrix(backend, caplog):
    if backend not in _importable():
        pytest.skip(f"{backend} is not installed")
    A = _spd()
    A = (A - 1.5 * A.shape[0] * sp.eye(A.shape[0])).tocsc()  # indefinite, nonsingular
    b = np.random.default_rng(3).standard_normal(A.shape[0])
    with caplog.at_level(logging.INFO, logger="gdfe.solver.linalg"):
        x = Factoriser(backend)(A).solve(b)
    assert "not positive definite" in caplog.text
    np.testing.assert_allclose(A @ x, b, rtol=0, atol=1e-8 * np.abs(b).max())


def test_the_newton_cg_answer_does_not_depend_on_the_backend(monkeypatch):
    des = gdfe.from_masks(*mask_sheet(900), 0.1, 0.7, nz=1)
    answers = {}
    for backend in _importable():
        monkeypatch.setenv("GDFE_FACTOR", backend)
        res = gdfe.simulate(des, method="newton-cg", tol=1e-9).check()
        answers[backend] = res
    ref = answers["superlu"]
    size = np.linalg.norm(np.ptp(des.mesh.points, axis=0))
    for backend, res in answers.items():
        assert res.energy == pytest.approx(ref.energy, rel=1e-9), backend
        assert gdfe.shape_distance(res.points, ref.points)["max"] < 1e-7 * size, backend


def test_a_backend_that_is_not_installed_is_refused_with_what_it_needs(monkeypatch):
    from gdfe._validation import GdfeError

    missing = [b for b in FACTOR_BACKENDS if b not in _importable()]
    if not missing:
        pytest.skip("every backend is installed")
    with pytest.raises(GdfeError, match=f"backend: the '{missing[0]}' factorisation needs"):
        Factoriser(missing[0])
    monkeypatch.setenv("GDFE_FACTOR", missing[0])
    with pytest.raises(GdfeError, match=f"GDFE_FACTOR: the '{missing[0]}' factorisation needs .*installed here: "):
        factor_backend()
