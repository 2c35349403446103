"""Linear and geometrically nonlinear solves of an eigenstrained layered strip.

Rigid-body modes are removed by the symmetry planes of the model and as few point supports as
needed, never by clamping: the eigenstrain load is self-equilibrated, so the supports carry no
reaction and the panels shrink freely.

- ``symmetry="xy"`` (quarter model): ``u_x = 0`` on ``x = 0``, ``u_y = 0`` on ``y = 0``, and
  ``u_z = 0`` at the point ``(0, 0, h/2)``.
- ``symmetry="y"`` (half model): ``u_y = 0`` on ``y = 0``; ``u_x = u_z = 0`` at the film mid-plane
  point nearest the middle of the strip and ``u_z = 0`` at the left end of that line.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np
import scipy.sparse.linalg as spla

from gdfe import _validation as v
from gdfe._validation import GdfeTypeError
from ._kernel import STATES, Discretisation, element_fields, linear_system, load_continuation
from .linear_solvers import LinearCost, SymmetricCSR, make_solver
from .material import BilayerMaterial
from .mesh import LayeredStrip
from .newton import TangentSolver, newton

__all__ = ["FemResult", "solve_linear", "solve_nonlinear"]

log = logging.getLogger(__name__)



@dataclasses.dataclass
class FemResult:
    """Displacement of a layered strip and how it was obtained.

    Attributes
    ----------
    strip : LayeredStrip
        The meshed model.
    material : BilayerMaterial
        Materials and the full eigenstrain.
    points : (N, 3) float array [mm]
        Reference positions of the scalar degrees of freedom.
    displacement : (N, 3) float array [mm]
        Displacement at ``points``.
    nonlinear : bool
        Geometrically nonlinear (total Lagrangian, neo-Hookean or St Venant-Kirchhoff: see
        :func:`solve_nonlinear`'s ``model``) or small-strain solution.
    converged : bool
        True when the solve reached the full eigenstrain with the residual below tolerance.
    iterations : int
        Newton iterations over all load steps (1 for the linear solve).
    residual : float
        Final residual norm relative to the norm of the eigenstrain load.
    load_steps : int
        Accepted load increments (1 for the linear solve).
    load_factor : float
        Fraction of the eigenstrain reached (1 when converged).
    seconds : float
        Wall-clock time of the solve, including assembly [s].
    dofs : int
        Number of unknowns (3 per degree-of-freedom location).
    element : str
        Element type (``"hex2"`` triquadratic, ``"hexs2"`` serendipity, ``"hex1"`` trilinear).
    linear_solver : str
        What solved the linear systems: ``"superlu"`` (SciPy), ``"pardiso"`` (MKL PARDISO, the
        ``fem-fast`` extra) or ``"amg"`` (:func:`reference_fem.linear_solvers.make_solver`). The
        solve's time depends on it several-fold, so a timing is quoted with it.
    """

    strip: LayeredStrip
    material: BilayerMaterial
    points: np.ndarray
    displacement: np.ndarray
    nonlinear: bool
    converged: bool
    iterations: int
    residual: float
    load_steps: int
    load_factor: float
    seconds: float
    dofs: int
    element: str
    linear_solver: str

    @property
    def deformed(self) -> np.ndarray:
        """Deformed positions ``points + displacement``, (N, 3) [mm]."""
        return self.points + self.displacement

    def summary(self) -> dict:
        return {"nonlinear": self.nonlinear, "converged": self.converged,
                "iterations": self.iterations, "residual": self.residual,
                "load_steps": self.load_steps, "load_factor": self.load_factor,
                "seconds": self.seconds, "dofs": self.dofs, "element": self.element,
                "linear_solver": self.linear_solver}


def _check(strip, material):
    if not isinstance(strip, LayeredStrip):
        raise GdfeTypeError(f"strip: expected a LayeredStrip (see hinge_mesh, strip_mesh), got "
                        f"{type(strip).__name__}")
    if not isinstance(material, BilayerMaterial):
        raise GdfeTypeError(f"material: expected a reference_fem.BilayerMaterial, got {type(material).__name__}")


def constrained_dofs(strip: LayeredStrip, X: np.ndarray) -> np.ndarray:
    """Vector dofs fixed to zero to remove the rigid-body modes (see the module docstring)."""
    tol = 1e-9 * max(1.0, strip.length)
    fixed = [3 * np.nonzero(np.abs(X[:, 1]) < tol)[0] + 1]
    line = np.nonzero((np.abs(X[:, 1]) < tol) & (np.abs(X[:, 2] - strip.z_mid) < tol))[0]
    if strip.symmetry == "xy":
        fixed.append(3 * np.nonzero(np.abs(X[:, 0]) < tol)[0])
        a = line[np.argmin(np.abs(X[line, 0]))]
        fixed.append(np.array([3 * a + 2]))
    else:
        a = line[np.argmin(np.abs(X[line, 0]))]
        b = line[np.argmin(X[line, 0])]
        fixed.append(np.array([3 * a, 3 * a + 2, 3 * b + 2]))
    return np.unique(np.concatenate(fixed))


def _solve(K, rhs):
    return spla.spsolve(K.tocsc(), rhs, permc_spec="MMD_AT_PLUS_A")


def solve_linear(strip: LayeredStrip, material: BilayerMaterial, *, element: str = "hex2") -> FemResult:
    """Small-strain solve with the eigenstrain as load (stress from the elastic strain only).

    Parameters
    ----------
    strip : LayeredStrip
        Meshed model (:func:`~reference_fem.hinge_mesh`, :func:`~reference_fem.strip_mesh`, ...).
    material : BilayerMaterial
        Elastic constants and eigenstrain.
    element : {"hex2", "hexs2", "hex1"}
        Element type; ``"hex2"`` (27-node triquadratic) is free of bending locking.

    Returns
    -------
    FemResult
        The displacement is linear in the eigenstrain.
    """
    _check(strip, material)
    t0 = time.perf_counter()
    disc = Discretisation(strip, element)
    lam, mu, _, eps = element_fields(strip, material, disc)
    K, f = linear_system(disc, lam, mu, eps)
    fixed = constrained_dofs(strip, disc.X)
    free = np.setdiff1d(np.arange(disc.ndofs), fixed)
    u = np.zeros(disc.ndofs)
    Kff, ff = K[free][:, free], f[free]
    u[free] = _solve(Kff, ff)
    res = np.linalg.norm(Kff @ u[free] - ff) / max(np.linalg.norm(ff), 1e-300)
    ok = bool(np.all(np.isfinite(u)))
    return FemResult(strip=strip, material=material, points=disc.X, displacement=u.reshape(-1, 3),
                     nonlinear=False, converged=bool(ok and res < 1e-8), iterations=1, residual=float(res),
                     load_steps=1, load_factor=1.0, seconds=time.perf_counter() - t0,
                     dofs=disc.ndofs, element=element, linear_solver="superlu")


def solve_nonlinear(strip: LayeredStrip, material: BilayerMaterial, *, element: str = "hex2",
                    model: str = "neohookean", steps: int = 4, tol: float = 1e-8,
                    max_iter: int = 15, min_step: float = 1e-3, solver: str = "auto",
                    reuse: bool = False) -> FemResult:
    """Geometrically nonlinear solve: total Lagrangian hyperelasticity with ``F = F_e F*``.

    The eigenstrain is applied in load steps (``eps*(s) = s eps*``, ``0 < s <= 1``). Each step is
    solved by Newton's method with a backtracking line search on the energy; a step that does not
    converge in ``max_iter`` iterations is halved (down to ``min_step``), one that converges in a
    few iterations lets the next step grow. The start of each step is extrapolated
    from the last two converged states.

    Parameters
    ----------
    strip : LayeredStrip
        Meshed model.
    material : BilayerMaterial
        Elastic constants and eigenstrain (the full load).
    element : {"hex2", "hexs2", "hex1"}
        Element type.
    steps : int
        Initial number of equal load steps, >= 1.
    model : {"neohookean", "svk"}
        Hyperelastic law of the elastic part ``F_e``: compressible neo-Hookean (default) or
        St Venant-Kirchhoff. Both reduce to the same Hooke's law at small strain; SVK softens
        under strong compression, which matters for eigenstrains of tens of per cent.
    tol : float
        Convergence when the residual norm is below ``tol`` times the norm of the linear
        eigenstrain load of the full step.
    max_iter : int
        Newton iterations with a new tangent per load step, >= 1 (and three times as many in all).
    min_step : float
        Smallest load increment tried before giving up, > 0.
    solver : {"auto", "direct", "amg"}
        Linear solver of the Newton steps (:func:`reference_fem.linear_solvers.make_solver`).
    reuse : bool
        Keep factorisations across iterations (inexact and modified Newton, the plate solver's
        default); False (the default here): a new tangent and factorisation every iteration. On a
        strip a factorisation costs a few triangular solves, and the kept ones cost more
        iterations than they save: the 1 mm hinge at 30 267 unknowns takes 12 plain Newton
        iterations in 10 s, 24 inexact ones in 13 s (the solver before this one: 12 iterations
        with SuperLU on the sliced full tangent, 40 s).

    Returns
    -------
    FemResult
        With ``converged=False`` (and the last converged state, at ``load_factor < 1``) when the
        load stepping gave up.
    """
    _check(strip, material)
    steps = v.check_int("steps", steps)
    tol = v.check_positive("tol", tol)
    max_iter = v.check_int("max_iter", max_iter)
    min_step = v.check_positive("min_step", min_step)
    v.check_choice("model", model, set(STATES))
    reuse = v.check_bool("reuse", reuse)
    t0 = time.perf_counter()
    disc = Discretisation(strip, element)
    fixed = constrained_dofs(strip, disc.X)
    free = np.setdiff1d(np.arange(disc.ndofs), fixed)
    lam, mu, _, eps = element_fields(strip, material, disc)
    _, f_lin = linear_system(disc, lam, mu, eps)
    scale = max(np.linalg.norm(f_lin[free]), 1e-300)

    pattern = disc.pattern(free, upper=True)
    factor, linear_solver = make_solver(solver, free.size, disc.X, free)
    steps_solver = TangentSolver(factor, LinearCost(), reuse)

    def solve_at(s_new, trial):
        G = element_fields(strip, material, disc, scale=s_new)[2]

        def state(u, tangent):
            energy, f, K = STATES[model](disc, u, lam, mu, G, tangent=tangent, pattern=pattern)
            return energy, f, (None if K is None else SymmetricCSR(K))

        return newton(state, trial, free, scale, tol, max_iter, steps_solver)

    def on_step(s_new, ok, u, it, residual):
        if ok:
            log.info("load %.4f converged in %d iterations (residual %.2e)", s_new, it, residual)

    u, s, iterations, residual, accepted = load_continuation(solve_at, disc.ndofs, steps, min_step, 4, on_step)
    converged = s >= 1.0 - 1e-12
    if not converged:
        log.warning("nonlinear solve stopped at load factor %.4f", s)
    return FemResult(strip=strip, material=material, points=disc.X, displacement=u.reshape(-1, 3),
                     nonlinear=True, converged=bool(converged), iterations=iterations,
                     residual=float(residual), load_steps=accepted, load_factor=float(s),
                     seconds=time.perf_counter() - t0, dofs=disc.ndofs, element=element,
                     linear_solver=linear_solver)
