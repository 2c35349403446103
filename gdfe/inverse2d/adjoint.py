"""The fold of a design with per-face contractions, and its derivative by the adjoint method.

A design's equilibrium ``V*(c)`` minimises Eq. 5, ``E(V, c) = sum_i w_i min_Q |D V_i - Q P_i(c)|^2``,
where the rest shape ``P_i`` of cell ``i`` is linear in the contractions ``c_i = (c_top, c_bottom)``
of its two faces (:func:`gdfe.rest_shapes`). For an objective ``J(V)`` the derivative of
``J(V*(c))`` is

    dJ/dc = - lambda^T d g / d c,      H lambda = dJ/dV,

with ``g = dE/dV`` the energy's gradient and ``H`` its exact Hessian at ``V*``: one sparse
solve more than the fold itself. Both pieces are written here from the energy of one cell,
``E_i = w (|X|^2 + |P|^2 - 2 tr(Q^T S))`` with ``X = D V_i``, ``S = X^T P`` and ``Q`` the
rotation closest to ``S`` (its derivative: ``Q^T dQ = [omega]x`` with
``(tr(Y) I - Y) omega = vee(Q^T dS - dS^T Q)``, ``Y = Q^T S``):

- the Hessian blocks of cell ``i`` in its 24 vertex coordinates,
  ``H_kl = 2 w (D_kl I - G_k^T M^-1 G_l)``, ``G_k = [p_k]x Q^T``, ``M = tr(Y) I - Y``, are
  assembled without any clamp of their eigenvalues (the solver's Newton steps clamp them to
  stay descent directions; an adjoint needs the exact matrix);
- the mixed derivative is local to each cell: with ``mu_k = Q^T lambda_k``, ``y_k = Q^T x_k``,
  ``z = M^-1 sum_k mu_k x p_k``, the derivative of ``-lambda^T g`` by the rest shape's vertex
  ``p_k`` is ``2 w (mu_k - y_k x z)``, and ``dp_k / dc`` is that of :func:`gdfe.rest_shapes`.

The six rigid motions, a null space of ``H``, are removed by holding six coordinates (one
vertex, two coordinates of a second and one of a third, chosen well conditioned); the
objective must not change under rigid motions (a distance after rigid alignment does not),
so its gradient has no part along them and the held coordinates change nothing.

Lengths in mm, energies in mm^5.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np
import scipy.sparse as sp

from gdfe._validation import GdfeError, check_array, check_instance
from gdfe.design import Design
from gdfe.solver import D8, Solver, factorise
from gdfe.solver.simulation import default_tol

__all__ = ["Fold", "fold", "exact_hessian", "rigid_gauge", "contraction_gradient", "rest_derivative"]

log = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True, eq=False)
class Fold:
    """The equilibrium of one design and what its adjoint needs.

    Attributes
    ----------
    design : Design
    points : (n, 3) float array [mm]
        The folded shape.
    Q, S : (m, 3, 3) float arrays
        The rotations and cross-covariances of every cell at ``points``.
    P : (m, 8, 3) float array [mm]
        The rest shapes.
    energy : float [mm^5]
    converged : bool
    iterations : int
    residual : float
        The solver's plain-step residual (units of h).
    seconds : float
    """

    design: Design
    points: np.ndarray
    Q: np.ndarray
    S: np.ndarray
    P: np.ndarray
    energy: float
    converged: bool
    iterations: int
    residual: float
    seconds: float


def fold(design, start=None, tol=1e-9, max_iter=200, method="auto"):
    """The equilibrium of ``design`` (Eq. 5 minimised) from ``start``, with its rotations.

    Parameters
    ----------
    design : Design
    start : (n, 3) float array [mm], optional
        Starting shape (an earlier fold of a similar design); default the solver's
        linearised start from the flat print.
    tol : float or None
        Tolerance of :meth:`gdfe.solver.Solver.solve` (units of h). The adjoint gradient is as
        accurate as the equilibrium: keep it tight. None: :func:`gdfe.simulate`'s test (the
        estimated distance to the solution below 1e-6 of the part's size), for a fold whose
        shape is wanted, not a gradient; on a large part 1e-9 asks for a distance the energy's
        round-off cannot resolve (on a 24 mm strip, 1.2e-10 of its size), and the solve may
        wander to ``max_iter`` there.
    max_iter : int
    method : str
        Solver method (:data:`gdfe.solver.METHODS`).

    Returns
    -------
    Fold
    """
    check_instance("design", design, Design)
    t0 = time.perf_counter()
    solver = Solver(design)
    if start is None:
        start = solver.linearised_start(design.mesh.points.copy())
    else:
        start = check_array("start", start, shape=design.mesh.points.shape)
    if tol is None:
        tol = default_tol(design, method)
    stats = solver.solve(start, 1.0, method=method, tol=tol, max_iter=max_iter)
    o = solver.orient(stats.points)
    return Fold(design=design, points=stats.points, Q=o.Q, S=o.S, P=solver.rest(1.0).P, energy=o.energy,
                converged=bool(stats.converged), iterations=int(stats.iterations), residual=float(stats.residual),
                seconds=time.perf_counter() - t0)


def _cross_matrices(v):
    """``[v]x`` of a batch of vectors ``(..., 3)`` -> ``(..., 3, 3)``."""
    K = np.zeros(v.shape + (3,))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    return K


def _m_inverse(Q, S):
    """``M^-1`` per cell, ``M = tr(Y) I - Y`` with ``Y = sym(Q^T S)`` ``(m, 3, 3)``."""
    Y = np.einsum("mji,mjk->mik", Q, S)
    Y = 0.5 * (Y + Y.transpose(0, 2, 1))
    M = np.trace(Y, axis1=1, axis2=2)[:, None, None] * np.eye(3) - Y
    return np.linalg.inv(M)


def exact_hessian(f):
    """The exact Hessian of the rotation-reduced energy at a fold, ``(3n, 3n)`` sparse CSR [mm^3].

    Unknowns vertex-major (``3 v + c``). Symmetric; rigid motions are in its null space.

    Parameters
    ----------
    f : Fold
    """
    design = f.design
    cells = design.mesh.cells
    m = cells.shape[0]
    n = design.mesh.n_points
    w = design.mesh.cell_volumes()
    Minv = _m_inverse(f.Q, f.S)
    G = np.matmul(_cross_matrices(f.P), f.Q.transpose(0, 2, 1)[:, None])  # [p_k]x Q^T, (m, 8, 3, 3)
    T = np.matmul(Minv[:, None], G)  # M^-1 G_l
    K = -np.einsum("mkab,mlac->mkblc", G, T)  # -(G_k^T M^-1 G_l)_{bc}, (m, 8, 3, 8, 3)
    K += np.einsum("kl,bc->klbc", D8, np.eye(3)).transpose(0, 2, 1, 3)[None]
    K *= 2.0 * w[:, None, None, None, None]
    dof = (3 * cells[:, :, None] + np.arange(3)).reshape(m, 24)
    rows = np.repeat(dof, 24, axis=1).ravel()
    cols = np.tile(dof, (1, 24)).ravel()
    H = sp.csr_matrix((K.reshape(m, 576).ravel(), (rows, cols)), shape=(3 * n, 3 * n))
    return H


def rigid_gauge(points):
    """Six coordinates (flat indices ``3 v + c``) whose values fix a rigid motion of ``points``.

    One vertex near the centroid holds the translation; of the coordinates of the vertex
    farthest from it and of the one farthest from the line through both, the three that best
    fix the rotation (a pivoted QR of their response to infinitesimal rotations) are held too.
    """
    X = np.asarray(points, float)
    c = X.mean(axis=0)
    a = int(np.argmin(np.linalg.norm(X - c, axis=1)))
    b = int(np.argmax(np.linalg.norm(X - X[a], axis=1)))
    e = (X[b] - X[a]) / max(np.linalg.norm(X[b] - X[a]), 1e-300)
    r = X - X[a]
    off = r - np.outer(r @ e, e)
    cc = int(np.argmax(np.linalg.norm(off, axis=1)))
    # displacement of b and cc under the rotation omega about X[a]: -[r]x omega, rows per coordinate
    A = np.concatenate([-_cross_matrices(X[b] - X[a]), -_cross_matrices(X[cc] - X[a])])  # (6, 3)
    from scipy.linalg import qr

    _, _, piv = qr(A.T, pivoting=True)
    verts = np.array([b, b, b, cc, cc, cc])
    comps = np.array([0, 1, 2, 0, 1, 2])
    pick = piv[:3]
    held = np.concatenate([3 * a + np.arange(3), 3 * verts[pick] + comps[pick]])
    return np.sort(held)


def rest_derivative(design):
    """``d P / d c`` of every cell's rest shape: ``(m, 8, 3, 2)`` [mm], for the top and bottom contraction.

    The rest shapes are linear in the face contractions (:func:`gdfe.rest_shapes` at activation 1).
    """
    mesh = design.mesh
    X = mesh.points[mesh.cells]
    t = X[..., 2] / design.h
    P0 = X - X.mean(axis=1, keepdims=True)
    out = np.zeros(X.shape + (2,))
    for j, weight in enumerate((t, 1.0 - t)):
        d = np.zeros_like(P0)
        d[..., 0] = -P0[..., 0] * weight
        d[..., 1] = -design.isotropy * P0[..., 1] * weight
        out[..., j] = d - d.mean(axis=1, keepdims=True)
    return out


def contraction_gradient(f, dJ_dV, hessian=None):
    """The derivative of ``J(V*(c))`` by every cell's face contractions, by the adjoint method.

    Parameters
    ----------
    f : Fold
        The equilibrium (converged: the formula holds at a minimum of Eq. 5).
    dJ_dV : (n, 3) float array
        The objective's gradient at ``f.points``; the objective must not change under rigid
        motions of the shape.
    hessian : sparse matrix, optional
        :func:`exact_hessian` of ``f``, if already made.

    Returns
    -------
    grad : (m, 2) float array
        ``dJ / dc_top`` and ``dJ / dc_bottom`` of every cell.
    info : dict
        ``seconds`` of the solve and ``residual`` (relative) of the adjoint system.
    """
    design = f.design
    n = design.mesh.n_points
    g = check_array("dJ_dV", dJ_dV, shape=(n, 3)).ravel()
    t0 = time.perf_counter()
    log.debug("adjoint solve: %d vertices", n, extra={"progress": {"event": "stage", "stage": "adjoint solve"}})
    H = exact_hessian(f) if hessian is None else hessian
    held = rigid_gauge(f.points)
    free = np.setdiff1d(np.arange(3 * n), held)
    Hff = H[free][:, free].tocsc()
    lam = np.zeros(3 * n)
    try:
        lam[free] = factorise(Hff).solve(g[free])
    except Exception:  # CHOLMOD refuses an indefinite matrix (a fold at a saddle point): LU
        from scipy.sparse.linalg import splu

        lam[free] = splu(Hff).solve(g[free])
    if not np.all(np.isfinite(lam)):
        raise GdfeError("fold: the adjoint system is singular: the equilibrium is not a strict minimum")
    res = float(np.linalg.norm(H @ lam - g) / max(np.linalg.norm(g), 1e-300))
    lam = lam.reshape(n, 3)
    cells = design.mesh.cells
    w = design.mesh.cell_volumes()
    X = f.points[cells]
    X = X - X.mean(axis=1, keepdims=True)
    Qt = f.Q.transpose(0, 2, 1)
    mu = np.einsum("mab,mkb->mka", Qt, lam[cells])  # Q^T lambda_k
    y = np.einsum("mab,mkb->mka", Qt, X)  # Q^T x_k
    a = np.cross(mu, f.P).sum(axis=1)  # sum_k mu_k x p_k
    z = np.einsum("mab,mb->ma", _m_inverse(f.Q, f.S), a)
    Gamma = 2.0 * w[:, None, None] * (mu - np.cross(y, z[:, None, :]))  # d(-lambda^T g)/dp_k
    grad = np.einsum("mkc,mkcj->mj", Gamma, rest_derivative(design))
    return grad, {"seconds": time.perf_counter() - t0, "residual": res}
