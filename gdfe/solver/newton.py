"""Damped Newton on the rotation-reduced energy: ``method="newton"`` and ``method="newton-cg"``.

With every rotation optimal, Eq. 5 is a function of the vertices alone. This module holds
its Hessian (:class:`ReducedHessian`: the per-step :class:`Linearisation` and ``J``, and the mesh-only constants
``L (x) I3``, the sparsity of the Jacobian ``J`` and the coarse space of the CG
preconditioner), the damped-Newton outer loop (:func:`solve_newton`) and the two ways to
compute its steps: the 3n x 3n Hessian factorised (:func:`factorised_directions`) or
preconditioned conjugate gradients (:func:`cg_directions`, :func:`pcg`) with a forcing
sequence (:func:`forcing_term`) and, for ``method="newton-cg"``, a damping that vanishes near
the solution (:func:`solve_newton`); the smoothed-aggregation preconditioner is in
:mod:`gdfe.solver.amg`.
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import logging
import time
import typing

import numpy as np
import scipy.sparse as sp

from gdfe import _memory
from gdfe._validation import GdfeError, check_choice, check_int, check_positive
from gdfe.solver.device import dot as _dot
from gdfe.solver.energy import SolveStats
from gdfe.solver.linalg import Factoriser, factorise
from gdfe.solver.multigrid import lattice
from gdfe.solver.recycling import AugmentedCoarse, mostly_turn
from gdfe.solver.rigid import turn_fit
from gdfe.solver.threads import RowBlocks, in_order, ranges, side_by_side

__all__ = ["MU_MIN", "HESSIAN_FLOOR", "STEP_TOL_FACTOR", "ENERGY_ROUNDOFF", "CONTACT_ALPHAS", "CONTACT_EXACT_RES", "DRIFT_WINDOW",
           "DRIFT_ENERGY", "DRIFT_SHRINK", "ON_DRIFT", "RELEASE_POINTS", "CG_RTOL_MIN", "CG_RTOL_MAX", "CG_TARGET_MARGIN",
           "EW_GAMMA", "EW_ALPHA", "FORCINGS", "MU_RESIDUAL", "MU_RESIDUAL_CONTACT", "MODEL_AGREEMENT", "PRECONDITIONERS",
           "AMG_REBUILD_DAMPING", "TWO_LEVELS", "COARSE_SOLVERS", "CGOperator", "NewtonStep", "convergence_rates", "forcing_term", "sqrt_forcing", "COARSE_REUSE", "COARSE_REUSE_DAMPING",
           "ReducedHessian", "Linearisation", "CoarseSpace", "CoarseCells", "pcg", "deformation", "solve_newton",
           "factorised_directions", "cg_directions"]

log = logging.getLogger(__name__)

#: Smallest damping of ``method="newton-cg"`` (times 2 L): it also keeps the rigid rotation
#: about the pinned vertex, a null direction of the energy, out of the steps.
MU_MIN = 1e-6
#: Near the solution ``method="newton-cg"`` lowers that floor with the residual, to
#: ``min(MU_MIN, MU_RESIDUAL * res)`` (``res`` the plain step's residual, units of h), so that
#: the damping vanishes at the solution and Newton's convergence stays superlinear; a floor
#: held at MU_MIN slowed the soft mode of the 10^5-cell Figure 8 twist to a linear rate of
#: about 0.45 per step (docs/bench, the solver's convergence); at 1e-3 its floor was still that
#: mode's curvature near the end (the twist: 9 steps against 8).
MU_RESIDUAL = 1e-6
#: ... and with self-contact: with 1e-6 the contact study's 9 mm offset hinge (its ends meet
#: off-centre, a state the activation's path decides) ended 1.7 mrad further on, and moved by 2 um
#: and solved again it rose by 6.6e-5 of its energy instead of coming back (why is not known).
MU_RESIDUAL_CONTACT = 1e-3
#: ... and after a full step whose energy fell by at least MODEL_AGREEMENT of what the quadratic
#: model predicted, the damping falls to that floor at once (a full step the model predicted less
#: well divides it by 4). Divided by 16 instead, the damping that starts every
#: solve at 1e-3 needed four steps to fall below the soft modes' curvature, and the 10^5-cell twist
#: took 10 steps where it takes 8 (docs/solver_history.md, the damping's fall).
MODEL_AGREEMENT = 0.75
#: A Newton solve also needs its estimated distance to the solution below
#: ``STEP_TOL_FACTOR * tol`` (units of h); see :func:`solve_newton`.
STEP_TOL_FACTOR = 10.0
#: Relative rise of the energy a full Newton step may cause and still be taken (round-off).
ENERGY_ROUNDOFF = 1e-13
#: Fractions of the collision-free step tried with contact, in order (see :func:`solve_newton`).
CONTACT_ALPHAS = (1.0, 0.5, 0.25, 0.125)
#: Below this residual (units of h) the contact barrier's Hessian enters the Newton system as
#: it is, not projected pair by pair onto the positive semi-definite cone: near a solution the
#: whole Hessian is positive definite, and the projected one only converges linearly.
CONTACT_EXACT_RES = 1e-2
#: The forcing of ``method="newton-cg"``: CG stops at a relative (preconditioned) residual in
#: [CG_RTOL_MIN, CG_RTOL_MAX], chosen by the forcing sequence (:func:`forcing_term`).
CG_RTOL_MIN = 1e-3
CG_RTOL_MAX = 0.1
#: Eisenstat and Walker's choice 2, ``eta = EW_GAMMA (res_k / res_k-1)^EW_ALPHA`` (their gamma
#: and alpha; see :func:`forcing_term`).
EW_GAMMA = 0.9
EW_ALPHA = 2.0
#: The forcing sequences of ``method="newton-cg"``: Eisenstat-Walker's choice 2, or the square
#: root of the plain step's residual (:func:`sqrt_forcing`).
FORCINGS = ("eisenstat-walker", "sqrt")
#: The preconditioners of ``method="newton-cg"`` (see :func:`cg_directions`).
PRECONDITIONERS = ("two-level", "amg")
#: How the two-level preconditioner combines its fine and coarse corrections
#: (:attr:`ReducedHessian.two_level`, :meth:`ReducedHessian.operator`).
TWO_LEVELS = ("deflated", "multiplicative", "additive")
#: How the two-level preconditioner solves its coarse matrix (:attr:`ReducedHessian.coarse_solver`):
#: a sparse factorisation, or smoothed-aggregation V-cycles (:class:`gdfe.solver.amg.CoarseAMG`).
COARSE_SOLVERS = ("factor", "amg")
#: The smoothed-aggregation hierarchy is made again when the damping moved by more than this.
AMG_REBUILD_DAMPING = 1e-2
#: ... and never tighter than this fraction of the reduction the stopping test still asks of the
#: estimated distance to the solution (``STEP_TOL_FACTOR * tol / estimate``): the last step need
#: only get below the tolerance, not to round-off.
CG_TARGET_MARGIN = 0.25
#: The coarse matrix of ``method="newton-cg"`` is made and factorised again only when the last
#: step moved the shape by more than this (the estimated distance to the solution, units of h)
#: or the damping changed much; otherwise the last one preconditions the step. Only with the
#: balancing forms of the two-level preconditioner (:attr:`ReducedHessian.two_level`); the deflated
#: one, the default, makes it at every iterate.
COARSE_REUSE = 0.1
#: ... and the damping changed the coarse matrix's L part by at most this fraction.
COARSE_REUSE_DAMPING = 1e-2
#: Lower clamp of every cell's Hessian eigenvalues (relative to the flat print's) in the Newton directions
#: of both methods (:meth:`ReducedHessian.linearise`): below 1 a cell may bring negative curvature, which
#: the sum over cells absorbs and the energy test guards. At 1 (every cell's Hessian positive semi-definite)
#: the factorised Newton converged only linearly (0.22 a step on the 2.6 mm Figure 6 hinge, 0.52 on a
#: 9 mm one), and the 5 and 9 mm hinges stopped 7.4 and 11.6 nm from the solution where their test asked
#: 7.0 and 11.0 nm (docs/solver_history.md). On the benchmark's 10^5 sheets no cell reaches it (0.25 and 0.1
#: give the same bits there), and at 1 the 10^5 corrugation did not converge in 200 iterations.
HESSIAN_FLOOR = 0.5
#: Drift (see :func:`solve_newton`): over this many iterations ...
DRIFT_WINDOW = 10
#: ... the energy fell by less than this fraction of itself (its 5th digit over ten iterations, the 6th in each) ...
DRIFT_ENERGY = 1e-4
#: ... while the estimated distance to the solution shrank by less than this factor.
DRIFT_SHRINK = 0.1
#: What a Newton solve does when it drifts: ``"warn"`` (say so and go on) or ``"stop"``.
ON_DRIFT = ("warn", "stop")
#: Above this many vertices a Newton solve gives the C heap's free memory back to the system
#: after every step (:func:`gdfe._memory.release`).
RELEASE_POINTS = 50_000


def _cross(p):
    """The cross-product matrices ``[p]x`` of the vectors ``p`` ``(..., 3)``: ``(..., 3, 3)``."""
    K = np.zeros(p.shape + (3,))
    K[..., 0, 1], K[..., 0, 2] = -p[..., 2], p[..., 1]
    K[..., 1, 0], K[..., 1, 2] = p[..., 2], -p[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -p[..., 1], p[..., 0]
    return K


#: Cells per chunk when a 3m x 3n matrix is built from per-cell blocks (bounds the temporaries).
_CHUNK = 65_536
#: Cells per slab when the coarse matrix is summed (:meth:`CoarseCells.gram_values`; bounds its memory at
#: 10^6 cells, and the slabs share the solver's threads evenly at 10^5).
_COARSE_CHUNK = 16_384


def _block_rows(lin, p, pattern):
    """The sparse matrix with rows ``root_i^T sum_k [p_ik]x Q_i^T (.)_{cols[i, k]}`` (CSR, 3m x 3 n_cols).

    With ``p`` the rest shapes and the cells as columns this is ``J``; with the rest shapes
    carried to the corners of a coarse grid, ``J Z``. Entry ``(a, k, b)`` of cell ``i`` is
    ``p_k . (q_b x r_a)``, ``q_b`` the rows of ``Q_i`` and ``r_a`` the columns of ``root_i``.

    Parameters
    ----------
    lin : Linearisation
    p : (m, r, 3) float array [mm]
    pattern : (indices, indptr, shape)
        The CSR structure (:func:`_row_pattern`).
    """
    m, r, _ = p.shape
    data = np.empty((m, 3, r, 3))

    def blocks(part):  # in chunks: bounded temporaries
        for s in range(*part, _CHUNK):
            e = min(part[1], s + _CHUNK)
            _cell_blocks(lin.Q[s:e], lin.root[s:e], p[s:e], out=data[s:e])
    in_order(blocks, ranges(m))
    indices, indptr, shape = pattern
    return sp.csr_matrix((data.ravel(), indices, indptr), shape=shape)


def _cell_blocks(Q, root, p, out=None):
    """Every cell's three rows of :func:`_block_rows`, ``(m, 3, r, 3)``: entry ``(i, a, k, b)`` is ``p_ik . (q_b x r_a)``."""
    c = np.cross(Q[:, None, :, :], root.transpose(0, 2, 1)[:, :, None, :])  # [i, a, b, d]
    return np.matmul(p[:, None], c.transpose(0, 1, 3, 2), out=out)


