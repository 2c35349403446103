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

A factorisation may also serve as the preconditioner of a Krylov solve with a later matrix
(:func:`gmres`, right-preconditioned GMRES: its residual is that of the system itself), the inexact
Newton iterations of :func:`reference_fem.solve_plate`. Every ``factor`` accepts the full matrix or
its upper triangle (:class:`SymmetricCSR`, what the plate solver assembles); PARDISO analyses the
sparsity pattern (ordering, symbolic factorisation) once and refactorises numerically while the
pattern stays the same.

A :class:`LinearCost` adds up the seconds of each kind of work (analyses, factorisations or
set-ups, triangular solves, and of the Krylov solves their preconditioner solves, ``krylov_solve_s``,
and the rest, ``krylov_s``: products with the matrix, orthogonalisation) and how many there were,
for the cost split of :func:`reference_fem.solve_plate`.
"""

from __future__ import annotations

import dataclasses
import functools
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from gdfe import _validation as v

__all__ = ["LinearCost", "SymmetricCSR", "make_solver", "gmres", "KrylovResult", "AMG_THRESHOLD", "SOLVERS"]

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
    analysis_s: float = 0.0
    analyses: int = 0
    factor_s: float = 0.0
    factorisations: int = 0
    solve_s: float = 0.0
    solves: int = 0
    krylov_s: float = 0.0
    krylov_solve_s: float = 0.0
    krylov_solves: int = 0
    krylov_iterations: int = 0
    failures: int = 0

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class SymmetricCSR:
    """A symmetric sparse matrix stored as its upper triangle (diagonal included).

    Attributes
    ----------
    upper : (n, n) csr_matrix
        Upper triangle with sorted column indices.
    """

    upper: sp.csr_matrix

    @property
    def shape(self):
        return self.upper.shape

    def diagonal(self) -> np.ndarray:
        return self.upper.diagonal()

    def matvec(self, x: np.ndarray) -> np.ndarray:
        """``A x`` from the upper triangle: ``U x + U^T x - diag(U) x``."""
        return self.upper @ x + self.upper.T @ x - self.upper.diagonal() * x

    def full(self) -> sp.csr_matrix:
        """The whole matrix as CSR."""
        return (self.upper + sp.triu(self.upper, k=1, format="csr").T).tocsr()

    def shifted(self, alpha: float) -> "SymmetricCSR":
        """``A + alpha diag(A)`` (same pattern)."""
        d = self.upper.diagonal()
        return SymmetricCSR((self.upper + sp.diags(alpha * d)).tocsr())


def _full(A):
    return A.full() if isinstance(A, SymmetricCSR) else A


def _upper(A):
    if isinstance(A, SymmetricCSR):
        return A.upper
    upper = sp.triu(A, format="csr")
    upper.sort_indices()
    return upper


def _matvec(A):
    return A.matvec if isinstance(A, SymmetricCSR) else A.__matmul__


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

    ``A`` is a sparse matrix or a :class:`SymmetricCSR`. A factorisation (or AMG hierarchy) is kept
    by its ``solve`` until the next ``factor``, so a Newton solve may use it for several right-hand
    sides, or as the preconditioner of later systems (:func:`gmres`).

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
        return _Pardiso(), "pardiso"
    import pyamg

    B = None if points is None else _rigid_modes(np.asarray(points, float))
    if B is not None and free is not None:
        B = B[free]

    def amg(A, cost):
        t0 = time.perf_counter()
        A = _full(A)
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


class _Pardiso:
    """MKL PARDISO's LDL^T of symmetric matrices, the analysis kept while the sparsity pattern stays.

    PARDISO works in phases: 11 orders and factorises symbolically, 22 factorises numerically, 33
    solves. A Newton solve refactorises matrices of one pattern, so phase 11 runs once per pattern
    and each factorisation is phase 22 alone; a solve is phase 33 without pypardiso's check that
    the matrix is the one factorised (a hash of all its entries, as long as a solve at this size).
    The process has one PARDISO handle, so it holds one factorisation: a solve whose factorisation
    a newer one replaced raises ``RuntimeError``.
    """

    #: the pattern the handle analysed last, and a token of its current factorisation
    _state = {"pattern": None, "current": None}

    @classmethod
    def _same_pattern(cls, upper):
        if cls._state["pattern"] is None:
            return False
        indptr, indices = cls._state["pattern"]
        if upper.indptr is indptr and upper.indices is indices:
            return True
        return (upper.shape[0] + 1 == indptr.size and upper.nnz == indices.size
                and np.array_equal(upper.indptr, indptr) and np.array_equal(upper.indices, indices))

    def __call__(self, A, cost):
        handle = _pardiso_solver()
        upper = _upper(A)
        if not hasattr(handle, "_call_pardiso"):  # pragma: no cover - another pypardiso: its public calls
            return _pardiso_public(handle, upper, cost)
        handle._check_A(upper)  # format, sorted indices, no empty row
        b = np.zeros(upper.shape[0])
        state = self._state
        state["current"] = None
        if not self._same_pattern(upper):
            t0 = time.perf_counter()
            handle.set_phase(11)
            handle._call_pardiso(upper, b)
            state["pattern"] = (upper.indptr, upper.indices)
            cost.analysis_s += time.perf_counter() - t0
            cost.analyses += 1
        t0 = time.perf_counter()
        handle.set_phase(22)
        handle._call_pardiso(upper, b)
        handle.factorized_A = sp.csr_matrix((0, 0))  # pypardiso's own solve must refactorise
        cost.factor_s += time.perf_counter() - t0
        cost.factorisations += 1
        token = state["current"] = object()

        def solve(rhs, cost):
            if state["current"] is not token:
                raise RuntimeError("this PARDISO factorisation was replaced by a newer one")
            t0 = time.perf_counter()
            handle.set_phase(33)
            x = handle._call_pardiso(upper, np.ascontiguousarray(rhs, dtype=float))
            cost.solve_s += time.perf_counter() - t0
            cost.solves += 1
            return x

        return solve


def _pardiso_public(handle, upper, cost):  # pragma: no cover - only with a pypardiso without _call_pardiso
    t0 = time.perf_counter()
    handle.factorize(upper)
    cost.factor_s += time.perf_counter() - t0
    cost.factorisations += 1

    def solve(b, cost):
        t0 = time.perf_counter()
        x = handle.solve(upper, b)
        cost.solve_s += time.perf_counter() - t0
        cost.solves += 1
        return x

    return solve


def _superlu(A, cost):
    t0 = time.perf_counter()
    lu = spla.splu(sp.csc_matrix(_full(A)), permc_spec="MMD_AT_PLUS_A")
    cost.factor_s += time.perf_counter() - t0
    cost.factorisations += 1

    def solve(b, cost):
        t0 = time.perf_counter()
        x = lu.solve(b)
        cost.solve_s += time.perf_counter() - t0
        cost.solves += 1
        return x

    return solve


@dataclasses.dataclass
class KrylovResult:
    """A Krylov solve: the solution, whether it met its tolerance, in how many iterations, at what
    relative residual ``|b - A x| / |b|``."""

    x: np.ndarray
    converged: bool
    iterations: int
    residual: float


def gmres(A, b, precondition, cost, *, rtol, maxiter=20):
    """Right-preconditioned GMRES: ``A M^-1 y = b``, ``x = M^-1 y``, from ``x = 0``.

    With the preconditioner on the right the residual GMRES minimises is the system's own,
    ``|b - A x|``, so ``rtol`` bounds it exactly (the forcing term of an inexact Newton step). The
    preconditioned directions ``z_j = M^-1 v_j`` are kept (flexible GMRES), so each iteration costs
    one product with ``A`` and one preconditioner solve, and none more at the end. Without restarts:
    the solve stops after ``maxiter`` iterations, or from the third on as soon as the mean rate of
    the iterations so far would not reach ``rtol`` within ``maxiter`` (a preconditioner that has
    aged too much is given up early).

    Parameters
    ----------
    A : sparse matrix or SymmetricCSR
    b : (n,) float array
    precondition : callable
        ``precondition(r, cost) -> z``, an approximate solve (a factorisation of an earlier matrix).
    cost : LinearCost
    rtol : float
        Relative residual to reach.
    maxiter : int

    Returns
    -------
    KrylovResult
    """
    t0 = time.perf_counter()
    solve_before = cost.solve_s
    matvec = _matvec(A)
    beta = float(np.linalg.norm(b))
    n = b.size
    x = np.zeros(n)
    if beta == 0.0:
        return KrylovResult(x, True, 0, 0.0)
    V = np.empty((maxiter + 1, n))
    Z = np.empty((maxiter, n))
    H = np.zeros((maxiter + 1, maxiter))
    cs = np.zeros(maxiter)
    sn = np.zeros(maxiter)
    g = np.zeros(maxiter + 1)
    g[0] = beta
    V[0] = b / beta
    k = 0
    rel = 1.0
    while k < maxiter and rel > rtol:
        Z[k] = precondition(V[k], cost)
        w = matvec(Z[k])
        for j in range(k + 1):  # modified Gram-Schmidt
            H[j, k] = float(w @ V[j])
            w -= H[j, k] * V[j]
        h_next = float(np.linalg.norm(w))
        H[k + 1, k] = h_next
        if h_next > 0.0:
            V[k + 1] = w / h_next
        for j in range(k):  # earlier Givens rotations on the new column
            hj = cs[j] * H[j, k] + sn[j] * H[j + 1, k]
            H[j + 1, k] = -sn[j] * H[j, k] + cs[j] * H[j + 1, k]
            H[j, k] = hj
        rho = float(np.hypot(H[k, k], H[k + 1, k]))
        if rho == 0.0 or not np.isfinite(rho):
            break
        cs[k], sn[k] = H[k, k] / rho, H[k + 1, k] / rho
        H[k, k], H[k + 1, k] = rho, 0.0
        g[k + 1] = -sn[k] * g[k]
        g[k] = cs[k] * g[k]
        k += 1
        rel = abs(g[k]) / beta
        if k >= 3 and rel > rtol and k + np.log(rtol / rel) / np.log(max(rel ** (1.0 / k), 1e-300)) > maxiter:
            break  # at the rate so far it would not reach rtol within maxiter: stop now
        if h_next == 0.0:  # pragma: no cover - the Krylov space holds the solution (lucky breakdown)
            break
    if k:
        y = np.linalg.solve(np.triu(H[:k, :k]), g[:k]) if k > 1 else g[:1] / H[0, 0]
        x = y @ Z[:k]
    cost.krylov_iterations += k
    cost.krylov_solves += 1
    cost.krylov_solve_s += cost.solve_s - solve_before
    cost.krylov_s += (time.perf_counter() - t0) - (cost.solve_s - solve_before)
    ok = bool(rel <= rtol and np.all(np.isfinite(x)))
    return KrylovResult(x, ok, k, float(rel))
