"""The two-level preconditioner's coarse space augmented by the last Newton directions (recycling).

A large sheet can have a soft mode the coarse grid cannot carry: the 10^6-cell corrugation
settles by bending as a whole across its folds, the panels rigid and the fold lines
turning, which bilinear fields on a grid ten pixels apart cannot follow without
stretching the panels, so the grid's Galerkin matrix makes that mode far stiffer than it
is and leaves it to CG. Newton creeps along it: on the 62 500-cell level of that sheet 14
steps in a row pointed the same way (successive steps at cosines 0.94-0.999), each 1-2 h
long, the energy falling in its sixth digit.

The last Newton direction is a good approximation of such a mode, so it is added to the
coarse space (Krylov subspace recycling, as in Parks, de Sturler et al., *SIAM J. Sci.
Comput.* 28, 2006, here for the deflated CG of Tang, Nabben, Vuik and Erlangga): with
``W = [Z, U]`` the coarse solve is ``W (W^T H W)^{-1} W^T r``, made from the grid's factor
of ``A = Z^T H Z`` by the Schur complement of its border,

    ``S = U^T H U - B^T A^{-1} B``,  ``B = Z^T H U``,

at the cost of one Hessian product and one coarse solve per recycled vector and Newton
step. Directions that the grid already holds, or along which the Hessian is not positive
(``S``'s eigenvalues below :data:`SCHUR_DROP` of ``U^T H U``'s), are left out, so the
coarse matrix stays positive definite and the deflated CG's equivalence with the balancing
preconditioner holds as for the grid alone.

What it does and does not do, measured: each step then resolves the mode as far as the
quadratic model reaches, and the creep itself remains (it is the model's reach along a
curved mode: steps extended 2-8 times along their direction lowered the energy only now and
then). On that 62 500-cell level, 20 steps either way, ending at residual 0.0096 h against
0.049 h; the whole 10^6 solve took 572 s against 691 s, its multilevel start 86 s against
158 s. On the 10^5 sheets the time is the same within the machine's noise.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SCHUR_DROP", "AugmentedCoarse"]

#: A recycled direction (an eigenvector of the Schur complement ``S``) is kept only where its
#: eigenvalue exceeds this fraction of the largest diagonal entry of ``U^T H U``: below it the
#: grid holds the direction already to round-off, or the Hessian is not positive along it.
SCHUR_DROP = 1e-8


class AugmentedCoarse:
    """The Galerkin coarse solve on the grid's space ``Z`` and extra directions ``U``.

    Parameters
    ----------
    solve : callable
        ``A^{-1}`` of the grid's coarse matrix ``A = Z^T H Z``, on flat arrays of ``3 k``
        numbers laid out as ``(Zt @ r).ravel()``.
    Z, Zt : sparse matrices
        The grid's interpolation ``(n, k)`` and its transpose, acting on ``(n, 3)`` arrays.
    apply_H : callable
        The Hessian product on ``(n, 3)`` arrays.
    U : sequence of (n, 3) float arrays
        The extra directions (zero at the pinned vertex); made orthonormal here, and those the
        grid already holds or along which the Hessian is not positive are left out.

    Attributes
    ----------
    rank : int
        How many directions were kept.
    """

    def __init__(self, solve, Z, Zt, apply_H, U):
        self.solve, self.Z, self.Zt = solve, Z, Zt
        self.U = []
        self.rank = 0
        if not len(U):
            return
        Q = _orthonormal(U)
        if not Q:
            return
        C = np.empty((len(Q), len(Q)))
        B = []
        for b, q in enumerate(Q):  # one product held at a time (48 MiB each at 10^6 cells)
            h = apply_H(q)
            C[:, b] = [_dot(u, h) for u in Q]
            B.append((Zt @ h).ravel())
            del h
        C = 0.5 * (C + C.T)
        B = np.stack(B, axis=1)
        AiB = np.stack([solve(B[:, a]) for a in range(B.shape[1])], axis=1)
        S = C - B.T @ AiB
        lam, vec = np.linalg.eigh(0.5 * (S + S.T))
        keep = lam > SCHUR_DROP * max(float(np.max(np.diag(C))), 0.0)
        if not keep.any():
            return
        vec = vec[:, keep]
        # W = [Z, Q vec]: in that basis the border's Schur complement is diag(lam), so the directions'
        # coefficients of a solve are P (Q^T r - AiB^T Z^T r) in the basis Q, P = vec diag(1 / lam) vec^T
        self.U, self.AiB = Q, AiB
        self.P = (vec / lam[keep]) @ vec.T
        self.rank = int(keep.sum())

    def __call__(self, r):
        """``W (W^T H W)^{-1} W^T r`` for ``r`` ``(n, 3)``."""
        rz = (self.Zt @ r).ravel()
        t = self.solve(rz)
        if not self.rank:
            return self.Z @ t.reshape(-1, 3)
        ru = np.array([_dot(u, r) for u in self.U])
        c = self.P @ (ru - self.AiB.T @ rz)
        out = self.Z @ (t - self.AiB @ c).reshape(-1, 3)
        for y, u in zip(c, self.U):
            out += y * u
        return out


def _dot(a, b):
    return float(np.einsum("ij,ij->", a, b))


def _orthonormal(U):
    """``U`` made orthonormal (modified Gram-Schmidt), without the directions that depend on the others."""
    out = []
    for u in U:
        size = np.sqrt(_dot(u, u))
        if not out and abs(size - 1.0) <= 1e-12:  # the first, of unit length already: itself, not a copy
            out.append(u)
            continue
        v = np.array(u, float)
        for q in out:
            v -= _dot(q, v) * q
        norm = np.sqrt(_dot(v, v))
        if norm > 1e-8 * size:
            v /= norm
            out.append(v)
    return out
