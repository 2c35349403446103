"""Geometrically nonlinear solve of a plate (:mod:`reference_fem.plate`) with its cost split.

Total Lagrangian hyperelasticity with ``F = F_e F*`` (:mod:`reference_fem._kernel`, neo-Hookean by
default), the film's eigenstrain applied in adaptive load steps (``eps*(s) = s eps*``): a step
that fails to converge in ``max_iter`` Newton iterations is halved, one that
converges in at most ``easy_iter`` iterations doubles the next, and each step starts from the
extrapolation of the last two converged states.

A Newton iteration assembles the tangent at the current state (vectorised over elements, straight
into the upper triangle of its free rows and columns: :meth:`Discretisation.pattern`), solves for
the step and takes a backtracking line search on the energy. The step is an inexact Newton step:
GMRES on the current tangent, preconditioned by the last factorisation
(:mod:`reference_fem.linear_solvers`: sparse LDL^T/LU, or AMG-preconditioned CG, chosen by size),
to an Eisenstat-Walker forcing term; the tangent is factorised afresh only when the Krylov
iterations pass what a factorisation costs (:mod:`reference_fem.newton`). After an iteration that cut
the residual fourfold or more, the next step is taken with the kept factorisation alone, without
assembling the tangent (modified Newton). The factorisation is kept across load steps, and PARDISO
analyses the tangent's pattern once per solve.

Supports (``support``):

``"free"``
    Free-floating: the six rigid motions are removed by fixing one film mid-plane node near the
    centroid (3 dofs), y and z of its neighbour along x (2) and z of its neighbour along y (1).
    The eigenstrain load is self-equilibrated, so the supports carry no reaction.
``"clamped"``
    Every node on the film's edge with the smallest x is fixed (a clamped edge).

The result's :attr:`PlateResult.cost` splits the wall time into set-up, assembly (tangent and
residual), analysis, factorisation (or AMG set-up), triangular solves (``solve_s``, of which
``krylov_solve_s`` inside GMRES), the rest of the Krylov iterations (``krylov_s``) and the rest, and
compares it with the limit of a plain Newton solve, one assembly and one factorisation per Newton
iteration (``over_limit`` below 1: the kept factorisations made it cheaper than that).
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np

from gdfe import _validation as v
from gdfe._validation import GdfeTypeError
from ._kernel import STATES, Discretisation, eigenstrain_load, linear_system, load_continuation
from .linear_solvers import LinearCost, SymmetricCSR, make_solver
from .material import BilayerMaterial
from .mesh import FILM
from .newton import TangentSolver, newton
from .plate import Plate

__all__ = ["PlateResult", "solve_plate", "plate_fields", "SUPPORTS"]

log = logging.getLogger(__name__)

SUPPORTS = ("free", "clamped")


@dataclasses.dataclass
class PlateResult:
    """Displacement of a plate, how it was obtained and what it cost.

    Attributes
    ----------
    plate : Plate
    material : BilayerMaterial
    points : (N, 3) float array [mm]
        Reference positions of the scalar degrees of freedom.
    displacement : (N, 3) float array [mm]
    converged : bool
        True when the full eigenstrain was reached with the residual below tolerance.
    load_factor : float
        Fraction of the eigenstrain reached (1 when converged).
    iterations : int
        Newton iterations over all load steps (accepted and rejected).
    residual : float
        Last residual norm relative to the eigenstrain load.
    steps : list of dict
        Every load step tried: ``load``, ``accepted``, ``iterations``, ``residual``, and the
        ``snapshot`` index of the state saved when accepted.
    snapshots : list of (N, 3) float arrays [mm]
        Displacement after each accepted load step (when asked for).
    seconds : float
        Wall time of the solve [s].
    cost : dict
        Cost split (see the module docstring).
    dofs : int
    n_elements : int
    element : str
    solver : str
        Linear solver used (``"direct"`` or ``"amg"``).
    """

    plate: Plate
    material: BilayerMaterial
    points: np.ndarray
    displacement: np.ndarray
    converged: bool
    load_factor: float
    iterations: int
    residual: float
    steps: list
    snapshots: list
    seconds: float
    cost: dict
    dofs: int
    n_elements: int
    element: str
    solver: str
    connectivity: np.ndarray = dataclasses.field(repr=False, default=None)

    @property
    def deformed(self) -> np.ndarray:
        return self.points + self.displacement

    def summary(self) -> dict:
        return {"converged": self.converged, "load_factor": self.load_factor,
                "iterations": self.iterations, "residual": self.residual,
                "load_steps": sum(s["accepted"] for s in self.steps),
                "rejected_steps": sum(not s["accepted"] for s in self.steps),
                "seconds": self.seconds, "dofs": self.dofs, "n_elements": self.n_elements,
                "element": self.element, "solver": self.solver, "cost": self.cost}


def plate_fields(plate, material, n_el, scale=1.0):
    """Per-element Lamé constants, inverse free stretch and eigenstrain of a plate.

    Returns
    -------
    lam, mu : (n_el,) float arrays [MPa]
    G : (n_el, 3) float array
        ``1 / (1 + scale eps*)``.
    eps : (n_el, 3) float array
        ``scale eps*`` in the film, 0 in the coats.
    """
    film = np.asarray(plate.ply) == FILM
    la, ma = material.lame("active")
    lp, mp = material.lame("passive")
    lam = np.where(film, la, lp)
    mu = np.where(film, ma, mp)
    if plate.stiffness is not None:
        lam = lam * plate.stiffness
        mu = mu * plate.stiffness
    if plate.eigenstrain is not None:
        eps = np.where(film[:, None], np.asarray(plate.eigenstrain, float), 0.0)
    else:
        ex, ey, ez = material.eigenstrain_xyz
        eps = np.zeros((n_el, 3))
        eps[film] = (ex, plate.isotropy * ey, ez)
    eps = scale * eps
    return lam, mu, 1.0 / (1.0 + eps), eps


def fixed_dofs(plate: Plate, X: np.ndarray, support: str = "free") -> np.ndarray:
    """Vector dofs held at zero (see the module docstring)."""
    v.check_choice("support", support, SUPPORTS)
    step = plate.in_plane_step
    tol = 1e-9 * max(1.0, plate.size)
    mid = np.nonzero(np.abs(X[:, 2] - plate.z_mid) < tol)[0]
    if support == "clamped":
        film_x = X[mid, 0].min()
        edge = np.nonzero((np.abs(X[:, 0] - film_x) < tol) & (X[:, 2] > -tol) & (X[:, 2] < plate.h + tol))[0]
        return np.sort((3 * edge[:, None] + np.arange(3)).ravel())
    centre = X[mid].mean(axis=0)
    a = mid[np.argmin(np.linalg.norm(X[mid, :2] - centre[:2], axis=1))]
    # the nearest mid-plane dofs beside a along x and along y (in the film, one step or less away)
    dx = X[mid, 0] - X[a, 0]
    dy = X[mid, 1] - X[a, 1]
    along_x = mid[(np.abs(dy) < tol) & (np.abs(dx) > tol) & (np.abs(dx) <= step[0] + tol)]
    along_y = mid[(np.abs(dx) < tol) & (np.abs(dy) > tol) & (np.abs(dy) <= step[1] + tol)]
    if along_x.size == 0 or along_y.size == 0:  # pragma: no cover - a mid-plane node has film around it
        raise RuntimeError("no mid-plane neighbours for the supports")
    b = along_x[np.argmin(np.abs(X[along_x, 0] - X[a, 0]))]
    c = along_y[np.argmin(np.abs(X[along_y, 1] - X[a, 1]))]
    return np.array([3 * a, 3 * a + 1, 3 * a + 2, 3 * b + 1, 3 * b + 2, 3 * c + 2])


def solve_plate(plate: Plate, material: BilayerMaterial | None = None, *, element: str = "hex2",
                model: str = "neohookean", support: str = "free", solver: str = "auto", steps: int = 8,
                tol: float = 1e-8, max_iter: int = 20, easy_iter: int = 6, min_step: float = 1e-3,
                reuse: bool = True, linear: bool = False, keep_steps: bool = False, progress=None) -> PlateResult:
    """Deform a plate by its film's eigenstrain.

    Parameters
    ----------
    plate : Plate
        From :func:`~reference_fem.plate_mesh`.
    material : BilayerMaterial, optional
        Elastic constants and the full eigenstrain (default: the Table-1 calibration).
    element : {"hex2", "hexs2", "hex1"}
        Element type (``"hex2"``, 27-node triquadratic, is free of bending locking).
    model : {"neohookean", "svk"}
        Hyperelastic law (:func:`reference_fem.solve_nonlinear`).
    support : {"free", "clamped"}
    solver : {"auto", "direct", "amg"}
        Linear solver of the Newton steps (:mod:`reference_fem.linear_solvers`).
    steps : int
        Initial number of equal load steps, >= 1 (a step that does not converge is halved, one that
        converges in ``easy_iter`` iterations or fewer doubles the next).
    tol : float
        Residual norm, relative to the linear eigenstrain load, below which a step has converged.
    max_iter : int
        Newton iterations with a new tangent per load step (and three times as many in all) before
        it is halved.
    easy_iter : int
        A step converged in at most this many iterations doubles the next.
    min_step : float
        Smallest load increment before the solve gives up (reported, ``converged=False``).
    reuse : bool
        Keep a factorisation as the preconditioner of GMRES on later tangents (inexact Newton,
        refactorised when the Krylov iterations pass what a factorisation costs), and for steps
        without a tangent after fast iterations (modified Newton); False: a new tangent and
        factorisation every iteration.
    linear : bool
        Small-strain solve instead (one assembly, one solve).
    keep_steps : bool
        Keep the displacement after every accepted load step (:attr:`PlateResult.snapshots`).
    progress : callable, optional
        Called as ``progress(load, iterations, residual)`` after every accepted step.

    Returns
    -------
    PlateResult
    """
    if not isinstance(plate, Plate):
        raise GdfeTypeError(f"plate: expected a reference_fem.Plate (see plate_mesh), got {type(plate).__name__}")
    material = BilayerMaterial() if material is None else material
    if not isinstance(material, BilayerMaterial):
        raise GdfeTypeError(f"material: expected a reference_fem.BilayerMaterial, got {type(material).__name__}")
    steps = v.check_int("steps", steps)
    tol = v.check_positive("tol", tol)
    max_iter = v.check_int("max_iter", max_iter)
    easy_iter = v.check_int("easy_iter", easy_iter)
    min_step = v.check_positive("min_step", min_step)
    v.check_choice("model", model, set(STATES))
    t_start = time.perf_counter()
    clock = {"setup_s": 0.0, "assembly_s": 0.0, "assemblies": 0, "residual_s": 0.0, "residuals": 0}
    t0 = time.perf_counter()
    disc = Discretisation(plate, element)
    fixed = fixed_dofs(plate, disc.X, support)
    free = np.setdiff1d(np.arange(disc.ndofs), fixed)
    lam, mu, _, eps = plate_fields(plate, material, disc.n_el)
    factor, method = make_solver(solver, free.size, disc.X, free)
    lin = LinearCost(method=method)
    record = []
    snapshots = []
    if linear:
        K0, f_lin = linear_system(disc, lam, mu, eps)
        scale = max(np.linalg.norm(f_lin[free]), 1e-300)
        clock["setup_s"] = time.perf_counter() - t0
        A = K0[free][:, free]
        u = np.zeros(disc.ndofs)
        u[free] = factor(A, lin)(f_lin[free], lin)
        r = float(np.linalg.norm(A @ u[free] - f_lin[free]) / scale)
        ok = bool(np.all(np.isfinite(u)) and r < 1e-6)
        record.append({"load": 1.0, "accepted": ok, "iterations": 1, "residual": r, "snapshot": 0})
        snapshots.append(u.reshape(-1, 3).copy())
        return _result(plate, material, disc, u, ok, 1.0 if ok else 0.0, 1, r, record, snapshots,
                       t_start, clock, lin, element, method)
    scale = max(np.linalg.norm(eigenstrain_load(disc, lam, mu, eps)[free]), 1e-300)
    pattern = disc.pattern(free, upper=True)  # the tangent's free rows and columns, upper triangle
    clock["setup_s"] = time.perf_counter() - t0

    def state(u, G, tangent):
        t = time.perf_counter()
        energy, f, K = STATES[model](disc, u, lam, mu, G, tangent=tangent, pattern=pattern)
        key, count = ("assembly_s", "assemblies") if tangent else ("residual_s", "residuals")
        clock[key] += time.perf_counter() - t
        clock[count] += 1
        return energy, f, (None if K is None else SymmetricCSR(K))

    steps_solver = TangentSolver(factor, lin, reuse)

    def solve_at(s_new, trial):
        G = plate_fields(plate, material, disc.n_el, scale=s_new)[2]
        return newton(lambda w, tangent: state(w, G, tangent), trial, free, scale, tol, max_iter, steps_solver)

    def on_step(s_new, ok, u, it, residual):
        step = {"load": float(s_new), "accepted": bool(ok), "iterations": int(it), "residual": float(residual)}
        record.append(step)
        if ok:
            if keep_steps:
                step["snapshot"] = len(snapshots)
                snapshots.append(u.reshape(-1, 3).copy())
            log.info("load %.4f converged in %d iterations (residual %.2e, %.1f s)", s_new, it, residual,
                     time.perf_counter() - t_start)
            if progress is not None:
                progress(s_new, it, residual)

    u, s, iterations, residual, _ = load_continuation(solve_at, disc.ndofs, steps, min_step, easy_iter, on_step)
    converged = s >= 1.0 - 1e-12
    if not converged:
        log.warning("plate solve stopped at load factor %.4f", s)
    if not keep_steps or not snapshots:
        snapshots.append(u.reshape(-1, 3).copy())
    return _result(plate, material, disc, u, converged, s, iterations, residual, record, snapshots, t_start,
                   clock, lin, element, method)


def _result(plate, material, disc, u, converged, s, iterations, residual, record, snapshots, t_start, clock,
            lin, element, method):
    seconds = time.perf_counter() - t_start
    newton = sum(r["iterations"] for r in record)
    per_assembly = clock["assembly_s"] / max(clock["assemblies"], 1)
    per_factor = lin.factor_s / max(lin.factorisations, 1)
    direct_solves = max(lin.solves - lin.krylov_iterations, 1)
    per_solve = (lin.solve_s - lin.krylov_solve_s) / direct_solves
    limit = newton * (per_assembly + per_factor + per_solve) + clock["setup_s"] + lin.analysis_s
    accounted = (clock["setup_s"] + clock["assembly_s"] + clock["residual_s"] + lin.analysis_s + lin.factor_s
                 + lin.solve_s + lin.krylov_s)
    cost = {**clock, **{k: val for k, val in lin.as_dict().items() if k != "method"},
            "other_s": max(seconds - accounted, 0.0), "newton_iterations": int(newton),
            "iterations_per_step": [r["iterations"] for r in record if r["accepted"]],
            "limit_s": float(limit), "over_limit": float(seconds / limit) if limit > 0 else float("nan")}
    return PlateResult(plate=plate, material=material, points=disc.X, displacement=u.reshape(-1, 3),
                       converged=bool(converged), load_factor=float(s), iterations=int(iterations),
                       residual=float(residual), steps=record, snapshots=snapshots, seconds=seconds, cost=cost,
                       dofs=disc.ndofs, n_elements=disc.n_el, element=element, solver=method,
                       connectivity=disc.edofs)
