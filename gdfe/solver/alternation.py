"""The paper's alternation of the two steps: ``method="plain"`` and ``method="anderson"``.

Each orientation step and each assembly step lowers the energy, so plain alternation
converges, but slowly for bending. ``"anderson"`` accelerates the same fixed-point map
with Anderson mixing, accepting a mixed iterate only when its energy is below that of
the current iterate (otherwise it takes the plain step and forgets its history). The
converged shape is a fixed point of the paper's alternation either way.

Above :data:`gdfe.solver.MULTIGRID_CELLS` each assembly step is solved by multigrid CG to the same
relative residual, started from the last move repeated (after an accepted Anderson mix, from the
mixed iterate): the moves settle as the alternation converges, and the solve shortens (from zero it
takes some 12 cycles at 10^5 cells, :meth:`gdfe.solver.multigrid.Multigrid.solve`; docs/solver_history.md).
"""

from __future__ import annotations

import numpy as np

from gdfe.solver.energy import SolveStats

__all__ = ["solve_alternation"]


def solve_alternation(steps, V0, activation, tol, max_iter, anderson=False, history=6):
    """Alternate the orientation and assembly steps from ``V0`` until the plain step's move is below ``tol``.

    Parameters
    ----------
    steps : LocalGlobal
    V0 : (n, 3) float array [mm]
        Start; its pinned vertex stays where it is.
    activation : float
    tol : float
        Tolerance on the largest vertex move of one plain step, in units of h.
    max_iter : int
        Limit on the assembly steps.
    anderson : bool
        Mix the last ``history`` iterates (Anderson acceleration with an energy safeguard).
    history : int

    Returns
    -------
    SolveStats
        ``points`` is the plain step from the last iterate: it is at least as good.
    """
    V = np.array(V0, float)
    Vp = V[steps.pin].copy()
    scale = steps.design.h
    o = steps.orient(V, activation)
    Q, E = o.Q, o.energy
    ahead = steps.uses_multigrid  # only the multigrid's solve starts from a guess (a factor's needs none)
    G = steps.assemble(Q, Vp, activation, guess=V).V
    F = G - V
    energies = [E]
    dF, dG = [], []
    res = float(np.abs(F).max() / scale)
    it = 1
    while res > tol and it < max_iter:
        if anderson and dF:
            dFm = np.stack([d.ravel() for d in dF], axis=1)
            dGm = np.stack([d.ravel() for d in dG], axis=1)
            gamma, *_ = np.linalg.lstsq(dFm, F.ravel(), rcond=None)
            Vt = G - (dGm @ gamma).reshape(V.shape)
            trial = steps.orient(Vt, activation)
            if trial.energy <= E:
                V, Q, E = Vt, trial.Q, trial.energy
                guess = V
            else:
                dF, dG = [], []
                V, guess = G, (G + F if ahead else None)
                o = steps.orient(V, activation)
                Q, E = o.Q, o.energy
        else:
            V, guess = G, (G + F if ahead else None)
            o = steps.orient(V, activation)
            Q, E = o.Q, o.energy
        energies.append(E)
        G_new = steps.assemble(Q, Vp, activation, guess=guess).V
        F_new = G_new - V
        it += 1
        if anderson:
            dF.append(F_new - F)
            dG.append(G_new - G)
            if len(dF) > history:
                dF.pop(0)
                dG.pop(0)
        F, G = F_new, G_new
        res = float(np.abs(F).max() / scale)
    # report the plain step's result: it is at least as good as V
    energies.append(steps.orient(G, activation).energy)
    return SolveStats(points=G, converged=res <= tol, iterations=it, residual=res, energies=energies)
