"""The benchmark (``gdfe bench``): GDFE's speed, against its own lower bound and the reference FEM.

A benchmark, not a timed test: every number is a median of repeated runs in one process
(a sheet of 500 000 cells or more runs once), on this machine (its core count and load are
recorded with the results). Sections:

1. **Figure 6 hinges** (L = 1, 1.6, 2.6 mm, d = 0.33 mm, h = 0.29 mm, default resolution):
   iterations and seconds to convergence of the accelerated solvers (damped Newton with
   CG steps, the default; damped Newton with a factorised Hessian) beside Anderson mixing
   and the paper's plain alternation.
2. **Sheets from a PNG mask** at 10^3, 10^4, 10^5 cells (``--sizes`` for others, e.g.
   10^6): seconds to convergence with ``method="auto"``, peak memory (the maximum resident
   set size of a child process that runs only that size, over its first run, Python and the
   libraries included, beside that child's resident size before the solve), and the time per
   iteration split into orientation, assembly and Newton-step linear algebra.
3. **The lower bound per iteration**, measured standalone on each sheet: one solve with
   the prefactorised n x n matrix for three right-hand sides (the fastest of the
   factorisations of section 4 that fit in memory; where none does, the multigrid's CG to
   1e-11, which is also recorded beside a factor's solve) plus one batched SVD over all
   cells. Our local-global iteration (one orientation step, one assembly step) is timed the
   same way, and the ratio stated; so is the time per outer iteration of the solver used.
4. **Sparse factorisation by measurement**: factorisation and three-column solve of the
   n x n matrix (and of the 3n x 3n Newton Hessian up to 10^4 cells) with each backend
   installed: SciPy's SuperLU, CHOLMOD through scikit-sparse or CVXOPT, cholespy.
5. **GDFE against the nonlinear reference FEM** on the Figure 6 hinge of L = 1.6 mm at
   equal fold-angle error, both folds measured on the outer half of the panels
   (:data:`FOLD_PANEL_FRACTION`): each model's limit is extrapolated by Richardson over
   three levels refined by 2 (the FEM's :data:`FEM_REFERENCE_SIZES`, halving size, layers
   and junction), a level's error is its distance from that limit, GDFE's R is set so
   that its fold is the FEM's limit (GDFE with Eq. 3's R is timed beside), each model's
   time at the relative errors :data:`FEM_ERROR_LEVELS` is interpolated log-log between
   the levels around it (extrapolated along its finest three levels, and flagged, where
   it does not get there), and the ratio of the times is taken at each.

The accelerated solver is ``method="auto"``, the default (``"newton-cg"`` above 64 cells);
``method="newton"``, which factorises the 3n x 3n Hessian, is timed beside it.

The sheet is a corrugation mask: stripes of hinge (0.6 mm every 2 mm along x) alternately
free on the top and on the bottom face between panels coated on both faces, pixel 0.1 mm,
one cell through h = 0.29 mm, R = 0.7. It folds into a zig-zag across the whole sheet.
The stripes also shrink along y while the panels do not, so the sheet cannot stay
developable: it buckles along the stripes, and several buckled states lie within 2e-5 of
each other in energy. Most Newton iterations on the large sheets go into that choice.
Sheets above ``gdfe.solver.MULTILEVEL_CELLS`` cells start from the solution of the design
coarsened 2 x 2 (``init="multilevel"``); its coarse levels are timed in the total and
shown as "start s". On the 10^5 sheet both starts reach the same buckled state (energy
6.552702e-2); how other starts can end elsewhere is in docs/solver.md ("How a large design is
solved").

Factorisation choice (``gdfe.solver.FACTOR_BACKENDS``): CHOLMOD when scikit-sparse or
CVXOPT is installed, else SuperLU; section 4 measures why, on the machine it runs on (the last
results: docs/solver.md, "Where it stands").

Each goal gets a verdict: MET or NOT MET by the medians; **MARGINAL** where the medians meet it
but the verdict differs between each sheet's fastest and slowest runs (for the exponent, between the
least and greatest exponent the runs of each size allow, :func:`_exponent_span`), so that it is
within the machine's noise; STATED where a number is given without a limit (the exponent over
fewer sizes than 10^3 to 10^6); n/a where the run did not include it; NOT MEASURED for the GPU
goal without a GPU.

:func:`run` returns the results as a JSON-ready dict, :func:`format_table` prints them and
:func:`plot` draws time against element count; the study ``bench-scaling``
(:mod:`studies.bench_scaling`) and the command ``gdfe bench`` call them.
"""

from __future__ import annotations

import logging
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_choice
from gdfe.calibration import Calibration
from gdfe.paper import FIG6_D, FIG6_LENGTHS, H
from gdfe.solver.newton import NewtonStep, convergence_rates
from studies._common import error_against_finest, median_time

__all__ = ["run", "format_table", "plot", "mask_sheet", "write_mask_pngs", "SETTINGS", "FEM_LEVELS"]

log = logging.getLogger(__name__)

#: The hinge of the FEM comparison: (L, d) [mm], strip width and panel length [mm].
FEM_HINGE = (1.6, FIG6_D)
FEM_WIDTH = 1.0
FEM_PANEL = 2.0
#: Reference-FEM mesh levels: (size cap [mm], elements per hinge length, layers per ply,
#: z growth, junction element / size); the last is the reference.
FEM_LEVELS = (
    (0.5, 2, 2, 1.5, 1 / 4),
    (0.35, 4, 2, 2.0, 1 / 8),
    (0.25, 4, 3, 2.0, 1 / 8),
    (0.125, 8, 4, 2.0, 1 / 16),
)
#: The FEM family of the comparison: (element size [mm], layers per ply); every level has its
#: junction elements FEM_JUNCTION times its size and its layers graded by FEM_GRADING
#: (thickest / thinnest) per ply, so the sizes 0.5, 0.25, 0.125 halve every dimension.
FEM_FAMILY = ((0.5, 2), (0.354, 3), (0.25, 4), (0.177, 6), (0.125, 8))
FEM_GRADING = 4.0
FEM_JUNCTION = 1 / 8
#: The FEM levels its reference limit is extrapolated from (refined by 2).
FEM_REFERENCE_SIZES = (0.5, 0.25, 0.125)
#: Relative fold-angle errors the two models' times are compared at.
FEM_ERROR_LEVELS = (1e-2, 3e-3, 1e-3)
#: Both models' fold: the turn between the rigid frames of this outer part of each panel.
FOLD_PANEL_FRACTION = 0.5
#: The Figure 8 patterns timed beside the corrugation at 10^5 cells, and the one at 10^6 (the
#: dome: a disc of film, an outline as real masks have).
FREEFORM = ("fig08-twist", "fig08-dome", "fig08-saddle")
FREEFORM_BIG = ("fig08-dome",)
DESIGNS = ("corrugation",) + FREEFORM
#: Above this many cells the benchmark does not ask SuperLU for a factorisation (it does not
#: fit in 24 GiB at 10^6 cells).
SUPERLU_MAX_CELLS = 300_000
#: Above this many cells it asks for no factorisation of the n x n matrix at all, and the bound's
#: solve is the multigrid's: CHOLMOD's factor of the 4*10^6-cell sheet, made beside that sheet's
#: solver, was killed for want of memory on 23.5 GiB (docs/solver_history.md, 4*10^6 cells).
FACTOR_MAX_CELLS = 2_000_000
SHEET_PIXEL = 0.1
SHEET_R = 0.7
SHEET_PERIOD = 2.0
SHEET_HINGE = 0.6

SETTINGS = {
    "full": {"hinge_lengths": FIG6_LENGTHS, "hinge_cells": 16, "repeats": 3, "plain_max_iter": 3000,
             "sheet_sizes": (1_000, 10_000, 100_000), "sheet_repeats": 3, "big_repeats": 1,
             "big": 500_000, "hessian_max": 10_000, "fem": True, "gdfe_levels": (4, 8, 16, 32, 64),
             "gdfe_reference": None, "fem_levels": tuple(range(len(FEM_FAMILY))),
             "freeform_sizes": (100_000,), "freeform": FREEFORM, "freeform_big": FREEFORM_BIG},
    "quick": {"hinge_lengths": (1.0,), "hinge_cells": 4, "repeats": 1, "plain_max_iter": 100,
              "sheet_sizes": (64, 144, 256), "sheet_repeats": 1, "big_repeats": 1, "big": 50_000,
              "hessian_max": 256, "fem": False, "gdfe_levels": (2, 4, 8), "gdfe_reference": None, "fem_levels": (),
              "freeform_sizes": (256,), "freeform": ("fig08-dome",), "freeform_big": FREEFORM_BIG},
}

