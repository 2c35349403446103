"""The two-level preconditioner's coarse space augmented by the last Newton directions (recycling).

A large sheet can have a soft mode the coarse grid cannot carry: the 10^6-cell corrugation
settles by bending as a whole across its folds, the panels rigid and the fold lines
turning, which bilinear fields on the grid ten pixels apart it then had cannot follow without
stretching the panels, so the grid's Galerkin matrix makes that mode far stiffer than it
is and leaves it to CG. Newton creeps along it: on the 62 500-cell level of that sheet 14
steps in a row pointed the same way (successive steps at cosines 0.94-0.999), each 1-2 h
long, the energy falling in its sixth digit.

The last Newton direction is a good approximation of such a mode, so it is added to the
coarse space (Krylov subspace recycling, as in Parks, de Sturler et al., *SIAM J. Sci.
Comput.* 28, 2006, here for the deflated CG of Tang, Nabben, Vuik and Erlangga): each
direction is made H-orthogonal to the grid, ``v = u - Z A^{-1} Z^T H u`` with the grid's
factor of ``A = Z^T H Z``, so that the coarse solve ``W (W^T H W)^{-1} W^T r`` on
``W = [Z, V]`` is the grid's plus one term per direction (:class:`AugmentedCoarse`), at the
cost of two Hessian products and one coarse solve per recycled direction and Newton step.
Directions that the grid already holds, or along which the Hessian is not positive, are left
out (:data:`DIRECTION_DROP`), so the coarse matrix stays positive definite and the deflated CG's
equivalence with the balancing preconditioner holds as for the grid alone.

What it does and does not do, measured (in a first form, the Schur complement by difference
and its eigenvectors): each step resolves the mode as far as the quadratic model reaches, and
the creep itself remains (it is the model's reach along a curved mode: steps extended 2-8
times along their direction lowered the energy only now and then). On that 62 500-cell level,
20 steps either way, ending at residual 0.0096 h against 0.049 h; the whole 10^6 solve took
572 s against 691 s, its multilevel start 86 s against 158 s. On the 10^5 sheets the time is
the same within the machine's noise.

A Newton direction that is nearly all a turn of the whole part about its pinned vertex, which
round-off makes near the solution, is not recycled (:func:`mostly_turn`): kept, the coarse
solve resolved that turn exactly from the gradient's round-off, and tight solves never stopped
(the stopping test's tight reference: residual 6.5e-8 after 200 steps; 10 steps now, 9 without
recycling).

Two things it needs from the solver (:mod:`gdfe.solver.newton`): CG meeting negative
curvature at its first iteration returns its start plus the preconditioned correction, not the
start alone (at a saddle of the 208-cell Figure 8 dome the start, a coarse solution that
cannot hold the direction of negative curvature, was a step of 1e-11 h, taken 200 times); and
a contact solve recycles nothing (with recycling there, the contact study's 14 mm hinge, moved
by 2 um and solved again, fell by 6.9e-5 of its energy instead of coming back).
"""

from __future__ import annotations

import numpy as np

from gdfe.solver.device import dot as _dot
from gdfe.solver.rigid import without_turn

__all__ = ["DIRECTION_DROP", "TURN_SHARE", "AugmentedCoarse", "mostly_turn"]

#: A recycled direction ``u`` is kept only where its part H-orthogonal to the grid (and to the
#: directions kept before it) holds more than this fraction of its energy ``u^T H u``: below it
#: the grid holds the direction already, to the accuracy of the grid's solve.
DIRECTION_DROP = 1e-8

#: A Newton direction is not recycled where all but this fraction of it (in norm) is a turn about the
#: pinned vertex (:func:`mostly_turn`).
TURN_SHARE = 1e-2


