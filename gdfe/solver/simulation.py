"""The simulation of a design's shape change: :func:`simulate` and its :class:`Result`.

:func:`simulate` checks its options, picks the method (:func:`gdfe.solver.auto_method`)
and the starting shape (:data:`INITS`), and ramps the contraction over ``steps`` frames,
each solved by one :class:`gdfe.solver.Solver` from the last.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import time

import numpy as np

from gdfe._validation import GdfeError, check_array, check_choice, check_instance, check_int, check_positive
from gdfe.design import Design, check_one_piece
from gdfe.model import as_model
from gdfe.resources import check_run, solve_heap
from gdfe.solver.contact import CONTACT_MODES, Contact, ContactReport, contact_available
from gdfe.solver.methods import METHODS, Solver, auto_method, check_tol
from gdfe.solver.newton import ON_DRIFT, STEP_TOL_FACTOR
from gdfe.solver.penetration import Penetration, PenetrationCheck
from gdfe.solver.starts import flat_start, multilevel_start
from gdfe.solver.threads import side_by_side

__all__ = ["Result", "ConvergenceError", "simulate", "INITS", "MULTILEVEL_CELLS", "CONTACT_LEVELS",
           "CONTACT_LEVEL_TOL", "CONTACT_LEVEL_ITER", "AUTO_CHECK_EVERY", "WATCH_MAX_CELLS", "SHAPE_ACCURACY", "ALTERNATION_TOL",
           "TRUSTED_TOL", "default_tol"]

log = logging.getLogger(__name__)

#: Starting shapes of :func:`simulate` (besides given vertex positions).
INITS = ("auto", "linear", "multilevel", "flat")
#: ``init="auto"`` starts designs above this many cells from a coarsened copy.
MULTILEVEL_CELLS = 20_000
#: A contact solve follows the contraction through at least this many activation levels
#: (the frames count; with fewer frames, levels are added between them): where the film
#: meets itself the shape depends on the path, and the film contracts gradually.
CONTACT_LEVELS = 4
#: Tolerance (units of h) of the added levels: their shapes are only the next level's start.
CONTACT_LEVEL_TOL = 1e-2
#: Iteration limit of an added level, and of the solves that make a start free of
#: self-intersection (the same reason).
CONTACT_LEVEL_ITER = 10
#: ``contact="auto"`` tests every this many iterates of a contact-free Newton solve, and every
#: frame but the last (the penetration check follows it), for self-intersection (the penetration
#: check's crossing test, :meth:`PenetrationCheck.crosses`: 0.2-0.3 s at 10^5 cells, a fifth to a
#: quarter of a Newton iteration there), and solves with contact as soon as one crosses itself,
#: without finishing the contact-free solve.
AUTO_CHECK_EVERY = 4
#: Above this many cells ``contact="auto"`` does not test during the solve, only the solved shape
#: (the penetration check, which leads to the contact solve as before): the check's set-up, made
#: beside the solver's arrays for the tests, would hold its topology (vertex pairs, the cells of
#: each vertex; 0.7 GiB at 10^6 cells) at the solve's peak. (When the tests were the IPC Toolkit's,
#: its collision mesh, about 2 KiB per cell, set the 10^6-cell corrugation's peak: 8.6 GiB against 6.4.)
WATCH_MAX_CELLS = 200_000
#: With ``tol=None`` a Newton solve stops when its estimated distance to the solution is below
#: this fraction of the part's size (the diagonal of the flat print's bounding box): far below
#: what a printer or a scan resolves, far above round-off (the stopping study, ``gdfe study
#: stopping``, measures the shape's change against ``tol``).
SHAPE_ACCURACY = 1e-6
#: ``tol`` of the alternation methods when none is given (units of h): their plain step
#: underestimates the distance to the solution, so they get no size-scaled test.
ALTERNATION_TOL = 1e-7
#: The loosest ``tol`` (units of h) whose solves the stopping study (``gdfe study stopping``,
#: its ``TIGHT``) finds within the accuracy they asked for; looser ones can stop far from the
#: solution while their test passes. :func:`simulate` warns above it; the command line refuses.
TRUSTED_TOL = 1e-4


def default_tol(design, method):
    """The ``tol`` (units of h) that ``tol=None`` gives ``method`` on ``design``.

    Newton methods: :data:`SHAPE_ACCURACY` times the part's size, over
    ``STEP_TOL_FACTOR * h`` (their stopping test asks the estimated distance to the solution
    to be below ``STEP_TOL_FACTOR * tol * h``); the alternation methods: :data:`ALTERNATION_TOL`.
    ``"auto"`` is the method :func:`~gdfe.solver.auto_method` picks for ``design``.
    """
    method = check_choice("method", method, METHODS)
    if method == "auto":
        method = auto_method(design)
    if not method.startswith("newton"):
        return ALTERNATION_TOL
    size = float(np.linalg.norm(np.ptp(design.mesh.points, axis=0)))
    return SHAPE_ACCURACY * size / (STEP_TOL_FACTOR * design.h)


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
        Newton steps (``"newton"``), the multilevel start (``"start"``), the penetration
        checks (``"penetration_check"``, with ``contact="auto"``'s crossing tests, and with the check's
        set-up where it is made after the solve, not beside the multilevel start), and with
        contact the barrier (``"barrier"``),
        collision detection (``"ccd"``) and the contact-free solve that came first
        (``"contact_free_solve"``, ``contact="auto"``).
    penetration : Penetration
        The penetration check of the final shape (:func:`gdfe.solver.check_penetration`).
    contact : ContactReport
        Whether the solve used self-contact, why, and with which gap.
    frame_penetration : list of Penetration
        The check of every frame after the flat print.
    tol : float
        The tolerance the solve ran with (units of h; :func:`default_tol` when none was given).
    error_estimate_mm : float or None
        The Newton methods' estimated distance of the last frame from the exact minimiser,
        rigid motions left out [mm] (None for the alternation methods).
    drift : dict or None
        The first frame whose Newton solve drifted between near-equal states
        (:attr:`gdfe.solver.SolveStats.drift`, with its ``frame``); None when none did.
    newton_steps : list of gdfe.solver.newton.NewtonStep
        Every Newton step of the last frame's solve: its residual, length, fraction taken, damping,
        CG iterations, the quadratic model's agreement and seconds (empty for the alternation);
        :func:`gdfe.solver.newton.convergence_rates` gives its contractions.
    device : str
        Where the solve's array work ran, ``"cpu"`` or ``"gpu"`` (``device="auto"``'s choice, see
        :func:`simulate`).
    start_levels : list of gdfe.solver.starts.StartLevel
        The levels of the first frame's multilevel start (``init="multilevel"``), the coarsest first:
        each one's cells, iterations, residual and seconds; empty for the other starts and where the
        returned frames were solved with contact.
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
    penetration: Penetration = None
    contact: ContactReport = None
    frame_penetration: list = dataclasses.field(default_factory=list)
    tol: float = None
    error_estimate_mm: float = None
    drift: dict = None
    newton_steps: list = dataclasses.field(default_factory=list)
    start_levels: list = dataclasses.field(default_factory=list)
    device: str = "cpu"

    @property
    def penetrates(self) -> bool:
        """Whether any frame passes through itself (:attr:`frame_penetration`)."""
        return any(p.found for p in self.frame_penetration)

    def check(self):
        """Raise :class:`ConvergenceError` unless the solve converged; return self."""
        if not self.converged:
            raise ConvergenceError(
                f"GDFE solve did not converge: residual {self.residual:.3g} after "
                f"{self.iterations} iterations ({self.method})")
        return self

    def summary(self) -> dict:
        """The numbers of the result for JSON: convergence, cost, and the penetration check.

        ``newton_steps`` and ``start_levels`` are :attr:`newton_steps` and :attr:`start_levels` as dicts
        (the levels without their steps). ``penetration_mm`` is the deepest self-penetration of any frame (0 when none),
        ``contact`` whether the solve used self-contact; ``penetration`` and
        ``contact_info`` give the details (:meth:`Penetration.as_dict`,
        :meth:`ContactReport.as_dict`).
        """
        out = {"converged": bool(self.converged), "iterations": int(self.iterations),
               "residual": float(self.residual), "energy": float(self.energy),
               "seconds": float(self.seconds), "n_elements": int(self.design.n_cells),
               "n_points": int(self.design.mesh.n_points), "method": self.method,
               "frames": len(self.frames), "device": self.device,
               "tol": None if self.tol is None else float(self.tol),
               "error_estimate_mm": None if self.error_estimate_mm is None else float(self.error_estimate_mm),
               "drift": self.drift, "newton_steps": [s.as_dict() for s in self.newton_steps],
               "start_levels": [lv.as_dict(steps=False) for lv in self.start_levels]}
        if self.penetration is not None:
            depth = max((p.depth_mm for p in self.frame_penetration), default=self.penetration.depth_mm)
            out["penetration_mm"] = float(depth)
            out["penetration"] = {**self.penetration.as_dict(), "frames_penetrating": int(
                sum(p.found for p in self.frame_penetration))}
        if self.contact is not None:
            out["contact"] = bool(self.contact.used)
            out["contact_info"] = self.contact.as_dict()
        return out

    def to_meshio(self, frame=-1):
        """The film of one frame as a ``meshio.Mesh`` (needs meshio).

        Parameters
        ----------
        frame : int
            Frame of the contraction ramp (``-1``: the final shape, ``0``: the flat print).

        Returns
        -------
        meshio.Mesh
            The hexahedra at the frame's points [mm]; cell data ``material``, ``R`` and ``layer``,
            point data ``displacement`` [mm] from the flat print, and ``field_data`` naming the
            material codes (``material_rigid``: ``[0]``, ...; :func:`gdfe.io.material_field_data`).
        """
        from gdfe.io import hex_meshio

        nf = len(self.frames)
        if not isinstance(frame, (int, np.integer)) or isinstance(frame, bool) or not -nf <= frame < nf:
            raise GdfeError(f"frame: expected an integer in [{-nf}, {nf - 1}] (the result has {nf} frames), "
                            f"got {frame!r}")
        points = np.asarray(self.frames[frame], float)
        return hex_meshio(points, self.design, {"displacement": points - self.design.mesh.points})

    def to_pyvista(self, frame=-1):
        """The film of one frame as a ``pyvista.UnstructuredGrid`` (needs pyvista and meshio): the
        mesh of :meth:`to_meshio`, its cell, point and field data included."""
        import pyvista

        mesh = self.to_meshio(frame)
        grid = pyvista.from_meshio(mesh)
        for name, value in mesh.field_data.items():  # pyvista.from_meshio leaves field data out
            grid.field_data[name] = value
        return grid


def simulate(design, *, method="auto", init="auto", steps=1, tol=None, max_iter=None,
             history=6, seed=0, model=None, process=None, contact="auto", dhat=None, on_drift="warn",
             device="auto"):
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
    tol : float, optional
        Convergence tolerance on the fixed-point residual (largest vertex move of one
        plain iteration, in units of the film thickness h). The Newton methods also need
        their estimated distance to the solution, rigid motions left out, below
        ``gdfe.solver.STEP_TOL_FACTOR * tol`` (h). Default (:func:`default_tol`): for the
        Newton methods the distance below :data:`SHAPE_ACCURACY` times the part's size
        (a 1 mm hinge: a few nm; a 100 mm sheet: 0.1 um); for the alternation
        :data:`ALTERNATION_TOL`. Give the shape accuracy you need as
        ``tol = accuracy_mm / (STEP_TOL_FACTOR * h)``.
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
    process : dict, optional
        The part's process variables for the model's process mechanisms (``partial_activation``,
        ``batch``), e.g. ``{"T_C": 150}``.
    device : {"auto", "cpu", "gpu"}
        Where ``method="newton-cg"`` runs its Hessian products, preconditioner and polar
        decompositions (:mod:`gdfe.solver.device`): ``"auto"`` (default) the GPU where CuPy
        (``pip install -e ".[gpu]"``) sees one, else the CPU; ``"gpu"`` without one is refused.
    contact : {"auto", "on", "off"}
        Self-contact, which keeps the film from passing through itself
        (:mod:`gdfe.solver.contact`; needs the IPC Toolkit, ``pip install 'gdfe[contact]'``).
        ``"auto"`` (default): the contact-free solve, checked for self-penetration on
        every frame, and solved again with contact only when it penetrates - so nothing
        slows down where nothing touches, and nothing that passes through itself is
        returned as an answer while contact is installed. The contact-free Newton solve is
        tested for self-intersection every :data:`AUTO_CHECK_EVERY` iterations and at the end
        of every frame but the last (designs of at most :data:`WATCH_MAX_CELLS` cells), and stops
        at the first that crosses itself: the contact solve then starts at once, and its result
        is that of ``"on"``. ``"on"``: every frame with
        contact. ``"off"``: no contact; a result that penetrates itself is logged as a
        warning. Every result carries the check (:attr:`Result.penetration`). A contact
        solve uses a Newton method (``"auto"``'s choice where ``method`` is an
        alternation; ``contact="on"`` with an alternation is an error) and follows the
        contraction through at least :data:`CONTACT_LEVELS` levels.
    dhat : float, optional
        Gap [mm] within which the contact barrier acts (default
        :func:`gdfe.solver.contact.default_dhat`, 0.1 h or less on fine meshes).
    on_drift : {"warn", "stop"}
        A design with several equilibria close in energy (a sheet that buckles) can keep a
        Newton solve moving between them, the energy changing in its 6th digit: the solve
        then logs a warning and records it in :attr:`Result.drift` and goes on
        (``"warn"``, default) or stops there, not converged (``"stop"``); see
        :func:`gdfe.solver.newton.solve_newton`.

    Returns
    -------
    Result
        Check ``result.converged`` (or call ``result.check()``): a solve that hit
        ``max_iter`` is returned with ``converged=False`` and logged as a warning; and
        ``result.penetration`` (or ``result.penetrates``).

    Notes
    -----
    A design whose rotations (a 3 x 3 matrix of doubles per vertex or cell) exceed 32 MiB, from
    about 2.3*10^5 cells in one layer, is solved with C's ``malloc`` serving arrays of that size from
    its heap, reused (:func:`gdfe.resources.solve_heap`): the same arithmetic, 10-14 % shorter at 10^6
    cells (docs/solver_history.md).

    With contact the shape depends on the path as well as on the design: two flaps that
    meet can end either way round, and two ends that meet head-on can stop there (a local
    minimum of the energy). The contact solve follows the activation ramp, as the film
    contracts when heated; a design symmetric about the place where it meets itself stays
    symmetric up to round-off, and may stop where a real part, never quite symmetric,
    would slide on.
    """
    method = check_choice("method", method, METHODS)
    check_instance("design", design, Design)
    check_one_piece(design)
    if model is not None:
        design = as_model(model).apply(design, process)
    contact = check_choice("contact", contact, CONTACT_MODES)
    if dhat is not None:
        dhat = float(check_positive("dhat", dhat))
    requested = method
    if method == "auto":
        method = auto_method(design)
    if contact == "on" and not method.startswith("newton"):
        raise GdfeError(f"contact: the contact solve needs a Newton method ('auto', 'newton' or 'newton-cg'), "
                        f"got method={requested!r}")
    if isinstance(init, str):
        init = check_choice("init", init, INITS)
        if init == "auto":
            init = "multilevel" if design.n_cells > MULTILEVEL_CELLS else "linear"
        start = None
    else:
        start = check_array("init", init, shape=design.mesh.points.shape)
        init = "given"
    steps = check_int("steps", steps)
    est = check_run(design, steps)  # a run whose memory estimate exceeds the machine's is refused (gdfe.resources)
    if est.large:  # the command line asks for --large first; a library call is told what it started
        log.warning("this run is large: %s (an estimate, gdfe.resources)", est.text())
    if max_iter is None:
        max_iter = 200 if method.startswith("newton") else 5000
    max_iter = check_int("max_iter", max_iter)
    history = check_int("history", history)
    tol = default_tol(design, method) if tol is None else check_tol(tol)
    if tol > TRUSTED_TOL:
        log.warning("tol = %g is looser than %g (units of h): such a solve can stop far from the shape while its "
                    "test passes (gdfe study stopping), so converged=True means only that the test passed",
                    tol, TRUSTED_TOL)
    on_drift = check_choice("on_drift", on_drift, ON_DRIFT)
    from gdfe.solver.device import resolve

    resolve(device)  # a bad name, or "gpu" without one, is refused before the set-up
    with solve_heap(design):  # a large solve's arrays reused from the C heap, not mapped afresh at every use
        return _solve_and_check(design, method, contact, dhat, init, start, steps, tol, max_iter, history, seed,
                                on_drift, device)


