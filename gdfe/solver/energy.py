"""The GDFE energy (paper Eq. 5) and its two local-global steps.

With ``D`` the 8x8 mean-centring matrix of Eq. 4 (:data:`D8`), the energy is

    E(V, {Q_i}) = sum_i  w_i || D V_i - Q_i P_i ||^2 ,

where ``V_i`` are the eight current vertices of cell ``i``, ``P_i`` its contracted rest
shape (centred, :func:`rest_shapes`), ``Q_i`` a rotation and ``w_i`` the cell volume.
For fixed ``V`` the best ``Q_i`` is the rotation closest to ``S_i = (D V_i)^T P_i``
(:func:`rotations`, the **orientation step**); for fixed ``Q`` the best ``V`` solves
``A^T A V = A^T p`` (:func:`system_matrix`, the **assembly step**), an ``n x n`` sparse
system shared by x, y and z and factorised once per design.

This module holds those pieces and :class:`LocalGlobal`, the two steps for one design,
with the data they hand on: :class:`RestState` (the constants of one activation),
:class:`Orientation`, :class:`Assembly`, and :class:`SolveStats`, what a solve returns.
"""

from __future__ import annotations

import dataclasses
import functools
import time

import numpy as np
import scipy.sparse as sp

from gdfe._validation import check_instance
from gdfe.design import Design, Material
from gdfe.solver.linalg import factorise
from gdfe.solver.multigrid import MULTIGRID_CELLS, Multigrid, lattice
from gdfe.solver.threads import in_order, ranges

__all__ = ["D8", "rest_shapes", "system_matrix", "rotations", "expmap", "energy", "RestState",
           "Orientation", "Assembly", "SolveStats", "LocalGlobal"]

#: The mean-centring matrix D of Eq. 4.
D8 = np.eye(8) - 1.0 / 8.0


def rest_shapes(design, activation=1.0):
    """Contracted rest shape of every cell, mean-centred.

    Parameters
    ----------
    design : Design
    activation : float
        Fraction of the contraction applied: the free face shrinks by ``1 - a (1 - R)``.

    Returns
    -------
    (m, 8, 3) float array [mm]
    """
    mesh = design.mesh
    X = mesh.points[mesh.cells]  # (m, 8, 3)
    t = X[..., 2] / design.h  # height in the film, 0 (bottom) .. 1 (top)
    top, bottom = design.face_contraction()
    # linear through the film, from the bottom face's contraction to the top face's
    shrink = activation * (top[:, None] * t + bottom[:, None] * (1.0 - t))
    sx = 1.0 - shrink
    sy = 1.0 - design.isotropy * shrink
    c = X.mean(axis=1, keepdims=True)
    P = X - c
    P[..., 0] *= sx
    P[..., 1] *= sy
    return P - P.mean(axis=1, keepdims=True)


def system_matrix(design):
    """The assembled ``A^T A = sum_i w_i S_i^T D S_i`` (n x n CSR, symmetric, rows sum to 0) [mm^3].

    With ``D = I - 1/8``, it is ``diag(C w) - C diag(w) C^T / 8`` for the vertex-cell incidence
    ``C`` (n x m, eight ones a column): no 64 entries per cell are listed on the way.
    """
    cells = design.mesh.cells
    w = design.mesh.cell_volumes()
    n, m = design.mesh.n_points, cells.shape[0]
    C = sp.csr_matrix((np.ones(8 * m), cells.ravel().astype(np.int32), np.arange(0, 8 * m + 1, 8, dtype=np.int32)),
                      shape=(m, n)).T.tocsr()  # (n, m)
    CW = C @ sp.diags(w)
    return (sp.diags(np.asarray(CW.sum(axis=1)).ravel()) - (CW @ C.T) / 8.0).tocsr()


def _det3(A):
    return (A[:, 0, 0] * (A[:, 1, 1] * A[:, 2, 2] - A[:, 1, 2] * A[:, 2, 1])
            - A[:, 0, 1] * (A[:, 1, 0] * A[:, 2, 2] - A[:, 1, 2] * A[:, 2, 0])
            + A[:, 0, 2] * (A[:, 1, 0] * A[:, 2, 1] - A[:, 1, 1] * A[:, 2, 0]))