GOALS = {
    "hinges": "Figure 6 hinges: <= 50 iterations and <= 0.1 s each at default resolution",
    "fem": ">= 20x faster than the nonlinear reference FEM at equal relative fold error on the same fold, "
           "at 1e-2, 3e-3 and 1e-3",
    "sheet": "10^5-cell sheets converged in <= 40 lower-bound iterations' time (bound: 3-column solve + batched SVD)",
    "sheet_1e6": "10^6-cell sheets converged in <= 60 lower-bound iterations' time, peak memory <= 6 GiB",
    "lower_bound": "time per iteration within 2x of the lower bound (solve + batched SVD)",
    "growth": "cost growth: fitted exponent of time against cell count, <= 1.1 from 10^3 to 10^6 cells",
    "newton": "the 10^5-cell Figure 8 twist in <= 8 Newton iterations, its last full step under a tenth of the one "
              "before",
    "gpu": "on a GPU: 10^6 cells <= 10 s (optional)",
}
#: Limits of the goals above.
HINGE_SECONDS = 0.1
HINGE_ITERATIONS = 50
SHEET_BOUND_ITERATIONS = {"sheet": 40, "sheet_1e6": 60}
#: The exponent of time against cells, fitted over corrugation sheets from at most GROWTH_SPAN[0] to at
#: least GROWTH_SPAN[1] cells (below that span the exponent is stated, not judged).
GROWTH_EXPONENT = 1.1
GROWTH_SPAN = (2_000, 500_000)
TWIST_ITERATIONS = 8
#: The twist's last full step against the one before it, at most (a contraction that falls: superlinear).
TWIST_LAST_CONTRACTION = 0.1
#: The GPU goal's limit [s] on the 10^6-cell corrugation.
GPU_SECONDS = 10.0
SHEET_1E6_MIB = 6 * 1024
FEM_RATIO = 20.0


# -- the mask sheet ---------------------------------------------------------------------------
def mask_sheet(n_cells, pixel=SHEET_PIXEL, period=SHEET_PERIOD, hinge=SHEET_HINGE):
    """Top and bottom masks of a square corrugation sheet of about ``n_cells`` pixels.

    Returns
    -------
    top, bottom : (s, s) bool arrays
        True where passive material is printed; ``s = round(sqrt(n_cells))``. Along x, a
        hinge stripe of width ``hinge`` starts every ``period`` mm, free on the top face
        (bottom coated) for even stripes and on the bottom face for odd ones.
    """
    s = max(2, int(round(np.sqrt(n_cells))))
    x = (np.arange(s) + 0.5) * pixel
    stripe = np.floor(x / period).astype(int)
    in_hinge = np.mod(x, period) < hinge
    up = in_hinge & (stripe % 2 == 0)
    down = in_hinge & (stripe % 2 == 1)
    top = np.repeat((~up)[:, None], s, axis=1)
    bottom = np.repeat((~down)[:, None], s, axis=1)
    return top, bottom


def write_mask_pngs(directory, top, bottom, film=None):
    """Write masks as PNGs (black = passive material or film, row 0 at the largest y); return their paths.

    Returns ``(top, bottom)``, or ``(top, bottom, film)`` with a ``film`` mask.
    """
    from PIL import Image

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    masks = (("top", top), ("bottom", bottom)) + ((("film", film),) if film is not None else ())
    for name, mask in masks:
        img = np.where(np.asarray(mask, bool).T[::-1], 0, 255).astype(np.uint8)
        path = directory / f"sheet_{mask.shape[0]}x{mask.shape[1]}_{name}.png"
        Image.fromarray(img, mode="L").save(path)
        paths.append(path)
    return tuple(paths)


# -- timing helpers ---------------------------------------------------------------------------
class _quiet:
    """Silence a logger's warnings inside a ``with`` block."""

    def __init__(self, name):
        self.logger = logging.getLogger(name)

    def __enter__(self):
        self.level = self.logger.level
        self.logger.setLevel(logging.ERROR)

    def __exit__(self, *exc):
        self.logger.setLevel(self.level)


def _machine():
    import scipy

    from gdfe.solver import factor_backend

    try:
        load = os.getloadavg()[0]
    except OSError:  # pragma: no cover - not on every platform
        load = None
    return {"cores": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version(),
            "numpy": np.__version__, "scipy": scipy.__version__, "factor_backend": factor_backend(),
            "load_average_1min_at_start": load}


# -- 1. hinges --------------------------------------------------------------------------------
def _hinges(cfg):
    import gdfe

    from gdfe.solver import auto_method

    rows = []
    for L in cfg["hinge_lengths"]:
        des = gdfe.hinge(L, d=FIG6_D, h=H, cell_size=L / cfg["hinge_cells"])
        auto = auto_method(des)
        for method in ("newton", "newton-cg", "anderson", "plain"):
            kw = {"max_iter": cfg["plain_max_iter"]} if method == "plain" else {}
            reps = 1 if method == "plain" else cfg["repeats"]
            with _quiet("gdfe.solver"):  # plain alternation is expected to stop at max_iter
                med, times, res = median_time(lambda: gdfe.simulate(des, method=method, **kw), reps)
            rows.append({"L_mm": L, "cells": des.n_cells, "method": method, "converged": res.converged,
                         "iterations": res.iterations, "residual": res.residual, "seconds": med,
                         "seconds_all": times, "fold_angle_rad": float(gdfe.fold_angle(res)),
                         "auto": method == auto})
    return rows, _hinge_verdict(rows, cfg["hinge_cells"])


def _hinge_verdict(rows, hinge_cells):
    """The hinges solved by the default method against :data:`HINGE_ITERATIONS` and :data:`HINGE_SECONDS`
    (their median runs; MARGINAL where their fastest and slowest runs disagree), the factorised Newton beside."""
    acc = [r for r in rows if r["auto"]]
    worst_it = max(r["iterations"] for r in acc)
    newton = [r for r in rows if r["method"] == "newton"]

    def met_at(seconds):  # seconds: a hinge's time, from its row
        return bool(all(r["converged"] for r in acc) and worst_it <= HINGE_ITERATIONS
                    and max(seconds(r) for r in acc) <= HINGE_SECONDS)

    verdict = {"goal": GOALS["hinges"], "method": "/".join(sorted({r["method"] for r in acc})),
               "value": {"max_iterations": worst_it, "max_seconds": max(r["seconds"] for r in acc)},
               "newton": {"max_iterations": max(r["iterations"] for r in newton),
                          "max_seconds": max(r["seconds"] for r in newton),
                          "converged": all(r["converged"] for r in newton)},
               "met": met_at(lambda r: r["seconds"]),
               "marginal": (met_at(lambda r: min(r.get("seconds_all") or [r["seconds"]]))
                            != met_at(lambda r: max(r.get("seconds_all") or [r["seconds"]])))}
    if hinge_cells != 16:
        verdict["note"] = f"measured at {hinge_cells} cells across the hinge (--quick), not the default 16"
    return verdict


# -- 2-4. sheets, lower bound, factorisations (one child process per size) ---------------------
def _factor_candidates():
    """The solver's factorisation backends installed here (:func:`gdfe.solver.linalg.installed_backends`), and cholespy."""
    from gdfe.solver.linalg import installed_backends

    names = list(reversed(installed_backends()))  # SuperLU first
    try:
        import cholespy  # noqa: F401
        names.append("cholespy")
    except ImportError:
        pass
    return names


def _factor_with(name, A):
    """Factorise SPD ``A`` with backend ``name``; return a function solving for a (k, r) array."""
    import scipy.sparse as sp

    from gdfe.solver import factorise

    if name == "cholespy":
        import cholespy

        A = sp.csc_matrix(A)
        f = cholespy.CholeskySolverD(A.shape[0], A.indptr.astype(np.int32), A.indices.astype(np.int32),
                                     np.ascontiguousarray(A.data), cholespy.MatrixType.CSC)

        def solve(b):
            b = np.ascontiguousarray(b, float)
            x = np.zeros_like(b)
            f.solve(b, x)
            return x
        return solve
    fac = factorise(A, backend=name)
    return lambda b: fac.solve(np.asfortranarray(b))


def _factor_skipped(name, cells):
    """Why the benchmark asks backend ``name`` for no factor of a ``cells``-cell sheet's matrix, or None
    (``cells`` None: a matrix of no sheet size, always factorised)."""
    if cells is None:
        return None
    if cells > FACTOR_MAX_CELLS:
        return f"above {FACTOR_MAX_CELLS} cells no factor fits in memory beside the solver"
    if name == "superlu" and cells > SUPERLU_MAX_CELLS:
        return f"above {SUPERLU_MAX_CELLS} cells SuperLU's factor does not fit in memory"
    return None


def _time_factorisations(A, nrhs, repeats, cells=None):
    """Each backend's factorisation and solve of ``A`` with ``nrhs`` columns, where :func:`_factor_skipped`
    allows it for a sheet of ``cells`` cells."""
    out = {}
    rng = np.random.default_rng(0)
    b = None
    for name in _factor_candidates():
        reason = _factor_skipped(name, cells)
        if reason is not None:
            out[name] = {"skipped": reason}
            continue
        if b is None:
            b = rng.standard_normal((A.shape[0], nrhs))
        t_fac, _, solve = median_time(lambda: _factor_with(name, A), repeats)
        t_sol, _, x = median_time(lambda: solve(b), max(3, repeats))
        x = np.asarray(x).reshape(b.shape)
        rel = float(np.abs(A @ x - b).max() / np.abs(b).max())
        out[name] = {"factorise_s": t_fac, "solve_s": t_sol, "relative_residual": rel}
    return out