def _solve_and_check(design, method, contact, dhat, init, start, steps, tol, max_iter, history, seed, on_drift,
                     device):
    """:func:`simulate` after its arguments are checked: the frames solved, checked for self-penetration,
    solved again with contact where ``contact="auto"`` finds a crossing, and the :class:`Result`."""
    t0 = time.perf_counter()
    solver = Solver(design, device=device)
    acts = np.linspace(0.0, 1.0, steps + 1)
    opts = dict(init=init, start=None if start is None else (start, float(acts[1])), seed=seed, tol=tol,
                max_iter=max_iter, history=history, on_drift=on_drift)
    term = Contact(design, dhat) if contact == "on" else None
    available = contact_available()
    watch = _Watch(design) if contact == "auto" and available else None
    timings = {}
    try:
        run = _run_frames(solver, acts, method, term,
                          monitor=watch if design.n_cells <= WATCH_MAX_CELLS else None, **opts)
    except _Crossed as stop:
        run, pens, t_check, crossed = None, [], 0.0, stop.reason
    else:
        pens, t_check = _check_frames(solver, run.frames, watch, known=None if watch is None else watch.frames)
        crossed = None
        if any(p.found for p in pens):
            worst = max(pens, key=lambda p: p.depth_mm)
            crossed = f"the contact-free solve penetrated itself ({worst.depth_mm:.3g} mm)"
    if watch is not None:
        t_check += watch.seconds
    report = ContactReport(mode=contact, used=term is not None, available=available,
                           reason="contact='on'" if term is not None else "")
    if contact == "auto" and crossed:
        if available:
            log.info("the contact-free solve passes through itself (%s); solving again with contact", crossed,
                     extra={"progress": {"event": "contact"}})
            timings["contact_free_solve"] = time.perf_counter() - t0
            term = Contact(design, dhat)
            cmethod = method if method.startswith("newton") else auto_method(design)
            if cmethod != method:
                log.info("contact solve with method=%r (the contact solve needs a Newton method)", cmethod)
            method = cmethod
            run = _run_frames(solver, acts, method, term, **opts)
            pens, t2 = _check_frames(solver, run.frames, watch)
            t_check += t2
            report = ContactReport(mode=contact, used=True, available=True, reason=crossed)
        else:
            report = ContactReport(mode=contact, used=False, available=False,
                                   reason="the contact-free solve penetrates itself but the IPC Toolkit is not "
                                          "installed: pip install 'gdfe[contact]'")
    if term is not None:
        report = dataclasses.replace(report, dhat_mm=term.dhat, stiffness=term.stiffness,
                                     pairs=run.contact_pairs, barrier_energy=run.contact_energy)
    if any(p.found for p in pens):
        worst = max(pens, key=lambda p: p.depth_mm)
        log.warning("the simulated shape passes through itself: %d crossing face pairs, %d cells, %.3g mm deep%s",
                    worst.intersecting_pairs, worst.penetrated_cells, worst.depth_mm,
                    "" if term is not None else
                    ("; simulate with contact='on' (or 'auto')" if report.available
                     else "; install the IPC Toolkit for contact: pip install 'gdfe[contact]'"))
    seconds = time.perf_counter() - t0
    timings.update(solver.timings)
    timings["penetration_check"] = t_check
    if term is not None:
        timings.update(term.timings)
    log.info("GDFE %s: %d cells, %d iterations, residual %.2e, %.3f s%s", method, design.n_cells, run.total,
             run.residual, seconds, ", with contact" if term is not None else "")
    return Result(design=design, points=run.frames[-1], converged=bool(run.converged), iterations=run.total,
                  residual=run.residual, energy=run.energies[-1], energy_history=np.array(run.energies),
                  seconds=seconds, frames=run.frames, activation=acts, frame_iterations=run.per_frame,
                  method=method, timings=timings, penetration=pens[-1], contact=report, frame_penetration=pens,
                  tol=tol, error_estimate_mm=None if run.error_estimate is None else run.error_estimate * design.h,
                  drift=run.drift, newton_steps=run.newton_steps, start_levels=run.start_levels,
                  device=solver.device)


