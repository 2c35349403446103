"""Smoothed aggregation on the Newton Hessian: a multilevel preconditioner for ``method="newton-cg"``, and a solver of its coarse matrix.

The Hessian of the rotation-reduced energy (:class:`gdfe.solver.newton.ReducedHessian`) is
``2 ((1 + mu) L (x) I3 - J^T J)``, a sum of 24 x 24 cell blocks. :func:`hessian_blocks`
assembles it as a block-sparse matrix (3 x 3 blocks, one per pair of vertices sharing a cell;
the pattern made once per mesh, :class:`BlockPattern`), and :class:`HessianAMG` builds a
smoothed-aggregation hierarchy on it with pyamg, with the rigid motions of the current shape
(three translations, three infinitesimal rotations ``omega x V``) as the near-null space:
the energy does not change under them, and the bending of a thin film is, locally, a
rotation. The levels' products and their smoothers (block Jacobi with the 3 x 3 diagonal
blocks inverted) run on an array module (:mod:`gdfe.solver.device`): NumPy, or CuPy on a GPU.
The coarsest level, of bounded size, is solved densely.

The hierarchy is built on the positive semi-definite Hessian model (every cell's eigenvalues
clamped, :meth:`~gdfe.solver.newton.ReducedHessian.linearise` with ``floor=1``) plus the
damping, so that it is symmetric positive definite, and it is kept across Newton steps while
it preconditions well (:class:`AMGPreconditioner`): CG on the Hessian of the current step
with the hierarchy of an earlier one converges as long as the two are close, and the
hierarchy is made again when CG needs more than a threshold of iterations.

pyamg is an optional dependency (extras ``fem`` and ``all``); without it
:func:`available` is False and ``method="newton-cg"`` keeps its two-level preconditioner.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np
import scipy.sparse as sp

from gdfe._validation import GdfeError, check_int
from gdfe.solver import device as _device
from gdfe.solver.multigrid import jacobi_weight, largest_eigenvalue

__all__ = ["AMG_MAX_COARSE", "AMG_REBUILD_CG", "available", "BlockPattern", "hessian_blocks", "rigid_modes",
           "HessianAMG", "CoarseAMG"]

log = logging.getLogger(__name__)

#: The coarsest level has at most this many unknowns; it is solved with a dense Cholesky factor.
AMG_MAX_COARSE = 1500
#: The hierarchy is made again at the next Newton step once CG needed more than this many
#: iterations with it (the Hessian has moved away from the one it was built on).
AMG_REBUILD_CG = 40

#: Cells per chunk when the cell blocks are summed (bounds the temporaries: 576 floats per cell).
_CHUNK = 16_384


def available():
    """Whether pyamg can be imported (the multilevel preconditioner needs it)."""
    try:
        import pyamg  # noqa: F401
    except ImportError:
        return False
    return True


@dataclasses.dataclass(frozen=True, eq=False)
class BlockPattern:
    """The 3 x 3 block structure of the Hessian on one mesh: which vertex pairs share a cell.

    Attributes
    ----------
    indptr, indices : int arrays
        The BSR (block CSR) structure over the ``n`` vertices.
    slot : (m, 8, 8) int array
        The block of the pair ``(cells[i, k], cells[i, l])`` in the BSR data.
    diagonal : (n,) int array
        The block of each vertex's diagonal.
    n : int
    """

    indptr: np.ndarray
    indices: np.ndarray
    slot: np.ndarray
    diagonal: np.ndarray
    n: int

    @classmethod
    def of(cls, cells, n):
        """The pattern of the cells ``(m, 8)`` over ``n`` vertices."""
        m = cells.shape[0]
        row = np.repeat(cells, 8, axis=1).reshape(m, 8, 8).astype(np.int64)
        col = np.tile(cells, (1, 8)).reshape(m, 8, 8).astype(np.int64)
        keys = row * n + col
        uniq, slot = np.unique(keys.ravel(), return_inverse=True)
        r, c = np.divmod(uniq, n)
        indptr = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(r, minlength=n), out=indptr[1:])
        diagonal = np.searchsorted(uniq, np.arange(n, dtype=np.int64) * (n + 1))
        itype = np.int32 if uniq.size < 2**31 else np.int64
        return cls(indptr=indptr.astype(itype), indices=c.astype(itype),
                   slot=slot.reshape(m, 8, 8).astype(itype), diagonal=diagonal.astype(itype), n=n)


def hessian_blocks(hessian, lin, rest, mu, pattern):
    """The Hessian ``2 ((1 + mu) L (x) I3 - J^T J)`` at ``lin`` as a block-sparse matrix.

    Parameters
    ----------
    hessian : gdfe.solver.newton.ReducedHessian
    lin : gdfe.solver.newton.Linearisation
    rest : RestState
    mu : float
        Damping.
    pattern : BlockPattern

    Returns
    -------
    (3n, 3n) scipy.sparse.bsr_matrix
        Blocksize 3, unknowns vertex-major (``3 v + c``); the pinned vertex's rows and
        columns are those of the identity (its position is held).
    """
    steps = hessian.steps
    P, Q, root, w = rest.P, lin.Q, lin.root, steps.w
    m = P.shape[0]
    nb = pattern.indices.size
    data = np.zeros((nb, 3, 3))
    lap = (2.0 * (1.0 + mu)) * (np.eye(8) - 1.0 / 8.0)  # each cell adds w D (x) I3 to L (x) I3
    eye3 = np.eye(3)
    for s in range(0, m, _CHUNK):
        e = min(m, s + _CHUNK)
        c = np.cross(Q[s:e, None, :, :], root[s:e].transpose(0, 2, 1)[:, :, None, :])  # [i, a, b, d]
        Jb = np.matmul(P[s:e, None], c.transpose(0, 1, 3, 2))  # [i, a, k, b]: row a, vertex k, coordinate b
        blocks = -2.0 * np.einsum("iakb,ialc->iklbc", Jb, Jb)
        blocks += (w[s:e, None, None] * lap)[..., None, None] * eye3
        idx = pattern.slot[s:e].ravel()
        flat = blocks.reshape(-1, 9)
        for q in range(9):
            data[:, q // 3, q % 3] += np.bincount(idx, weights=flat[:, q], minlength=nb)
    # the pinned vertex: identity row and column
    pin = steps.pin
    lo, hi = pattern.indptr[pin], pattern.indptr[pin + 1]
    data[lo:hi] = 0.0
    data[pattern.indices == pin] = 0.0
    data[pattern.diagonal[pin]] = eye3
    return sp.bsr_matrix((data, pattern.indices, pattern.indptr), shape=(3 * pattern.n, 3 * pattern.n))


def rigid_modes(V, pin=None):
    """The rigid motions of the shape ``V`` ``(n, 3)`` [mm]: ``(3n, 6)``, translations then rotations.

    The rotations are ``omega x (V - centroid)`` for the three axes ``omega``, scaled to the
    size of the shape so that all six columns have similar norms; the pinned vertex's rows
    are zero (its position is held).
    """
    n = V.shape[0]
    r = V - V.mean(axis=0)
    size = float(np.sqrt(np.mean(np.sum(r * r, axis=1)))) or 1.0
    B = np.zeros((n, 3, 6))
    for a in range(3):
        B[:, a, a] = 1.0
        axis = np.zeros(3)
        axis[a] = 1.0
        B[:, :, 3 + a] = np.cross(axis, r) / size
    if pin is not None:
        B[pin] = 0.0
    return B.reshape(3 * n, 6)


def _block_inverse_diagonal(A):
    """The inverses of the diagonal blocks of a BSR matrix (its own blocksize, 1 for CSR): ``(n, k, k)``."""
    A = A if sp.isspmatrix_bsr(A) else sp.bsr_matrix(A, blocksize=(1, 1))
    k = A.blocksize[0]
    n = A.shape[0] // k
    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    on = np.nonzero(rows == A.indices)[0]
    D = np.zeros((n, k, k))
    D[rows[on]] = A.data[on]
    # a block of zeros (unknowns no cell touches at this level) is left out of the smoothing
    dead = np.abs(np.linalg.det(D)) <= 1e-300
    D[dead] = np.eye(k)
    out = np.linalg.inv(D)
    out[dead] = 0.0
    return out


class HessianAMG:
    """A smoothed-aggregation V-cycle for one assembled Hessian (symmetric positive definite).

    Parameters
    ----------
    A : (3n, 3n) sparse matrix
        The Hessian model (:func:`hessian_blocks`), blocksize 3.
    B : (3n, 6) float array
        Near-null space (:func:`rigid_modes`).
    xp : array module
        Where the cycle runs (:mod:`gdfe.solver.device`); the hierarchy is built with pyamg
        on the CPU and moved there.
    max_coarse : int
        Unknowns of the coarsest level (default :data:`AMG_MAX_COARSE`).
    smoothing : int
        Block-Jacobi sweeps before and after each coarse correction.

    Attributes
    ----------
    sizes : list of int
        Unknowns per level, finest first.
    complexity : float
        Operator complexity: the nonzeros of all levels over those of the finest.
    setup_s : float
        Seconds the hierarchy took to build.
    """

    def __init__(self, A, B, xp=np, max_coarse=AMG_MAX_COARSE, smoothing=1):
        import pyamg

        # the prolongation smoother weighted by local (Gershgorin) bounds, not an eigenvalue
        # estimate: the same CG iterations on the 10^4-cell twist, a quarter of the set-up time
        t0 = time.perf_counter()
        ml = pyamg.smoothed_aggregation_solver(
            A, B=B, BH=None, symmetry="hermitian", strength=("symmetric", {"theta": 0.0}),
            smooth=("jacobi", {"omega": 4.0 / 3.0, "degree": 1, "weighting": "local"}), improve_candidates=None,
            max_coarse=max_coarse, max_levels=25, keep=False)
        rng = np.random.default_rng(0)
        self.xp = xp
        self.smoothing = int(smoothing)
        self.levels = []
        for lvl in ml.levels[:-1]:
            Dinv = _block_inverse_diagonal(lvl.A)
            lam = largest_eigenvalue(
                lambda x, A=lvl.A, Dinv=Dinv: np.einsum("vij,vj->vi", Dinv, (A @ x).reshape(len(Dinv), -1)).ravel(),
                lvl.A.shape[0], rng)
            weight = jacobi_weight(lam)
            self.levels.append((_device.to_device_sparse(lvl.A.tocsr(), xp),
                                _device.to_device_sparse(lvl.P.tocsr(), xp),
                                _device.to_device_sparse(lvl.R.tocsr(), xp),
                                xp.asarray(weight * Dinv)))
        Ac = ml.levels[-1].A.toarray()
        Ac = 0.5 * (Ac + Ac.T)
        # the coarsest level: dense Cholesky (shifted by round-off where semi-definite)
        shift = 1e-12 * max(float(np.abs(np.diag(Ac)).max()), 1e-300)
        Lc = np.linalg.cholesky(Ac + shift * np.eye(Ac.shape[0]))
        self._coarse = xp.asarray(np.linalg.inv(Lc))  # L^-1: the coarse solve is two products
        self.sizes = [lvl.A.shape[0] for lvl in ml.levels]
        self.complexity = float(ml.operator_complexity())
        self.setup_s = time.perf_counter() - t0

    def vcycle(self, b):
        """One V-cycle from zero for ``b`` ``(3n,)`` on the array module: an approximation of ``A^{-1} b``."""
        return self._cycle(b, 0)

    def _smooth(self, x, b, A, Dw):
        xp = self.xp
        r = (b - A @ x).reshape(Dw.shape[0], -1)
        return x + xp.einsum("vij,vj->vi", Dw, r).ravel()

    def _cycle(self, b, level):
        xp = self.xp
        if level == len(self.levels):
            Li = self._coarse
            return Li.T @ (Li @ b)
        A, P, R, Dw = self.levels[level]
        x = xp.einsum("vij,vj->vi", Dw, b.reshape(Dw.shape[0], -1)).ravel()
        for _ in range(self.smoothing - 1):
            x = self._smooth(x, b, A, Dw)
        x = x + P @ self._cycle(R @ (b - A @ x), level + 1)
        for _ in range(self.smoothing):
            x = self._smooth(x, b, A, Dw)
        return x


class CoarseAMG:
    """The coarse matrix of the two-level preconditioner, solved by smoothed-aggregation V-cycles.

    What :func:`gdfe.solver.linalg.factorise` gives the two-level preconditioner of
    ``method="newton-cg"`` (:meth:`gdfe.solver.newton.ReducedHessian.coarse_factor`), without a
    factorisation beyond the hierarchy's coarsest level: ``solve(b)`` is ``cycles`` steps of the
    stationary iteration ``x <- x + V(b - A x)`` from zero, ``V`` one V-cycle of
    :class:`HessianAMG` built on ``A`` with the rigid motions of ``points`` as near-null space.
    From zero, ``k`` such steps are the fixed operator ``sum_j (I - V A)^j V``, symmetric like
    ``V``, so the preconditioner is the same at every CG iteration.

    Parameters
    ----------
    A : (3k, 3k) sparse matrix
        The coarse matrix, unknowns vertex-major (``3 q + c``), symmetric positive definite.
    points : (k, 3) float array [mm]
        The shape at the coarse vertices (:meth:`gdfe.solver.newton.CoarseSpace.points`).
    cycles : int
        V-cycles per solve.
    max_coarse : int, optional
        Unknowns of the hierarchy's coarsest level (default :data:`AMG_MAX_COARSE`).
    """

    def __init__(self, A, points, cycles=3, max_coarse=None):
        self.cycles = check_int("cycles", cycles)
        A = sp.csr_matrix(A)
        points = np.asarray(points, float)
        if A.shape[0] != A.shape[1] or points.ndim != 2 or points.shape[1] != 3 or A.shape[0] != 3 * points.shape[0]:
            raise GdfeError(f"A, points: expected a (3k, 3k) matrix and (k, 3) points, got {A.shape} and {points.shape}")
        self.A = A
        max_coarse = AMG_MAX_COARSE if max_coarse is None else int(max_coarse)
        self.ml = HessianAMG(A.tobsr(blocksize=(3, 3)), rigid_modes(points), max_coarse=max_coarse)
        log.debug("coarse AMG: levels %s, operator complexity %.2f, %.2f s", self.ml.sizes, self.ml.complexity,
                  self.ml.setup_s)

    def solve(self, b):
        """``cycles`` V-cycles from zero for ``b`` ``(3k,)``: an approximation of ``A^{-1} b``."""
        x = self.ml.vcycle(b)
        for _ in range(self.cycles - 1):
            x = x + self.ml.vcycle(b - self.A @ x)
        return x