def freeform_sheet(n_cells, pattern):
    """Masks of the Figure 8 plate (:mod:`studies.fig08_freeform`) at about ``n_cells`` pixels.

    The 8 mm plate's pattern, drawn in millimetres, printed at the pixel that gives the
    cell count (10^5: 25 um; 10^6: 8 um).

    Returns
    -------
    top, bottom, film : (s, s) bool arrays
    pixel : float [mm]
    R : float
        The free faces' contraction ratio (Eq. 3 at the study's d).
    """
    import gdfe
    from studies import fig08_freeform as f8

    s = max(2, int(round(np.sqrt(n_cells))))
    pixel = f8.SIZE / s
    top, bottom, film = f8.masks(pattern, s, pixel)
    return top, bottom, film, pixel, float(gdfe.Calibration().ratio(f8.D))


def _design(kind, n_cells, mask_dir):
    """The benchmark design ``kind`` (:data:`DESIGNS`) of about ``n_cells`` cells, read back from its PNG masks."""
    import gdfe

    if kind == "corrugation":
        top, bottom = mask_sheet(n_cells)
        ptop, pbot = write_mask_pngs(mask_dir, top, bottom)
        return gdfe.from_masks(ptop, pbot, SHEET_PIXEL, SHEET_R, h=H, nz=1), list(top.shape)
    top, bottom, film, pixel, R = freeform_sheet(n_cells, kind.split("-", 1)[1])
    paths = write_mask_pngs(Path(mask_dir) / kind, top, bottom, None if film.all() else film)
    pfilm = paths[2] if len(paths) == 3 else None
    return gdfe.from_masks(paths[0], paths[1], pixel, R, h=H, nz=1, film=pfilm), list(top.shape)