class _Crossed(Exception):
    """Raised by :class:`_Watch` to end a contact-free solve that crosses itself; ``reason`` says where."""

    def __init__(self, reason):
        super().__init__(reason)
        self.reason = reason


class _Watch:
    """The self-intersection test of ``contact="auto"`` on a contact-free run (see :data:`AUTO_CHECK_EVERY`).

    Called with the frame, the Newton iteration (None at the end of a frame) and the shape;
    raises :class:`_Crossed` when the shape's boundary surface crosses itself: the crossing test
    of the penetration check (:meth:`PenetrationCheck.crosses`), whose set-up the check after the
    solve then uses (:func:`_check_frames`). At the end of a frame the shape is the frame's own, so
    it gets the whole check there, kept in :attr:`frames` for the check after the solve. Above
    :data:`WATCH_MAX_CELLS` cells :func:`simulate` does not hand it to the solve.

    The IPC Toolkit's collision mesh, which the contact solve needs, is not made for the test:
    its making holds Python's interpreter lock (about 0.5 s at 10^5 cells, nearly all of it), and
    made beside the multilevel start it stopped the start for that long.
    """

    def __init__(self, design):
        self.design = design
        self._check = None
        self.seconds = 0.0
        self.frames = {}  # frame -> its Penetration, for the frames checked at their end

    def check(self) -> PenetrationCheck:
        """The :class:`PenetrationCheck` of the tests (made now where none is kept)."""
        if self._check is None:
            self._check = PenetrationCheck(self.design)
        return self._check

    def __call__(self, frame, iteration, V):
        if iteration is not None and iteration % AUTO_CHECK_EVERY:
            return
        t0 = time.perf_counter()
        if iteration is None:
            self.frames[frame] = self.check()(V)
            crosses = self.frames[frame].intersecting_pairs > 0
        else:
            crosses = self.check().crosses(V)
        self.seconds += time.perf_counter() - t0
        if crosses:
            where = "at the end of frame %d" % frame if iteration is None else \
                "at iteration %d of frame %d, where it stopped" % (iteration, frame)
            raise _Crossed(f"the contact-free solve crossed itself {where}")


