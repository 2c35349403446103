"""Sparse linear solvers for the Newton steps of the reference FEM, chosen by size, with their cost.

``"direct"``
    A sparse direct factorisation per Newton iteration, exact to round-off: MKL PARDISO's
    symmetric indefinite LDL^T (pypardiso, where installed: the ``fem-fast`` extra), else
    SuperLU's LU with a minimum-degree ordering of ``A^T + A``. The fill grows faster than the
    unknowns.
``"amg"``
    Conjugate gradients preconditioned by smoothed-aggregation algebraic multigrid (pyamg), the
    six rigid-body modes as its near-null space; its setup replaces the factorisation. Its memory
    grows like the unknowns.
``"auto"``
    ``"amg"`` above :data:`AMG_THRESHOLD` unknowns when pyamg is installed, else ``"direct"``.
    On thin plates of quadratic elements the AMG-preconditioned CG needs tens of iterations per
    solve and is slower than the factorisation at every size measured (see
    ``docs/reference_fem_plates.md``), so the threshold only guards the factorisation's memory.

A :class:`LinearCost` adds up the seconds of each kind of work (factorisations or set-ups, solves)
and how many there were, for the cost split of :func:`reference_fem.solve_plate`.
"""

from __future__ import annotations

import dataclasses
import functools
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from gdfe import _validation as v

__all__ = ["LinearCost", "make_solver", "AMG_THRESHOLD", "SOLVERS"]

SOLVERS = ("auto", "direct", "amg")
#: Unknowns above which ``"auto"`` takes algebraic multigrid: only where a factorisation would outgrow the
#: memory, since AMG was slower at every size measured (docs/reference_fem_plates.md).
AMG_THRESHOLD = 2_000_000
#: Relative residual of the preconditioned CG solve of a Newton step.
AMG_TOL = 1e-8


@dataclasses.dataclass
class LinearCost:
    """Seconds and counts of the linear algebra of a solve."""

    method: str = "direct"
    factor_s: float = 0.0
    factorisations: int = 0
    solve_s: float = 0.0
    solves: int = 0
    krylov_iterations: int = 0
    failures: int = 0

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def _rigid_modes(X):
    """The six rigid-body modes at points X, as (3 n, 6) columns (interleaved dofs)."""
    n = X.shape[0]
    c = X - X.mean(axis=0)
    B = np.zeros((n, 3, 6))
    for i in range(3):
        B[:, i, i] = 1.0
    # rotations about x, y, z: omega x r
    B[:, 1, 3], B[:, 2, 3] = -c[:, 2], c[:, 1]
    B[:, 0, 4], B[:, 2, 4] = c[:, 2], -c[:, 0]
    B[:, 0, 5], B[:, 1, 5] = -c[:, 1], c[:, 0]
    return B.reshape(3 * n, 6)


def make_solver(method, n, points=None, free=None):
    """A factorisation for systems of ``n`` unknowns: ``factor(A, cost) -> solve``, ``solve(b, cost) -> x``.

    A factorisation (or AMG hierarchy) is kept by its ``solve`` until the next ``factor``, so a
    Newton solve may use it for several right-hand sides.

    Parameters
    ----------
    method : {"auto", "direct", "amg"}
    n : int
        Unknowns of the systems to come.
    points : (N, 3) float array [mm], optional
        Positions of the degrees of freedom (for the rigid-body modes of ``"amg"``).
    free : (n,) int array, optional
        Vector dofs kept in the systems (the rest are fixed).

    Returns
    -------
    factor : callable
    method : str
        The method chosen: ``"pardiso"``, ``"superlu"`` or ``"amg"``.
    """
    v.check_choice("solver", method, SOLVERS)
    if method == "auto":
        try:
            import pyamg  # noqa: F401
            have_amg = True
        except ImportError:
            have_amg = False
        method = "amg" if (have_amg and n > AMG_THRESHOLD) else "direct"
    if method == "direct":
        try:
            import pypardiso  # noqa: F401
        except ImportError:
            return _superlu, "superlu"
        return _pardiso, "pardiso"
    import pyamg

    B = None if points is None else _rigid_modes(np.asarray(points, float))
    if B is not None and free is not None:
        B = B[free]

    def amg(A, cost):
        t0 = time.perf_counter()
        ml = pyamg.smoothed_aggregation_solver(A.tocsr(), B=B, symmetry="symmetric", max_coarse=2000)
        cost.factor_s += time.perf_counter() - t0
        cost.factorisations += 1

        def solve(b, cost):
            t0 = time.perf_counter()
            res = []
            x = ml.solve(b, tol=AMG_TOL, accel="cg", maxiter=500, residuals=res)
            cost.solve_s += time.perf_counter() - t0
            cost.solves += 1
            cost.krylov_iterations += max(len(res) - 1, 0)
            if not res or res[-1] > 10 * AMG_TOL * max(res[0], 1e-300):
                cost.failures += 1  # CG stalled (an indefinite tangent): factorise instead
                return _superlu(A, cost)(b, cost)
            return x

        return solve

    return amg, "amg"


@functools.lru_cache(maxsize=1)
def _pardiso_solver():
    """One PARDISO handle per process (making one searches for the MKL library: slow)."""
    import pypardiso

    return pypardiso.PyPardisoSolver(mtype=-2)  # real symmetric indefinite


def _pardiso(A, cost):
    t0 = time.perf_counter()
    upper = sp.triu(A, format="csr")
    upper.sort_indices()
    handle = _pardiso_solver()
    handle.factorize(upper)
    cost.factor_s += time.perf_counter() - t0
    cost.factorisations += 1

    def solve(b, cost):
        t0 = time.perf_counter()
        x = handle.solve(upper, b)  # the handle's factorisation, as long as it is of this matrix
        cost.solve_s += time.perf_counter() - t0
        cost.solves += 1
        return x

    return solve


def _superlu(A, cost):
    t0 = time.perf_counter()
    lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A")
    cost.factor_s += time.perf_counter() - t0
    cost.factorisations += 1

    def solve(b, cost):
        t0 = time.perf_counter()
        x = lu.solve(b)
        cost.solve_s += time.perf_counter() - t0
        cost.solves += 1
        return x

    return solve