def _centred(V, cells):
    """Every cell's vertices ``V[cells]`` less their mean, ``(m, 8, 3)``."""
    X = np.take(V, cells, axis=0)  # np.take: 3.6x faster than fancy indexing here
    X -= X.mean(axis=1, keepdims=True)
    return X


def _misfits(V, cells, P, s, e, X, S, Q):
    """The orientation step on cells ``s:e``, into ``X`` (the misfits ``x_k - Q p_k``), ``S`` and ``Q``."""
    X[s:e] = _centred(V, cells[s:e])
    np.matmul(X[s:e].transpose(0, 2, 1), P[s:e], out=S[s:e])  # 3.8x faster than the same einsum
    Q[s:e] = rotations(S[s:e])[0]
    X[s:e] -= np.matmul(P[s:e], Q[s:e].transpose(0, 2, 1))


def rotations(S, tol=1e-12, max_iter=30):
    """Closest rotations to a batch of 3x3 matrices (the polar factor, made proper).

    Matrices with a positive determinant go through the scaled Newton iteration for the
    polar factor (quadratic convergence, all elements at once, each stopping when its
    own update is below ``tol``); the few with ``det(S) <= 0`` (a cell turned inside out)
    go through an SVD whose smallest singular direction is flipped, which gives the
    closest proper rotation.

    Parameters
    ----------
    S : (m, 3, 3) float array

    Returns
    -------
    Q : (m, 3, 3) float array
        The rotations.
    trace : (m,) float array
        ``tr(Q^T S)``, the sum of the signed singular values.
    """
    Q = np.empty_like(S)
    scale = np.sqrt(np.einsum("mij,mij->m", S, S))
    scale = np.where(scale > 0, scale, 1.0)
    A = S / scale[:, None, None]
    det = _det3(A)
    good = det > 1e-10
    idx = np.nonzero(good)[0]
    # the nine entries as rows of a (9, k) array: the iteration runs on contiguous vectors
    X = np.ascontiguousarray(A[idx].reshape(-1, 9).T)
    out = np.empty_like(X)
    active = np.arange(idx.size)
    C = np.empty_like(X)
    for _ in range(max_iter):
        if not active.size:
            break
        a, b, c, d, e, f, g, h, i = X
        C[0], C[1], C[2] = e * i - f * h, f * g - d * i, d * h - e * g
        C[3], C[4], C[5] = c * h - b * i, a * i - c * g, b * g - a * h
        C[6], C[7], C[8] = b * f - c * e, c * d - a * f, a * e - b * d
        dt = a * C[0] + b * C[1] + c * C[2]
        gm = 1.0 / np.cbrt(np.abs(dt))
        Xn = 0.5 * (gm * X + C / (gm * dt))
        done = np.abs(Xn - X).max(axis=0) < tol
        if done.all():
            out[:, active] = Xn
            active = active[:0]
            break
        if done.any():
            out[:, active[done]] = Xn[:, done]
            keep = ~done
            active, X = active[keep], Xn[:, keep]
            C = np.empty_like(X)
        else:
            X = Xn
    if active.size:  # not converged within max_iter: keep the last iterate
        out[:, active] = X
    Q[idx] = out.T.reshape(-1, 3, 3)
    bad = np.nonzero(~good)[0]
    if bad.size:
        U, _, Vt = np.linalg.svd(S[bad])
        dd = np.linalg.det(U) * np.linalg.det(Vt)
        U[:, :, 2] *= dd[:, None]
        Q[bad] = U @ Vt
    return Q, np.einsum("mij,mij->m", Q, S)


def expmap(omega):
    """Rotation matrices ``exp([omega]x)``, ``(m, 3, 3)``, of rotation vectors ``omega`` ``(m, 3)`` [rad]."""
    th = np.linalg.norm(omega, axis=1)
    k = omega / np.where(th > 0, th, 1.0)[:, None]
    Kx = np.zeros((omega.shape[0], 3, 3))
    Kx[:, 0, 1], Kx[:, 0, 2] = -k[:, 2], k[:, 1]
    Kx[:, 1, 0], Kx[:, 1, 2] = k[:, 2], -k[:, 0]
    Kx[:, 2, 0], Kx[:, 2, 1] = -k[:, 1], k[:, 0]
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3) + s * Kx + (1 - c) * (Kx @ Kx)


