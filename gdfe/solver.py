"""The GDFE local-global solver (paper Sec. 3.1).

The energy of Eq. 5 is, with ``D`` the 8x8 mean-centring matrix of Eq. 4,

    E(V, {Q_i}) = sum_i  w_i || D V_i - Q_i P_i ||^2 ,

where ``V_i`` are the eight current vertices of cell ``i``, ``P_i`` its contracted rest
shape (centred) and ``Q_i`` a rotation, ``w_i`` the cell volume. The solver alternates

* the **orientation step**: for fixed ``V``, every ``Q_i`` is the rotation closest to the
  cross-covariance ``S_i = (D V_i)^T P_i`` (one batched SVD; a reflection is turned into
  the nearest rotation by flipping the smallest singular direction), and
* the **assembly step**: for fixed ``Q``, ``V`` solves ``A^T A V = A^T p``, an ``n x n``
  sparse system shared by x, y and z, factorised once. Translations are its null space;
  one vertex is held where it is, which fixes them without changing the shape.

Each step lowers E, so plain alternation converges, but slowly for bending. The default
solver accelerates the same fixed-point map with Anderson mixing, accepting a mixed
iterate only when its energy is below that of the current iterate (otherwise it takes
the plain step), and starts from the small-rotation (linearised) solution of the same
energy, which already bends the right way. The converged shape is a fixed point of the
paper's alternation either way.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from gdfe._validate import check_int, check_positive
from gdfe.design import Design, Material

__all__ = ["Result", "ConvergenceError", "simulate", "rest_shapes", "system_matrix", "energy",
           "face_contraction", "Solver", "METHODS", "auto_method", "factor_backend"]

log = logging.getLogger(__name__)

#: Smallest damping of ``method="newton-cg"`` (times 2 L): it also keeps the rigid rotation
#: about the pinned vertex, a null direction of the energy, out of the steps.
MU_MIN = 1e-6
#: A Newton solve also needs its estimated distance to the solution below
#: ``STEP_TOL_FACTOR * tol`` (units of h); see :meth:`Solver._solve_newton`.
STEP_TOL_FACTOR = 10.0
#: Relative rise of the energy a full Newton step may cause and still be taken (round-off).
ENERGY_ROUNDOFF = 1e-13

#: The mean-centring matrix D of Eq. 4.
D8 = np.eye(8) - 1.0 / 8.0


class ConvergenceError(RuntimeError):
    """Raised by :meth:`Result.check` when the solver did not converge."""


@dataclasses.dataclass
class Result:
    """Outcome of :func:`simulate`.

    Attributes
    ----------
    design : Design
        The simulated design.
    points : (n, 3) float array [mm]
        Vertex positions of the final (fully contracted) shape.
    converged : bool
        Whether every frame met the tolerance within ``max_iter`` iterations.
    iterations : int
        Assembly steps (sparse solves) over all frames.
    residual : float
        Final fixed-point residual: the largest vertex move one more plain iteration
        would make, divided by the film thickness.
    energy : float
        Final energy (Eq. 5) [mm^5].
    energy_history : (k,) float array
        Energy of each accepted iterate, all frames in sequence.
    seconds : float
        Wall-clock time of the solve, factorisation included.
    frames : list of (n, 3) float arrays
        Shape at each activation level (first the flat print), for a time series.
    activation : (f,) float array
        Activation of each frame, 0 (as printed) to 1 (fully contracted).
    frame_iterations : list of int
        Iterations per frame.
    method : str
        The method that ran: ``"newton"``, ``"newton-cg"``, ``"anderson"`` or ``"plain"``.
    timings : dict
        Seconds spent in factorisation, orientation steps and assembly steps.
    """

    design: Design
    points: np.ndarray
    converged: bool
    iterations: int
    residual: float
    energy: float
    energy_history: np.ndarray
    seconds: float
    frames: list
    activation: np.ndarray
    frame_iterations: list
    method: str
    timings: dict

    def check(self):
        """Raise :class:`ConvergenceError` unless the solve converged; return self."""
        if not self.converged:
            raise ConvergenceError(
                f"GDFE solve did not converge: residual {self.residual:.3g} after "
                f"{self.iterations} iterations ({self.method})")
        return self

    def summary(self) -> dict:
        return {"converged": bool(self.converged), "iterations": int(self.iterations),
                "residual": float(self.residual), "energy": float(self.energy),
                "seconds": float(self.seconds), "n_elements": int(self.design.n_cells),
                "n_points": int(self.design.mesh.n_points), "method": self.method,
                "frames": len(self.frames)}


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
    top, bottom = face_contraction(design)
    # linear through the film, from the bottom face's contraction to the top face's
    shrink = activation * (top[:, None] * t + bottom[:, None] * (1.0 - t))
    sx = 1.0 - shrink
    sy = 1.0 - design.isotropy * shrink
    c = X.mean(axis=1, keepdims=True)
    P = X - c
    P[..., 0] *= sx
    P[..., 1] *= sy
    return P - P.mean(axis=1, keepdims=True)


def face_contraction(design):
    """Contraction ``1 - R`` of the top and of the bottom face of every cell (0 where coated).

    Returns
    -------
    top, bottom : (m,) float arrays
    """
    mat = design.material
    s = 1.0 - design.R
    top = np.where((mat == Material.CONTRACT_TOP) | (mat == Material.FREE_SHRINK), s, 0.0)
    bottom = np.where((mat == Material.CONTRACT_BOTTOM) | (mat == Material.FREE_SHRINK), s, 0.0)
    return top, bottom


def system_matrix(design):
    """The assembled ``A^T A = sum_i w_i S_i^T D S_i`` (n x n, symmetric, rows sum to 0)."""
    cells = design.mesh.cells
    w = design.mesh.cell_volumes()
    rows = np.repeat(cells, 8, axis=1).ravel()
    cols = np.tile(cells, (1, 8)).ravel()
    data = (w[:, None, None] * D8[None]).ravel()
    n = design.mesh.n_points
    return sp.csr_matrix((data, (rows, cols)), shape=(n, n))


def _det3(A):
    return (A[:, 0, 0] * (A[:, 1, 1] * A[:, 2, 2] - A[:, 1, 2] * A[:, 2, 1])
            - A[:, 0, 1] * (A[:, 1, 0] * A[:, 2, 2] - A[:, 1, 2] * A[:, 2, 0])
            + A[:, 0, 2] * (A[:, 1, 0] * A[:, 2, 1] - A[:, 1, 1] * A[:, 2, 0]))


def _cof3(A):
    """Cofactor matrices of a batch of 3x3 matrices (``det(A) * inv(A).T``)."""
    C = np.empty_like(A)
    C[:, 0] = np.cross(A[:, 1], A[:, 2])
    C[:, 1] = np.cross(A[:, 2], A[:, 0])
    C[:, 2] = np.cross(A[:, 0], A[:, 1])
    return C


def _rotations(S, tol=1e-12, max_iter=30):
    """Closest rotations to a batch of 3x3 matrices ``S`` (m, 3, 3).

    Returns the rotations and ``tr(Q^T S)``, the sum of the signed singular values.
    Matrices with a positive determinant go through the scaled Newton iteration for the
    polar factor (quadratic convergence, all elements at once, each stopping when its
    own update is below ``tol``); the few with ``det(S) <= 0`` (a cell turned inside out)
    go through an SVD whose smallest singular direction is flipped, which gives the
    closest proper rotation.
    """
    m = S.shape[0]
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


def energy(points, design, activation=1.0):
    """Energy of Eq. 5 at ``points`` with the optimal rotations [mm^5]."""
    return Solver(design).energy(points, activation)


class Solver:
    """A GDFE solver for one design: the factorised system, reused for every solve.

    Parameters
    ----------
    design : Design
    """

    #: Spacing of the coarse grid of ``method="newton-cg"``, in film thicknesses.
    coarse_spacing = 1.5
    #: How ``method="newton-cg"`` combines the n x n and coarse corrections.
    two_level = "multiplicative"

    def __init__(self, design):
        if not isinstance(design, Design):
            raise TypeError(f"design: expected a gdfe.Design, got {type(design).__name__}")
        self.design = design
        mesh = design.mesh
        self.cells = mesh.cells
        self.w = mesh.cell_volumes()
        self.n = mesh.n_points
        m = mesh.n_cells
        t0 = time.perf_counter()
        self.L = system_matrix(design).tocsc()
        # hold one vertex of the first rigid cell (else of cell 0) in place
        rigid = np.nonzero(design.material == Material.RIGID)[0]
        self.pin = int(self.cells[rigid[0] if rigid.size else 0, 0])
        self.free = np.setdiff1d(np.arange(self.n), [self.pin])
        self.L_ff = self.L[self.free][:, self.free].tocsc()
        self.L_fp = self.L[self.free][:, [self.pin]]
        self._lu = _factorise(self.L_ff)
        # scatter: b = B @ T.reshape(8m, 3) with B[v, 8i + k] = w_i when cells[i, k] == v
        self.B = sp.csr_matrix((np.repeat(self.w, 8), (self.cells.ravel(), np.arange(8 * m))),
                               shape=(self.n, 8 * m))
        self.timings = {"factorise": time.perf_counter() - t0, "orientation": 0.0, "assembly": 0.0}
        self._P = {}
        self._Psq = {}

    # -- the two steps -------------------------------------------------------------------
    def _rest(self, activation):
        key = float(activation)
        if key not in self._P:
            self._P = {key: rest_shapes(self.design, activation)}
            self._Psq = {key: np.einsum("mkj,mkj->m", self._P[key], self._P[key])}
        return self._P[key], self._Psq[key]

    def orient(self, V, activation=1.0):
        """Orientation step: optimal rotations ``(m, 3, 3)`` and the energy at ``V``."""
        t0 = time.perf_counter()
        P, Psq = self._rest(activation)
        X = V[self.cells]
        X -= X.mean(axis=1, keepdims=True)
        S = np.einsum("mki,mkj->mij", X, P)
        Q, _ = _rotations(S)
        # sum of squares of the misfit itself, not |X|^2 + |P|^2 - 2 tr(Q^T S), which
        # cancels to round-off when a cell reaches its rest shape
        X -= np.matmul(P, Q.transpose(0, 2, 1))
        E = float(self.w @ np.einsum("mki,mki->m", X, X))
        self._last_S = S
        self.timings["orientation"] += time.perf_counter() - t0
        return Q, max(E, 0.0)

    def assemble(self, Q, V_pin, activation=1.0):
        """Assembly step: the vertices minimising Eq. 5 for rotations ``Q``, one vertex held at ``V_pin``."""
        t0 = time.perf_counter()
        P, _ = self._rest(activation)
        T = np.einsum("mij,mkj->mki", Q, P).reshape(-1, 3)
        b = self.B @ T
        self._b = b
        rhs = b[self.free] - self.L_fp @ V_pin[None, :]
        V = np.empty((self.n, 3))
        V[self.free] = self._lu.solve(np.asfortranarray(rhs))
        V[self.pin] = V_pin
        self.timings["assembly"] += time.perf_counter() - t0
        return V

    def energy(self, V, activation=1.0):
        return self.orient(np.asarray(V, float), activation)[1]

    def _solve_newton(self, V0, activation, tol, max_iter, directions, alphas=(1.0,)):
        """Damped Newton on the rotation-reduced energy; the outer loop of both Newton methods.

        ``directions(Q, S, grad, res)`` returns a function of the damping ``mu`` giving the
        Newton step as an ``(n, 3)`` array (None when it cannot be computed). A step is
        tried at the lengths ``alphas``; the first that lowers the energy is taken and
        ``mu`` shrinks (a full step) or doubles (a shortened one); when none does, ``mu``
        grows eightfold and the step is recomputed.

        Stopping: the plain step's residual must be below ``tol`` (the paper's test) and
        the estimated distance to the solution below ``STEP_TOL_FACTOR * tol`` (both in
        units of h). The plain step underestimates that distance by the ratio of
        stretching to bending stiffness; the Newton step does not. The estimate is the
        last step's length ``|s_k|``, or ``|s_k| theta / (1 - theta)`` with the contraction
        ``theta = |s_k| / |s_k-1|`` of two full steps when that is smaller (the bound of
        a sequence contracting by ``theta``).
        """
        V = np.array(V0, float)
        Vp = V[self.pin].copy()
        scale = self.design.h
        Q, E = self.orient(V, activation)
        S = self._last_S
        energies = [E]
        mu = 1e-3
        it = 0
        error = prev = np.inf  # estimated distance to the solution; last full step, in units of h
        while True:
            G = self.assemble(Q, Vp, activation)  # the plain step from V
            it += 1
            res = float(np.abs(G - V).max() / scale)
            if (res <= tol and error <= STEP_TOL_FACTOR * tol) or it >= max_iter:
                break
            t0 = time.perf_counter()
            grad = 2.0 * (self.L @ V - self._b)  # set by assemble
            grad[self.pin] = 0.0
            direction = directions(Q, S, grad, res)
            self.timings["newton"] = self.timings.get("newton", 0.0) + time.perf_counter() - t0
            for _ in range(20):
                t0 = time.perf_counter()
                step = direction(mu)
                self.timings["newton"] += time.perf_counter() - t0
                taken = None
                if step is not None and np.any(step):
                    for alpha in alphas:
                        Vt = V + alpha * step
                        Qt, Et = self.orient(Vt, activation)
                        # a full step may raise the energy by its round-off: near the
                        # solution every step changes it by less than that
                        if Et < E or (alpha == 1.0 and Et <= E * (1.0 + ENERGY_ROUNDOFF)):
                            V, Q, E, S, taken = Vt, Qt, Et, self._last_S, alpha
                            break
                if taken is not None:
                    moved = float(np.abs(taken * step).max() / scale)
                    error = moved
                    if taken == 1.0:
                        theta = moved / prev  # 0 after a first full step: no estimate yet
                        if 0.0 < theta < 1.0:
                            error = min(moved, moved * theta / (1.0 - theta))
                        prev = moved
                    else:
                        prev = np.inf
                    mu = max(mu / 4.0, MU_MIN) if taken == 1.0 else 2.0 * mu
                    break
                mu *= 8.0
            else:  # no descent even with heavy damping: take the plain step
                V = G
                Q, E = self.orient(V, activation)
                S = self._last_S
                error, prev = res, np.inf
            log.debug("newton %d: residual %.3e, error estimate %.3e, energy %.6e, mu %.1e",
                      it, res, error, E, mu)
            energies.append(E)
        return G, res <= tol, it, res, energies + [self.orient(G, activation)[1]]

    def _factorised_directions(self, activation):
        """Newton steps of ``method="newton"``: the 3n x 3n Hessian factorised, per ``mu``."""
        fdof = (3 * self.free[:, None] + np.arange(3)).ravel()
        n = self.n

        def directions(Q, S, grad, res):
            def step(mu):
                H = self.hessian(Q, S, activation, mu=mu)[fdof][:, fdof]
                out = np.zeros(3 * n)
                try:
                    out[fdof] = _factorise(H).solve(-grad.ravel()[fdof])
                except RuntimeError:  # numerically singular: damp more
                    return None
                return out.reshape(n, 3)
            return step
        return directions

    def hessian(self, Q, S, activation=1.0, mu=0.0):
        """Positive semi-definite Hessian of the rotation-reduced energy, plus ``mu`` times ``2 L``.

        With every rotation optimal, the energy of a cell is
        ``w (|X|^2 + |P|^2 - 2 tr(Q^T S))`` and its gradient ``2 w (x_k - Q p_k)``. The
        rotation moves with the vertices by ``Q^T dQ = [omega]x``,
        ``omega = M^{-1} sum_l p_l x Q^T dx_l`` with ``M = tr(Y) I - Y`` and ``Y = Q^T S``
        (the derivative of the polar factor). Hence the cell Hessian in its 24 vertex
        coordinates is ``2 w (D (x) I3 - G^T M^{-1} G)`` with ``G_k = [p_k]x Q^T``. Since
        ``G G^T = M0 = tr(C) I - C``, ``C = P^T P``, it is positive semi-definite exactly
        when the eigenvalues of ``M0^{-1/2} M M0^{-1/2}`` are >= 1; they are clamped to
        that, per cell, which keeps every Newton step a descent direction.

        Returns
        -------
        (3n, 3n) sparse matrix
            Unknowns ordered vertex-major (``3 v + c``).
        """
        RG = self._hessian_blocks(Q, S, activation, floor=1.0)
        if getattr(self, "_L3", None) is None:
            self._L3 = sp.kron(self.L, sp.eye(3), format="csr")
        J, _ = self._jacobian(RG)
        return (2.0 * (1.0 + mu)) * self._L3 - 2.0 * (J.T @ J)

    def _hessian_setup(self, activation):
        """Per-cell constants of :meth:`hessian` that depend on the rest shapes only."""
        if getattr(self, "_hess_key", None) == float(activation):
            return
        P, _ = self._rest(activation)
        C = np.einsum("mki,mkj->mij", P, P)
        M0 = np.trace(C, axis1=1, axis2=2)[:, None, None] * np.eye(3) - C
        lam0, W0 = np.linalg.eigh(M0)
        self._M0is = np.einsum("mij,mj,mkj->mik", W0, 1.0 / np.sqrt(np.maximum(lam0, 1e-300)), W0)
        Kx = np.zeros(P.shape + (3,))  # [p]x
        Kx[..., 0, 1], Kx[..., 0, 2] = -P[..., 2], P[..., 1]
        Kx[..., 1, 0], Kx[..., 1, 2] = P[..., 2], -P[..., 0]
        Kx[..., 2, 0], Kx[..., 2, 1] = -P[..., 1], P[..., 0]
        self._Kx = Kx
        self._hess_key = float(activation)

    def _jacobian(self, RG):
        """``J`` (3m x 3n, rows ``3 i + a``) and ``J^T``, both CSR, from the blocks ``RG``."""
        if getattr(self, "_J_pattern", None) is None:
            # the sparsity of J and of its transpose depends on the mesh only: each step
            # fills values (the data of J0 and Jt0 are 1 + the flat index into the blocks)
            m = self.cells.shape[0]
            rows = np.broadcast_to((3 * np.arange(m))[:, None, None, None] + np.arange(3)[None, None, :, None],
                                   (m, 8, 3, 3))
            cols = np.broadcast_to(3 * self.cells[:, :, None, None] + np.arange(3)[None, None, None, :],
                                   (m, 8, 3, 3))
            shape = (3 * m, 3 * self.n)
            order = np.lexsort((cols.ravel(), rows.ravel()))
            J0 = sp.csr_matrix((order + 1.0, cols.ravel()[order], np.arange(0, 72 * m + 1, 24)), shape=shape)
            Jt0 = J0.T.tocsr()
            self._J_pattern = (order, J0.indices, J0.indptr, shape)
            self._Jt_pattern = (Jt0.data.astype(np.int64) - 1, Jt0.indices, Jt0.indptr, shape[::-1])
        values = RG.ravel()
        order, indices, indptr, shape = self._J_pattern
        J = sp.csr_matrix((values[order], indices, indptr), shape=shape)
        order, indices, indptr, shape = self._Jt_pattern
        return J, sp.csr_matrix((values[order], indices, indptr), shape=shape)

    def _hessian_blocks(self, Q, S, activation=1.0, floor=1.0):
        """``root^T G_k`` of every cell, ``(m, 8, 3, 3)``: the Hessian is ``2 (L (x) I3 - J^T J)``.

        ``floor`` is the lower clamp of the eigenvalues of ``M0^{-1/2} M M0^{-1/2}``:
        1 makes every cell's Hessian positive semi-definite (:meth:`hessian`); below 1 a
        cell may contribute negative curvature, which the sum over cells usually absorbs.
        """
        self._hessian_setup(activation)
        Y = np.einsum("mji,mjk->mik", Q, S)
        Y = 0.5 * (Y + Y.transpose(0, 2, 1))
        M = np.trace(Y, axis1=1, axis2=2)[:, None, None] * np.eye(3) - Y
        B = self._M0is @ M @ self._M0is
        lam, W = np.linalg.eigh(B)
        lam = np.maximum(lam, floor)
        # (w N)^(1/2) with N = M0^{-1/2} W diag(1/lam) W^T M0^{-1/2}
        root = np.einsum("mij,mjk,mk->mik", self._M0is, W, np.sqrt(self.w[:, None] / lam))
        G = np.matmul(self._Kx, Q.transpose(0, 2, 1)[:, None])  # G_k = [p_k]x Q^T, (m, 8, 3, 3)
        return np.matmul(root.transpose(0, 2, 1)[:, None], G)  # root^T G_k

    # -- Newton with conjugate gradients, for large designs ---------------------------------
    def _coarse_space(self):
        """Bilinear interpolation ``Z`` (n, k) from a coarse grid, per layer of vertices.

        The coarse grid spacing is about 1.5 film thicknesses (at least two cells), so that
        the coarse space carries the bending at lengths above the thickness, which the
        n x n system alone resolves badly. The pinned vertex's row is zero.
        """
        if getattr(self, "_Z", None) is not None:
            return self._Z
        mesh = self.design.mesh
        X = mesh.points
        dx, dy, dz = mesh.spacing
        c = max(2, int(np.ceil(self.coarse_spacing * self.design.h / min(dx, dy))))
        i = np.rint((X[:, 0] - X[:, 0].min()) / dx).astype(int)
        j = np.rint((X[:, 1] - X[:, 1].min()) / dy).astype(int)
        k = np.rint((X[:, 2] - X[:, 2].min()) / dz).astype(int)
        I0, ti = np.divmod(i, c)
        J0, tj = np.divmod(j, c)
        ti, tj = ti / c, tj / c
        nJ, nK = j.max() // c + 2, k.max() + 1
        rows = np.tile(np.arange(self.n), 4)
        cols = np.concatenate([((I0 + a) * nJ + (J0 + b)) * nK + k for a in (0, 1) for b in (0, 1)])
        vals = np.concatenate([wa * wb for wa in (1 - ti, ti) for wb in (1 - tj, tj)])
        vals[rows == self.pin] = 0.0
        Z = sp.csr_matrix((vals, (rows, cols)))
        Z.eliminate_zeros()
        used = np.unique(Z.indices)
        self._Z = Z[:, used].tocsr()
        Zf = self._Z[self.free]
        self._Lc3 = sp.kron(Zf.T @ self.L_ff @ Zf, sp.eye(3), format="csc")
        self._Z3 = sp.kron(self._Z, sp.eye(3), format="csr")
        return self._Z

    def _newton_operator(self, RG, mu):
        """Hessian product, preconditioner and its factorised coarse part for blocks ``RG``.

        The preconditioner combines the exact inverse of the (scaled) n x n system for
        the three coordinates with a Galerkin coarse correction ``Z (Z^T H Z)^{-1} Z^T``:
        symmetrically, coarse - fine - coarse (:attr:`two_level` ``"multiplicative"``,
        which halves the CG iterations on the mask sheets for one more Hessian product),
        or summed (``"additive"``).
        Returns ``(apply_H, apply_P)`` acting on ``(n, 3)`` arrays, or None when the
        coarse matrix is not positive definite.
        """
        Z = self._coarse_space()
        J, Jt = self._jacobian(RG)
        JZ = (J @ self._Z3).tocsc()
        Hc = (2.0 * (1.0 + max(mu, MU_MIN))) * self._Lc3 - 2.0 * (JZ.T @ JZ)
        try:
            fc = _factorise(Hc)
        except RuntimeError:  # SuperLU: exactly singular
            return None
        pin = self.pin
        scale = 2.0 * (1.0 + mu)

        def apply_H(v):
            out = scale * (self.L @ v) - 2.0 * (Jt @ (J @ v.ravel())).reshape(-1, 3)
            out[pin] = 0.0
            return out

        def coarse(r):
            return Z @ fc.solve((Z.T @ r).ravel()).reshape(-1, 3)

        def fine(r):
            z = np.zeros_like(r)
            z[self.free] = self._lu.solve(np.asfortranarray(r[self.free])) / scale
            return z

        def apply_P(r):
            if self.two_level == "additive":
                return fine(r) + coarse(r)
            z = coarse(r)  # symmetric multiplicative: coarse, fine, coarse
            z += fine(r - apply_H(z))
            return z + coarse(r - apply_H(z))

        return apply_H, apply_P

    @staticmethod
    def _pcg(apply_H, apply_P, rhs, rtol, max_iter):
        """Preconditioned CG from 0; stops at negative curvature. Returns ``(x, iterations)``."""
        x = np.zeros_like(rhs)
        r = rhs.copy()
        z = apply_P(r)
        rz = float(np.vdot(r, z))
        if not rz > 0:
            return x, 0
        stop = rtol * np.sqrt(rz)
        p = z
        for k in range(1, max_iter + 1):
            Hp = apply_H(p)
            pHp = float(np.vdot(p, Hp))
            if not pHp > 0:
                return x, k
            a = rz / pHp
            x += a * p
            r -= a * Hp
            z = apply_P(r)
            rz_new = float(np.vdot(r, z))
            if not rz_new > 0 or np.sqrt(rz_new) <= stop:
                return x, k
            p = z + (rz_new / rz) * p
            rz = rz_new
        return x, max_iter

    def _cg_directions(self, activation, floor=0.5, cg_rtol=None, cg_max=200):
        """Newton steps of ``method="newton-cg"``: preconditioned CG, no 3n x 3n factorisation.

        The Hessian is :meth:`hessian`'s with the per-cell clamp lowered to ``floor``
        (nearer the true Hessian, hence fewer Newton steps; CG stops at negative curvature
        and the energy test rejects a bad step). Each CG iteration costs one solve with
        the factorised n x n system for three right-hand sides, Hessian products and
        solves with the coarse matrix, which is factorised once per step. CG stops at a
        relative (preconditioned) residual ``cg_rtol``, by default the square root of the
        plain step's residual clipped to [1e-3, 0.1]: loose far from the solution, tight near it.
        """
        self.cg_iterations = 0

        def directions(Q, S, grad, res):
            RG = self._hessian_blocks(Q, S, activation, floor=floor)
            rtol = cg_rtol if cg_rtol is not None else min(0.1, max(1e-3, np.sqrt(res)))

            def step(mu):
                ops = self._newton_operator(RG, mu)
                if ops is None:
                    return None
                x, k = self._pcg(*ops, -grad, rtol, cg_max)
                self.cg_iterations += k
                log.debug("CG: %d iterations to %.1e", k, rtol)
                return x
            return step
        return directions

    # -- starting shapes -----------------------------------------------------------------
    def linearised_start(self, V, activation=1.0):
        """Shape from the small-rotation solution of Eq. 5 around ``V``.

        Minimises ``sum_i w_i || D V_i - (I + [omega_i]x) P_i ||^2`` jointly over the
        vertices and one infinitesimal rotation ``omega_i`` per cell (the quadratic model
        of the energy), then applies the finite rotations ``exp([omega_i]x)`` in one
        assembly step. Cells are compared in the frame of ``V``, so ``V`` must be the
        flat print or a shape whose cells are unrotated.

        Up to :data:`DIRECT_START_CELLS` cells the joint system is factorised with the
        rotation of the pinned vertex's cell held; larger designs eliminate the rotations
        cell by cell and solve for the vertices by preconditioned CG (see
        :meth:`_linearised_start_cg`), which fixes the rigid rotation about the pinned
        vertex only approximately.
        """
        if self.cells.shape[0] > DIRECT_START_CELLS:
            return self._linearised_start_cg(V, activation)
        P, _ = self._rest(activation)
        m = self.cells.shape[0]
        n = self.n
        sw = np.sqrt(self.w)
        # residual rows (i, k, c): sum_l D_kl V[cell_il, c] + (p_ik x omega_i)_c - p_ikc
        # -[omega]x p = p x omega:  row c: eps_{c a b} p_a omega_b
        r_idx = np.arange(24 * m).reshape(m, 8, 3)
        Dr = np.broadcast_to(r_idx[:, :, None, :], (m, 8, 8, 3))
        Dc = 3 * self.cells[:, None, :, None] + np.arange(3)[None, None, None, :]
        Dc = np.broadcast_to(Dc, (m, 8, 8, 3))
        Dd = np.broadcast_to((sw[:, None, None, None] * D8[None, :, :, None]), (m, 8, 8, 3))
        cross = np.zeros((m, 8, 3, 3))  # cross[i,k,c,b]: coefficient of omega_ib in row c
        px, py, pz = P[..., 0], P[..., 1], P[..., 2]
        cross[..., 0, 1], cross[..., 0, 2] = -pz, py
        cross[..., 1, 0], cross[..., 1, 2] = pz, -px
        cross[..., 2, 0], cross[..., 2, 1] = -py, px
        Wr = np.broadcast_to(r_idx[..., None], (m, 8, 3, 3))
        Wc = np.broadcast_to(3 * n + 3 * np.arange(m)[:, None, None, None] + np.arange(3), (m, 8, 3, 3))
        Wd = sw[:, None, None, None] * cross
        J = sp.csr_matrix(
            (np.concatenate([Dd.ravel(), Wd.ravel()]),
             (np.concatenate([Dr.ravel(), Wr.ravel()]), np.concatenate([Dc.ravel(), Wc.ravel()]))),
            shape=(24 * m, 3 * (n + m)))
        rhs = (sw[:, None, None] * P).ravel()
        # hold the pinned vertex (3 dofs) and the rotation of the cell it belongs to
        pin_cell = int(np.nonzero((self.cells == self.pin).any(axis=1))[0][0])
        fixed = np.r_[3 * self.pin + np.arange(3), 3 * n + 3 * pin_cell + np.arange(3)]
        keep = np.setdiff1d(np.arange(3 * (n + m)), fixed)
        x0 = np.zeros(3 * (n + m))
        x0[:3 * n] = V.ravel()
        Jk = J[:, keep].tocsc()
        A = (Jk.T @ Jk).tocsc()
        y = _factorise(A).solve(Jk.T @ (rhs - J[:, fixed] @ x0[fixed]))
        x = x0.copy()
        x[keep] = y
        omega = x[3 * n:].reshape(m, 3)
        Q = _expmap(omega)
        return self.assemble(Q, V[self.pin], activation)

    def _linearised_start_cg(self, V, activation=1.0, rtol=1e-6, max_iter=500):
        """:meth:`linearised_start` with the rotations eliminated, solved by PCG.

        Minimising over ``omega_i`` leaves the quadratic ``sum_i w_i |D V_i - P_i|^2 -
        |J_i V|^2`` in the vertices, whose Hessian is :meth:`hessian`'s at ``Q = I`` with
        ``M = M0`` (so nothing is clamped); then ``omega_i = M0^{-1} sum_k p_k x x_k``.
        """
        t0 = time.perf_counter()
        P, _ = self._rest(activation)
        V = np.asarray(V, float)
        m = self.cells.shape[0]
        eye = np.broadcast_to(np.eye(3), (m, 3, 3))
        C = np.einsum("mki,mkj->mij", P, P)
        RG = self._hessian_blocks(eye, C, activation, floor=1.0)
        apply_H, apply_P = self._newton_operator(RG, 0.0)
        b = self.B @ P.reshape(-1, 3)
        grad = apply_H(V) - 2.0 * b  # 2 (L V - b) - 2 J^T J V; zero at the pinned vertex
        grad[self.pin] = 0.0
        step, k = self._pcg(apply_H, apply_P, -grad, rtol, max_iter)
        self.cg_iterations = getattr(self, "cg_iterations", 0) + k
        X = (V + step)[self.cells]
        X -= X.mean(axis=1, keepdims=True)
        rhs = np.cross(P, X).sum(axis=1)  # sum_k p_k x x_k
        M0is = self._M0is
        omega = np.einsum("mij,mjk,mk->mi", M0is, M0is, rhs)
        self.timings["newton"] = self.timings.get("newton", 0.0) + time.perf_counter() - t0
        return self.assemble(_expmap(omega), V[self.pin], activation)

    # -- the solve ----------------------------------------------------------------------
    def solve(self, V0, activation=1.0, method="newton", tol=1e-7, max_iter=200, history=6):
        """Minimise Eq. 5 from ``V0``.

        Returns ``(V, converged, iterations, residual, energies)``.
        """
        if method == "newton":
            return self._solve_newton(V0, activation, tol, max_iter, self._factorised_directions(activation))
        if method == "newton-cg":
            return self._solve_newton(V0, activation, tol, max_iter, self._cg_directions(activation),
                                      alphas=(1.0, 0.5, 0.25))
        V = np.array(V0, float)
        Vp = V[self.pin].copy()
        scale = self.design.h
        Q, E = self.orient(V, activation)
        G = self.assemble(Q, Vp, activation)
        F = G - V
        energies = [E]
        dF, dG = [], []
        res = float(np.abs(F).max() / scale)
        it = 1
        while res > tol and it < max_iter:
            if method == "anderson" and dF:
                dFm = np.stack([d.ravel() for d in dF], axis=1)
                dGm = np.stack([d.ravel() for d in dG], axis=1)
                gamma, *_ = np.linalg.lstsq(dFm, F.ravel(), rcond=None)
                Vt = G - (dGm @ gamma).reshape(V.shape)
                Qt, Et = self.orient(Vt, activation)
                if Et <= E:
                    V, Q, E = Vt, Qt, Et
                else:
                    dF, dG = [], []
                    V = G
                    Q, E = self.orient(V, activation)
            else:
                V = G
                Q, E = self.orient(V, activation)
            energies.append(E)
            G_new = self.assemble(Q, Vp, activation)
            F_new = G_new - V
            it += 1
            if method == "anderson":
                dF.append(F_new - F)
                dG.append(G_new - G)
                if len(dF) > history:
                    dF.pop(0)
                    dG.pop(0)
            F, G = F_new, G_new
            res = float(np.abs(F).max() / scale)
        # report the plain step's result: it is at least as good as V
        V = G
        _, E = self.orient(V, activation)
        energies.append(E)
        return V, res <= tol, it, res, energies


#: Sparse factorisations of the symmetric positive definite systems, fastest first
#: (measured by ``gdfe bench``): CHOLMOD's supernodal Cholesky through scikit-sparse
#: (needs SuiteSparse from the system packages), then SciPy's SuperLU, which needs
#: nothing beyond SciPy. The environment variable ``GDFE_FACTOR`` (``cholmod`` or
#: ``superlu``) forces one.
FACTOR_BACKENDS = ("cholmod", "superlu")


def factor_backend():
    """Name of the sparse factorisation :func:`_factorise` uses here."""
    import os

    forced = os.environ.get("GDFE_FACTOR", "").strip().lower()
    if forced:
        if forced not in FACTOR_BACKENDS:
            raise ValueError(f"GDFE_FACTOR: expected one of {FACTOR_BACKENDS}, got {forced!r}")
        return forced
    try:
        import sksparse.cholmod  # noqa: F401
    except ImportError:
        return "superlu"
    return "cholmod"


class _Cholmod:
    """CHOLMOD's Cholesky factor with the ``solve`` of SciPy's SuperLU."""

    def __init__(self, A):
        import warnings

        from sksparse.cholmod import cholesky

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # CHOLMOD's note on converting the index type
            self._f = cholesky(sp.csc_matrix(A, dtype=float))

    def solve(self, b):
        return self._f(np.asarray(b, float))


def _factorise(A, backend=None):
    """Factorise a sparse symmetric positive definite matrix; the result has ``solve(b)``.

    ``backend`` (default :func:`factor_backend`): ``"cholmod"`` (supernodal Cholesky,
    falls back to SuperLU if CHOLMOD finds the matrix not positive definite) or
    ``"superlu"`` (sparse LU with a symmetric ordering and no pivoting).
    """
    backend = backend or factor_backend()
    if backend == "cholmod":
        from sksparse.cholmod import CholmodError

        try:
            return _Cholmod(A)
        except CholmodError as exc:
            log.info("CHOLMOD failed (%s); using SuperLU", exc)
    return spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def _expmap(omega):
    """Rotation matrices ``exp([omega]x)`` for a batch of rotation vectors ``(m, 3)``."""
    th = np.linalg.norm(omega, axis=1)
    k = omega / np.where(th > 0, th, 1.0)[:, None]
    Kx = np.zeros((omega.shape[0], 3, 3))
    Kx[:, 0, 1], Kx[:, 0, 2] = -k[:, 2], k[:, 1]
    Kx[:, 1, 0], Kx[:, 1, 2] = k[:, 2], -k[:, 0]
    Kx[:, 2, 0], Kx[:, 2, 1] = -k[:, 1], k[:, 0]
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3) + s * Kx + (1 - c) * (Kx @ Kx)


#: Methods of :func:`simulate`.
METHODS = ("newton", "newton-cg", "auto", "anderson", "plain")
#: Largest design (cells) for which ``method="auto"`` factorises the full Hessian. Above
#: it ``"newton-cg"`` is faster on every design ``gdfe bench`` times: the Figure 6 hinges
#: of 84-384 cells take 0.061-0.105 s against 0.087-0.277 s (docs/bench/bench.txt).
AUTO_NEWTON_CELLS = 64
#: Largest design (cells) whose linearised start is one sparse factorisation of the joint
#: system; larger ones eliminate the rotations and use preconditioned CG.
DIRECT_START_CELLS = 2000


#: ``init="auto"`` starts designs above this many cells from a coarsened copy.
MULTILEVEL_CELLS = 20_000
#: ``init="multilevel"`` coarsens until a level has at most this many cells.
MULTILEVEL_COARSEST = 2_000
#: Tolerance of the coarse levels of ``init="multilevel"`` (their shape is only a start).
MULTILEVEL_TOL = 1e-3
INITS = ("auto", "linear", "multilevel", "flat")
_INIT_NAMES = ", ".join(map(repr, INITS))


def _multilevel_start(design, activation):
    """Start for ``design``: the solved shape of its 2 x 2 coarsening, interpolated."""
    from .multilevel import coarsen

    coarse, prolong = coarsen(design)
    solver = Solver(coarse)
    if coarse.n_cells > MULTILEVEL_COARSEST:
        V = _multilevel_start(coarse, activation)
    else:
        V = solver.linearised_start(coarse.mesh.points.copy(), activation)
    V, _, it, res, _ = solver.solve(V, activation, method=auto_method(coarse), tol=MULTILEVEL_TOL,
                                    max_iter=50)
    log.debug("multilevel: %d cells, %d iterations, residual %.2e", coarse.n_cells, it, res)
    return prolong @ V


def auto_method(design):
    """The method ``"auto"`` picks for ``design``: ``"newton"`` or ``"newton-cg"``."""
    return "newton" if design.n_cells <= AUTO_NEWTON_CELLS else "newton-cg"


def simulate(design, *, method="auto", init="auto", steps=1, tol=1e-7, max_iter=None,
             history=6, seed=0):
    """Simulate the heat-activated shape change of a design.

    Parameters
    ----------
    design : Design
        The film, its material map and contraction ratios.
    method : {"auto", "newton", "newton-cg", "anderson", "plain"}
        ``"plain"`` is the paper's alternation; ``"anderson"`` accelerates it with an
        energy safeguard; ``"newton"`` takes damped Newton steps on the same energy
        (:meth:`Solver.hessian`), factorising the 3n x 3n Hessian each step;
        ``"newton-cg"`` solves the Newton steps by conjugate gradients preconditioned with
        the factorised n x n system and a coarse grid; ``"auto"`` (default) picks
        ``"newton"`` up to :data:`AUTO_NEWTON_CELLS` cells, else ``"newton-cg"``. All stop
        at a fixed point of the same map, and the residual is always that of the paper's
        plain step.
    init : {"auto", "linear", "multilevel", "flat"} or (n, 3) float array [mm]
        Starting shape of the first frame: the small-rotation solution (``"linear"``),
        the solution of the design coarsened 2 x 2 in the plane, interpolated
        (``"multilevel"``, recursively down to :data:`MULTILEVEL_COARSEST` cells, each
        coarse level solved to ``MULTILEVEL_TOL``; see :mod:`gdfe.multilevel`), the
        flat print with a seeded perturbation of 1e-4 h out of plane (the flat print itself
        is a fixed point of the alternation, so it must be perturbed to bend at all), or
        given vertex positions (e.g. a shape a designer expects, or an earlier result).
        ``"auto"`` (default) is ``"multilevel"`` above :data:`MULTILEVEL_CELLS` cells,
        else ``"linear"``.
    steps : int
        Number of frames the contraction is ramped over (activation k/steps for
        k = 1..steps), each started from the last: the time series of the fold.
    tol : float
        Convergence tolerance on the fixed-point residual (largest vertex move of one
        plain iteration, in units of the film thickness h). The Newton methods also need
        their estimated distance to the solution below ``STEP_TOL_FACTOR * tol``.
    max_iter : int, optional
        Iteration limit per frame; default 200 for the Newton methods, 5000 otherwise.
    history : int
        Anderson history length.
    seed : int
        Seed of the perturbation used by ``init="flat"``.

    Returns
    -------
    Result
        Check ``result.converged`` (or call ``result.check()``): a solve that hit
        ``max_iter`` is returned with ``converged=False`` and logged as a warning.
    """
    if method not in METHODS:
        names = ", ".join(map(repr, METHODS[:-1])) + f" or {METHODS[-1]!r}"
        raise ValueError(f"method: expected {names}, got {method!r}")
    if not isinstance(design, Design):
        raise TypeError(f"design: expected a gdfe.Design, got {type(design).__name__}")
    if method == "auto":
        method = auto_method(design)
    if isinstance(init, str):
        if init not in INITS:
            raise ValueError(f"init: expected {_INIT_NAMES} or an (n, 3) array, got {init!r}")
        if init == "auto":
            init = "multilevel" if design.n_cells > MULTILEVEL_CELLS else "linear"
    else:
        start = np.asarray(init, dtype=float)
        if start.shape != design.mesh.points.shape or not np.isfinite(start).all():
            raise ValueError(f"init: expected {_INIT_NAMES} or a finite array of shape "
                             f"{design.mesh.points.shape}, got shape {start.shape}")
        init = "given"
    steps = check_int("steps", steps)
    if max_iter is None:
        max_iter = 200 if method.startswith("newton") else 5000
    max_iter = check_int("max_iter", max_iter)
    history = check_int("history", history)
    tol = check_positive("tol", tol)
    t0 = time.perf_counter()
    solver = Solver(design)
    V = design.mesh.points.copy()
    frames = [V.copy()]
    acts = np.linspace(0.0, 1.0, steps + 1)
    converged, total, res, energies, per_frame = True, 0, 0.0, [], []
    for k, a in enumerate(acts[1:]):
        if k == 0:
            if init == "linear":
                V = solver.linearised_start(V, a)
            elif init == "multilevel":
                t_start = time.perf_counter()
                V = _multilevel_start(design, a)
                solver.timings["start"] = time.perf_counter() - t_start
            elif init == "given":
                V = start.copy()
            else:
                rng = np.random.default_rng(seed)
                V = V + np.column_stack([np.zeros((len(V), 2)), 1e-4 * design.h * rng.standard_normal(len(V))])
        V, ok, it, res, E = solver.solve(V, a, method=method, tol=tol, max_iter=max_iter, history=history)
        converged &= ok
        total += it
        per_frame.append(it)
        energies.extend(E)
        frames.append(V.copy())
        if not ok:
            log.warning("frame %d/%d (activation %.3g) did not converge: residual %.3g after %d iterations",
                        k + 1, steps, a, res, it)
    seconds = time.perf_counter() - t0
    log.info("GDFE %s: %d cells, %d iterations, residual %.2e, %.3f s", method, design.n_cells, total, res, seconds)
    return Result(design=design, points=V, converged=bool(converged), iterations=total, residual=res,
                  energy=energies[-1], energy_history=np.array(energies), seconds=seconds, frames=frames,
                  activation=acts, frame_iterations=per_frame, method=method, timings=dict(solver.timings))
