"""The linearised start: the small-rotation solution of Eq. 5, which already bends the right way.

Minimises ``sum_i w_i || D V_i - (I + [omega_i]x) P_i ||^2`` jointly over the vertices
and one infinitesimal rotation ``omega_i`` per cell (the quadratic model of the energy),
then applies the finite rotations ``exp([omega_i]x)`` in one assembly step. By default
(:data:`DIRECT_START_CELLS`) the rotations are eliminated and the vertices solved for by
preconditioned CG (:func:`linearised_start_cg`); :func:`linearised_start_direct`
factorises the joint system instead.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp

from gdfe.solver.energy import D8, expmap
from gdfe.solver.linalg import factorise
from gdfe.solver.newton import deformation, pcg

__all__ = ["DIRECT_START_CELLS", "linearised_start", "linearised_start_direct", "linearised_start_cg"]

log = logging.getLogger(__name__)

#: Largest design (cells) whose linearised start is one sparse factorisation of the joint
#: system; larger ones eliminate the rotations and use preconditioned CG. 0: CG for every
#: design - on the Figure 6 hinges it is as fast and its start takes fewer Newton iterations
#: (6 / 7 / 11 against 7 / 10 / 13 for L = 1 / 1.6 / 2.6 mm, same angles to 1e-6 rad).
DIRECT_START_CELLS = 0


def linearised_start(steps, hessian, V, activation=1.0):
    """Shape from the small-rotation solution of Eq. 5 around ``V``.

    Parameters
    ----------
    steps : LocalGlobal
    hessian : ReducedHessian
        Its CG preconditioner serves designs above :data:`DIRECT_START_CELLS` cells.
    V : (n, 3) float array [mm]
        Cells are compared in the frame of ``V``, so ``V`` must be the flat print or a
        shape whose cells are unrotated.
    activation : float

    Returns
    -------
    (n, 3) float array [mm]
    """
    if steps.cells.shape[0] > DIRECT_START_CELLS:
        return linearised_start_cg(steps, hessian, V, activation)
    return linearised_start_direct(steps, V, activation)


def linearised_start_direct(steps, V, activation=1.0):
    """:func:`linearised_start` by one factorisation of the joint system.

    The rotation of the pinned vertex's cell is held with that vertex.
    """
    P = steps.rest(activation).P
    m = steps.cells.shape[0]
    n = steps.n
    sw = np.sqrt(steps.w)
    # residual rows (i, k, c): sum_l D_kl V[cell_il, c] + (p_ik x omega_i)_c - p_ikc
    # -[omega]x p = p x omega:  row c: eps_{c a b} p_a omega_b
    r_idx = np.arange(24 * m).reshape(m, 8, 3)
    Dr = np.broadcast_to(r_idx[:, :, None, :], (m, 8, 8, 3))
    Dc = 3 * steps.cells[:, None, :, None] + np.arange(3)[None, None, None, :]
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
    pin_cell = int(np.nonzero((steps.cells == steps.pin).any(axis=1))[0][0])
    fixed = np.r_[3 * steps.pin + np.arange(3), 3 * n + 3 * pin_cell + np.arange(3)]
    keep = np.setdiff1d(np.arange(3 * (n + m)), fixed)
    x0 = np.zeros(3 * (n + m))
    x0[:3 * n] = V.ravel()
    Jk = J[:, keep].tocsc()
    A = (Jk.T @ Jk).tocsc()
    y = factorise(A).solve(Jk.T @ (rhs - J[:, fixed] @ x0[fixed]))
    x = x0.copy()
    x[keep] = y
    omega = x[3 * n:].reshape(m, 3)
    return steps.assemble(expmap(omega), V[steps.pin], activation).V


def linearised_start_cg(steps, hessian, V, activation=1.0, rtol=1e-6, max_iter=500):
    """:func:`linearised_start` with the rotations eliminated, solved by PCG.

    Minimising over ``omega_i`` leaves the quadratic ``sum_i w_i |D V_i - P_i|^2 -
    |J_i V|^2`` in the vertices, whose Hessian is :class:`ReducedHessian`'s at ``Q = I``
    with ``M = M0`` (so nothing is clamped); then ``omega_i = M0^{-1} sum_k p_k x x_k``.
    The rigid rotations, a null direction of that quadratic, are taken out of the step
    (:func:`gdfe.solver.newton.deformation`), the pinned vertex held.
    """
    t0 = time.perf_counter()
    rest = steps.rest(activation)
    P = rest.P
    V = np.asarray(V, float)
    m = steps.cells.shape[0]
    eye = np.broadcast_to(np.eye(3), (m, 3, 3))
    C = np.einsum("mki,mkj->mij", P, P)
    lin = hessian.linearise(eye, C, rest, floor=1.0)
    ops = hessian.operator(lin, rest, 0.0)
    if ops is None:  # the coarse matrix is singular (rest shapes shrunk to almost nothing)
        log.info("linearised start: the coarse matrix is singular; solving the joint system directly")
        steps.timings["newton"] = steps.timings.get("newton", 0.0) + time.perf_counter() - t0
        return linearised_start_direct(steps, V, activation)
    apply_H = ops.apply_H
    b = steps.B @ P.reshape(-1, 3)
    # 2 (L V - b) - 2 J^T J V, zero at the pinned vertex; the products take vectors zero there, and
    # a translation is in the null space of both L and J
    grad = apply_H(V - V[steps.pin]) - 2.0 * b
    grad[steps.pin] = 0.0
    if np.abs(grad).max() <= 1e-12 * max(np.abs(b).max(), 1e-300):  # V already minimises the model (R = 1)
        step, k = np.zeros_like(V), 0
    else:
        step, k = pcg(apply_H, ops.apply_P, -grad, rtol, max_iter, start=ops.start, flexible=ops.flexible)
    log.debug("linearised start: %d CG iterations", k)
    # the rigid rotations are a null direction of this quadratic: CG leaves round-off along
    # them, which would turn the whole shape; keep the step's deformation, the pin held
    step = deformation(step, V)
    step -= step[steps.pin]
    X = (V + step)[steps.cells]
    X -= X.mean(axis=1, keepdims=True)
    rhs = np.cross(P, X).sum(axis=1)  # sum_k p_k x x_k
    M0is = rest.M0is
    omega = np.einsum("mij,mjk,mk->mi", M0is, M0is, rhs)
    steps.timings["newton"] = steps.timings.get("newton", 0.0) + time.perf_counter() - t0
    return steps.assemble(expmap(omega), V[steps.pin], activation).V