@dataclasses.dataclass(frozen=True, eq=False)
class _FrameRun:
    """The frames of one run of the ramp (what :func:`simulate` makes its :class:`Result` from)."""

    frames: list
    converged: bool
    total: int
    residual: float
    energies: list
    per_frame: list
    contact_pairs: int = 0
    contact_energy: float = 0.0
    error_estimate: float = None
    drift: dict = None
    newton_steps: list = dataclasses.field(default_factory=list)
    start_levels: list = dataclasses.field(default_factory=list)


def _check_frames(solver, frames, watch=None, known=None):
    """The penetration check of every frame after the flat print, and the seconds it took with its set-up.

    ``known`` (frame -> :class:`Penetration`, :attr:`_Watch.frames`): the frames of these ``frames``
    that the watch checked at their end, not checked again.

    The check is made once: by ``watch`` (a :class:`_Watch`) where its tests made it during the
    solve, else here (kept by the watch where there is one). The solver's caches are dropped first
    (:meth:`Solver.drop_caches`), after the contact solve too: a check made here need not hold its
    topology (vertex pairs, the cells of each vertex; 0.7 GiB at 10^6 cells) beside the solver's
    largest arrays. Above :data:`WATCH_MAX_CELLS` cells the watch tests nothing during the solve, so
    the check is always made here.
    """
    solver.drop_caches()
    design = solver.design
    t0 = time.perf_counter()
    log.debug("checking self-penetration: %d cells, %d frames", design.n_cells, len(frames) - 1,
              extra={"progress": {"event": "check", "frame": None, "frames": len(frames) - 1}})
    check = watch.check() if watch is not None else PenetrationCheck(design)
    pens = []
    for k, V in enumerate(frames[1:]):
        log.debug("checking self-penetration: frame %d/%d", k + 1, len(frames) - 1,
                  extra={"progress": {"event": "check", "frame": k + 1, "frames": len(frames) - 1}})
        pens.append(known[k + 1] if known and k + 1 in known else check(V))
    return pens, time.perf_counter() - t0


