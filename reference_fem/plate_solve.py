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
iterations pass what a factorisation costs (:class:`_TangentSolver`). After an iteration that cut
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
from .linear_solvers import LinearCost, SymmetricCSR, gmres, make_solver
from .material import BilayerMaterial
from .mesh import FILM
from .plate import Plate

__all__ = ["PlateResult", "solve_plate", "plate_fields", "SUPPORTS"]

log = logging.getLogger(__name__)

SUPPORTS = ("free", "clamped")
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

    steps_solver = _TangentSolver(factor, lin, reuse)

    def solve_at(s_new, trial):
        G = plate_fields(plate, material, disc.n_el, scale=s_new)[2]
        return _newton(lambda w, tangent: state(w, G, tangent), trial, free, scale, tol, max_iter, steps_solver)

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


class _TangentSolver:
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
        self.precondition, slope, du = _factor_downhill(K, rhs, self.factor, self.cost)
        self.aged = False
        return du, slope, True


def _forcing(eta_prev, rate, r, tol):
    """Eisenstat-Walker forcing term (choice 2, safeguarded), not below what the stopping test needs."""
    eta = EW_GAMMA * rate ** EW_ALPHA
    floor = EW_GAMMA * eta_prev ** EW_ALPHA
    if floor > 0.1:
        eta = max(eta, floor)
    return float(min(max(eta, 0.5 * tol / r), ETA_MAX))


def _newton(state, u, free, scale, tol, max_iter, tangent_solver):
    """Newton iterations on one load level; returns ``(ok, u, iterations, residual)``.

    Each iteration assembles the tangent at the current state and solves for the step
    (:class:`_TangentSolver`: exactly with a fresh factorisation, or inexactly by GMRES preconditioned
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
            eta = _forcing(eta, rate, r, tol) if tangents > 1 else ETA_MAX
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


def _factor_downhill(A, rhs, factor, lin):
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