def _sheet_case(args):
    """Everything measured on one sheet size; runs in a child process of its own."""
    import resource

    import gdfe
    from gdfe.solver import AUTO_NEWTON_CELLS, auto_method, factor_backend
    from gdfe.solver.newton import ReducedHessian

    kind, n_cells, repeats, mask_dir, hessian_max, coarse_solver = args
    # how this process's Newton-CG solves its coarse matrix (a fresh process: nothing else reads it)
    ReducedHessian.coarse_solver = coarse_solver

    def rss_kib():  # maximum resident set size so far, KiB on Linux
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    des, pixels = _design(kind, n_cells, mask_dir)
    # warm up (imports, first calls) on a small sheet of both methods, outside the timings
    for warm in (100, 2500) if n_cells > AUTO_NEWTON_CELLS else (100,):
        with _quiet("gdfe.solver"):
            gdfe.simulate(gdfe.from_masks(*mask_sheet(warm), SHEET_PIXEL, SHEET_R, h=H, nz=1), method="auto",
                          max_iter=2)
    base = rss_kib()
    method = auto_method(des)
    runs = [gdfe.simulate(des, method="auto")]
    # one run's peak: the runs after it share the process and raised its maximum by 90-220 MiB at
    # 10^5 cells (docs/bench/medians)
    peak = rss_kib()
    runs += [gdfe.simulate(des, method="auto") for _ in range(repeats - 1)]
    secs = [r.seconds for r in runs]
    med = statistics.median(secs)
    res = sorted(runs, key=lambda r: r.seconds)[(len(runs) - 1) // 2]  # the median run: its steps, start and check
    it = max(res.iterations, 1)
    tm = res.timings
    once = ("setup", "factorise", "multigrid", "start", "penetration_check")
    row = {"design": kind, "cells": des.n_cells, "points": des.mesh.n_points, "pixels": pixels,
           "pixel_mm": float(des.mesh.spacing[0]), "method": method,
           "converged": res.converged, "iterations": res.iterations, "residual": res.residual,
           "tol": res.tol, "error_estimate_mm": res.error_estimate_mm, "drift": res.drift,
           "seconds": med, "seconds_all": secs, "peak_rss_mib": peak / 1024.0, "rss_before_mib": base / 1024.0,
           "z_range_mm": float(np.ptp(res.points[:, 2])), "x_extent_mm": float(np.ptp(res.points[:, 0])),
           "per_iteration_s": (res.seconds - sum(tm.get(k, 0.0) for k in once)) / it,
           "init": "multilevel" if "start" in tm else "linear", "start_s": tm.get("start", 0.0),
           "penetration_check_s": tm.get("penetration_check", 0.0),
           "energy": res.energy, "assembly_solver": "multigrid" if "multigrid" in tm else factor_backend(),
           "coarse_solver": coarse_solver,
           "split_s": {k: v / it for k, v in tm.items() if k not in once},
           "factorise_s": tm.get("factorise", 0.0) + tm.get("multigrid", 0.0),
           "start_levels": [lv.as_dict() for lv in res.start_levels],
           "newton_steps": [s.as_dict() for s in res.newton_steps], "device": res.device}
    if res.device == "gpu":  # the GPU's answer against the CPU's
        row["cpu_answer"] = _cpu_answer(des, res)
    row["lower_bound"], row["factorisation"] = _lower_bound(des, res, med, row["per_iteration_s"], hessian_max)
    return row


def _lower_bound(des, res, seconds, per_iteration, hessian_max):
    """The sheet's lower bound per iteration and its local-global iteration beside it, and the factorisation
    backends timed on its matrices: ``(lower_bound, factorisation)``.

    The bound is one 3-column solve with the prefactorised n x n matrix (the fastest backend's) plus one
    batched polar decomposition of all cells (numpy's SVD; the solver's own polar iteration beside it),
    measured with the C heap as the solve had it (:func:`gdfe.resources.solve_heap`). ``seconds`` is the
    solve's median time, ``per_iteration`` its fine level's seconds per Newton iteration.
    """
    from gdfe.resources import solve_heap
    from gdfe.solver import Solver
    from gdfe.solver.energy import rotations

    with solve_heap(des):
        sv = Solver(des)
        V = res.points
        o = sv.orient(V)
        Q, S = o.Q, o.S
        rhs = np.asfortranarray(np.random.default_rng(0).standard_normal((len(sv.free), 3)))
        big = des.n_cells > 20_000
        k = 3 if big else 5
        # factorisation backends on this sheet's matrices; the bound's solve is the fastest of their solves
        fac = {"n": _time_factorisations(sv.L_ff, 3, 1 if big else 3, cells=des.n_cells)}
        solves = {name: v["solve_s"] for name, v in fac["n"].items() if "solve_s" in v}
        # the multigrid's solve to round-off: the bound where no factorisation fits in memory (SuperLU's alone
        # above SUPERLU_MAX_CELLS), and beside the factor's, where one does, the bound as measured before CHOLMOD
        t_multigrid = median_time(lambda: sv.multigrid.solve(rhs), k)[0] if sv.uses_multigrid else None
        if solves:
            best = min(solves, key=solves.get)
            t_solve, solve_kind = solves[best], f"{best} factor (the fastest of {', '.join(sorted(solves))})"
        else:
            t_solve, solve_kind = t_multigrid, "multigrid CG to 1e-11 (no factorisation fits in memory)"
        t_svd = median_time(lambda: np.linalg.svd(S), k)[0]
        t_polar = median_time(lambda: rotations(S), k)[0]
        t_orient = median_time(lambda: sv.orient(V), k)[0]
        t_assemble = median_time(lambda: sv.assemble(Q, V[sv.pin]), k)[0]
        t_vcycle = median_time(lambda: sv.multigrid.vcycle(rhs), k)[0] if sv.uses_multigrid else None
    bound = t_solve + t_svd
    lower_bound = {"solve_3rhs_s": t_solve, "solve_kind": solve_kind, "svd_s": t_svd, "bound_s": bound,
                   "multigrid_solve_3rhs_s": t_multigrid,
                   "bound_iterations_multigrid": None if t_multigrid is None else seconds / (t_multigrid + t_svd),
                   "polar_s": t_polar, "bound_polar_s": t_solve + t_polar, "vcycle_3rhs_s": t_vcycle,
                   "orientation_s": t_orient, "assembly_s": t_assemble, "local_global_s": t_orient + t_assemble,
                   "local_global_ratio": (t_orient + t_assemble) / bound,
                   "solver_iteration_ratio": per_iteration / bound,
                   "bound_iterations": seconds / bound, "bound_polar_iterations": seconds / (t_solve + t_polar)}
    if des.n_cells <= hessian_max:
        fdof = (3 * sv.free[:, None] + np.arange(3)).ravel()
        Hs = sv.hessian(Q, S, mu=1e-3)[fdof][:, fdof].tocsc()
        fac["3n_hessian"] = _time_factorisations(Hs, 1, 1)
    return lower_bound, fac


def _cpu_answer(des, res):
    """The sheet solved again on the CPU, against ``res`` (solved on the GPU): energies, steps, seconds, the
    largest vertex distance between the two shapes after the best rigid motion [mm], and whether they agree:
    that distance no more than the two solves' estimated distances from the solution summed (both within
    their estimates of one minimiser)."""
    import gdfe
    from gdfe.measure import shape_distance

    cpu = gdfe.simulate(des, method="auto", device="cpu")
    distance = shape_distance(cpu.points, res.points)["max"]
    estimates = (res.error_estimate_mm, cpu.error_estimate_mm)
    allowed = None if None in estimates else sum(estimates)  # no estimate: no bound, so no agreement claimed
    return {"energy": cpu.energy, "iterations": cpu.iterations, "seconds": cpu.seconds,
            "energy_relative_difference": abs(res.energy - cpu.energy) / abs(cpu.energy),
            "max_distance_mm": distance, "allowed_mm": allowed,
            "agrees": bool(res.converged and cpu.converged and allowed is not None and distance <= allowed)}


def _run_child(fn, args):
    """Run ``fn(args)`` in a fresh process (its peak memory is its own)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as ex:
        return ex.submit(fn, args).result()


def _sheets(cfg, mask_dir, progress):
    rows = []
    jobs = [("corrugation", n) for n in cfg["sheet_sizes"]]
    jobs += [(kind, n) for n in cfg["freeform_sizes"] for kind in (cfg["freeform"] if n < 500_000
                                                                   else cfg["freeform_big"])]
    for kind, n in _progress(jobs, "sheets", progress):
        reps = cfg["sheet_repeats"] if n < cfg["big"] else cfg["big_repeats"]
        try:
            rows.append(_run_child(_sheet_case, (kind, int(n), reps, str(mask_dir), cfg["hessian_max"],
                                                 cfg["coarse_solver"])))
        except MemoryError as exc:  # pragma: no cover - depends on the machine
            rows.append({"design": kind, "cells": int(n), "skipped": f"out of memory: {exc}"})
    return rows


def _progress(items, desc, progress):
    try:
        from tqdm.auto import tqdm
    except ModuleNotFoundError:  # pragma: no cover
        return items
    return tqdm(items, desc=desc, disable=not progress)


def _fit_exponent(cells, seconds):
    cells, seconds = np.asarray(cells, float), np.asarray(seconds, float)
    if cells.size < 2:
        return None
    return float(np.polyfit(np.log(cells), np.log(seconds), 1)[0])


def _exponent_span(cells, runs):
    """The least and greatest exponent :func:`_fit_exponent` gives when each size's time may be any of
    its ``runs`` (its fastest to its slowest). The least-squares slope is ``sum w_i log t_i`` with
    ``w_i = (x_i - mean x) / sum (x_j - mean x)^2``, ``x = log cells``: its extremes take each size's
    fastest or slowest run by the sign of ``w_i``."""
    x = np.log(np.asarray(cells, float))
    if np.unique(x).size < 2:
        return None
    w = (x - x.mean()) / np.sum((x - x.mean()) ** 2)
    lo = np.log([min(r) for r in runs])
    hi = np.log([max(r) for r in runs])
    return [float(np.sum(np.where(w > 0, w * lo, w * hi))), float(np.sum(np.where(w > 0, w * hi, w * lo)))]


def _growth_verdict(corr, fem_expo):
    """The fitted exponent of the converged corrugation sheets (their median times), its span over their
    runs, and against :data:`GROWTH_EXPONENT` where the sheets span :data:`GROWTH_SPAN`."""
    cells = [r["cells"] for r in corr]
    # a slope needs two sizes: sheets of one cell count (--sizes 100,110 rounds both to 10 x 10) have none
    expo = _fit_exponent(cells, [r["seconds"] for r in corr]) if len(set(cells)) >= 2 else None
    v = {"goal": GOALS["growth"], "value": expo, "fem_value": fem_expo,
         "note": "time ~ cells^exponent, least squares in log-log over the converged corrugation sheets' medians"}
    if expo is None:
        return {**v, "met": None, "stated": True,
                "note": v["note"] + "; none: fewer than two sheet sizes" if corr else v["note"]}
    span = _exponent_span(cells, [r.get("seconds_all") or [r["seconds"]] for r in corr])
    v["span"] = span
    if min(cells) > GROWTH_SPAN[0] or max(cells) < GROWTH_SPAN[1]:
        return {**v, "met": True, "stated": True,
                "note": v["note"] + f"; stated, not judged: the sheets span {min(cells)} to {max(cells)} cells"}
    return {**v, "met": bool(expo <= GROWTH_EXPONENT),
            "marginal": bool((span[0] <= GROWTH_EXPONENT) != (span[1] <= GROWTH_EXPONENT))}


# -- 5. the reference FEM ---------------------------------------------------------------------
def _richardson(angles):
    """Limit and order of three levels refined by 2: ``(alpha_inf, order)`` (order None if not monotone)."""
    a0, a1, a2 = angles
    d1, d2 = a1 - a0, a2 - a1
    if d1 == 0 or d2 == 0 or np.sign(d1) != np.sign(d2) or abs(d2) >= abs(d1):
        return float(a2), None
    p = float(np.log2(d1 / d2))
    return float(a2 + d2 / (2.0 ** p - 1.0)), p


def _gdfe_hinge(L, d, n, R=None):
    import gdfe

    if R is None:
        return gdfe.hinge(L, d=d, h=H, width=FEM_WIDTH, panel_length=FEM_PANEL, cell_size=L / n)
    return gdfe.hinge(L, R=R, h=H, width=FEM_WIDTH, panel_length=FEM_PANEL, cell_size=L / n)


def _gdfe_levels(cfg, L, d, R, progress, desc):
    import gdfe

    rows = []
    extra = (cfg["gdfe_reference"],) if cfg.get("gdfe_reference") else ()
    for n in _progress(cfg["gdfe_levels"] + extra, desc, progress):
        des = _gdfe_hinge(L, d, n, R)
        reference = n in extra
        med, times, res = median_time(lambda: gdfe.simulate(des), 1 if reference else cfg["repeats"])
        rows.append({"level": f"{n} cells across the hinge", "n": n, "cell_mm": L / n, "method": res.method,
                     "elements": des.n_cells,
                     "seconds": med, "seconds_all": times, "converged": res.converged, "reference_only": reference,
                     "alpha_rad": float(gdfe.fold_angle(res, panel_fraction=FOLD_PANEL_FRACTION)),
                     "alpha_columns_rad": float(gdfe.fold_angle(res))})
    return rows


def _gdfe_ratio_for(L, target, n):
    """Contraction ratio R of the hinge whose fold at ``n`` cells across is ``target`` [rad] (secant)."""
    import gdfe

    def fold(R):
        res = gdfe.simulate(_gdfe_hinge(L, None, n, R)).check()
        return float(gdfe.fold_angle(res, panel_fraction=FOLD_PANEL_FRACTION))
    R0 = 1.0 - target * H / L  # Eq. 2
    a0 = fold(R0)
    R1 = 1.0 - (1.0 - R0) * target / a0
    a1 = fold(R1)
    for _ in range(4):
        if abs(a1 - target) < 1e-9 * target:
            break
        R0, a0, R1 = R1, a1, R1 + (target - a1) * (R1 - R0) / (a1 - a0)
        a1 = fold(R1)
    return float(R1)


def _with_errors(rows, size_key, reference_rows):
    """Add the reference (Richardson over the levels in ``reference_rows``) and each level's relative error."""
    ref, order = _richardson([r["alpha_rad"] for r in reference_rows])
    for r in rows:
        r["error_rad"] = abs(r["alpha_rad"] - ref)
        r["relative_error"] = r["error_rad"] / abs(ref)
    cmp = [r for r in rows if not r.get("reference_only")]
    h = np.array([r[size_key] for r in cmp], float)
    e = np.array([r["relative_error"] for r in cmp])
    ok = e > 0
    rate = float(np.polyfit(np.log(h[ok]), np.log(e[ok]), 1)[0]) if ok.sum() >= 3 else None
    return {"alpha_reference_rad": ref, "richardson_order": order, "observed_order": rate,
            "reference_levels": [r["level"] for r in reference_rows]}


def _time_at(levels, err):
    """Seconds at relative error ``err``: log-log interpolation between the levels that bracket it, or
    extrapolation along the fitted log-log line of the finest three levels (then ``extrapolated``)."""
    lv = sorted((e, t) for e, t in levels if e > 0)
    for (e0, t0), (e1, t1) in zip(lv, lv[1:]):
        if e0 <= err <= e1:
            return _time_at_error([(e0, t0), (e1, t1)], err), False
    if not lv:
        return None, True
    if err > lv[-1][0]:
        return float(lv[-1][1]), False  # coarser than the coarsest level: its time bounds it
    fin = lv[:3]
    if len(fin) < 2:
        return None, True
    slope, icpt = np.polyfit(np.log([e for e, _ in fin]), np.log([t for _, t in fin]), 1)
    return float(np.exp(icpt + slope * np.log(err))), True


def _at_errors(fem_rows, g_same, g_own, target):
    """Both models' seconds and their ratio at each of :data:`FEM_ERROR_LEVELS`, GDFE on the same fold and on its own.

    Where the FEM's finest level does not get to an error, the FEM takes longer than that level
    did: ``ratio_at_least`` is that level's time over GDFE's, a lower bound with no extrapolation.
    """
    f = [(r["relative_error"], r["seconds"]) for r in fem_rows]
    fem_finest = max(fem_rows, key=lambda r: r["elements"])
    at = []
    for name, rows in (("same_fold", g_same), ("own_fold", g_own)):
        g = [(r["relative_error"], r["seconds"]) for r in rows if not r["reference_only"]]
        for e in FEM_ERROR_LEVELS:
            tg, xg = _time_at(g, e)
            tf, xf = _time_at(f, e)
            reached = min(r["relative_error"] for r in fem_rows) <= e
            at.append({"comparison": name, "relative_error": e, "error_rad": e * abs(target), "gdfe_seconds": tg,
                       "fem_seconds": tf, "gdfe_extrapolated": xg, "fem_extrapolated": xf,
                       "ratio": None if tg is None or tf is None else tf / tg,
                       "fem_seconds_at_least": None if reached else fem_finest["seconds"],
                       "ratio_at_least": (None if reached or tg is None or xg else fem_finest["seconds"] / tg)})
    return at


def _fem_comparison(cfg, progress):
    try:
        import reference_fem as rf
    except ModuleNotFoundError as exc:
        return {"skipped": f"reference FEM not importable ({exc})"}
    if not hasattr(rf, "solve_nonlinear"):
        return {"skipped": "reference_fem has no solve_nonlinear"}
    L, d = FEM_HINGE
    fem_rows = []
    levels = [FEM_FAMILY[k] for k in cfg["fem_levels"]]
    for i, (size, layers) in enumerate(_progress(levels, "FEM levels", progress)):
        strip = rf.hinge_mesh(L, d, H, width=FEM_WIDTH, panel_length=FEM_PANEL, element_size=size,
                              layers_per_ply=layers, z_ratio=FEM_GRADING ** (1.0 / (layers - 1)),
                              junction_size=FEM_JUNCTION * size)
        reps = 1 if strip.n_elements > 600 else cfg["repeats"]
        med, times, res = median_time(lambda: rf.solve_nonlinear(strip, rf.BilayerMaterial()), reps)
        fem_rows.append({"level": f"size {size:.3g} mm, {layers} layers/ply", "element_size_mm": size,
                         "layers_per_ply": layers, "elements": int(strip.n_elements), "dofs": int(res.dofs),
                         "seconds": med, "seconds_all": times, "alpha_rad": float(rf.fold_angle(res)),
                         "converged": bool(res.converged), "linear_solver": res.linear_solver})
    # the FEM's reference: Richardson over the levels refined by 2 (every size, layer and junction halved)
    by_size = {r["element_size_mm"]: r for r in fem_rows}
    halving = [by_size[s] for s in FEM_REFERENCE_SIZES if s in by_size]
    out = {"hinge": {"L_mm": L, "d_mm": d, "h_mm": H, "width_mm": FEM_WIDTH, "panel_mm": FEM_PANEL},
           "fold_measure": f"both models: the turn between the rigid frames of the outer {FOLD_PANEL_FRACTION:g} "
                           "of each panel",
           "fem_nonlinear": fem_rows}
    if len(halving) < 3 or len(fem_rows) < 3:
        for r in fem_rows:
            r["error_rad"] = r["relative_error"] = float("nan")
        out["skipped"] = "too few FEM levels for a reference (--quick)"
        return out
    out["fem_reference"] = _with_errors(fem_rows, "element_size_mm", halving)
    target = out["fem_reference"]["alpha_reference_rad"]
    # the same fold: GDFE's R chosen so that its fold (at the level below its finest) is the FEM's limit
    R_same = _gdfe_ratio_for(L, target, cfg["gdfe_levels"][-1])
    g_same = _gdfe_levels(cfg, L, d, R_same, progress, "GDFE hinge levels (same fold)")
    out["gdfe"] = g_same
    out["gdfe_R"] = R_same
    out["gdfe_reference"] = _with_errors(g_same, "cell_mm", g_same[-3:])
    g_own = _gdfe_levels(cfg, L, d, None, progress, "GDFE hinge levels (own fold, Eq. 3)")
    out["gdfe_own_fold"] = g_own
    out["gdfe_own_fold_reference"] = _with_errors(g_own, "cell_mm", g_own[-3:])
    out["error_rule"] = ("relative error = |alpha - alpha_inf| / alpha_inf, alpha_inf each model's Richardson limit "
                         "over three levels refined by 2; GDFE's R makes its fold the FEM's limit (same fold); "
                         "time at an error interpolated log-log between the levels around it, extrapolated "
                         "along the finest three levels where a model does not get there (flagged); where the "
                         "FEM's finest level does not get there, its time bounds the FEM's from below "
                         "(ratio_at_least), and the verdict uses that bound, not the extrapolation")
    at = _at_errors(fem_rows, g_same, g_own, target)
    out["at_error"] = at
    out.update(_headline_ratios(at))
    return out


def _headline_ratios(at):
    """The comparison's top-level numbers, at the smallest error level on the same fold: the FEM's time and the
    ratio without extrapolation (its finest level's time, a lower bound, where it does not get there), and the
    extrapolated ones beside them."""
    same = [a for a in at if a["comparison"] == "same_fold"]
    best = min(same, key=lambda a: a["relative_error"])
    extrapolated = bool(best["fem_extrapolated"])
    return {"target_error_rad": best["error_rad"], "target_relative_error": best["relative_error"],
            "fem_seconds": best["fem_seconds_at_least"] if extrapolated else best["fem_seconds"],
            "fem_seconds_is_lower_bound": extrapolated, "fem_seconds_extrapolated": best["fem_seconds"],
            "gdfe_seconds": best["gdfe_seconds"], "ratio": _measured_ratio(best), "ratio_is_lower_bound": extrapolated,
            "ratio_extrapolated": best["ratio"],
            "min_ratio": min(a["ratio"] for a in same if a["ratio"] is not None),
            "min_ratio_measured": min((_measured_ratio(a) for a in same if _measured_ratio(a) is not None),
                                      default=None)}


def _measured_ratio(a):
    """The ratio at one error level without the FEM's extrapolation: its lower bound where the FEM's finest
    level does not get there, else the interpolated ratio (None where neither is known)."""
    if a["fem_extrapolated"]:
        return a.get("ratio_at_least")
    return a["ratio"]


def _time_at_error(levels, err):
    """Seconds at ``err``: log-log interpolation between the levels that bracket it."""
    lv = sorted(levels)  # ascending error
    for (e0, t0), (e1, t1) in zip(lv, lv[1:]):
        if e0 <= err <= e1:
            if e1 == e0:
                return min(t0, t1)
            s = np.log(err / e0) / np.log(e1 / e0)
            return float(np.exp(np.log(t0) + s * np.log(t1 / t0)))
    return float(lv[0][1])  # only one level, at err


# -- the whole benchmark ----------------------------------------------------------------------
def run(quick=False, sizes=None, fem=None, out=None, progress=None, freeform_sizes=None, hinges=True,
        coarse_solver=None):
    """Run the benchmark; return its results (a JSON-ready dict).

    Parameters
    ----------
    quick : bool
        Tiny sizes and one repeat (seconds): checks that everything runs, measures little.
    sizes : sequence of int, optional
        Corrugation sheet sizes [cells]; default 10^3, 10^4, 10^5 (``quick``: 64, 144, 256).
    freeform_sizes : sequence of int, optional
        Sizes of the Figure 8 plates (:data:`FREEFORM`, at 10^6 and above :data:`FREEFORM_BIG`);
        default 10^5 (``quick``: 256); empty: none.
    hinges : bool
        Time the Figure 6 hinges (section 1).
    fem : bool, optional
        Run the FEM comparison (default: not with ``quick``).
    out : path, optional
        Directory for ``bench.json``, ``bench.txt`` (:func:`format_table`), ``bench_scaling.png``
        and the mask PNGs.
    progress : bool, optional
        Progress bars (default: when stderr is a terminal).
    coarse_solver : {"factor", "amg"}, optional
        How the sheets' Newton-CG solves its coarse matrix
        (:attr:`gdfe.solver.newton.ReducedHessian.coarse_solver`; default its default).
    """
    import sys

    from gdfe.solver.newton import COARSE_SOLVERS, ReducedHessian

    cfg = dict(SETTINGS["quick" if quick else "full"])
    cfg["coarse_solver"] = check_choice("coarse_solver", ReducedHessian.coarse_solver if coarse_solver is None
                                        else coarse_solver, COARSE_SOLVERS)
    if sizes is not None:
        sizes = [int(s) for s in sizes]
        if not sizes or min(sizes) < 4:
            raise GdfeError(f"sizes: expected cell counts >= 4, got {sizes}")
        cfg["sheet_sizes"] = tuple(sizes)
    if freeform_sizes is not None:
        freeform_sizes = [int(s) for s in freeform_sizes]
        if freeform_sizes and min(freeform_sizes) < 4:
            raise GdfeError(f"freeform_sizes: expected cell counts >= 4, got {freeform_sizes}")
        cfg["freeform_sizes"] = tuple(freeform_sizes)
    if fem is not None:
        cfg["fem"] = bool(fem)
        if fem and not cfg["fem_levels"]:
            cfg["fem_levels"] = tuple(range(len(FEM_FAMILY)))
            cfg["gdfe_levels"] = SETTINGS["full"]["gdfe_levels"]
            cfg["gdfe_reference"] = SETTINGS["full"]["gdfe_reference"]
    if progress is None:
        progress = sys.stderr.isatty()
    t0 = time.perf_counter()
    result = {"mode": "quick" if quick else "full", "machine": _machine()}
    if hinges:
        hinge_rows, hinge_verdict = _hinges(cfg)
    else:
        hinge_rows, hinge_verdict = [], {"goal": GOALS["hinges"], "value": None, "met": None,
                                         "note": "not run (--no-hinges)"}
    result["hinges"] = hinge_rows
    with tempfile.TemporaryDirectory() as tmp:
        mask_dir = Path(out) / "masks" if out is not None else Path(tmp)
        result["sheets"] = _sheets(cfg, mask_dir, progress)
    result["fem_comparison"] = (_fem_comparison(cfg, progress) if cfg["fem"]
                                else {"skipped": "not run (--quick or --no-fem)"})
    result["verdicts"] = _verdicts(result, hinge_verdict, cfg)
    result["seconds"] = time.perf_counter() - t0
    try:
        result["machine"]["load_average_1min_at_end"] = os.getloadavg()[0]
    except OSError:  # pragma: no cover
        pass
    if out is not None:
        _write(result, Path(out))
    return result


def _sheet_verdict(key, rows, machine):
    limit = SHEET_BOUND_ITERATIONS[key]
    if not rows:
        return {"goal": GOALS[key], "value": None, "met": None, "note": f"no sheet of that size in this run"}
    per = [{"design": r.get("design", "corrugation"), "cells": r["cells"], "seconds": r["seconds"],
            "converged": r["converged"], "bound_iterations": r["lower_bound"]["bound_iterations"],
            "bound_iterations_runs": _runs_over_bound(r), "runs": len(r.get("seconds_all") or [r["seconds"]]),
            "bound_polar_iterations": r["lower_bound"]["bound_polar_iterations"],
            "peak_rss_mib": r["peak_rss_mib"], "iterations": r["iterations"]} for r in rows]
    worst = max(per, key=lambda p: p["bound_iterations"])

    def met_at(run):  # run: each sheet's median (None), fastest (0) or slowest (1) run
        ok = all(p["converged"] and (p["bound_iterations"] if run is None else p["bound_iterations_runs"][run]) <= limit
                 for p in per)
        if key == "sheet_1e6":
            ok = ok and all(p["peak_rss_mib"] <= SHEET_1E6_MIB for p in per)
        return bool(ok)

    return {"goal": GOALS[key], "value": worst["bound_iterations"], "worst": worst["design"], "sheets": per,
            "met": met_at(None), "marginal": met_at(0) != met_at(1), "cores": machine["cores"]}


def _runs_over_bound(row):
    """The fewest and most bound iterations among a sheet's runs (``seconds_all`` over the run's bound)."""
    bound = row["lower_bound"]["bound_s"]
    secs = row.get("seconds_all") or [row["seconds"]]
    return [min(secs) / bound, max(secs) / bound]


def _sheet_name(row):
    """A sheet's name in the verdicts: its design and cells."""
    return f"{row.get('design', 'corrugation')} {row['cells']}"


def _last_contractions(row, k=3):
    """The last ``k`` contractions of a sheet's consecutive full Newton steps (:func:`gdfe.solver.newton.convergence_rates`
    of its ``newton_steps``)."""
    return [float(x) for x in convergence_rates([NewtonStep(**d) for d in row.get("newton_steps", [])])[-k:]]


def _newton_verdict(rows):
    """The twist's Newton iterations against :data:`TWIST_ITERATIONS` and its last contraction against
    :data:`TWIST_LAST_CONTRACTION`, and every 10^5 sheet's last contractions: superlinear where they fall
    towards 0."""
    rates = {_sheet_name(r): _last_contractions(r) for r in rows}
    twist = [r for r in rows if r.get("design") == "fig08-twist"]
    if not twist:
        return {"goal": GOALS["newton"], "value": None, "met": None, "last_contractions": rates,
                "note": "no 10^5-cell twist in this run"}
    r = twist[0]
    last = rates[_sheet_name(r)]
    return {"goal": GOALS["newton"], "value": r["iterations"], "last_contractions": rates,
            "met": bool(r["converged"] and r["iterations"] <= TWIST_ITERATIONS and bool(last)
                        and last[-1] <= TWIST_LAST_CONTRACTION),
            "note": "value: the twist's iterations (its last finds the test met); last_contractions: each sheet's "
                    "last three length ratios of consecutive full steps"}


def _verdicts(result, hinge_verdict, cfg):
    sheets = [r for r in result["sheets"] if "skipped" not in r]
    v = {"hinges": hinge_verdict}
    fc = result["fem_comparison"]
    if fc.get("at_error"):
        same = [a for a in fc["at_error"] if a["comparison"] == "same_fold"]
        extrapolated = [a["relative_error"] for a in same if a["fem_extrapolated"] or a["gdfe_extrapolated"]]
        who = sorted({m for a in same for m, x in (("the FEM", a["fem_extrapolated"]), ("GDFE", a["gdfe_extrapolated"]))
                      if x})
        measured = [_measured_ratio(a) for a in same]
        v["fem"] = {"goal": GOALS["fem"], "value": fc.get("min_ratio_measured", fc["min_ratio"]),
                    "at": {f"{a['relative_error']:g}": a["ratio"] for a in same if not a["fem_extrapolated"]},
                    "at_least": {f"{a['relative_error']:g}": a.get("ratio_at_least") for a in same
                                 if a.get("ratio_at_least") is not None},
                    "at_extrapolated": {f"{a['relative_error']:g}": a["ratio"] for a in same
                                        if a["fem_extrapolated"]},
                    "met": bool(all(m is not None and m >= FEM_RATIO for m in measured)),
                    "extrapolated_at": extrapolated}
        if extrapolated:
            v["fem"]["note"] = (" and ".join(who) + ": time at relative error " + ", ".join(f"{e:g}" for e in extrapolated)
                                + " extrapolated along the finest three levels (the finest mesh does not get there);"
                                " the verdict takes the FEM's finest level's time as a lower bound there instead")
    else:
        v["fem"] = {"goal": GOALS["fem"], "value": None, "met": None, "note": fc.get("skipped", "")}
    v["sheet"] = _sheet_verdict("sheet", [r for r in sheets if 50_000 <= r["cells"] <= 200_000], result["machine"])
    v["sheet_1e6"] = _sheet_verdict("sheet_1e6", [r for r in sheets if r["cells"] >= 500_000], result["machine"])
    if sheets:
        r = max(sheets, key=lambda r: r["cells"])
        lb = r["lower_bound"]
        v["lower_bound"] = {"goal": GOALS["lower_bound"], "cells": r["cells"], "design": r.get("design"),
                            "value": lb["local_global_ratio"],
                            "solver_iteration_ratio": lb["solver_iteration_ratio"],
                            "met": bool(lb["local_global_ratio"] <= 2.0),
                            "note": "value: one local-global iteration (orientation + assembly) over the "
                                    "bound; solver_iteration_ratio: one outer iteration of the method used"}
    else:
        v["lower_bound"] = {"goal": GOALS["lower_bound"], "value": None, "met": None}
    corr = [r for r in sheets if r.get("design", "corrugation") == "corrugation" and r["converged"]]
    fem_expo = None
    if fc.get("fem_nonlinear"):
        rows = fc["fem_nonlinear"]
        fem_expo = _fit_exponent([r["elements"] for r in rows], [r["seconds"] for r in rows])
    v["growth"] = _growth_verdict(corr, fem_expo)
    expo = v["growth"]["value"]
    if expo is not None and not any(r["cells"] >= 500_000 for r in corr):
        last = max(corr, key=lambda r: r["cells"])
        scale = 1e6 / last["cells"]
        mem_expo = _fit_exponent([r["cells"] for r in corr], [r["peak_rss_mib"] for r in corr])
        v["growth"]["projected_1e6"] = {"seconds": last["seconds"] * scale ** expo,
                                        "peak_rss_mib": last["peak_rss_mib"] * scale ** max(mem_expo, 1.0),
                                        "note": "not run: extrapolated from the largest sheet with the fitted "
                                                "exponents (memory at least linear)"}
    v["newton"] = _newton_verdict([r for r in sheets if 50_000 <= r["cells"] <= 200_000])
    from gdfe.solver.device import gpu_available

    v["gpu"] = _gpu_verdict(sheets, gpu_available())
    return v


def _gpu_verdict(sheets, gpu_here):
    """The 10^6-cell corrugation's seconds where the sheets ran on the GPU (``device="auto"`` picks it where
    CuPy sees one), and the smaller sheets' answers against the CPU's (:func:`_cpu_answer`)."""
    on_gpu = [r for r in sheets if r.get("device") == "gpu"]
    if not on_gpu:
        note = ("not measured: a GPU is here but no sheet ran on it" if gpu_here else
                "not measured: no GPU here (the GPU path, gdfe.solver.device, runs its code on the CPU in "
                "tests/test_gpu_path.py)")
        return {"goal": GOALS["gpu"], "value": None, "met": None, "note": note}
    agreement = {_sheet_name(r): r["cpu_answer"] for r in on_gpu if "cpu_answer" in r}
    big = [r for r in on_gpu if r["cells"] >= 500_000 and r.get("design", "corrugation") == "corrugation"]
    if not big:
        return {"goal": GOALS["gpu"], "value": None, "met": None, "agreement": agreement,
                "note": "not measured: no 10^6-cell corrugation on the GPU in this run"}
    r = big[0]
    same = agreement.get(_sheet_name(r), {}).get("agrees", False)
    return {"goal": GOALS["gpu"], "value": r["seconds"], "agreement": agreement,
            "met": bool(r["converged"] and r["seconds"] <= GPU_SECONDS and same),
            "note": "value: the 10^6-cell corrugation's seconds on the GPU, met where it is within the limit and "
                    "its shape agrees with the CPU's (within the two solves' estimated distances summed); "
                    "agreement: every sheet solved on both"}


def _write(result, out):
    from gdfe.io import write_json, write_text

    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "bench.json", result)
    write_text(out / "bench.txt", format_table(result) + "\n")
    try:
        plot(result, out / "bench_scaling.png")
    except ModuleNotFoundError as exc:  # matplotlib is optional
        log.warning("no plot: %s", exc)


