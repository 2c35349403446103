"""Newton's method on one load level of the reference FEM, shared by the plate and the strip solvers.

Each iteration assembles the tangent at the current state and solves for the step
(:class:`TangentSolver`: exactly with a fresh factorisation, or inexactly by GMRES preconditioned
with a kept one, to the Eisenstat-Walker forcing term :func:`forcing`), then takes a backtracking
line search on the energy; after an iteration that cut the residual by :data:`REUSE_RATE` or more
the step is the kept factorisation's alone, without a tangent (modified Newton). An indefinite
tangent is shifted by a multiple of its diagonal until the step goes downhill
(:func:`factor_downhill`). With ``reuse=False`` every iteration assembles and factorises its
tangent (plain Newton, the limit of the plate solver's cost split).

The tangent is a :class:`~reference_fem.linear_solvers.SymmetricCSR` (the upper triangle of the
free rows and columns) and the factorisations come from
:func:`~reference_fem.linear_solvers.make_solver`; the cost of every part is counted in a
:class:`~reference_fem.linear_solvers.LinearCost`.
"""

from __future__ import annotations

import logging

import numpy as np

from .linear_solvers import gmres

__all__ = ["TangentSolver", "newton", "factor_downhill", "forcing", "KRYLOV_MAX", "KRYLOV_RANGE",
           "REUSE_RATE", "ETA_MAX"]

log = logging.getLogger(__name__)

#: Krylov iterations a kept factorisation may take on a Newton step before the tangent is factorised
#: afresh, until the solve has measured what a factorisation and a Krylov iteration cost; then the
#: cap is their ratio, within KRYLOV_RANGE.
KRYLOV_MAX = 12
#: A Newton iteration that cut the residual at least this much is followed by a step with the kept
#: factorisation alone, without assembling the tangent (modified Newton).
REUSE_RATE = 0.25
KRYLOV_RANGE = (3, 30)
#: Eisenstat-Walker forcing (their choice 2): ``eta = GAMMA (r_k / r_k-1)^ALPHA``, at most ETA_MAX. Looser
#: steps (ETA_MAX = 0.1) cost more Newton iterations than GMRES saved (docs/reference_fem_plates.md).
EW_GAMMA, EW_ALPHA, ETA_MAX = 0.9, 2.0, 1e-3




class TangentSolver:
    """Newton steps ``K du = -f`` with a factorisation kept across iterations and load steps.

    With ``reuse`` the last factorisation preconditions GMRES on the current tangent (an inexact
    Newton step to the forcing term ``eta``). The tangent is factorised afresh, and the step solved
    with it, when GMRES does not reach ``eta`` within the cap (what one factorisation costs in Krylov
    iterations, as measured so far: :data:`KRYLOV_MAX` before that), when its step does not go
    downhill, or when the last Krylov solve needed more than half the cap (the factorisation has
    aged). Without ``reuse`` every step factorises its tangent (the limit of the cost split).
    """

    def __init__(self, factor, cost, reuse):
        self.factor, self.cost, self.reuse = factor, cost, reuse
        self.precondition = None
        self.aged = False

    def cap(self) -> int:
        """The Krylov iterations one factorisation costs, as measured so far (in seconds: the path of
        an inexact solve, and its shape within the stopping test, depend on the machine's load)."""
        c = self.cost
        if not (c.factorisations and c.krylov_iterations):
            return KRYLOV_MAX
        per_factor = c.factor_s / c.factorisations
        per_iteration = (c.krylov_s + c.krylov_solve_s) / c.krylov_iterations
        return int(np.clip(per_factor / max(per_iteration, 1e-12), *KRYLOV_RANGE))

    def modified_step(self, rhs):
        """A step with the kept factorisation alone, no tangent (modified Newton), and its slope;
        ``(None, None)`` without one, or where it does not go downhill."""
        if not self.reuse or self.precondition is None:
            return None, None
        du = self.precondition(rhs, self.cost)
        slope = float(-rhs @ du)
        if np.all(np.isfinite(du)) and slope < 0:
            return du, slope
        return None, None

    def step(self, K, rhs, eta):
        """The step and its slope ``-rhs . du``, and whether the tangent was factorised for it;
        ``(None, slope, True)`` when no factorisation gave a step downhill."""
        if self.reuse and self.precondition is not None and not self.aged:
            cap = self.cap()
            kr = gmres(K, rhs, self.precondition, self.cost, rtol=eta, maxiter=cap)
            slope = float(-rhs @ kr.x)
            if kr.converged and slope < 0:
                self.aged = kr.iterations > cap // 2
                return kr.x, slope, False
        self.precondition, slope, du = factor_downhill(K, rhs, self.factor, self.cost)
        self.aged = False
        return du, slope, True