def _first_start(solver, design, init, start, seed, a, beside=None, record=None):
    """The starting shape of the first frame, at activation ``a``.

    ``start`` is a given shape with the activation it is meant for, ``(V, a_start)``: at a
    lower ``a`` it is taken that fraction of the way from the flat print. ``beside``, a
    function of no arguments, runs beside the multilevel start on the solver's second thread
    (:func:`gdfe.solver.threads.side_by_side`): the set-up of the solve that follows. ``record``,
    a list, is given the multilevel start's levels (:func:`gdfe.solver.starts.multilevel_start`).
    """
    V = design.mesh.points.copy()
    if init == "linear":
        return solver.linearised_start(V, a)
    if init == "multilevel":
        t_start = time.perf_counter()
        V, _ = side_by_side(lambda: multilevel_start(design, a, record), beside or (lambda: None))
        solver.timings["start"] = solver.timings.get("start", 0.0) + time.perf_counter() - t_start
        return V
    if init == "given":
        V0, a_start = start
        return V0.copy() if a >= a_start else V + (a / a_start) * (V0 - V)
    return flat_start(design, seed)


def _prepare(solver, method, a, monitor):
    """What the first frame's solve and ``monitor`` (a :class:`_Watch`, or None) make on first use from the mesh alone."""
    solver.prepare(method, a)
    if isinstance(monitor, _Watch):
        monitor.check()