def plot(result, path):
    """Seconds against elements (GDFE sheets and hinge levels, the nonlinear FEM), and seconds
    against the hinge's relative fold error for both models (same fold)."""
    from gdfe._plotting import pyplot
    from gdfe.io import save_figure

    plt = pyplot()
    fc = result["fem_comparison"]
    two = "gdfe" in fc and fc.get("fem_reference")
    fig, axes = plt.subplots(1, 2 if two else 1, figsize=(12.4 if two else 6.4, 4.6), squeeze=False)
    ax = axes[0, 0]
    sheets = [r for r in result["sheets"] if "skipped" not in r and r["converged"]]
    for k, kind in enumerate(DESIGNS):
        rows = [r for r in sheets if r.get("design", "corrugation") == kind]
        if not rows:
            continue
        x = np.array([r["cells"] for r in rows], float)
        y = np.array([r["seconds"] for r in rows])
        ax.loglog(x, y, "o-" if kind == "corrugation" else "D", color=f"C{k if k < 2 else k + 3}",
                  label=f"GDFE, {kind} mask sheet")
        if kind == "corrugation":
            lb = np.array([r["lower_bound"]["bound_s"] for r in rows])
            ax.loglog(x, lb, "s:", color="C0", alpha=0.6, label="lower bound per iteration (solve + SVD)")
            expo = result["verdicts"]["growth"]["value"]
            if expo is not None and len(rows) > 1:
                ax.text(x[-1], y[-1], f"  slope {expo:.2f}", va="center", color="C0")
    if "gdfe" in fc:
        ax.loglog([r["elements"] for r in fc["gdfe"]], [r["seconds"] for r in fc["gdfe"]], "^-", color="C2",
                  label=f"GDFE, hinge L = {fc['hinge']['L_mm']} mm")
        ax.loglog([r["elements"] for r in fc["fem_nonlinear"]], [r["seconds"] for r in fc["fem_nonlinear"]],
                  "v-", color="C3", label=f"nonlinear FEM, hinge L = {fc['hinge']['L_mm']} mm")
    ax.set(xlabel="elements", ylabel="seconds to convergence",
           title=f"gdfe bench ({result['machine']['cores']} cores, {result['machine']['factor_backend']})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    if two:
        ax = axes[0, 1]
        for name, rows, c in (("GDFE", [r for r in fc["gdfe"] if not r["reference_only"]], "C2"),
                              ("nonlinear FEM", fc["fem_nonlinear"], "C3")):
            ax.loglog([r["relative_error"] for r in rows], [r["seconds"] for r in rows], "o-", color=c, label=name)
        for a in (a for a in fc["at_error"] if a["comparison"] == "same_fold"):
            # where the FEM's finest level does not reach the error, its time there is only a lower bound
            text = (f">= {a['ratio_at_least']:.0f}x" if a.get("fem_extrapolated") and a.get("ratio_at_least")
                    else None if a["ratio"] is None else f"{a['ratio']:.0f}x")
            if text is not None:
                ax.annotate(text, (a["relative_error"], a["gdfe_seconds"]), fontsize=8,
                            textcoords="offset points", xytext=(0, 8), ha="center")
        for e in FEM_ERROR_LEVELS:
            ax.axvline(e, color="0.7", lw=0.8, ls="--")
        ax.invert_xaxis()
        ax.set(xlabel="relative fold-angle error (each model against its own limit)", ylabel="seconds",
               title=f"hinge L = {fc['hinge']['L_mm']} mm, same fold {fc['fem_reference']['alpha_reference_rad']:.4f} rad")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


# -- text -------------------------------------------------------------------------------------
def _fmt(x, spec=".3g"):
    return "-" if x is None else format(x, spec)


def _verdict_word(v):
    """MET, NOT MET, ... and MARGINAL: met by the medians, but not by every run (the slowest runs of each
    sheet, or of each size for the exponent), so the verdict is within the machine's noise."""
    if v.get("stated"):
        return "STATED"
    if v["met"] and v.get("marginal"):
        return "MARGINAL"
    if v["met"] is None and v.get("note", "").startswith("not built"):
        return "NOT BUILT"
    if v["met"] is None and v.get("note", "").startswith("not measured"):
        return "NOT MEASURED"
    return {True: "MET", False: "NOT MET", None: "n/a"}[v["met"]]


def _steps_lines(sheets):
    """The median run's Newton steps, sheet by sheet: its start's levels and its fine steps (bench.json has
    every field of them)."""
    out = []
    for r in sheets:
        if "newton_steps" not in r:
            continue
        levels = ", ".join(f"{lv['cells']} cells {lv['iterations']} it. {lv['seconds']:.2f} s"
                           + ("" if lv["converged"] else " (stopped)") for lv in r["start_levels"])
        fine = " ".join(f"{s['length_h']:.1e}/{s['cg_iterations']}" + (
            "" if s["alpha"] == 1.0 else f"*{_fmt(s['alpha'])}" if s["kind"] == "newton" else f" ({s['kind']})")
            for s in r["newton_steps"])
        rates = ", ".join(f"{x:.2g}" for x in _last_contractions(r))
        out.append(f"  {r.get('design', 'corrugation'):>12} {r['cells']:7d}: start {levels or 'none'}; fine steps "
                   f"(length h / CG iterations, *fraction taken) {fine or 'none'}; last contractions {rates or '-'}")
    return out


def format_table(res):
    """The benchmark as text tables."""
    m = res["machine"]
    lines = [f"gdfe bench ({res['mode']}): {m['cores']} cores, {m['platform']}, factorisation {m['factor_backend']},"
             f" load average {_fmt(m['load_average_1min_at_start'], '.2f')} at start,"
             f" {_fmt(m.get('load_average_1min_at_end'), '.2f')} at end", ""]
    lines += _hinge_lines(res["hinges"])
    lines += _sheet_lines(res["sheets"])
    lines += _steps_lines(res["sheets"])
    lines += ["  (seconds = the median of the runs, bench.json's seconds_all, and the other columns the median "
              "run's; start = the multilevel start's coarse levels, pen. = the penetration check, both inside the "
              "total; s/iter = fine-level seconds per Newton iteration; bound = 3-column solve with the factorised "
              "n x n matrix + batched SVD; t/bd = seconds over the bound, t/bd_p with the solver's polar iteration "
              "instead of the SVD; LG = one orientation + one assembly step)", ""]
    lines += _factorisation_lines(res["sheets"])
    lines += _fem_lines(res["fem_comparison"])
    lines += ["", "Goals"]
    lines += [f"  {_verdict_word(v):>9}  {v['goal']}: {_verdict_value(v)}{_verdict_extra(key, v)}{_verdict_note(v)}"
              for key, v in res["verdicts"].items()]
    lines.append(f"\n({res['seconds']:.0f} s in all)")
    return "\n".join(lines)


def _hinge_lines(hinges):
    """The Figure 6 hinges' table (none where the benchmark ran none)."""
    if not hinges:
        return []
    lines = ["Figure 6 hinges (d = 0.33 mm, h = 0.29 mm)",
             f"  {'L mm':>5} {'cells':>6} {'method':>9} {'conv':>5} {'iter':>6} {'seconds':>8} {'angle rad':>9}"]
    for r in hinges:
        lines.append(f"  {r['L_mm']:5.2g} {r['cells']:6d} {r['method']:>9} {str(r['converged']):>5} "
                     f"{r['iterations']:6d} {r['seconds']:8.3f} {r['fold_angle_rad']:9.4f}")
    return lines + [""]


def _sheet_lines(sheets):
    """The mask sheets' table: each solve beside its lower bound, then which solve each bound took."""
    coarse = sorted({r["coarse_solver"] for r in sheets if "coarse_solver" in r})
    lines = ["Mask sheets (corrugation: pixel 0.1 mm, R = 0.7; fig08: the 8 mm Figure 8 plate at the pixel that "
             "gives the cell count, R = 0.6947; nz = 1); peak = max RSS of a child process over its first run"
             + (f"; Newton-CG's coarse matrix: {', '.join(coarse)}" if coarse else "")]
    lines.append(f"  {'design':>12} {'cells':>7} {'pixel':>6} {'conv':>5} {'iter':>4} {'seconds':>8} {'start':>6} "
                 f"{'pen.':>5} {'peak MiB':>8} {'s/iter':>7} | {'solve':>7} {'svd':>6} {'polar':>6} {'bound':>6} "
                 f"{'t/bd':>6} {'t/bd_p':>6} {'LG/bd':>5}")
    for r in sheets:
        if "skipped" in r:
            lines.append(f"  {r.get('design', 'corrugation'):>12} {r['cells']:7d} skipped: {r['skipped']}")
            continue
        lb = r["lower_bound"]
        drift = " (drift reported)" if r.get("drift") else ""
        lines.append(f"  {r.get('design', 'corrugation'):>12} {r['cells']:7d} {r.get('pixel_mm', SHEET_PIXEL):6.3f} "
                     f"{str(r['converged']):>5} {r['iterations']:4d} {r['seconds']:8.2f} {r.get('start_s', 0.0):6.2f} "
                     f"{r.get('penetration_check_s', 0.0):5.2f} {r['peak_rss_mib']:8.0f} {r['per_iteration_s']:7.3f} | "
                     f"{lb['solve_3rhs_s']:7.4f} {lb['svd_s']:6.3f} {lb.get('polar_s', float('nan')):6.3f} "
                     f"{lb['bound_s']:6.3f} {lb.get('bound_iterations', float('nan')):6.0f} "
                     f"{lb.get('bound_polar_iterations', float('nan')):6.0f} {lb['local_global_ratio']:5.2f}{drift}")
    for r in sheets:  # which solve the bound took, and the multigrid's bound beside a factor's
        lb = r.get("lower_bound")
        if lb is None or lb.get("bound_iterations_multigrid") is None or lb["solve_kind"].startswith("multigrid"):
            continue
        lines.append(f"  {r.get('design', 'corrugation'):>12} {r['cells']:7d}: the bound's solve is the "
                     f"{lb['solve_kind']}; with the multigrid's CG to 1e-11 instead ({lb['multigrid_solve_3rhs_s']:.3g} s) "
                     f"t/bd would be {lb['bound_iterations_multigrid']:.0f}")
    return lines


def _factorisation_lines(sheets):
    """The sparse factorisations' timings per sheet."""
    lines = ["Sparse factorisation (median seconds: factorise / solve)"]
    for r in sheets:
        if "skipped" in r:
            continue
        for kind, backends in r["factorisation"].items():
            cells = ", ".join(f"{k} {v['factorise_s']:.3g} / {v['solve_s']:.3g}" if "skipped" not in v
                              else f"{k} skipped" for k, v in backends.items())
            lines.append(f"  {r.get('design', 'corrugation'):>12} {r['cells']:7d} {kind:>10}: {cells}")
    return lines


def _fem_lines(fc):
    """GDFE against the nonlinear reference FEM: the levels, their limits and the ratios at equal error."""
    lines = ["", f"GDFE against the nonlinear reference FEM (hinge L = {FEM_HINGE[0]} mm, d = {FEM_HINGE[1]} mm, "
                 f"width {FEM_WIDTH} mm, panels {FEM_PANEL} mm)"]
    used = sorted({r["linear_solver"] for r in fc.get("fem_nonlinear", []) if "linear_solver" in r})
    if used:
        lines.append(f"  the FEM's linear solves: {', '.join(used)}"
                     + (" (MKL PARDISO, pip install -e \".[fem-fast]\", factorises the same tangents several "
                        "times faster)" if "pardiso" not in used else ""))
    if "fem_reference" in fc:
        fr, gr, go = fc["fem_reference"], fc["gdfe_reference"], fc["gdfe_own_fold_reference"]
        lines.append(f"  fold measured on the outer {FOLD_PANEL_FRACTION:g} of each panel; limits by Richardson over "
                     "three levels refined by 2")
        lines.append(f"  FEM limit {fr['alpha_reference_rad']:.5f} rad (order {_fmt(fr['richardson_order'], '.2f')}; "
                     f"fitted {_fmt(fr['observed_order'], '.2f')} in element size); GDFE with R = {fc['gdfe_R']:.5f}: "
                     f"limit {gr['alpha_reference_rad']:.5f} rad (order {_fmt(gr['richardson_order'], '.2f')}; fitted "
                     f"{_fmt(gr['observed_order'], '.2f')} in cell size); GDFE with Eq. 3 (R = "
                     f"{float(Calibration().ratio(FEM_HINGE[1])):.4f}): limit {go['alpha_reference_rad']:.5f} rad")
    for name in ("gdfe", "gdfe_own_fold", "fem_nonlinear"):
        for r in fc.get(name, []):
            tag = " (reference only)" if r.get("reference_only") else ""
            lines.append(f"  {name:>13} {r['level']:>28} {r['elements']:6d} el {r['seconds']:8.3f} s "
                         f"alpha {r['alpha_rad']:.5f} rel. err {r.get('relative_error', float('nan')):.2e}{tag}")
    for a in fc.get("at_error", []):
        fx = " (FEM extrapolated)" if a["fem_extrapolated"] else ""
        gx = " (GDFE extrapolated)" if a["gdfe_extrapolated"] else ""
        least = (f"; at least {a['ratio_at_least']:.3g} (the FEM's finest level, {a['fem_seconds_at_least']:.3g} s, "
                 "does not get there)") if a.get("ratio_at_least") is not None else ""
        lines.append(f"  {a['comparison']:>9} at relative error {a['relative_error']:.0e}: FEM "
                     f"{_fmt(a['fem_seconds'], '.3g')} s{fx}, GDFE {_fmt(a['gdfe_seconds'], '.3g')} s{gx}: ratio "
                     f"{_fmt(a['ratio'], '.3g')}{least}")
    if "skipped" in fc:
        lines.append(f"  skipped: {fc['skipped']}")
    return lines


def _verdict_value(v):
    """A verdict's measured value as text (a dict of values as ``key value`` pairs)."""
    val = v["value"]
    if isinstance(val, dict):
        return ", ".join(f"{k} {_fmt(x)}" for k, x in val.items())
    return _fmt(val)


def _verdict_note(v):
    """A verdict's note where it qualifies the word shown (not measured, quick, extrapolated, not judged)."""
    if v.get("note") and (v["met"] is None or any(w in v["note"] for w in ("quick", "extrapolated", "not judged"))):
        return f" [{v['note']}]"
    return ""


def _verdict_extra(key, v):
    """What a verdict line adds after its value: its method, ratios, sheets, agreement or projection."""
    extra = ""
    if "newton" in v:
        dn = v["newton"]
        extra = (f" with method {v['method']} (method newton: {dn['max_iterations']} iterations,"
                 f" {dn['max_seconds']:.3g} s)")
    if "solver_iteration_ratio" in v:
        extra = f" (outer iteration of the solver used: {v['solver_iteration_ratio']:.1f}x)"
    if key == "fem" and "at" in v:
        parts = [f"{e}: {_fmt(x, '.3g')}" for e, x in v["at"].items()]
        parts += [f"{e}: at least {_fmt(x, '.3g')}" for e, x in v.get("at_least", {}).items()]
        extra = " (ratio at " + ", ".join(parts) + ")"
        if v.get("at_extrapolated"):
            extra += " (extrapolating the FEM, not used: " + ", ".join(
                f"{e}: {_fmt(x, '.3g')}" for e, x in v["at_extrapolated"].items()) + ")"
    if key.startswith("sheet") and "sheets" in v:
        extra = " bound iterations, worst " + str(v["worst"]) + " (" + "; ".join(
            f"{p['design']} {p['cells']}: {p['seconds']:.3g} s, {p['bound_iterations']:.0f} x bound"
            + (f" ({p['bound_iterations_runs'][0]:.0f}-{p['bound_iterations_runs'][1]:.0f} over its {p['runs']} runs)"
               if p.get("runs", 1) > 1 else " (one run: its spread not measured)" if p.get("runs") == 1 else "")
            + f", {p['bound_polar_iterations']:.0f} x bound with the polar iteration, {p['peak_rss_mib']:.0f} MiB"
            for p in v["sheets"]) + ")"
    if key == "gpu" and v.get("agreement"):
        extra = (" s" if v["value"] is not None else "") + "; against the CPU: " + "; ".join(
            f"{name}: energy {a['energy_relative_difference']:.1e} apart, shapes {a['max_distance_mm']:.2g} mm "
            f"({'agree' if a['agrees'] else 'DO NOT AGREE'}: at most {_fmt(a['allowed_mm'], '.2g')} mm)"
            for name, a in v["agreement"].items())
    if key == "newton" and v.get("last_contractions"):
        extra = " iterations; last contractions " + "; ".join(
            f"{name}: {', '.join(f'{x:.2g}' for x in xs) or '-'}" for name, xs in v["last_contractions"].items())
    if key == "growth" and v.get("span"):
        extra = f" ({v['span'][0]:.2f}-{v['span'][1]:.2f} over each size's runs)"
    if v.get("fem_value") is not None:
        extra += f" (FEM hinge levels: {v['fem_value']:.2f})"
    if "projected_1e6" in v:
        pj = v["projected_1e6"]
        extra += (f"; 10^6 cells not run, extrapolated {pj['seconds']:.3g} s and "
                  f"{pj['peak_rss_mib'] / 1024:.2g} GiB from the fitted exponents")
    return extra