def _cholesky3(A):
    """The Cholesky factors of symmetric 3 x 3 matrices ``A`` ``(m, 3, 3)``, in closed form.

    Returns ``L`` ``(m, 3, 3)`` (lower triangular, ``A = L L^T``) and ``ok`` ``(m,)``: whether
    every pivot was positive (``A`` positive definite); where not, that ``L`` is not finite.
    """
    a = A
    with np.errstate(invalid="ignore", divide="ignore"):
        d1 = a[:, 0, 0]
        l11 = np.sqrt(d1)
        l21, l31 = a[:, 1, 0] / l11, a[:, 2, 0] / l11
        d2 = a[:, 1, 1] - l21 * l21
        l22 = np.sqrt(d2)
        l32 = (a[:, 2, 1] - l31 * l21) / l22
        d3 = a[:, 2, 2] - l31 * l31 - l32 * l32
        l33 = np.sqrt(d3)
    L = np.zeros_like(a)
    L[:, 0, 0], L[:, 1, 0], L[:, 2, 0] = l11, l21, l31
    L[:, 1, 1], L[:, 2, 1], L[:, 2, 2] = l22, l32, l33
    return L, (d1 > 0) & (d2 > 0) & (d3 > 0)


def _inverse_lower3(L):
    """The inverses of lower triangular 3 x 3 matrices ``L`` ``(m, 3, 3)``, in closed form."""
    with np.errstate(invalid="ignore", divide="ignore"):
        i11, i22, i33 = 1.0 / L[:, 0, 0], 1.0 / L[:, 1, 1], 1.0 / L[:, 2, 2]
        out = np.zeros_like(L)
        out[:, 0, 0], out[:, 1, 1], out[:, 2, 2] = i11, i22, i33
        out[:, 1, 0] = -L[:, 1, 0] * i11 * i22
        out[:, 2, 1] = -L[:, 2, 1] * i22 * i33
        out[:, 2, 0] = (L[:, 1, 0] * L[:, 2, 1] - L[:, 2, 0] * L[:, 1, 1]) * i11 * i22 * i33
    return out


def _row_pattern(cols, n_cols):
    """The CSR structure of :func:`_block_rows` for the columns ``cols`` ``(m, r)`` of every cell."""
    m, r = cols.shape
    indices = np.broadcast_to((3 * cols[:, None, :, None] + np.arange(3)).astype(np.int32), (m, 3, r, 3)).ravel()
    return indices, np.arange(0, 9 * r * m + 1, 3 * r), (3 * m, 3 * n_cols)


@dataclasses.dataclass(frozen=True, eq=False)
class Linearisation:
    """The rotation-reduced energy's Hessian at one iterate, per cell (:meth:`ReducedHessian.linearise`).

    The Hessian is ``2 (L (x) I3 - J^T J)``; row block ``i`` of ``J`` maps the vertices
    ``v`` to ``root_i^T sum_k p_k x (Q_i^T v_k)`` over the cell's vertices.

    Attributes
    ----------
    Q : (m, 3, 3) float array
        The rotations.
    root : (m, 3, 3) float array [mm^(1/2)]
        ``(w N)^(1/2)``, see :meth:`ReducedHessian.linearise`.
    """

    Q: np.ndarray
    root: np.ndarray


@dataclasses.dataclass(eq=False)
class CoarseSpace:
    """The coarse grid of the ``"newton-cg"`` preconditioner.

    Attributes
    ----------
    Z : (n, k) sparse matrix
        Bilinear interpolation from the coarse grid, per layer of vertices; the pinned
        vertex's row is zero.
    Z3 : (3n, 3k) sparse matrix
        ``Z (x) I3`` (made when asked for: only the contact barrier's Hessian needs it).
    Lc : (k, k) sparse matrix
        ``Z_f^T L_ff Z_f``, the coarse n x n system (each coordinate's: ``Lc (x) I3`` for the three).
    Zt : (k, n) sparse matrix
        ``Z^T`` (CSR), made once: the restriction of every coarse correction.
    corners : (m, 8) int array
        The columns of ``Z`` at the corners of the coarse cell each cell lies in
        (``(a, b, l)`` in x, y and layer, ``4 a + 2 b + l``).
    coarse_cell : (m,) int array
        A label of that coarse cell (its cells share their ``corners``).
    spacing : int
        The coarse grid's spacing, in cells.
    ijk : (n, 3) int array
        Lattice indices of the vertices (:func:`gdfe.solver.multigrid.lattice`).
    solver : {"factor", "amg"}
        How the coarse matrix is solved (:attr:`ReducedHessian.coarse_solver`, resolved).
    """

    Z: sp.csr_matrix
    Lc: sp.spmatrix
    Zt: sp.csr_matrix
    corners: np.ndarray
    spacing: int
    ijk: np.ndarray
    coarse_cell: np.ndarray
    solver: str = "factor"

    def points(self, V):
        """The shape ``V`` ``(n, 3)`` [mm] at the coarse vertices: each one's weighted mean of the vertices it interpolates to, ``(k, 3)``."""
        return (self.Zt @ V) * self._inverse_weight[:, None]

    @functools.cached_property
    def products(self):
        """``(Z, Zt)`` whose products with ``(n, 3)`` and ``(k, 3)`` arrays run on the solver's threads by rows
        (:class:`gdfe.solver.threads.RowBlocks`: the same bits), for the coarse solve at every CG iteration."""
        return RowBlocks(self.Z), RowBlocks(self.Zt)

    @functools.cached_property
    def _inverse_weight(self):
        """One over the sum of every coarse vertex's interpolation weights (the rows of ``Zt``)."""
        return 1.0 / np.maximum(np.asarray(self.Zt.sum(axis=1)).ravel(), 1e-300)

    @functools.cached_property
    def Z3(self):
        return sp.kron(self.Z, sp.eye(3), format="csr")

    @functools.cached_property
    def cells(self) -> CoarseCells:
        """The cells grouped by coarse cell (:class:`CoarseCells`), made on first use."""
        return CoarseCells.of(self.coarse_cell, self.corners, self.Z.shape[1], self.Lc)


@dataclasses.dataclass(eq=False)
class CoarseCells:
    """The cells grouped by the coarse cell they lie in, for the coarse matrix (:meth:`ReducedHessian.coarse_matrix`).

    Every cell of a coarse cell has the same eight corners, so its rows of ``J Z`` are a
    3 x 24 block on the same 24 columns, and ``(J Z)^T J Z`` is a sum of one 24 x 24 block
    per coarse cell: the cells' blocks stacked, ``G^T G``, one batched product, then
    scattered into a CSR pattern made once. On the 10^5-cell Figure 8 twist this replaced
    SciPy's sparse product ``(J Z)^T (J Z)`` (and its conversions), which took about a
    quarter of the fine Newton time once the coarse matrix was made at every iterate.

    Attributes
    ----------
    order : (m,) int array
        The cells, sorted by coarse cell.
    starts : (g + 1,) int array
        Where each coarse cell's cells begin in ``order``.
    columns : (g, 24) int array
        The coarse matrix's columns of each coarse cell (corner ``q``, coordinate ``b``: ``3 q + b``).
    indptr, indices : int arrays
        The CSR pattern of the sum of the blocks (3k x 3k).
    scatter : (g * 576,) int array
        The index into that pattern's values of every block entry.
    L_values : (nnz,) float array
        ``Lc (x) I3`` (:class:`CoarseSpace`) on that pattern (which holds its entries too), so that the
        coarse matrix is made on it with no sparse sum or conversion.
    """

    order: np.ndarray
    starts: np.ndarray
    columns: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    scatter: np.ndarray
    L_values: np.ndarray

    @classmethod
    def of(cls, coarse_cell, corners, k, Lc):
        """From every cell's coarse cell (any integer label), its corner columns ``corners`` ``(m, 8)``
        on a coarse grid of ``k`` vertices, and ``Lc`` (k x k).

        The pattern is found on the coarse vertices (8 x 8 pairs per coarse cell, nine times
        fewer to sort than the 24 x 24 unknowns: 0.39 s to 0.07 s on the 10^5-cell corrugation),
        and every pair of vertices is then a 3 x 3 block laid out in the CSR order of the unknowns.
        """
        _, group, counts = np.unique(coarse_cell, return_inverse=True, return_counts=True)
        order = np.argsort(group.ravel(), kind="stable")
        starts = np.concatenate([[0], np.cumsum(counts)])
        nodes = corners[order[starts[:-1]]].astype(np.int64)  # (g, 8): each coarse cell's corner vertices
        columns = (3 * nodes[:, :, None] + np.arange(3)).reshape(-1, 24)
        Lc = sp.coo_matrix(Lc)
        pairs = (nodes[:, :, None] * k + nodes[:, None, :]).ravel()
        keys, at = np.unique(np.concatenate([pairs, Lc.row.astype(np.int64) * k + Lc.col]), return_inverse=True)
        at = at.ravel()
        row, col = keys // k, keys % k
        degree = np.bincount(row, minlength=k)
        first = np.concatenate([[0], np.cumsum(degree)])[:-1]  # each vertex's first pair
        abc = np.arange(3)
        # unknown (3 r + a, 3 c + b) of pair p = (r, c): row 3 r + a begins at 9 first[r] + 3 a degree[r],
        # and holds the pair's three columns at 3 (p - first[r]) + b
        position = (9 * first[row] + 3 * (np.arange(keys.size) - first[row]))[:, None, None] \
            + 3 * abc[None, :, None] * degree[row][:, None, None] + abc[None, None, :]  # (pairs, a, b)
        indptr = np.append((9 * first[:, None] + 3 * abc * degree[:, None]).ravel(), 9 * keys.size)
        indices = np.empty(9 * keys.size, np.int32)
        indices[position] = 3 * col[:, None, None] + abc[None, None, :]
        itype = np.int32 if indices.size < 2**31 else np.int64  # half the memory of the scatter (g * 576 entries)
        # a coarse cell's block entry (q1, b1; q2, b2) lies on the pair of its corners q1, q2
        scatter = position[at[:pairs.size].reshape(-1, 8, 8)].transpose(0, 1, 3, 2, 4).ravel().astype(itype)
        L_values = np.zeros(indices.size)
        L_values[position[at[pairs.size:]][:, abc, abc]] = Lc.data[:, None]  # L (x) I3: the diagonal of each block
        return cls(order=order, starts=starts, columns=columns, indptr=indptr, indices=indices, scatter=scatter,
                   L_values=L_values)

    def gram_values(self, lin, pc):
        """``(J Z)^T (J Z)``: its values on the pattern ``indptr``, ``indices``, from the linearisation ``lin`` and the coarse rest shapes ``pc``."""
        g = self.columns.shape[0]
        blocks = np.empty((g, 24, 24))
        starts = self.starts
        # coarse cells in slabs of about _COARSE_CHUNK cells: the stacked blocks' memory stays bounded
        # (about 600 bytes per cell of a slab, with the temporaries of _cell_blocks)
        # (slabs on the solver's threads, gdfe.solver.threads: at most one slab's memory per thread)
        edges = np.unique(np.concatenate([np.searchsorted(starts, np.arange(0, starts[-1], _COARSE_CHUNK)), [g]]))

        def slab(bounds):
            g0, g1 = bounds
            cells = self.order[starts[g0]:starts[g1]]
            D = _cell_blocks(lin.Q[cells], lin.root[cells], pc[cells]).reshape(-1, 3, 24)
            counts = np.diff(starts[g0:g1 + 1])
            slot = np.arange(cells.size) - np.repeat(starts[g0:g1] - starts[g0], counts)
            G = np.zeros((g1 - g0, int(counts.max()), 3, 24))
            G[np.repeat(np.arange(g1 - g0), counts), slot] = D
            G = G.reshape(g1 - g0, -1, 24)
            np.matmul(G.transpose(0, 2, 1), G, out=blocks[g0:g1])
        in_order(slab, zip(edges[:-1], edges[1:]))
        return np.bincount(self.scatter, weights=blocks.ravel(), minlength=self.indices.size)