def energy(points, design, activation=1.0):
    """Energy of Eq. 5 at ``points`` ``(n, 3)`` [mm] with the optimal rotations [mm^5]."""
    return LocalGlobal(design).energy(points, activation)


@dataclasses.dataclass(frozen=True, eq=False)
class RestState:
    """The constants of one activation: the rest shapes, and (made on first use) the Hessian's.

    Attributes
    ----------
    activation : float
    P : (m, 8, 3) float array [mm]
        The rest shapes, :func:`rest_shapes`.
    Psq : (m,) float array [mm^2]
        ``|P_i|^2``, the sum of squares of each rest shape.
    """

    activation: float
    P: np.ndarray
    Psq: np.ndarray

    @classmethod
    def of(cls, design, activation):
        P = rest_shapes(design, activation)
        return cls(float(activation), P, np.einsum("mkj,mkj->m", P, P))

    @functools.cached_property
    def M0(self):
        """``M0 = tr(C) I - C`` per cell, ``(m, 3, 3)`` [mm^2], ``C = P^T P``."""
        C = np.einsum("mki,mkj->mij", self.P, self.P)
        return np.trace(C, axis1=1, axis2=2)[:, None, None] * np.eye(3) - C

    @functools.cached_property
    def M0is(self):
        """``M0^{-1/2}`` per cell, ``(m, 3, 3)``, with ``M0 = tr(C) I - C`` and ``C = P^T P``."""
        lam0, W0 = np.linalg.eigh(self.M0)
        return np.einsum("mij,mj,mkj->mik", W0, 1.0 / np.sqrt(np.maximum(lam0, 1e-300)), W0)


@dataclasses.dataclass(frozen=True, eq=False)
class Orientation:
    """Outcome of the orientation step at vertices ``V``.

    Attributes
    ----------
    Q : (m, 3, 3) float array
        The optimal rotation of every cell.
    S : (m, 3, 3) float array [mm^2]
        The cross-covariances ``S_i = (D V_i)^T P_i`` they were taken from.
    energy : float
        Energy of Eq. 5 at ``V`` with these rotations [mm^5].
    """

    Q: np.ndarray
    S: np.ndarray
    energy: float


@dataclasses.dataclass(frozen=True, eq=False)
class Assembly:
    """Outcome of the assembly step for rotations ``Q``.

    Attributes
    ----------
    V : (n, 3) float array [mm]
        The vertices minimising Eq. 5 for ``Q``, one vertex held.
    b : (n, 3) float array [mm^4]
        The right-hand side ``A^T p`` it solved with (before the held vertex is removed);
        the energy's gradient at any ``V`` for these rotations is ``2 (L V - b)``.
    """

    V: np.ndarray
    b: np.ndarray


@dataclasses.dataclass(frozen=True, eq=False)
class SolveStats:
    """Outcome of one solve (:meth:`gdfe.solver.Solver.solve`).

    Attributes
    ----------
    points : (n, 3) float array [mm]
        The final shape (the plain step's result from the last iterate).
    converged : bool
        Whether the tolerance was met within ``max_iter`` iterations.
    iterations : int
        Assembly steps (sparse solves).
    residual : float
        The plain step's largest vertex move at the end, in units of h.
    energies : list of float
        Energy [mm^5] of each accepted iterate, then of ``points``.
    cg_iterations : int
        Conjugate-gradient iterations of ``method="newton-cg"`` (0 for the others).
    contact_pairs : int
        Surface pairs within the contact gap at ``points`` (0 without contact).
    contact_energy : float
        The contact barrier's part of the last energy [mm^5] (0 without contact).
    error_estimate : float
        The Newton methods' estimated distance to the solution at the end, rigid motions
        left out, in units of h (inf before the first step; None for the alternation).
    drift : dict or None
        Where a Newton solve drifted between near-equal states (:func:`gdfe.solver.newton.solve_newton`):
        ``since_iteration``, ``detected_at``, ``iterations`` spent from then on,
        ``energy_change`` (relative), ``moved_mm``, ``estimate_mm``; None when it did not.
    newton_steps : list of gdfe.solver.newton.NewtonStep
        The Newton methods' record of every step taken (empty for the alternation).
    """

    points: np.ndarray
    converged: bool
    iterations: int
    residual: float
    energies: list
    cg_iterations: int = 0
    contact_pairs: int = 0
    contact_energy: float = 0.0
    error_estimate: float | None = None
    drift: dict | None = None
    newton_steps: list = dataclasses.field(default_factory=list)