def forcing(eta_prev, rate, r, tol):
    """Eisenstat-Walker forcing term (choice 2, safeguarded), not below what the stopping test needs."""
    eta = EW_GAMMA * rate ** EW_ALPHA
    floor = EW_GAMMA * eta_prev ** EW_ALPHA
    if floor > 0.1:
        eta = max(eta, floor)
    return float(min(max(eta, 0.5 * tol / r), ETA_MAX))


def newton(state, u, free, scale, tol, max_iter, tangent_solver):
    """Newton iterations on one load level; returns ``(ok, u, iterations, residual)``.

    Each iteration assembles the tangent at the current state and solves for the step
    (:class:`TangentSolver`: exactly with a fresh factorisation, or inexactly by GMRES preconditioned
    with a kept one, to the Eisenstat-Walker forcing term), then takes a backtracking line search on
    the energy; after an iteration that cut the residual by :data:`REUSE_RATE` or more the step is
    the kept factorisation's alone, without a tangent (modified Newton). An indefinite tangent is
    shifted by a multiple of its diagonal until the step goes downhill. Converged when the residual
    (relative to ``scale``) is below ``tol``, or below ``1000 tol`` while the update has stalled at
    round-off; not converged after ``max_iter`` tangents or ``3 max_iter`` iterations.
    """
    u = u.copy()
    energy, f, K = state(u, True)
    if K is None:  # the extrapolated start turns an element inside out: cut the load step
        return False, u, 0, np.inf
    r = np.linalg.norm(f[free]) / scale
    if r < tol:
        return True, u, 0, r
    eta, rate = ETA_MAX, 1.0
    it = tangents = 0
    while tangents < max_iter and it < 3 * max_iter:
        it += 1
        rhs = -f[free]
        du, kind = None, "modified"
        if rate < REUSE_RATE:  # the kept factorisation alone (no tangent) still converges fast
            du, slope = tangent_solver.modified_step(rhs)
        if du is None:
            if K is None:
                energy, f, K = state(u, True)
            tangents += 1
            eta = forcing(eta, rate, r, tol) if tangents > 1 else ETA_MAX
            du, slope, fresh = tangent_solver.step(K, rhs, eta)
            kind = "factorised" if fresh else "GMRES"
        if du is None:
            return False, u, it, r
        step = np.zeros_like(u)
        step[free] = du
        beta = 1.0
        for _ in range(10):
            e_try, f_try, _ = state(u + beta * step, False)
            r_try = np.linalg.norm(f_try[free]) / scale
            if np.isfinite(e_try) and (e_try <= energy + 1e-4 * beta * slope or r_try < r):
                break
            beta *= 0.5
        u += beta * step
        update = beta * np.linalg.norm(du) / max(np.linalg.norm(u[free]), 1e-300)
        energy, f, K = e_try, f_try, None
        rate, r = r_try / r, r_try
        log.debug("iteration %d: residual %.3e (eta %.2e, step %.3g, %s)", it, r, eta, beta, kind)
        if not np.isfinite(r):
            return False, u, it, r
        if r < tol or (r < 1e3 * tol and update < 1e-11):
            return True, u, it, r
    return False, u, it, r


def factor_downhill(A, rhs, factor, lin):
    """Factorise ``A`` (shifted by a multiple of its diagonal until the step goes downhill);
    returns ``(solve, slope, du)``, ``solve`` None when no shift helped."""
    shift = 0.0
    while True:
        try:
            solve = factor(A.shifted(shift) if shift else A, lin)
            du = solve(rhs, lin)
        except RuntimeError:  # singular tangent
            du = np.full(rhs.shape, np.nan)
        slope = float(-rhs @ du)
        if np.all(np.isfinite(du)) and slope < 0:
            return solve, slope, du
        shift = 1e-4 if shift == 0.0 else 10 * shift
        if shift > 1.0:
            return None, slope, du