class AugmentedCoarse:
    """The Galerkin coarse solve on the grid's space ``Z`` and extra directions ``U``.

    Each direction ``u`` is first made H-orthogonal to the grid, ``v = u - Z A^{-1} Z^T H u``,
    and to the directions kept before it; then ``W = [Z, V]`` spans the grid and the
    directions, ``W^T H W`` is block diagonal, and the coarse solve is the grid's plus
    ``sum_i v_i (v_i^T r) / (v_i^T H v_i)``. The energy ``v^T H v`` is computed from a
    product with ``v`` itself, not as the difference ``u^T H u - B^T A^{-1} B`` of the Schur
    complement, which loses its digits when ``u`` lies nearly in the grid (on the 208-cell
    Figure 8 dome, directions kept at 1e-8 of their energy that way stopped Newton at a
    residual of 4e-4 h after 200 steps). A direction is kept where that energy exceeds
    :data:`DIRECTION_DROP` of ``u^T H u``, so not where the grid holds it already or the Hessian
    is not positive along it.

    Parameters
    ----------
    solve : callable
        ``A^{-1}`` of the grid's coarse matrix ``A = Z^T H Z``, on flat arrays of ``3 k``
        numbers laid out as ``(Zt @ r).ravel()``.
    Z, Zt : sparse matrices, or :class:`gdfe.solver.threads.RowBlocks` of them
        The grid's interpolation ``(n, k)`` and its transpose, acting on ``(n, 3)`` arrays.
    apply_H : callable
        The Hessian product on ``(n, 3)`` arrays.
    U : sequence of (n, 3) float arrays
        The extra directions (zero at the pinned vertex).
    """

    def __init__(self, solve, Z, Zt, apply_H, U):
        self.solve, self.Z, self.Zt = solve, Z, Zt
        self.V, self.inv_energy = [], []
        # (H v_i)^T u_j for the directions u_j still to come: one product held at a time (48 MiB at 10^6 cells)
        later = [[] for _ in U]
        for j, u in enumerate(U):
            h = apply_H(u)
            energy = _dot(u, h)
            if not energy > 0.0:  # the Hessian is not positive along u
                continue
            v = u - Z @ solve((Zt @ h).ravel()).reshape(-1, 3)
            del h
            for (w, inv), c in zip(zip(self.V, self.inv_energy), later[j]):
                v -= (c * inv) * w
            hv = apply_H(v)
            e = _dot(v, hv)
            if e > DIRECTION_DROP * energy:
                self.V.append(v)
                self.inv_energy.append(1.0 / e)
                for k in range(j + 1, len(U)):
                    later[k].append(_dot(hv, U[k]))
            del hv
        self._work = np.empty_like(self.V[0]) if self.V else None  # c v, of every direction at every call

    @property
    def rank(self) -> int:
        """How many directions were kept."""
        return len(self.V)

    def __call__(self, r):
        """``W (W^T H W)^{-1} W^T r`` for ``r`` ``(n, 3)``."""
        out = self.Z @ self.solve((self.Zt @ r).ravel()).reshape(-1, 3)
        for v, inv in zip(self.V, self.inv_energy):
            out += np.multiply(v, _dot(v, r) * inv, out=self._work)
        return out


def mostly_turn(u, V, pin):
    """Whether all but less than :data:`TURN_SHARE` of ``u`` (in norm) is a turn about the pinned vertex of ``V``.

    The energy does not change when the part turns about its pinned vertex, so the Hessian along
    a turn is only the damping's floor. Near the solution a Newton step can be such a turn, made
    by round-off (CG's on a gradient of 1e-11 h); recycled, the coarse solve resolves that turn
    exactly, dividing the gradient's round-off along it by nearly nothing, and the next steps
    are turns again: on the stopping test's tight 900-cell solve, turns of 1e-4 mm, each followed
    by half of it back (Rayleigh quotients of the directions 1e-13 to 1e-17), and no stop after
    200 steps. Such a direction is not recycled. One that is a turn only in part is recycled
    whole: with every direction's turn taken out, the 10^6-cell corrugation took 21 fine steps
    instead of 18 (docs/solver_history.md).
    """
    rest = without_turn(u, V, pin)
    return bool(_dot(rest, rest) < TURN_SHARE ** 2 * _dot(u, u))