class LocalGlobal:
    """The two steps of the local-global solver for one design, with its factorised system.

    Parameters
    ----------
    design : Design

    Attributes
    ----------
    design : Design
    cells : (m, 8) int array
    w : (m,) float array [mm^3]
        Cell volumes.
    n : int
        Number of vertices.
    L : (n, n) sparse matrix
        :func:`system_matrix`; where the design has a multigrid, made from ``L_ff`` and ``L_fp``
        when asked, not kept (the solves use :meth:`apply_L`, which needs no copy of it).
    pin : int
        The vertex held in place (a vertex of the first rigid cell, else of cell 0): it
        fixes the translations, the null space of ``L``, without changing the shape.
    free : (n - 1,) int array
        The other vertices.
    L_ff, L_fp : sparse matrices
        ``L`` restricted to the free rows, and the free and pinned columns.
    factor
        ``L_ff`` factorised (:func:`gdfe.solver.factorise`): ``factor.solve(b)``; made on
        first use.
    multigrid : gdfe.solver.multigrid.Multigrid
        A V-cycle hierarchy for ``L_ff``; made on first use.
    uses_multigrid : bool
        Whether the assembly step solves with :attr:`multigrid` (designs above
        :data:`gdfe.solver.multigrid.MULTIGRID_CELLS` cells) instead of :attr:`factor`.
    B : (n, 8m) sparse matrix
        The scatter ``b = B @ T.reshape(8m, 3)``, ``B[v, 8i + k] = w_i`` where ``cells[i, k] == v``.
    timings : dict
        Seconds spent so far in the factorisation (or the multigrid set-up, ``"multigrid"``)
        and in the orientation and assembly steps (the solve methods add theirs).
    """

    def __init__(self, design):
        check_instance("design", design, Design)
        self.design = design
        mesh = design.mesh
        self.cells = mesh.cells
        self.w = mesh.cell_volumes()
        self.n = mesh.n_points
        m = mesh.n_cells
        t0 = time.perf_counter()
        L = system_matrix(design).tocsr()  # CSR: its products with (n, 3) arrays are 1.4x faster than CSC
        rigid = np.nonzero(design.material == Material.RIGID)[0]
        self.pin = int(self.cells[rigid[0] if rigid.size else 0, 0])
        self.free = np.delete(np.arange(self.n), self.pin)
        rows = L[self.free]
        self.L_ff = rows[:, self.free].tocsr()  # symmetric: its CSR arrays are also its CSC arrays
        self.L_fp = rows[:, [self.pin]].tocsr()
        self._L_pp = float(L[self.pin, self.pin])
        del rows
        self.B = sp.csr_matrix((np.repeat(self.w, 8), (self.cells.ravel(), np.arange(8 * m))),
                               shape=(self.n, 8 * m))
        self.uses_multigrid = m > MULTIGRID_CELLS
        # with a multigrid L itself is not kept beside L_ff (0.4 GiB at 10^6 cells): see apply_L
        self._L = None if self.uses_multigrid else L
        del L
        self.timings = {"setup": time.perf_counter() - t0, "orientation": 0.0, "assembly": 0.0}
        if not self.uses_multigrid:
            self.factor  # noqa: B018  (factorised now: every assembly step uses it)
        self._rest_cache = None

    #: The array module of the orientation step's polar decompositions (:mod:`gdfe.solver.device`):
    #: NumPy (the polar iteration, :func:`rotations`) unless a solver on the GPU sets CuPy.
    xp = np

    @property
    def L(self):
        """``L`` (n x n, CSR); with a multigrid made from its blocks when asked (not kept)."""
        if self._L is not None:
            return self._L
        n, free, pin = self.n, self.free, self.pin
        ff, fp = self.L_ff.tocoo(), self.L_fp.tocoo()
        rows = np.concatenate([free[ff.row], free[fp.row], np.full(fp.nnz, pin), [pin]])
        cols = np.concatenate([free[ff.col], np.full(fp.nnz, pin), free[fp.row], [pin]])
        vals = np.concatenate([ff.data, fp.data, fp.data, [self._L_pp]])
        return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))

    @functools.cached_property
    def L_free(self):
        """``L`` with the pinned vertex's row and column zero (n x n, CSR): ``L_ff`` on the full index range.

        Its values are ``L_ff``'s own array (where the design keeps no ``L``); only its column
        indices are new (4 bytes per entry). It multiplies ``(n, r)`` arrays as they are, with
        no gather of the free rows before and no scatter after: 11 ms against 18 ms for
        :meth:`apply_L` on the 10^5-cell Figure 8 plate, three columns.
        """
        pin, A = self.pin, self.L_ff
        indices = A.indices + (A.indices >= pin).astype(A.indices.dtype)
        indptr = np.insert(A.indptr, pin, A.indptr[pin])
        return sp.csr_matrix((A.data, indices, indptr), shape=(self.n, self.n))

    def apply_L_free(self, V):
        """``L_free @ V`` for ``V`` ``(n, r)``: ``L V`` on the free rows where ``V`` is zero at the pinned vertex
        (its value there is not read), and zero at the pinned vertex."""
        return self.L_free @ V

    def apply_L(self, V):
        """``L @ V`` for ``V`` ``(n, r)`` (with a multigrid from the blocks of ``L``)."""
        if self._L is not None:
            return self._L @ V
        out = self.L_free @ V
        rows, values = self._pinned_column
        vp = V[self.pin]
        out[rows] += values[:, None] * vp
        out[self.pin] = values @ V[rows] + self._L_pp * vp  # L is symmetric: its pinned row is L_fp^T
        return out

    @functools.cached_property
    def _pinned_column(self):
        """The vertices (full numbering) and values of the pinned column's entries off the diagonal."""
        fp = self.L_fp.tocoo()
        return self.free[fp.row], fp.data

    @functools.cached_property
    def factor(self):
        """``L_ff`` factorised (:func:`gdfe.solver.factorise`), made on first use."""
        t0 = time.perf_counter()
        f = factorise(self.L_ff)
        self.timings["factorise"] = self.timings.get("factorise", 0.0) + time.perf_counter() - t0
        return f

    @functools.cached_property
    def multigrid(self) -> Multigrid:
        """The V-cycle hierarchy of ``L_ff`` (:class:`gdfe.solver.multigrid.Multigrid`), made on first use."""
        t0 = time.perf_counter()
        mg = Multigrid(self.L_ff, lattice(self.design.mesh)[self.free])
        self.timings["multigrid"] = self.timings.get("multigrid", 0.0) + time.perf_counter() - t0
        return mg

    def solve_free(self, rhs, guess=None):
        """``L_ff^{-1} rhs`` for ``rhs`` ``(n - 1, r)``: by :attr:`factor`, or by :attr:`multigrid` to round-off
        (from ``guess``, like ``rhs``, where given; the factor needs none)."""
        if self.uses_multigrid:
            return self.multigrid.solve(rhs, x0=guess)
        return self.factor.solve(np.asfortranarray(rhs))

    def approx_solve_free(self, rhs):
        """An approximation of ``L_ff^{-1} rhs`` (symmetric positive definite in ``rhs``): one V-cycle
        in single precision, or the factor's exact solve where the design has no multigrid."""
        if self.uses_multigrid:
            return self.multigrid.vcycle(rhs, single=True)
        return self.factor.solve(np.asfortranarray(rhs))

    def approx_solve_pinned(self, r, scale=1.0):
        """:meth:`approx_solve_free` of ``r`` ``(n, 3)`` on the free vertices over ``scale``, zero at the pinned
        vertex, ``(n, 3)``: ``z[free] = approx_solve_free(r[free]) / scale``, the same numbers.

        The free vertices are all but the pinned one, in order, so they are taken and put back by two
        slices each, not by an index array; with a multigrid they are taken straight into its single
        precision and put back into double. Each array as large as the mesh's vertices is fresh
        memory at every use (at 10^6 cells 48 MiB, its pages faulted in), and this runs at every
        CG iteration of ``method="newton-cg"``.
        """
        p = self.pin
        if not self.uses_multigrid:
            z = np.zeros_like(r)
            z[self.free] = self.approx_solve_free(r[self.free]) / scale
            return z
        b = np.empty((r.shape[0] - 1,) + r.shape[1:], np.float32)
        b[:p], b[p:] = r[:p], r[p + 1:]
        x = self.multigrid.vcycle_single(b)
        z = np.empty(r.shape)
        z[:p], z[p], z[p + 1:] = x[:p], 0.0, x[p:]
        z /= scale
        return z

    def rest(self, activation=1.0) -> RestState:
        """The :class:`RestState` of ``activation`` (the last one is kept for the next call)."""
        cached = self._rest_cache
        if cached is None or cached.activation != float(activation):
            cached = self._rest_cache = RestState.of(self.design, activation)
        return cached

    def orient(self, V, activation=1.0) -> Orientation:
        """Orientation step: the optimal rotations at ``V`` ``(n, 3)`` [mm] and the energy there."""
        t0 = time.perf_counter()
        P = self.rest(activation).P
        if self.xp is np:  # cell by cell: ranges of cells on the solver's threads (gdfe.solver.threads)
            m = self.cells.shape[0]
            X, S, Q = np.empty((m,) + P.shape[1:]), np.empty((m, 3, 3)), np.empty((m, 3, 3))
            in_order(lambda part: _misfits(V, self.cells, P, *part, X, S, Q), ranges(m))
        else:  # one batched SVD on the GPU (gdfe.solver.device.polar)
            from gdfe.solver.device import polar, to_host

            X = _centred(V, self.cells)
            S = np.matmul(X.transpose(0, 2, 1), P)
            Q = to_host(polar(S, self.xp))
            X -= np.matmul(P, Q.transpose(0, 2, 1))
        # sum of squares of the misfit itself, not |X|^2 + |P|^2 - 2 tr(Q^T S), which
        # cancels to round-off when a cell reaches its rest shape; over all cells at once
        E = float(np.einsum("m,mki,mki->", self.w, X, X))  # no BLAS dot: see gdfe.solver.device.dot
        self.timings["orientation"] += time.perf_counter() - t0
        return Orientation(Q, S, max(E, 0.0))

    def assemble(self, Q, V_pin, activation=1.0, solve=True, guess=None) -> Assembly:
        """Assembly step: the vertices minimising Eq. 5 for rotations ``Q`` ``(m, 3, 3)``.

        The vertex :attr:`pin` is held at ``V_pin`` ``(3,)`` [mm]. With ``solve=False``
        only the right-hand side is made (``Assembly.V`` is None): the gradient needs no solve.
        ``guess`` ``(n, 3)`` [mm], a shape near the answer, starts the multigrid's solve (:meth:`solve_free`).
        """
        t0 = time.perf_counter()
        P = self.rest(activation).P
        T = np.matmul(P, Q.transpose(0, 2, 1)).reshape(-1, 3)
        b = self.B @ T
        if not solve:
            self.timings["assembly"] += time.perf_counter() - t0
            return Assembly(None, b)
        rhs = b[self.free] - self.L_fp @ V_pin[None, :]
        V = np.empty((self.n, 3))
        V[self.free] = self.solve_free(rhs, None if guess is None else guess[self.free])
        V[self.pin] = V_pin
        self.timings["assembly"] += time.perf_counter() - t0
        return Assembly(V, b)

    def energy(self, V, activation=1.0):
        """Energy of Eq. 5 at ``V`` ``(n, 3)`` [mm] with the optimal rotations [mm^5]."""
        return self.orient(np.asarray(V, float), activation).energy
