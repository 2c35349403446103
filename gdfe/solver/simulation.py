"""The simulation of a design's shape change: :func:`simulate` and its :class:`Result`.

:func:`simulate` checks its options, picks the method (:func:`gdfe.solver.auto_method`)
and the starting shape (:data:`INITS`), and ramps the contraction over ``steps`` frames,
each solved by one :class:`gdfe.solver.Solver` from the last.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np

from gdfe._validation import check_array, check_choice, check_instance, check_int
from gdfe.design import Design
from gdfe.model import as_model
from gdfe.solver.methods import METHODS, Solver, auto_method, check_tol
from gdfe.solver.starts import flat_start, multilevel_start

__all__ = ["Result", "ConvergenceError", "simulate", "INITS", "MULTILEVEL_CELLS"]

log = logging.getLogger(__name__)

#: Starting shapes of :func:`simulate` (besides given vertex positions).
INITS = ("auto", "linear", "multilevel", "flat")
#: ``init="auto"`` starts designs above this many cells from a coarsened copy.
MULTILEVEL_CELLS = 20_000


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
        Seconds spent in the factorisation, the orientation and assembly steps, the
        Newton steps (``"newton"``) and the multilevel start (``"start"``).
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


def simulate(design, *, method="auto", init="auto", steps=1, tol=1e-7, max_iter=None,
             history=6, seed=0, model=None):
    """Simulate the heat-activated shape change of a design.

    Parameters
    ----------
    design : Design
        The film, its material map and contraction ratios.
    method : {"auto", "newton", "newton-cg", "anderson", "plain"}
        ``"plain"`` is the paper's alternation; ``"anderson"`` accelerates it with an
        energy safeguard; ``"newton"`` takes damped Newton steps on the same energy
        (:meth:`gdfe.solver.Solver.hessian`), factorising the 3n x 3n Hessian each step;
        ``"newton-cg"`` solves the Newton steps by conjugate gradients preconditioned with
        the factorised n x n system and a coarse grid; ``"auto"`` (default) picks
        ``"newton"`` up to :data:`gdfe.solver.AUTO_NEWTON_CELLS` cells, else ``"newton-cg"``. All stop
        at a fixed point of the same map, and the residual is always that of the paper's
        plain step.
    init : {"auto", "linear", "multilevel", "flat"} or (n, 3) float array [mm]
        Starting shape of the first frame: the small-rotation solution (``"linear"``),
        the solution of the design coarsened 2 x 2 in the plane, interpolated
        (``"multilevel"``, recursively down to :data:`gdfe.solver.MULTILEVEL_COARSEST` cells,
        each coarse level solved to ``MULTILEVEL_TOL``; see :func:`gdfe.solver.starts.multilevel_start`), the
        flat print with a seeded perturbation of 1e-4 h out of plane (``"flat"``: the
        flat print itself is a fixed point of the alternation, so it must be perturbed
        to bend at all), or given vertex positions (e.g. a shape a designer expects, or
        an earlier result). ``"auto"`` (default) is ``"multilevel"`` above
        :data:`MULTILEVEL_CELLS` cells, else ``"linear"``.
    steps : int
        Number of frames the contraction is ramped over (activation k/steps for
        k = 1..steps), each started from the last: the time series of the fold.
    tol : float
        Convergence tolerance on the fixed-point residual (largest vertex move of one
        plain iteration, in units of the film thickness h). The Newton methods also need
        their estimated distance to the solution below ``gdfe.solver.STEP_TOL_FACTOR * tol``.
    max_iter : int, optional
        Iteration limit per frame; default 200 for the Newton methods, 5000 otherwise.
    history : int
        Anderson history length.
    seed : int
        Seed of the perturbation used by ``init="flat"``.
    model : DeformationModel or path of a model file, optional
        Simulate the design with the contractions this deformation model gives its cells
        (:meth:`gdfe.DeformationModel.apply`; the design must carry its passive thickness
        ``d``) instead of those it was made with.

    Returns
    -------
    Result
        Check ``result.converged`` (or call ``result.check()``): a solve that hit
        ``max_iter`` is returned with ``converged=False`` and logged as a warning.
    """
    method = check_choice("method", method, METHODS)
    check_instance("design", design, Design)
    if model is not None:
        design = as_model(model).apply(design)
    if method == "auto":
        method = auto_method(design)
    if isinstance(init, str):
        init = check_choice("init", init, INITS)
        if init == "auto":
            init = "multilevel" if design.n_cells > MULTILEVEL_CELLS else "linear"
    else:
        start = check_array("init", init, shape=design.mesh.points.shape)
        init = "given"
    steps = check_int("steps", steps)
    if max_iter is None:
        max_iter = 200 if method.startswith("newton") else 5000
    max_iter = check_int("max_iter", max_iter)
    history = check_int("history", history)
    tol = check_tol(tol)
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
                V = multilevel_start(design, a)
                solver.timings["start"] = time.perf_counter() - t_start
            elif init == "given":
                V = start.copy()
            else:
                V = flat_start(design, seed)
        stats = solver.solve(V, a, method=method, tol=tol, max_iter=max_iter, history=history)
        V, res = stats.points, stats.residual
        converged &= stats.converged
        total += stats.iterations
        per_frame.append(stats.iterations)
        energies.extend(stats.energies)
        frames.append(V.copy())
        if not stats.converged:
            log.warning("frame %d/%d (activation %.3g) did not converge: residual %.3g after %d iterations",
                        k + 1, steps, a, res, stats.iterations)
    seconds = time.perf_counter() - t0
    log.info("GDFE %s: %d cells, %d iterations, residual %.2e, %.3f s", method, design.n_cells, total, res, seconds)
    return Result(design=design, points=V, converged=bool(converged), iterations=total, residual=res,
                  energy=energies[-1], energy_history=np.array(energies), seconds=seconds, frames=frames,
                  activation=acts, frame_iterations=per_frame, method=method, timings=dict(solver.timings))