def _clear_start(solver, term, init, start, seed, a, method, max_iter, depth=0):
    """A start at activation ``a`` free of self-intersection, and the iterations it took.

    The first-frame start of ``init`` if it is clear; else the contact solution at ``a / 2``
    (recursively) from the start of ``init`` there (a given shape is meant for the first
    frame: at a fraction of its activation, the same fraction of its displacement from the
    flat print), down to the flat print's own start, which is flat and clear.
    """
    design = solver.design
    V = _first_start(solver, design, init, start, seed, a)
    if term.is_clear(V):
        return V, 0
    if depth >= 6:
        V = flat_start(design, seed)
        if not term.is_clear(V):
            raise GdfeError("contact: the flat print itself is not free of self-intersection")
        return V, 0
    Vh, its = _clear_start(solver, term, init, start, seed, 0.5 * a, method, max_iter, depth + 1)
    stats = solver.solve(Vh, 0.5 * a, method=method, tol=CONTACT_LEVEL_TOL,
                         max_iter=min(max_iter, CONTACT_LEVEL_ITER), contact=term)
    return stats.points, its + stats.iterations


def _run_frames(solver, acts, method, term, *, init, start, seed, tol, max_iter, history, on_drift="warn",
                monitor=None):
    """Solve every frame of the ramp ``acts``, each from the last (with contact: through added levels).

    ``monitor`` (contact-free runs): called as ``monitor(frame, iteration, V)`` with every
    accepted Newton iterate and (``iteration`` None) every frame; see :class:`_Watch`.
    """
    design = solver.design
    V = design.mesh.points.copy()
    frames = [V.copy()]
    converged, total, res, energies, per_frame = True, 0, 0.0, [], []
    stats, drift = None, None
    levels_made = []  # the first frame's multilevel start, level by level
    for k, a in enumerate(acts[1:]):
        frame_its = 0
        log.debug("frame %d/%d: activation %.3g%s", k + 1, len(acts) - 1, a, "" if term is None else ", with contact",
                  extra={"progress": {"event": "frame", "frame": k + 1, "frames": len(acts) - 1}})
        if term is None:
            if k == 0:
                V = _first_start(solver, design, init, start, seed, a, beside=functools.partial(
                    _prepare, solver, method, a, monitor), record=levels_made)
            watch = None if monitor is None else functools.partial(monitor, k + 1)
            stats = solver.solve(V, a, method=method, tol=tol, max_iter=max_iter, history=history,
                                 on_drift=on_drift, monitor=watch)
            if monitor is not None and k + 2 < len(acts):  # the last frame: the penetration check follows
                monitor(k + 1, None, stats.points)
        else:
            a_prev = acts[k]
            n_levels = max(1, int(np.ceil(CONTACT_LEVELS * (a - a_prev) - 1e-9)))
            if k == 0 and init == "given":  # a given start is meant for this frame
                n_levels = 1
            levels = np.linspace(a_prev, a, n_levels + 1)[1:]
            for j, b in enumerate(levels):
                if k == 0 and j == 0:
                    V, its = _clear_start(solver, term, init, start, seed, b, method, max_iter)
                    frame_its += its
                last = j == len(levels) - 1
                stats = solver.solve(V, b, method=method, tol=tol if last else CONTACT_LEVEL_TOL,
                                     max_iter=max_iter if last else min(max_iter, CONTACT_LEVEL_ITER), contact=term,
                                     on_drift=on_drift)
                V = stats.points
                if not last:
                    frame_its += stats.iterations
        V, res = stats.points, stats.residual
        converged &= stats.converged
        frame_its += stats.iterations
        total += frame_its
        per_frame.append(frame_its)
        log.debug("frame %d/%d: %d iterations, residual %.2e", k + 1, len(acts) - 1, frame_its, res,
                  extra={"progress": {"event": "frame solved", "frame": k + 1, "frames": len(acts) - 1}})
        energies.extend(stats.energies)
        frames.append(V.copy())
        if drift is None and stats.drift is not None:
            drift = {"frame": k + 1, **stats.drift}
        if not stats.converged:
            log.warning("frame %d/%d (activation %.3g) did not converge: residual %.3g after %d iterations",
                        k + 1, len(acts) - 1, a, res, stats.iterations)
    return _FrameRun(frames=frames, converged=bool(converged), total=total, residual=res, energies=energies,
                     per_frame=per_frame, contact_pairs=stats.contact_pairs, contact_energy=stats.contact_energy,
                     error_estimate=stats.error_estimate, drift=drift, newton_steps=list(stats.newton_steps),
                     start_levels=levels_made)