class CGOperator(typing.NamedTuple):
    """What preconditioned CG (:func:`pcg`) needs of one Newton system.

    Attributes
    ----------
    apply_H, apply_P : callable
        The Hessian product and the preconditioner, on ``(n, 3)`` arrays.
    start : callable or None
        The first iterate as a function of the right-hand side (a deflated CG's coarse
        solution, :meth:`ReducedHessian.operator`); None starts from zero.
    flexible : bool
        Whether CG should take its flexible form (:func:`pcg`): the deflated preconditioner
        with a coarse solve that is not exact.
    """

    apply_H: typing.Callable
    apply_P: typing.Callable
    start: typing.Callable | None = None
    flexible: bool = False


class ReducedHessian:
    """The Hessian of the rotation-reduced energy on one design's mesh.

    With every rotation optimal, the energy of a cell is ``w (|X|^2 + |P|^2 - 2 tr(Q^T S))``
    and its gradient ``2 w (x_k - Q p_k)``. The rotation moves with the vertices by
    ``Q^T dQ = [omega]x``, ``omega = M^{-1} sum_l p_l x Q^T dx_l`` with ``M = tr(Y) I - Y``
    and ``Y = Q^T S`` (the derivative of the polar factor). Hence the cell Hessian in its
    24 vertex coordinates is ``2 w (D (x) I3 - G^T M^{-1} G)`` with ``G_k = [p_k]x Q^T``.
    Since ``G G^T = M0 = tr(C) I - C``, ``C = P^T P``, it is positive semi-definite exactly
    when the eigenvalues of ``M0^{-1/2} M M0^{-1/2}`` are >= 1. Summed over cells, the
    Hessian is ``2 (L (x) I3 - J^T J)``; ``J`` (3m x 3n, :meth:`jacobian`) is made per
    step from a :class:`Linearisation` straight into its CSR arrays (its column indices made
    once), and ``J^T`` is its transpose's view: one copy of the blocks, none of ``J^T J``.

    Parameters
    ----------
    steps : LocalGlobal
        The design's local-global steps (its mesh, ``L``, pinned vertex and factorised ``L_ff``).
    """

    #: Spacing of the coarse grid of ``method="newton-cg"``, in film thicknesses. Measured on the
    #: 10^5-cell Figure 8 plates (25 um pixels, h = 0.29 mm), fine-level Newton seconds at 1.5 / 0.75 / 0.5 / 0.4 / 0.3 / 0.2: twist 50.8 / 27.5 / 25.1 / 22.3 /
    #: 24.7 / 25.2; at 1.5 / 0.4: dome 10.2 / 6.5, saddle 16.7 / 10.8, the corrugation (0.1 mm
    #: pixels) 15.8 / 14.8 - same iterations and energies; a grid of 18 pixels left the bending
    #: between the pixel and the thickness to CG.
    coarse_spacing = 0.4
    #: ... where that is at least this many cells; on coarser cells (the thickness a few cells)
    #: :attr:`coarse_spacing_few` thicknesses, at least two cells: a coarse matrix of a quarter of
    #: the cells costs more to factorise than it saves (the 10^4-cell corrugation, 0.1 mm = h / 2.9
    #: pixels: 1.68 s with grids 4 cells apart, 1.83 s with 5, 2.48 s with 2), and the contact
    #: study's paths (symmetric hinges, the box) depend on the grid to round-off.
    coarse_min_cells = 4
    coarse_spacing_few = 1.5
    #: ... widened so that the grid has at most about this many coarse cells per layer where the
    #: coarse matrix is factorised (every step; its factorisation grows faster than its size),
    #: not where smoothed aggregation solves it (:attr:`coarse_solver`). At 40 000 the 10^6-cell
    #: corrugation keeps the 10^5 sheet's 5 pixels (1.7 h, two layers of 201 x 201 coarse vertices):
    #: from one start its fine level took 200 CG iterations in 19 steps where 10 000 (10 pixels)
    #: took 379 in 18, and 357 s against 424 s (docs/solver_history.md); 20 000 (8 pixels) took 382.
    coarse_cells = 40_000
    #: How the coarse matrix is solved (:data:`COARSE_SOLVERS`): ``"factor"`` (the default), a
    #: sparse factorisation at every step, which bounds the grid to :attr:`coarse_cells` cells
    #: per layer, so that on larger parts it is wider and leaves more to CG; ``"amg"``,
    #: :attr:`coarse_cycles` smoothed-aggregation V-cycles (:class:`gdfe.solver.amg.CoarseAMG`,
    #: needs pyamg), whose cost grows with the grid's size and no faster, so the grid keeps its
    #: spacing at every size. On the 10^6-cell corrugation, against a factorised grid of 10 000 cells
    #: per layer, ``"amg"`` took 20 % fewer CG iterations but about the same time, and 420 MiB more
    #: (docs/solver_history.md): not the default.
    coarse_solver = "factor"
    #: V-cycles of one coarse solve with ``"amg"`` (a stationary iteration from zero: a fixed,
    #: symmetric operator, so that CG's preconditioner does not change from one iteration to the next).
    coarse_cycles = 3
    #: How many of the last Newton directions ``method="newton-cg"`` adds to the coarse space
    #: (:mod:`gdfe.solver.recycling`): the soft modes the grid cannot carry; none with contact.
    #: A direction that is nearly all a turn about the pinned vertex is not recycled
    #: (:func:`gdfe.solver.recycling.mostly_turn`): kept, tight solves never stopped. 0 turns recycling
    #: off (docs/solver_history.md).
    recycle = 2
    #: How ``method="newton-cg"`` combines the n x n and coarse corrections
    #: (:data:`TWO_LEVELS`, see :meth:`operator`).
    two_level = "deflated"

    def __init__(self, steps):
        self.steps = steps
        self._coarse_rest = None

    # -- mesh-only constants, made on first use -------------------------------------------
    @functools.cached_property
    def L3(self):
        """``L (x) I3`` (3n x 3n, CSR), unknowns ordered vertex-major (``3 v + c``)."""
        return sp.kron(self.steps.L, sp.eye(3), format="csr")

    @functools.cached_property
    def coarse(self) -> CoarseSpace:
        """The :class:`CoarseSpace`: a grid about :attr:`coarse_spacing` film thicknesses apart.

        At least two cells apart (:attr:`coarse_min_cells`, :attr:`coarse_spacing_few`), so that
        the coarse space carries the bending at lengths above a fraction of the thickness, which
        the n x n system alone resolves badly; wider where that would give more than
        :attr:`coarse_cells` coarse cells per layer.
        """
        steps = self.steps
        design = steps.design
        dx, dy, _ = design.mesh.spacing
        layers = int(design.mesh.cell_k.max()) + 1
        c = int(np.ceil(self.coarse_spacing * design.h / min(dx, dy)))
        if c < self.coarse_min_cells:
            c = max(2, int(np.ceil(self.coarse_spacing_few * design.h / min(dx, dy))))
        wide = max(c, int(np.ceil(np.sqrt(design.n_cells / layers / self.coarse_cells))))
        solver = check_choice("coarse_solver", self.coarse_solver, COARSE_SOLVERS)
        if solver == "amg":
            check_int("coarse_cycles", self.coarse_cycles)
            from gdfe.solver.amg import available

            if not available():
                raise GdfeError("coarse_solver: expected 'factor' here, got 'amg': it needs pyamg "
                                "(pip install -e \".[fem]\")")
        else:
            c = wide
        ijk = lattice(design.mesh)
        i, j, k = ijk.T
        I0, ti = np.divmod(i, c)
        J0, tj = np.divmod(j, c)
        ti, tj = ti / c, tj / c
        nJ, nK = j.max() // c + 2, k.max() + 1
        rows = np.tile(np.arange(steps.n), 4)
        cols = np.concatenate([((I0 + a) * nJ + (J0 + b)) * nK + k for a in (0, 1) for b in (0, 1)])
        vals = np.concatenate([wa * wb for wa in (1 - ti, ti) for wb in (1 - tj, tj)])
        vals[rows == steps.pin] = 0.0
        Z = sp.csr_matrix((vals, (rows, cols)))
        Z.eliminate_zeros()
        used = np.nonzero(np.bincount(Z.indices, minlength=Z.shape[1]))[0]
        Z = Z[:, used].tocsr()
        # every cell lies in one coarse cell: the columns of that cell's eight corners
        cells = steps.cells
        cI, cJ, cK = i[cells].min(axis=1) // c, j[cells].min(axis=1) // c, k[cells].min(axis=1)
        keys = np.stack([((cI + a) * nJ + (cJ + b)) * nK + cK + l for a in (0, 1) for b in (0, 1) for l in (0, 1)],
                        axis=1)
        column = np.zeros(max(int(cols.max()), int(keys.max())) + 1, np.int64)
        column[used] = np.arange(used.size)  # a corner no vertex of the cell weighs on gets 0, weight 0
        Zf = Z[steps.free]
        return CoarseSpace(Z=Z, Lc=(Zf.T @ steps.L_ff @ Zf).tocsr(), Zt=Z.T.tocsr(), corners=column[keys].astype(np.int32), spacing=c,
                           coarse_cell=keys[:, 0], ijk=ijk.astype(np.int32), solver=solver)

    def _corner_weights(self, s, e):
        """``W[i, k, q]``, cells ``s:e``: the weight of cell ``i``'s corner ``q`` (:attr:`CoarseSpace.corners`) at its vertex ``k``."""
        cs = self.coarse
        cells = self.steps.cells[s:e]
        i, j, k = (cs.ijk[cells, a].astype(np.int64) for a in range(3))  # (c, 8) each
        c = cs.spacing
        ti = (i - (i.min(axis=1) // c * c)[:, None]) / c
        tj = (j - (j.min(axis=1) // c * c)[:, None]) / c
        up = k - k.min(axis=1)[:, None]
        live = cells != self.steps.pin  # the pinned vertex's row of Z is zero
        return np.stack([(ti if a else 1 - ti) * (tj if b else 1 - tj) * (up == l) * live
                         for a in (0, 1) for b in (0, 1) for l in (0, 1)], axis=2)

    def coarse_rest(self, rest):
        """The rest shapes carried to the coarse corners of every cell, ``W_i^T P_i``: ``(m, 8, 3)`` [mm]."""
        cached = self._coarse_rest
        if cached is None or cached[0] is not rest:
            P = rest.P
            out = np.empty_like(P)
            for s in range(0, P.shape[0], _CHUNK):
                e = min(P.shape[0], s + _CHUNK)
                out[s:e] = np.matmul(self._corner_weights(s, e).transpose(0, 2, 1), P[s:e])
            cached = self._coarse_rest = (rest, out)
        return cached[1]

    def prepare(self, rest):
        """Make the constants of the CG steps now (the first step of :func:`cg_directions` makes them otherwise):
        the coarse space and its cells' pattern, the Jacobian's pattern, ``L_free`` and the rest
        shapes at the coarse corners."""
        self.coarse.cells  # noqa: B018  (cached)
        self._j_pattern  # noqa: B018
        self.steps.L_free  # noqa: B018
        self.coarse_rest(rest)

    # -- per step ------------------------------------------------------------------------
    def linearise(self, Q, S, rest, floor=1.0) -> Linearisation:
        """The :class:`Linearisation` at rotations ``Q`` and cross-covariances ``S``.

        Parameters
        ----------
        Q, S : (m, 3, 3) float arrays
            The rotations and the cross-covariances they came from (:class:`Orientation`).
        rest : RestState
            The constants of the activation.
        floor : float
            Lower clamp of the eigenvalues of ``M0^{-1/2} M M0^{-1/2}``: 1 makes every
            cell's Hessian positive semi-definite (:meth:`matrix`); below 1 a cell may
            contribute negative curvature, which the sum over cells usually absorbs.
        """
        Y = np.matmul(Q.transpose(0, 2, 1), S)
        Y = 0.5 * (Y + Y.transpose(0, 2, 1))
        M = np.trace(Y, axis1=1, axis2=2)[:, None, None] * np.eye(3) - Y
        w = self.steps.w
        # where no eigenvalue is clamped (M - floor M0 positive definite) N = M^{-1}, and any square
        # root of w N serves (J^T J holds root root^T alone): sqrt(w) L^{-T} with M = L L^T, by the
        # 3 x 3 Cholesky factor in closed form instead of a batched eigendecomposition (8x faster)
        _, unclamped = _cholesky3(M - floor * rest.M0)
        Lc, positive = _cholesky3(M)
        fast = unclamped & positive
        root = np.sqrt(w)[:, None, None] * _inverse_lower3(Lc).transpose(0, 2, 1)
        slow = np.flatnonzero(~fast)
        if slow.size:
            M0is = rest.M0is[slow]
            lam, W = np.linalg.eigh(M0is @ M[slow] @ M0is)
            lam = np.maximum(lam, floor)
            # root = (w N)^(1/2) = M0^{-1/2} W diag((w/lam)^(1/2)) with N = M0^{-1/2} W diag(1/lam) W^T M0^{-1/2}
            root[slow] = (M0is @ W) * np.sqrt(w[slow, None] / lam)[:, None, :]
        return Linearisation(Q=Q, root=root)

    @functools.cached_property
    def _j_pattern(self):
        return _row_pattern(self.steps.cells, self.steps.n)

    def jacobian(self, lin, rest):
        """``J`` (3m x 3n, CSR, rows ``3 i + a``) at ``lin``."""
        return _block_rows(lin, rest.P, self._j_pattern)

    def matrix(self, Q, S, rest, mu=0.0, floor=1.0):
        """The Hessian (3n x 3n, sparse), plus ``mu`` times ``2 L``.

        The per-cell eigenvalues are clamped to >= ``floor`` (:meth:`linearise`): at 1 the matrix is
        positive semi-definite, which keeps every Newton step a descent direction. Unknowns ordered
        vertex-major (``3 v + c``).
        """
        J = self.jacobian(self.linearise(Q, S, rest, floor=floor), rest)
        return (2.0 * (1.0 + mu)) * self.L3 - 2.0 * (J.T @ J)

    def coarse_matrix(self, lin, rest, mu, extra=None):
        """``Z3^T H Z3``: the Hessian with damping ``max(mu, MU_MIN)`` on the coarse grid (3k x 3k, CSC)."""
        cs = self.coarse
        cc, scale = cs.cells, 2.0 * (1.0 + max(mu, MU_MIN))
        n = cc.indptr.size - 1
        data = scale * cc.L_values - 2.0 * cc.gram_values(lin, self.coarse_rest(rest))
        Hc = sp.csc_matrix((data, cc.indices, cc.indptr), shape=(n, n))  # symmetric: its CSR arrays are its CSC ones
        if extra is not None:
            Hc = sp.csc_matrix(Hc + cs.Z3.T @ extra @ cs.Z3)
        return Hc

    @functools.cached_property
    def _coarse_factoriser(self):
        """The coarse matrices' :class:`~gdfe.solver.linalg.Factoriser`: one pattern at every step, its form kept
        (with the contact barrier's Hessian added the pattern changes, and is made anew)."""
        return Factoriser()

    def coarse_factor(self, lin, rest, mu, extra=None, V=None):
        """:meth:`coarse_matrix` factorised, or its smoothed-aggregation solver (:attr:`coarse_solver`); None when it is singular.

        ``V`` ``(n, 3)`` [mm], the iterate, gives smoothed aggregation its near-null space (the
        rigid motions of the shape at the coarse vertices); default the flat print.
        """
        Hc = self.coarse_matrix(lin, rest, mu, extra)
        if self.coarse.solver == "amg":
            from gdfe.solver.amg import CoarseAMG

            V = self.steps.design.mesh.points if V is None else V
            try:
                return CoarseAMG(Hc, self.coarse.points(V), cycles=self.coarse_cycles)
            except np.linalg.LinAlgError:  # its coarsest level is not positive definite
                return None
        try:
            return self._coarse_factoriser(Hc)
        except RuntimeError:  # SuperLU: exactly singular
            return None

    def operator(self, lin, rest, mu, extra=None, coarse_factor=None, J=None, recycled=()):
        """Hessian product and preconditioner at ``lin`` with damping ``mu``.

        The preconditioner combines the exact inverse of the (scaled) n x n system for
        the three coordinates, ``M``, with a Galerkin coarse correction
        ``Q = Z (Z^T H Z)^{-1} Z^T``, as :attr:`two_level` says:

        ``"deflated"`` (the default)
            ``M r + Q (r - H M r)`` with CG started from the coarse solution ``Q b``
            (:attr:`CGOperator.start`): Tang, Nabben, Vuik and Erlangga's A-DEF2. Started
            there, every CG residual is H-orthogonal to the coarse space (``Q r = 0``), where
            it gives the iterates of ``"multiplicative"`` (their Theorem: the balancing
            preconditioner and A-DEF2 from that start are equal) for one Hessian product and
            one coarse solve per CG iteration fewer. It needs the coarse matrix of this
            iterate: with one made at an earlier iterate (:data:`COARSE_REUSE`) CG stalled near
            the 10^4-cell twist's solution, so :func:`cg_directions` reuses none with it. With
            the coarse matrix solved by smoothed aggregation (:attr:`coarse_solver`) the
            equivalence holds only approximately, and CG takes its flexible form
            (:attr:`CGOperator.flexible`).
        ``"multiplicative"``
            Symmetrically, coarse - fine - coarse (the balancing Neumann-Neumann
            preconditioner ``Q + (I - Q H) M (I - H Q)``), which halves the CG iterations
            on the mask sheets against ``"additive"``, ``M + Q``.

        ``extra`` (3n x 3n, vertex-major, positive semi-definite; the contact barrier's
        Hessian) is added to the Hessian and to the coarse matrix. ``coarse_factor``, one
        made earlier (:meth:`coarse_factor`), is used instead of making one; ``J``, made
        earlier (:meth:`jacobian` at ``lin``), likewise. ``recycled``, ``(n, 3)`` arrays zero at
        the pinned vertex (the last Newton directions, :attr:`recycle`), are added to the coarse
        space (:class:`gdfe.solver.recycling.AugmentedCoarse`).

        Returns
        -------
        CGOperator or None
            Functions acting on ``(n, 3)`` arrays zero at the pinned vertex (CG's vectors; the
            Hessian product does not read that row); None when the coarse matrix is not
            positive definite.
        """
        steps = self.steps
        cs = self.coarse
        Z, Zt = cs.products
        fc = self.coarse_factor(lin, rest, mu, extra) if coarse_factor is None else coarse_factor
        if fc is None:
            return None
        J = self.jacobian(lin, rest) if J is None else J
        Jt = J.T
        # CG's vectors are zero at the pinned vertex, and so is the product there
        pin, apply_L = steps.pin, steps.apply_L_free
        scale = 2.0 * (1.0 + mu)
        two_level = check_choice("two_level", self.two_level, TWO_LEVELS)

        def apply_H(v):
            # L v and J^T J v side by side on two threads (gdfe.solver.threads): the same arithmetic
            Lv, JJv = side_by_side(lambda: apply_L(v), lambda: Jt @ (J @ v.ravel()), rows=steps.n)
            out = _combine(scale, Lv, JJv)
            if extra is not None:
                out += (extra @ v.ravel()).reshape(-1, 3)
            out[pin] = 0.0
            return out

        coarse = AugmentedCoarse(fc.solve, Z, Zt, apply_H, recycled)

        def fine(r):
            return steps.approx_solve_pinned(r, scale)

        if two_level == "deflated":
            def apply_P(r):
                z = fine(r)
                t = apply_H(z)
                np.subtract(r, t, out=t)  # r - H z, in the product's array
                out = coarse(t)
                out += z
                return out
            # with an approximate coarse solve the residuals keep a coarse part and A-DEF2 is no longer
            # equivalent to the balancing preconditioner: CG takes its flexible form
            return CGOperator(apply_H, apply_P, start=coarse, flexible=cs.solver != "factor")

        def apply_P(r):
            if two_level == "additive":
                return fine(r) + coarse(r)
            z = coarse(r)  # symmetric multiplicative: coarse, fine, coarse
            z += fine(r - apply_H(z))
            return z + coarse(r - apply_H(z))

        return CGOperator(apply_H, apply_P)

    @functools.cached_property
    def block_pattern(self):
        """The 3 x 3 block structure of the assembled Hessian (:class:`gdfe.solver.amg.BlockPattern`)."""
        from gdfe.solver.amg import BlockPattern

        return BlockPattern.of(self.steps.cells, self.steps.n)

    def _device_L(self, xp):
        """``L`` with the pinned row and column zero (``steps.L_free``) on the array module ``xp`` (kept for the next call)."""
        from gdfe.solver.device import to_device_sparse

        cached = self.__dict__.get("_L_on")
        if cached is None or cached[0] is not xp:
            cached = self.__dict__["_L_on"] = (xp, to_device_sparse(self.steps.L_free, xp))
        return cached[1]

    def amg_operator(self, lin, rest, mu, ml, extra=None, J=None, xp=np):
        """Hessian product and smoothed-aggregation preconditioner on the array module ``xp``.

        The product is :meth:`operator`'s (``2 ((1 + mu) L - J^T J)``, plus ``extra``, the
        pinned vertex's rows zero), made with ``J`` on ``xp``; the preconditioner is one
        V-cycle of ``ml`` (:class:`gdfe.solver.amg.HessianAMG`), possibly built on an
        earlier Hessian.

        Returns
        -------
        CGOperator
            Functions acting on ``(n, 3)`` arrays of ``xp``.
        """
        from gdfe.solver.device import to_device_sparse

        steps = self.steps
        pin = steps.pin
        J = self.jacobian(lin, rest) if J is None else J
        scale = 2.0 * (1.0 + mu)
        if xp is np:
            Jd, Jtd, apply_L = J, J.T, steps.apply_L_free
        else:
            Jd = to_device_sparse(J, xp)
            Jtd = Jd.T.tocsr()
            Ld = self._device_L(xp)
            apply_L = Ld.__matmul__
        Ed = None if extra is None else to_device_sparse(sp.csr_matrix(extra), xp)

        def apply_H(v):
            if xp is np:  # as operator's: L v and J^T J v side by side on the CPU's threads
                Lv, JJv = side_by_side(lambda: apply_L(v), lambda: Jtd @ (Jd @ v.ravel()), rows=steps.n)
            else:
                Lv, JJv = apply_L(v), Jtd @ (Jd @ v.ravel())
            out = _combine(scale, Lv, JJv)
            if Ed is not None:
                out += (Ed @ v.ravel()).reshape(-1, 3)
            out[pin] = 0.0
            return out

        def apply_P(r):
            z = ml.vcycle(r.ravel()).reshape(-1, 3)
            z[pin] = 0.0
            return z

        return CGOperator(apply_H, apply_P)



def pcg(apply_H, apply_P, rhs, rtol, max_iter, start=None, flexible=False, leave_saddle=False):
    """Preconditioned CG; stops at negative curvature.

    At negative curvature CG returns its iterate; with ``leave_saddle``, met at the first
    iteration, the start plus the preconditioned residual there, ``x0 + P r0`` (Nocedal and
    Wright's Algorithm 7.1 returns the steepest descent direction there). Newton-CG asks for it
    where it recycles directions (:attr:`ReducedHessian.recycle`): at a saddle the start alone,
    a coarse solution that cannot hold the direction of negative curvature, is a step of
    round-off, which a line search takes and a Newton solve repeats (the 208-cell Figure 8 dome:
    200 steps of 1e-11 h; with it, 19 steps to the minimum).

    ``rhs`` and what ``apply_H`` and ``apply_P`` return are arrays of one module (NumPy or CuPy);
    each call must return a new array, which CG then updates in place (the residual, the direction).
    ``rtol`` is relative to the preconditioned norm ``sqrt(rhs^T P rhs)`` of the right-hand
    side; it may be a function of that norm (a forcing sequence that measures the gradient
    in the norm CG stops in, :func:`cg_directions`).

    ``start`` (optional) gives the first iterate ``x0 = start(rhs)``, the coarse solution of
    a deflated CG (:meth:`ReducedHessian.operator`); the right-hand side's norm is then
    ``sqrt(rhs^T x0 + r0^T P r0)`` (``r0 = rhs - H x0``), the balancing preconditioner's
    ``rhs^T P rhs`` that the same CG started from zero measures (where that sum is not positive,
    the coarse space holding negative curvature, ``sqrt(r0^T P r0)``).

    ``flexible`` takes Notay's flexible CG (*SIAM J. Sci. Comput.* 22, 2000): the direction's
    coefficient ``z_k^T (r_k - r_k-1) / z_k-1^T r_k-1`` (Polak-Ribiere) instead of
    ``z_k^T r_k / z_k-1^T r_k-1``, the same in exact arithmetic with a symmetric positive
    definite preconditioner, and robust where the preconditioner is not quite one (a
    deflated preconditioner whose coarse solve is approximate).

    Returns
    -------
    x : array like ``rhs``
    iterations : int
    """
    if start is None:
        x = rhs * 0.0
        r = rhs.copy()
    else:
        x = start(rhs)
        r = rhs - apply_H(x)
    z = apply_P(r)
    rz = _dot(r, z)
    norm2 = rz if start is None else rz + _dot(rhs, x)
    if not rz > 0:
        return x, 0
    if not norm2 > 0:
        # the coarse solution climbs (rhs^T x0 < -r0^T P r0): the coarse space holds negative curvature
        # (a recycled direction across a saddle), and the balancing norm is no norm; CG measures from
        # its own start's residual instead (the square root of the negative one was a tolerance of
        # nan, and CG ran on to negative curvature or max_iter with no stopping test)
        log.debug("CG: the coarse start climbs (rhs.x0 = %.3e, r0.P r0 = %.3e)", float(norm2 - rz), float(rz))
        norm2 = rz
    if callable(rtol):
        rtol = rtol(float(np.sqrt(norm2)))
    stop = rtol * float(np.sqrt(norm2))
    if np.sqrt(rz) <= stop:
        return x, 0
    p = z
    # the updates in place, a p and a H p in one kept array: a new temporary as large as the mesh's vertices
    # is fresh memory from the system (its pages faulted in) at every use, at 10^6 cells 48 MiB each; the
    # same arithmetic, so the same bits (on the GPU, CuPy's own temporaries)
    work = p.copy() if isinstance(p, np.ndarray) else None
    for k in range(1, max_iter + 1):
        Hp = apply_H(p)
        pHp = _dot(p, Hp)
        if not pHp > 0:
            log.debug("CG: negative curvature at iteration %d (p.Hp = %.3e)", k, pHp)
            if k == 1 and leave_saddle:  # at the start itself: its preconditioned correction
                return x + p, k
            return x, k
        a = rz / pHp
        x += _times(p, a, work)
        r -= _times(Hp, a, work)
        z = apply_P(r)
        rz_new = _dot(r, z)
        if not rz_new > 0 or float(np.sqrt(rz_new)) <= stop:
            return x, k
        # flexible: z_k^T (r_k - r_k-1) with r_k - r_k-1 = -a H p, no copy of the last residual
        beta = -a * _dot(z, Hp) / rz if flexible else rz_new / rz
        p *= beta  # p = z + beta p
        p += z
        rz = rz_new
    return x, max_iter


def _times(v, a, work):
    """``a v``: in ``work`` where given (no temporary), else a new array."""
    return a * v if work is None else np.multiply(v, a, out=work)


def _combine(scale, Lv, JJv):
    """``scale L v - 2 J^T J v`` from the two products (``(n, 3)`` and flat), in ``Lv``'s array (``JJv``'s is
    overwritten too): the Hessian product of :meth:`ReducedHessian.operator` with no temporary (the same arithmetic)."""
    JJv = JJv.reshape(Lv.shape)
    Lv *= scale
    JJv *= 2.0
    Lv -= JJv
    return Lv


def factorised_directions(hessian, rest, floor=HESSIAN_FLOOR):
    """Newton steps of ``method="newton"``: the 3n x 3n Hessian factorised, per damping ``mu``.

    The Hessian is :meth:`ReducedHessian.matrix`'s with the per-cell clamp at ``floor``
    (:data:`HESSIAN_FLOOR`): an indefinite matrix is factorised by LU (:class:`gdfe.solver.linalg.Factoriser`),
    and a step that does not lower the energy is damped more.

    Returns ``directions(Q, S, grad, res, extra=None, error=inf, target=0, V=None)``, see :func:`solve_newton`.
    """
    floor = float(check_positive("floor", floor))  # at 0 or below a cell's zero eigenvalue would divide by zero
    steps = hessian.steps
    fdof = (3 * steps.free[:, None] + np.arange(3)).ravel()
    n = steps.n

    def directions(Q, S, grad, res, extra=None, error=np.inf, target=0.0, V=None):
        def step(mu):
            H = hessian.matrix(Q, S, rest, mu=mu, floor=floor)
            if extra is not None:
                H = H + extra
            H = H[fdof][:, fdof]
            out = np.zeros(3 * n)
            try:
                out[fdof] = factorise(H).solve(-grad.ravel()[fdof])
            except RuntimeError:  # numerically singular: damp more
                return None, 0
            return out.reshape(n, 3), 0
        return step
    return directions


def forcing_term(res, prev, eta_prev, target=0.0, error=np.inf, plain=None):
    """The relative CG tolerance of one Newton step: Eisenstat and Walker's choice 2.

    ``eta = EW_GAMMA (res / prev)^EW_ALPHA``: as tight as the last step's reduction of the
    residual says the iteration is converging, so that Newton-CG keeps the order of
    Newton's method near the solution (superlinear) and does not over-solve far from it.
    Safeguarded as they propose: when ``EW_GAMMA eta_prev^EW_ALPHA`` exceeds 0.1 it is a lower
    bound (eta does not drop suddenly), and eta lies in [:data:`CG_RTOL_MIN`,
    :data:`CG_RTOL_MAX`]; no looser than :func:`sqrt_forcing` (``sqrt(plain)``): a step's
    length estimates the distance to the solution in the stopping test, and a step CG left
    at 0.1 after one iteration (the term after a residual that rose) had stopped the
    10^5-cell twist 3 um from its solution; and no tighter than :data:`CG_TARGET_MARGIN`
    times the reduction the stopping test still asks of the estimated distance ``error``
    (``target / error``).

    Parameters
    ----------
    res : float
        The gradient's norm at this iterate, in the norm CG stops in (its preconditioned
        norm, :func:`pcg`).
    prev, eta_prev : float or None
        That norm and the forcing term at the previous Newton step (None at the first).
    target, error : float
        See :func:`solve_newton`.
    plain : float, optional
        The plain step's residual (units of h).
    """
    if prev is None or eta_prev is None or not prev > 0.0:
        eta = CG_RTOL_MAX
    else:
        eta = EW_GAMMA * (res / prev) ** EW_ALPHA
        floor = EW_GAMMA * eta_prev ** EW_ALPHA
        if floor > 0.1:
            eta = max(eta, floor)
    if plain is not None:  # never looser than sqrt_forcing: the stopping test reads the step's length
        eta = min(eta, np.sqrt(plain))
    eta = min(CG_RTOL_MAX, max(CG_RTOL_MIN, eta))
    if target > 0.0 and np.isfinite(error):
        eta = min(CG_RTOL_MAX, max(eta, CG_TARGET_MARGIN * target / error))
    return float(eta)


def sqrt_forcing(res, target=0.0, error=np.inf):
    """The CG tolerance of ``forcing="sqrt"``: ``sqrt(res)`` clipped to [:data:`CG_RTOL_MIN`,
    :data:`CG_RTOL_MAX`], no tighter than :data:`CG_TARGET_MARGIN` ``target / error``."""
    eta = min(CG_RTOL_MAX, max(CG_RTOL_MIN, np.sqrt(res)))
    if target > 0.0 and np.isfinite(error):
        eta = min(CG_RTOL_MAX, max(eta, CG_TARGET_MARGIN * target / error))
    return float(eta)


def cg_directions(hessian, rest, floor=HESSIAN_FLOOR, cg_rtol=None, cg_max=200, forcing="eisenstat-walker",
                  preconditioner="two-level", device="cpu"):
    """Newton steps of ``method="newton-cg"``: preconditioned CG, no 3n x 3n factorisation.

    The Hessian is :meth:`ReducedHessian.matrix`'s with the per-cell clamp lowered to
    ``floor`` (nearer the true Hessian, hence fewer Newton steps; CG stops at negative
    curvature and the energy test rejects a bad step). CG stops at a relative
    (preconditioned) residual ``cg_rtol``, by default the forcing term ``forcing``:
    ``"eisenstat-walker"`` (:func:`forcing_term`) or ``"sqrt"`` (:func:`sqrt_forcing`, the
    square root of the plain step's residual).

    Preconditioners (``preconditioner``):

    ``"two-level"``
        One solve with the n x n system for three right-hand sides and a Galerkin coarse
        correction on a grid (:meth:`ReducedHessian.operator`); the coarse matrix is
        factorised once per step (kept for the next while the shape moves by less than
        :data:`COARSE_REUSE`); the last :attr:`ReducedHessian.recycle` Newton directions join
        the coarse space (:mod:`gdfe.solver.recycling`).
    ``"amg"``
        Smoothed aggregation on the assembled Hessian model with the rigid motions as
        near-null space (:mod:`gdfe.solver.amg`, needs pyamg), built once and kept across
        Newton steps until CG needs more than :data:`gdfe.solver.amg.AMG_REBUILD_CG`
        iterations with it. Its products run on ``device`` (:mod:`gdfe.solver.device`).

    Returns ``directions(Q, S, grad, res, extra=None, error=inf, target=0, V=None)``, see
    :func:`solve_newton`.
    """
    preconditioner = check_choice("preconditioner", preconditioner, PRECONDITIONERS)
    forcing = check_choice("forcing", forcing, FORCINGS)
    floor = float(check_positive("floor", floor))  # at 0 or below a cell's zero eigenvalue would divide by zero
    if preconditioner == "amg":
        return _amg_directions(hessian, rest, floor, cg_rtol, cg_max, forcing, device)
    kept = {}  # the last coarse factor and the damping it was made with
    history = {"res": None, "eta": None}  # the forcing sequence
    recycle = check_int("recycle", hessian.recycle, minimum=0)
    recent = collections.deque(maxlen=recycle)  # the last Newton directions
    proposed = {}  # the direction last computed (the step taken, or one tried with more damping)

    def directions(Q, S, grad, res, extra=None, error=np.inf, target=0.0, V=None, recycle_here=True):
        x = proposed.pop("x", None)
        # the step's own array, which solve_newton does not change in place; not one made by round-off
        # that is all but a turn of the whole part (near the solution: tight solves then never stopped)
        if x is not None and not mostly_turn(x, V, hessian.steps.pin):
            recent.appendleft(x)
        # none in a contact solve (recycle_here False): with them the contact study's 14 mm hinge, moved by
        # 2 um and solved again, fell by 6.9e-5 of its energy (1.5e-3 with them left out only where
        # pairs are active) instead of coming back
        recycled = list(recent) if recycle_here else []
        lin = hessian.linearise(Q, S, rest, floor=floor)
        rtol = _forcing(cg_rtol, forcing, history, res, target, error)
        # only a first try may reuse the last factor, and only with the balancing forms: the deflated one
        # needs the coarse matrix of this iterate (with one made at the last, CG stalled on the soft modes
        # near the solution of the 10^4-cell twist, 200 iterations where it took 10; falling back to the
        # balancing form with a reused factor took the 10^5 twist's fine solve from 21.0 s to 25.4 s)
        reusable = extra is None and hessian.two_level != "deflated"
        may_reuse = reusable and error <= COARSE_REUSE
        J = None  # the same for every damping tried at this iterate: made beside the first coarse factorisation

        def step(mu):
            nonlocal may_reuse, J
            # the damping enters the coarse matrix as the factor 1 + max(mu, MU_MIN) of its L part
            same = "mu" in kept and abs(max(mu, MU_MIN) - max(kept["mu"], MU_MIN)) <= COARSE_REUSE_DAMPING
            fc = kept["factor"] if may_reuse and same else None
            may_reuse = False
            if fc is None:
                kept.clear()  # the last factor is not held while the next is made
                fc, J = side_by_side(lambda: hessian.coarse_factor(lin, rest, mu, extra, V=V),
                                     lambda: hessian.jacobian(lin, rest) if J is None else J, rows=hessian.steps.n)
                if fc is None:
                    return None, 0
                if reusable:
                    kept.update(factor=fc, mu=mu)
            if J is None:
                J = hessian.jacobian(lin, rest)
            ops = hessian.operator(lin, rest, mu, extra, coarse_factor=fc, J=J, recycled=recycled)
            x, k = pcg(ops.apply_H, ops.apply_P, -grad, rtol, cg_max, start=ops.start, flexible=ops.flexible,
                       leave_saddle=bool(recycled))
            if recycle and recycle_here:  # a contact solve recycles nothing, so holds no direction either
                proposed["x"] = x
            log.debug("CG: %d iterations to %.1e", k, history["eta"] if callable(rtol) else rtol)
            return x, k
        return step
    directions.wants_shape = True  # a coarse matrix solved by smoothed aggregation takes its near-null space from the iterate
    directions.recycles = True  # told whether this solve may recycle (not with contact)
    return directions


def _forcing(cg_rtol, forcing, history, res, target, error):
    """The CG tolerance of this Newton step: ``cg_rtol`` when given, else a function of the
    gradient's preconditioned norm (the forcing sequence, remembered in ``history``)."""
    if cg_rtol is not None:
        return cg_rtol
    if forcing == "sqrt":
        return sqrt_forcing(res, target, error)

    def rtol(norm):
        # a retry at this iterate (more damping) repeats the last step's term
        if history.get("at") is not None and history["at"] == (res, error):
            return history["eta"]
        eta = forcing_term(norm, history["res"], history["eta"], target, error, plain=res)
        history.update(res=norm, eta=eta, at=(res, error))
        return eta
    return rtol


def _amg_directions(hessian, rest, floor, cg_rtol, cg_max, forcing, device):
    """:func:`cg_directions` with the smoothed-aggregation preconditioner (``preconditioner="amg"``)."""
    from gdfe.solver import amg, device as dev

    if not amg.available():
        raise GdfeError("preconditioner: expected 'two-level' here, got 'amg': it needs pyamg "
                        "(pip install -e \".[fem]\")")
    xp = dev.array_module(device)
    steps = hessian.steps
    kept = {"ml": None, "cg": 0, "mu": None}
    history = {"res": None, "eta": None}

    def directions(Q, S, grad, res, extra=None, error=np.inf, target=0.0, V=None):
        lin = hessian.linearise(Q, S, rest, floor=floor)
        rtol = _forcing(cg_rtol, forcing, history, res, target, error)
        J = hessian.jacobian(lin, rest)
        g = dev.to_device(-grad, xp)

        def step(mu):
            ml = kept["ml"]
            # made again after a step CG found hard, after a large change of the damping, and with contact
            if (ml is None or kept["cg"] > amg.AMG_REBUILD_CG or extra is not None
                    or abs(max(mu, MU_MIN) - max(kept["mu"], MU_MIN)) > AMG_REBUILD_DAMPING):
                model = hessian.linearise(Q, S, rest, floor=1.0)
                A = amg.hessian_blocks(hessian, model, rest, max(mu, MU_MIN), hessian.block_pattern)
                if extra is not None:
                    A = (A + _pinned_out(extra, steps.pin)).tobsr(blocksize=(3, 3))
                shape = V if V is not None else np.zeros((steps.n, 3))
                t0 = time.perf_counter()
                try:
                    ml = amg.HessianAMG(A, amg.rigid_modes(shape, steps.pin), xp=xp)
                except np.linalg.LinAlgError:  # the coarsest level is not positive definite: damp more
                    return None, 0
                log.debug("AMG: levels %s, operator complexity %.2f, %.2f s", ml.sizes, ml.complexity,
                          time.perf_counter() - t0)
                kept.update(ml=ml, mu=mu, builds=kept.get("builds", 0) + 1)
            ops = hessian.amg_operator(lin, rest, mu, ml, extra=extra, J=J, xp=xp)
            x, k = pcg(ops.apply_H, ops.apply_P, g, rtol, cg_max)
            kept["cg"] = k
            log.debug("CG (AMG): %d iterations to %.1e", k, history["eta"] if callable(rtol) else rtol)
            return dev.to_host(x), k
        return step
    directions.state = kept
    directions.wants_shape = True  # the near-null space is the rigid motions of the iterate
    return directions


def _pinned_out(M, pin):
    """The 3n x 3n matrix ``M`` with the pinned vertex's rows and columns zero (CSR)."""
    M = sp.csr_matrix(M)
    keep = np.ones(M.shape[0])
    keep[3 * pin:3 * pin + 3] = 0.0
    D = sp.diags(keep)
    return (D @ M @ D).tocsr()


def deformation(step, V):
    """``step`` ``(n, 3)`` [mm] less its best-fit infinitesimal rigid motion about the centroid of ``V``.

    The energy does not change under rigid motions, and the pinned vertex holds only the
    translations: a step may turn the whole shape about it by round-off (``MU_MIN`` keeps
    that small, not zero), which moves far vertices of a large part by more than the
    tolerance while the shape stays the same. The stopping test measures what is left.
    """
    r = V - V.mean(axis=0)
    d = step - step.mean(axis=0)
    omega = turn_fit(r, d)
    return d if omega is None else d - np.cross(omega, r)  # None: all points on a line, no turn to remove


def _next_damping(mu, full, fast, res, vanishing_damping, contact=False):
    """The damping after an accepted step (:func:`solve_newton`).

    A shortened step doubles it; a full one divides it by 4, or where ``fast`` (the energy
    fell by at least :data:`MODEL_AGREEMENT` of what the quadratic model predicted) drops it
    at once, down to its floor: :data:`MU_MIN`, or with ``vanishing_damping``
    ``min(MU_MIN, MU_RESIDUAL * res)``, ``res`` the plain step's residual (units of h)
    (:data:`MU_RESIDUAL_CONTACT` in place of ``MU_RESIDUAL`` with ``contact``).
    """
    if not full:
        return 2.0 * mu
    factor = MU_RESIDUAL_CONTACT if contact else MU_RESIDUAL
    floor = min(MU_MIN, factor * res) if vanishing_damping else MU_MIN
    return floor if fast else max(mu / 4.0, floor)


class _DriftWatch:
    """Drift between near-equal states in a Newton solve (:func:`solve_newton`, Notes).

    Every :data:`DRIFT_WINDOW` iterations, from an anchor (iteration, energy, estimated distance
    and shape): the energy fell by less than :data:`DRIFT_ENERGY` of itself while the estimate,
    still above ``target`` (units of h), shrank by less than :data:`DRIFT_SHRINK` - the first
    time a warning, and :attr:`stop` with ``on_drift="stop"``.
    """

    def __init__(self, E, V, on_drift, target, scale):
        self.anchor = (0, E, np.inf, V.copy())
        self.on_drift, self.target, self.scale = on_drift, target, scale
        self.drift = None
        self.stop = False

    def update(self, it, E, error, V):
        """After iteration ``it``: energy ``E``, estimated distance ``error`` (h), shape ``V`` ``(n, 3)`` [mm]."""
        since, E0, error0, V0 = self.anchor
        if it - since < DRIFT_WINDOW:
            return
        fell = (E0 - E) / max(abs(E), 1e-300)
        if fell < DRIFT_ENERGY and error > self.target and not error < DRIFT_SHRINK * error0:
            moved_mm = float(np.linalg.norm(deformation(V - V0, V0), axis=1).max())
            if self.drift is None:
                self.drift = {"since_iteration": since, "detected_at": it, "energy": E, "energy_change": fell,
                              "moved_mm": moved_mm, "estimate_mm": error * self.scale}
                log.warning("newton: drifting between near-equal states: over iterations %d-%d the energy fell "
                            "by %.1e of itself while the shape moved %.3g mm (distance to the solution "
                            "estimated %.3g mm); %s", since, it, fell, moved_mm, error * self.scale,
                            "stopping (on_drift='stop')" if self.on_drift == "stop" else
                            "going on (on_drift='stop' stops at this point)")
            self.drift["moved_mm"] = max(self.drift["moved_mm"], moved_mm)
            self.stop = self.on_drift == "stop"
        self.anchor = (it, E, error, V.copy())

    def report(self, it):
        """``SolveStats.drift`` after ``it`` iterations: None, or the drift with its ``iterations``."""
        if self.drift is not None:
            self.drift["iterations"] = it - self.drift["since_iteration"]
        return self.drift


@dataclasses.dataclass(frozen=True)
class NewtonStep:
    """One step of a Newton solve (:attr:`gdfe.solver.SolveStats.newton_steps`, :func:`solve_newton`).

    Attributes
    ----------
    iteration : int
        The solve's iteration (1 for the first step); the last iteration takes no step, it
        finds the stopping test met (or the limit reached), unless it is a ``"none"``.
    residual_h : float
        The plain step's residual at the iterate the step starts from (units of h).
    kind : str
        ``"newton"``; ``"plain"`` where no damped Newton direction lowered the energy and the
        plain step was taken instead; ``"none"`` where with contact neither did, and the solve
        stopped there (the shape unchanged, ``length_h`` 0).
    length_h : float
        The step's largest vertex move, its rigid part left out (:func:`deformation`; units of h).
    alpha : float or None
        The fraction of the Newton step taken (1: a full step; None for a plain step).
    damping : float or None
        The damping ``mu`` of the direction taken (None for a plain step).
    tries : int
        Directions computed at this iterate, one per damping tried.
    cg_iterations : int
        CG iterations of those directions (0 where they are factorised).
    model_agreement : float or None
        The energy's fall against the quadratic model's predicted fall along the step taken
        (1: the model exact; None where the model predicted no fall, or for a plain step).
    energy : float
        The energy after the step [mm^5] (with the barrier's under contact).
    estimate_h : float
        The estimated distance to the solution after the step (units of h; :func:`solve_newton`, Notes).
    seconds : float
        The wall time of the iteration: the plain step, the directions, the trial energies.
    """

    iteration: int
    residual_h: float
    kind: str
    length_h: float
    alpha: float | None
    damping: float | None
    tries: int
    cg_iterations: int
    model_agreement: float | None
    energy: float
    estimate_h: float
    seconds: float

    def as_dict(self):
        """The record as a dict of plain Python numbers (for JSON)."""
        return dataclasses.asdict(self)


def convergence_rates(steps):
    """The contractions ``length_k / length_k-1`` of consecutive full Newton steps, ``(k,)``.

    ``steps`` is a solve's :class:`NewtonStep` records. A contraction is given only where both steps
    were whole Newton steps (``alpha`` 1); a shortened or plain step begins the sequence again. Near
    the solution the contractions fall towards 0 where the convergence is superlinear, and stay
    at a constant where it is linear.
    """
    rates, prev = [], None
    for s in steps:
        full = s.kind == "newton" and s.alpha == 1.0
        if full and prev is not None and prev > 0.0:
            rates.append(s.length_h / prev)
        prev = s.length_h if full else None
    return np.array(rates)


class _DistanceEstimate:
    """The estimated distance to the solution (units of h), from the steps taken (:func:`solve_newton`, Notes).

    ``error`` is the last step's length without its rigid part, or, with ``extrapolate``, the
    bound ``|s_k| theta / (1 - theta)`` of a sequence contracting by ``theta`` where that is
    smaller, ``theta`` the larger of the last two contractions of full steps.
    """

    def __init__(self, extrapolate):
        self.extrapolate = extrapolate
        self.error = np.inf
        self._prev = np.inf  # the last full step's length
        self._theta = 0.0  # the contraction of the last two full steps (0: none yet)

    def step(self, moved, full):
        """After a step of length ``moved`` (h), ``full`` where it was taken whole."""
        self.error = moved
        if not full:
            self._prev, self._theta = np.inf, 0.0
            return
        theta = moved / self._prev  # 0 after a first full step: no estimate yet
        rate = max(theta, self._theta)
        # with a vanishing damping the estimate is the step itself: extrapolated by the
        # contraction, it fell 18x short of the distance in the stopping study
        if 0.0 < theta and rate < 1.0 and self.extrapolate:
            self.error = min(moved, moved * rate / (1.0 - rate))
        self._prev, self._theta = moved, theta

    def plain(self, res):
        """After a plain step whose residual was ``res`` (h)."""
        self.error, self._prev, self._theta = res, np.inf, 0.0


class _Iterate(typing.NamedTuple):
    """A Newton iterate: shape ``V`` ``(n, 3)`` [mm], its best rotations ``Q`` and stretches ``S``, its
    energy ``E`` (with the barrier's under contact) and the contact state (None without)."""
    V: np.ndarray
    Q: np.ndarray
    S: np.ndarray
    E: float
    state: typing.Any = None


def _iterate(steps, V, activation, contact):
    """The iterate at shape ``V``: its orientation, and with ``contact`` the barrier's state and energy."""
    o = steps.orient(V, activation)
    if contact is None:
        return _Iterate(V, o.Q, o.S, o.energy)
    state = contact.evaluate(V)
    return _Iterate(V, o.Q, o.S, o.energy + state.energy, state)


class _Plain(typing.NamedTuple):
    """The plain (assembly) step from an iterate (:func:`_plain_step`)."""
    G: np.ndarray | None  # the plain step's shape, None where only estimated
    res: float  # its residual (units of h)
    b: np.ndarray  # the assembly's right-hand side: the gradient is 2 (L V - b)
    grad: np.ndarray | None  # the gradient at the iterate, where it was made
    move: np.ndarray | None  # with contact, the move with the contact forces held
    gB: np.ndarray | None  # with contact, the barrier's gradient


def _plain_step(steps, x, Vp, activation, contact, lazy, may_end):
    """The plain step from iterate ``x`` and its residual, the stopping test's (:func:`solve_newton`).

    ``lazy`` (a multigrid without contact): the exact solve is made only where ``may_end(res,
    slack=2)`` says the test could pass on the V-cycle's estimate; the Newton step needs only the
    gradient. With ``contact`` the move holds the barrier's force at ``x``.
    """
    scale = steps.design.h
    plain = steps.assemble(x.Q, Vp, activation, solve=not lazy, guess=x.V)
    G = plain.V
    if lazy:
        g = 2.0 * (steps.apply_L(x.V) - plain.b)
        move = np.zeros_like(x.V)
        move[steps.free] = steps.approx_solve_free(-0.5 * g[steps.free])
        res = float(np.abs(move).max() / scale)
        if may_end(res, slack=2.0):
            move += x.V  # the approximate plain step: the exact solve starts there
            G = steps.assemble(x.Q, Vp, activation, guess=move).V
            res = float(np.abs(G - x.V).max() / scale)
        return _Plain(G, res, plain.b, g, None, None)
    if contact is None:
        return _Plain(G, float(np.abs(G - x.V).max() / scale), plain.b, None, None, None)
    gB = contact.gradient(x.state)
    move = G - x.V
    if x.state.active:
        move = move - 0.5 * _solve_free(steps, gB)
    return _Plain(G, float(np.abs(move).max() / scale), plain.b, None, move, gB)


def _newton_direction(steps, directions, x, plain, res, contact, error, target):
    """The gradient at iterate ``x`` (the barrier's added with ``contact``, zero at the pinned vertex) and
    the Newton direction there, a function of the damping (``directions``, :func:`solve_newton`)."""
    grad = 2.0 * (steps.apply_L(x.V) - plain.b) if plain.grad is None else plain.grad
    kwargs = {"V": x.V} if getattr(directions, "wants_shape", False) else {}
    if getattr(directions, "recycles", False):
        kwargs["recycle_here"] = contact is None
    if contact is not None:
        grad += plain.gB
        kwargs["extra"] = contact.hessian(x.state, project=res > CONTACT_EXACT_RES)
    grad[steps.pin] = 0.0
    return grad, directions(x.Q, x.S, grad, res, error=error, target=target, **kwargs)


def _predicted_fall(grad, step, alpha):
    """The quadratic model's fall of the energy along ``alpha`` times the Newton ``step`` from where the
    gradient is ``grad``: ``-g.s alpha (1 - alpha / 2)`` (CG's iterates satisfy ``s.H s = -g.s``)."""
    return -float(np.einsum("ij,ij->", grad, step)) * alpha * (1.0 - 0.5 * alpha)


def _line_search(steps, x, step, activation, alphas, contact):
    """The first of the trial lengths whose iterate lowers the energy: ``(alpha, iterate, trials)``,
    ``(None, None, trials)`` where none does.

    Without contact the lengths are ``alphas``; with it :data:`CONTACT_ALPHAS` of the
    collision-free fraction of ``step``. A full step may raise the energy by its round-off
    (:data:`ENERGY_ROUNDOFF`): near the solution every step changes it by less than that.
    """
    if contact is None:
        trials = alphas
    else:
        amax = contact.max_step(x.V, x.V + step, x.state)
        trials = tuple(amax * a for a in CONTACT_ALPHAS) if amax > 0 else ()
    for alpha in trials:
        trial = _iterate(steps, x.V + alpha * step, activation, contact)
        if trial.E < x.E or (alpha == 1.0 and trial.E <= x.E * (1.0 + ENERGY_ROUNDOFF)):
            return alpha, trial, trials
    return None, None, trials


def _plain_fallback(steps, x, plain, Vp, activation, contact):
    """The iterate after the plain step, where no Newton step lowered the energy; None where none does.

    Without contact the plain step itself; with contact the move with the contact forces held,
    cut by collision detection and shortened by :data:`CONTACT_ALPHAS` until the energy falls.
    """
    if contact is None:
        V = plain.G if plain.G is not None else steps.assemble(x.Q, Vp, activation, guess=x.V).V
        return _iterate(steps, V, activation, None)
    amax = contact.max_step(x.V, x.V + plain.move, x.state)
    for alpha in tuple(amax * a for a in CONTACT_ALPHAS) if amax > 0 else ():
        trial = _iterate(steps, x.V + alpha * plain.move, activation, contact)
        if trial.E < x.E:
            return trial
    return None


def _solve_free(steps, F):
    """``L_ff^{-1} F`` on the free vertices (zero at the pinned one), ``(n, 3)``."""
    out = np.zeros_like(F)
    out[steps.free] = steps.solve_free(F[steps.free])
    return out


def _damped_step(steps, x, plain, Vp, activation, contact, grad, direction, mu, alphas, estimate, res,
                 vanishing_damping, timed, it):
    """One iteration of :func:`solve_newton` from its Newton system: the damped step that lowers the energy.

    Returns the new iterate, the next damping and the step's fields of its :class:`NewtonStep`. The
    step at damping ``mu`` is tried at the lengths ``alphas`` (:func:`_line_search`); the first
    that lowers the energy is taken and the damping follows (:func:`_next_damping`); when none does,
    ``mu`` grows eightfold and the step is recomputed, 20 times at most, and then the plain step
    is taken where it lowers the energy (``kind`` "plain", else "none"). ``estimate`` is told the
    step's length.
    """
    scale = steps.design.h
    before = x
    cg_here = 0
    for tries in range(1, 21):
        step, k = timed(direction, mu)
        cg_here += k
        taken, trial, trials = None, None, ()
        if step is not None and np.any(step):
            taken, trial, trials = _line_search(steps, x, step, activation, alphas, contact)
        if taken is not None:
            x = trial
            moved = float(np.abs(deformation(taken * step, x.V)).max() / scale)
            estimate.step(moved, full=taken == 1.0)
            # a step cut short by collision detection, not by the energy, keeps the damping
            full = taken == 1.0 or (contact is not None and taken == trials[0])
            predicted, fell = _predicted_fall(grad, step, taken), before.E - x.E
            agreement = fell / predicted if predicted > 0.0 else None
            log.debug("newton %d: step %.3e h (alpha %g), model agreement %.3f", it, moved, taken,
                      np.nan if agreement is None else agreement)
            fast = (vanishing_damping and taken == 1.0 and contact is None and predicted > 0.0
                    and fell >= MODEL_AGREEMENT * predicted)
            return x, _next_damping(mu, full, fast, res, vanishing_damping, contact=contact is not None), dict(
                kind="newton", length_h=moved, alpha=taken, damping=mu, model_agreement=agreement, tries=tries,
                cg_iterations=cg_here)
        mu *= 8.0
    # no descent even with heavy damping: take the plain step
    after = _plain_fallback(steps, x, plain, Vp, activation, contact)
    fields = dict(kind="none", length_h=0.0, alpha=None, damping=None, model_agreement=None, tries=tries,
                  cg_iterations=cg_here)
    if after is None:
        return x, mu, fields
    estimate.plain(res)
    fields.update(kind="plain", length_h=float(np.abs(deformation(after.V - x.V, after.V)).max() / scale))
    return after, mu, fields


def solve_newton(steps, V0, activation, tol, max_iter, directions, alphas=(1.0,), contact=None, on_drift="warn",
                 monitor=None, vanishing_damping=False, extrapolate=None):
    """Damped Newton on the rotation-reduced energy; the outer loop of both Newton methods.

    Parameters
    ----------
    steps : LocalGlobal
    V0 : (n, 3) float array [mm]
        Start; its pinned vertex stays where it is. With ``contact`` it must be free of
        self-intersection (:meth:`gdfe.solver.contact.Contact.is_clear`).
    activation : float
    tol : float
        Tolerance (units of h), see below.
    max_iter : int
        Limit on the assembly steps.
    directions : callable
        ``directions(Q, S, grad, res, extra=None, error=inf, target=0)`` returns a function of
        the damping ``mu`` giving ``(step, cg_iterations)``: the Newton step as an ``(n, 3)``
        array (None when it cannot be computed) and the CG iterations it took; ``extra`` is
        a positive semi-definite 3n x 3n matrix added to the Hessian (the contact barrier's),
        ``error`` the estimated distance to the solution and ``target`` the distance the
        stopping test asks for (units of h); one with the attribute ``wants_shape`` True is
        also given the iterate ``V`` ``(n, 3)`` [mm], and one with ``recycles`` True is given
        ``recycle_here``, False in a contact solve (:attr:`ReducedHessian.recycle`).
    alphas : tuple of float
        Step lengths tried, in order; the first that lowers the energy is taken and
        ``mu`` shrinks (a full step) or doubles (a shortened one); when none does, ``mu``
        grows eightfold and the step is recomputed.
    contact : gdfe.solver.contact.Contact, optional
        Self-contact: the barrier is added to the energy, its gradient to the gradient and
        its Hessian to the Newton system; every step is first cut to the collision-free
        fraction of it (:meth:`~gdfe.solver.contact.Contact.max_step`), then shortened by
        :data:`CONTACT_ALPHAS` until the energy with the barrier falls. The barrier's
        Hessian is projected pair by pair onto the positive semi-definite cone while the
        residual is above :data:`CONTACT_EXACT_RES`, and enters as it is below.
    on_drift : {"warn", "stop"}
        What to do when the solve drifts (see below): log a warning and go on, or stop
        there (the solve is then not converged).
    monitor : callable, optional
        Without contact: called with the iteration number and each accepted iterate
        ``(n, 3)`` [mm]; an exception it raises ends the solve (``contact="auto"`` stops a
        contact-free solve there once it passes through itself, see :func:`gdfe.simulate`).
    vanishing_damping : bool
        The damping's floor falls with the residual, ``min(MU_MIN, MU_RESIDUAL * res)``
        (:data:`MU_RESIDUAL_CONTACT` with ``contact``)
        (Levenberg-Marquardt with a damping proportional to the residual: superlinear near
        the solution), instead of staying at :data:`MU_MIN`, and without contact falls to that
        floor at once after a step the quadratic model predicted well (:data:`MODEL_AGREEMENT`). The
        distance estimate is then the last step's length, never extrapolated by the
        contraction (see Notes): with steps near Newton's, the contraction of two steps
        says little of the next, and the extrapolated estimate fell 18x short of the
        distance in the stopping study (``gdfe study stopping``).
    extrapolate : bool, optional
        Whether the distance estimate may be extrapolated by the contraction of the last two
        full steps (Notes); default: not with ``vanishing_damping``. ``method="newton-cg"``
        with Eisenstat-Walker forcing does not either (2.8x short in the stopping study).

    Returns
    -------
    SolveStats
        Without contact, ``points`` is the plain step from the last iterate; with
        contact, the last iterate itself (the plain step ignores the barrier and could
        cross a face), and the residual is the plain step's with the contact forces held.

    Notes
    -----
    Stopping: the plain step's residual must be below ``tol`` (the paper's test) and the
    estimated distance to the solution below ``STEP_TOL_FACTOR * tol`` (both in units of
    h). The plain step underestimates that distance by the ratio of stretching to bending
    stiffness; the Newton step does not. The estimate is the last step's length ``|s_k|``,
    or ``|s_k| theta / (1 - theta)`` when that is smaller (the bound of a sequence contracting
    by ``theta``), with ``theta`` the larger of the last two contractions ``|s_k| / |s_k-1|``
    of full steps: one small step after a large one (a buckled sheet settling) is not yet a
    contraction (the 10^6-cell corrugation had stopped on a 0.45 um step, estimated 2 nm, where
    the tolerance asked 0.14 um), and with CG's forcing loosened near the end
    (:data:`CG_TARGET_MARGIN`) the last contraction alone fell short of the distance by 9x on
    the stopping study's dome (``gdfe study stopping``).
    Steps are measured without their rigid part (:func:`deformation`): a turn of the whole
    part by round-off is not a distance from the solution. A solve converges when both
    tests hold, also at its last iteration.

    Drift: a design with several equilibria close in energy (a buckled sheet) can take
    many iterations moving between them. When over :data:`DRIFT_WINDOW` iterations the
    energy falls by less than :data:`DRIFT_ENERGY` of itself while the estimated distance
    shrinks by less than :data:`DRIFT_SHRINK`, the solve says so once (a warning, and
    ``SolveStats.drift``: where it began, the energy change, how far the shape moved) and
    goes on or stops, as ``on_drift`` says.
    With contact, the plain step's move is ``L^{-1} (b - L V - g_B / 2)``: the assembly
    step with the barrier's force ``g_B`` held at its value at ``V``.
    """
    Vp = np.array(V0, float)[steps.pin].copy()
    scale = steps.design.h
    target = STEP_TOL_FACTOR * tol
    extrapolate = not vanishing_damping if extrapolate is None else bool(extrapolate)
    x = _iterate(steps, np.array(V0, float), activation, contact)
    if contact is not None and not np.isfinite(x.state.energy):
        raise GdfeError("V0: the start crosses or touches itself; the contact solve needs a start free "
                        "of self-intersection")
    E0 = x.E
    mu = 1e-3
    it = 0
    estimate = _DistanceEstimate(extrapolate)
    watch = _DriftWatch(x.E, x.V, on_drift, target, scale)
    record = []  # a NewtonStep per iteration that tried a step: the energies and CG iterations are theirs

    def ends(res, slack=1.0):  # the stopping test (Notes) at ``slack`` times the tolerance, or the last iteration
        return (res <= slack * tol and estimate.error <= target) or it >= max_iter or watch.stop

    def timed(f, *args, **kwargs):
        t0 = time.perf_counter()
        out = f(*args, **kwargs)
        steps.timings["newton"] = steps.timings.get("newton", 0.0) + time.perf_counter() - t0
        return out

    # with a multigrid, the plain step's exact solve is made only where the test could pass
    lazy = contact is None and steps.uses_multigrid
    while True:
        grad = direction = None  # the last step's linearisation, Jacobian and coarse factor: not held beside the next's
        it += 1
        t_it = time.perf_counter()
        plain = _plain_step(steps, x, Vp, activation, contact, lazy, ends)
        res = plain.res
        if ends(res):
            break
        grad, direction = timed(_newton_direction, steps, directions, x, plain, res, contact, estimate.error, target)
        x, mu, fields = _damped_step(steps, x, plain, Vp, activation, contact, grad, direction, mu, alphas, estimate,
                                     res, vanishing_damping, timed, it)
        record.append(NewtonStep(iteration=it, residual_h=res, energy=float(x.E), estimate_h=float(estimate.error),
                                 seconds=time.perf_counter() - t_it, **fields))
        if record[-1].kind == "none":  # with contact, no step lowers the energy: stopped, not converged
            log.warning("newton with contact: no step lowers the energy at residual %.3e", res)
            break
        log.debug("newton %d: residual %.3e, error estimate %.3e, energy %.6e, mu %.1e",
                  it, res, estimate.error, x.E, mu,
                  extra={"progress": {"event": "newton", "iteration": it, "residual_h": res,
                                      "estimate_h": estimate.error}})
        if steps.n > RELEASE_POINTS:
            _memory.release()
        if monitor is not None and contact is None:
            monitor(it, x.V)
        watch.update(it, x.E, estimate.error, x.V)
    drift = watch.report(it)
    error = estimate.error
    stalled = bool(record) and record[-1].kind == "none"
    energies = [E0] + [r.energy for r in record]
    cg = sum(r.cg_iterations for r in record)
    done = res <= tol and error <= target and not (stalled or watch.stop)
    if contact is None:
        return SolveStats(points=plain.G, converged=done, iterations=it, residual=res,
                          energies=energies + [steps.orient(plain.G, activation).energy], cg_iterations=cg,
                          error_estimate=error, drift=drift, newton_steps=record)
    return SolveStats(points=x.V, converged=done, iterations=it, residual=res,
                      energies=energies + [x.E], cg_iterations=cg, contact_pairs=x.state.active,
                      contact_energy=x.state.energy, error_estimate=error, drift=drift, newton_steps=record)
