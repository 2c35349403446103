"""The benchmark (``gdfe bench``): GDFE's speed, against its own lower bound and the reference FEM.

A benchmark, not a timed test: every number is a median of repeated runs in one process,
on this machine (its core count and load are recorded with the results). Sections:

1. **Figure 6 hinges** (L = 1, 1.6, 2.6 mm, d = 0.33 mm, h = 0.29 mm, default resolution):
   iterations and seconds to convergence of the accelerated solvers (damped Newton with
   CG steps, the default; damped Newton with a factorised Hessian) beside Anderson mixing
   and the paper's plain alternation.
2. **Sheets from a PNG mask** at 10^3, 10^4, 10^5 cells (``--sizes`` for others, e.g.
   10^6): seconds to convergence with ``method="auto"``, peak memory (the maximum resident
   set size of a child process that runs only that size, Python and the libraries
   included, beside that child's resident size before the solve), and the time per
   iteration split into orientation, assembly and Newton-step linear algebra.
3. **The lower bound per iteration**, measured standalone on each sheet: one solve with
   the prefactorised n x n matrix for three right-hand sides plus one batched SVD over all
   cells. Our local-global iteration (one orientation step, one assembly step) is timed the
   same way, and the ratio stated; so is the time per outer iteration of the solver used.
4. **Sparse factorisation by measurement**: factorisation and three-column solve of the
   n x n matrix (and of the 3n x 3n Newton Hessian up to 10^4 cells) with each backend
   installed: SciPy's SuperLU, CHOLMOD through scikit-sparse, cholespy.
5. **GDFE against the nonlinear reference FEM** on the Figure 6 hinge of L = 1.6 mm at
   equal fold-angle error: each model is refined to its own finest mesh, its error is the
   distance of its fold angle from that finest answer, each model's time at a given error
   is interpolated (log-log) between its coarser levels, and the ratio of the times is
   taken at the smallest error both reach (and at two larger ones).

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
6.552702e-2); how other starts can end elsewhere is in the README ("Large designs and speed").

Factorisation choice (``gdfe.solver.FACTOR_BACKENDS``): CHOLMOD when scikit-sparse is
installed, else SuperLU; section 4 measures why (the last results are in
``docs/bench/bench.txt``), on the machine it runs on.

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

from gdfe._validation import GdfeError
from gdfe.paper import FIG6_D, FIG6_LENGTHS, H
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
SHEET_PIXEL = 0.1
SHEET_R = 0.7
SHEET_PERIOD = 2.0
SHEET_HINGE = 0.6

SETTINGS = {
    "full": {"hinge_lengths": FIG6_LENGTHS, "hinge_cells": 16, "repeats": 3, "plain_max_iter": 3000,
             "sheet_sizes": (1_000, 10_000, 100_000), "sheet_repeats": 3, "big_repeats": 1,
             "big": 50_000, "hessian_max": 10_000, "fem": True, "gdfe_levels": (4, 8, 16, 32, 64),
             "fem_levels": tuple(range(len(FEM_LEVELS)))},
    "quick": {"hinge_lengths": (1.0,), "hinge_cells": 4, "repeats": 1, "plain_max_iter": 100,
              "sheet_sizes": (64, 144, 256), "sheet_repeats": 1, "big_repeats": 1, "big": 50_000,
              "hessian_max": 256, "fem": False, "gdfe_levels": (2, 4, 8), "fem_levels": ()},
}

GOALS = {
    "hinges": "Figure 6 hinges: <= 50 iterations and <= 0.5 s each at default resolution",
    "fem": ">= 20x faster than the nonlinear reference FEM at equal fold-angle error",
    "sheet": "10^5-cell sheet converged in <= 30 s",
    "lower_bound": "time per iteration within 2x of the lower bound (solve + batched SVD)",
    "growth": "cost growth: fitted exponent of time against cell count",
}


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


def write_mask_pngs(directory, top, bottom):
    """Write masks as PNGs (black = passive material, row 0 at the largest y); return paths."""
    from PIL import Image

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, mask in (("top", top), ("bottom", bottom)):
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
    acc = [r for r in rows if r["auto"]]
    worst_it = max(r["iterations"] for r in acc)
    worst_s = max(r["seconds"] for r in acc)
    newton = [r for r in rows if r["method"] == "newton"]
    verdict = {"goal": GOALS["hinges"], "method": "/".join(sorted({r["method"] for r in acc})),
               "value": {"max_iterations": worst_it, "max_seconds": worst_s},
               "newton": {"max_iterations": max(r["iterations"] for r in newton),
                                  "max_seconds": max(r["seconds"] for r in newton),
                                  "converged": all(r["converged"] for r in newton)},
               "met": bool(all(r["converged"] for r in acc) and worst_it <= 50 and worst_s <= 0.5)}
    if cfg["hinge_cells"] != 16:
        verdict["note"] = f"measured at {cfg['hinge_cells']} cells across the hinge (--quick), not the default 16"
    return rows, verdict


# -- 2-4. sheets, lower bound, factorisations (one child process per size) ---------------------
def _factor_candidates():
    names = ["superlu"]
    try:
        import sksparse.cholmod  # noqa: F401
        names.append("cholmod")
    except ImportError:
        pass
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


def _time_factorisations(A, nrhs, repeats):
    out = {}
    rng = np.random.default_rng(0)
    b = rng.standard_normal((A.shape[0], nrhs))
    for name in _factor_candidates():
        t_fac, _, solve = median_time(lambda: _factor_with(name, A), repeats)
        t_sol, _, x = median_time(lambda: solve(b), max(3, repeats))
        x = np.asarray(x).reshape(b.shape)
        rel = float(np.abs(A @ x - b).max() / np.abs(b).max())
        out[name] = {"factorise_s": t_fac, "solve_s": t_sol, "relative_residual": rel}
    return out


def _sheet_case(args):
    """Everything measured on one sheet size; runs in a child process of its own."""
    import resource

    import gdfe
    from gdfe.solver import AUTO_NEWTON_CELLS, Solver, auto_method

    n_cells, repeats, mask_dir, hessian_max = args

    def rss_kib():  # maximum resident set size so far, KiB on Linux
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    top, bottom = mask_sheet(n_cells)
    ptop, pbot = write_mask_pngs(mask_dir, top, bottom)
    des = gdfe.from_masks(ptop, pbot, SHEET_PIXEL, SHEET_R, h=H, nz=1)
    # warm up (imports, first calls) on a small sheet of both methods, outside the timings
    for warm in (100, 2500) if n_cells > AUTO_NEWTON_CELLS else (100,):
        with _quiet("gdfe.solver"):
            gdfe.simulate(gdfe.from_masks(*mask_sheet(warm), SHEET_PIXEL, SHEET_R, h=H, nz=1), method="auto",
                          max_iter=2)
    base = rss_kib()
    method = auto_method(des)
    runs = []
    for _ in range(repeats):
        res = gdfe.simulate(des, method="auto")
        runs.append(res)
    peak = rss_kib()
    res = runs[len(runs) // 2]
    secs = [r.seconds for r in runs]
    med = statistics.median(secs)
    it = max(res.iterations, 1)
    tm = res.timings
    row = {"cells": des.n_cells, "points": des.mesh.n_points, "pixels": list(top.shape), "method": method,
           "converged": res.converged, "iterations": res.iterations, "residual": res.residual,
           "seconds": med, "seconds_all": secs, "peak_rss_mib": peak / 1024.0, "rss_before_mib": base / 1024.0,
           "z_range_mm": float(np.ptp(res.points[:, 2])), "x_extent_mm": float(np.ptp(res.points[:, 0])),
           "per_iteration_s": (res.seconds - tm.get("factorise", 0.0) - tm.get("start", 0.0)) / it,
           "init": "multilevel" if "start" in tm else "linear", "start_s": tm.get("start", 0.0),
           "energy": res.energy,
           "split_s": {k: v / it for k, v in tm.items() if k not in ("factorise", "start")},
           "factorise_s": tm.get("factorise", 0.0)}
    # lower bound: one prefactorised solve for 3 right-hand sides plus one batched SVD
    sv = Solver(des)
    V = res.points
    o = sv.orient(V)
    Q, S = o.Q, o.S
    rhs = np.asfortranarray(np.random.default_rng(0).standard_normal((len(sv.free), 3)))
    k = 5 if des.n_cells <= 20_000 else 3
    t_solve = median_time(lambda: sv.factor.solve(rhs), k)[0]
    t_svd = median_time(lambda: np.linalg.svd(S), k)[0]
    t_orient = median_time(lambda: sv.orient(V), k)[0]
    t_assemble = median_time(lambda: sv.assemble(Q, V[sv.pin]), k)[0]
    bound = t_solve + t_svd
    row["lower_bound"] = {"solve_3rhs_s": t_solve, "svd_s": t_svd, "bound_s": bound,
                          "orientation_s": t_orient, "assembly_s": t_assemble,
                          "local_global_s": t_orient + t_assemble,
                          "local_global_ratio": (t_orient + t_assemble) / bound,
                          "solver_iteration_ratio": row["per_iteration_s"] / bound}
    # factorisation backends on this sheet's matrices
    fac = {"n": _time_factorisations(sv.L_ff, 3, 1 if des.n_cells > 20_000 else 3)}
    if des.n_cells <= hessian_max:
        fdof = (3 * sv.free[:, None] + np.arange(3)).ravel()
        Hs = sv.hessian(Q, S, mu=1e-3)[fdof][:, fdof].tocsc()
        fac["3n_hessian"] = _time_factorisations(Hs, 1, 1)
    row["factorisation"] = fac
    return row


def _run_child(fn, args):
    """Run ``fn(args)`` in a fresh process (its peak memory is its own)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as ex:
        return ex.submit(fn, args).result()


def _sheets(cfg, sizes, mask_dir, progress):
    rows = []
    for n in _progress(sizes, "sheets", progress):
        reps = cfg["sheet_repeats"] if n < cfg["big"] else cfg["big_repeats"]
        try:
            rows.append(_run_child(_sheet_case, (int(n), reps, str(mask_dir), cfg["hessian_max"])))
        except MemoryError as exc:  # pragma: no cover - depends on the machine
            rows.append({"cells": int(n), "skipped": f"out of memory: {exc}"})
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


# -- 5. the reference FEM ---------------------------------------------------------------------
def _fem_comparison(cfg, progress):
    try:
        import reference_fem as rf
    except ModuleNotFoundError as exc:
        return {"skipped": f"reference FEM not importable ({exc})"}
    if not hasattr(rf, "solve_nonlinear"):
        return {"skipped": "reference_fem has no solve_nonlinear"}
    import gdfe

    L, d = FEM_HINGE
    gdfe_rows = []
    for n in _progress(cfg["gdfe_levels"], "GDFE hinge levels", progress):
        des = gdfe.hinge(L, d=d, h=H, width=FEM_WIDTH, panel_length=FEM_PANEL, cell_size=L / n)
        med, times, res = median_time(lambda: gdfe.simulate(des, method="auto"), cfg["repeats"])
        gdfe_rows.append({"level": f"{n} cells across the hinge", "method": res.method, "elements": des.n_cells, "seconds": med,
                          "seconds_all": times, "alpha_rad": float(gdfe.fold_angle(res)),
                          "converged": res.converged})
    fem_rows = []
    levels = [FEM_LEVELS[k] for k in cfg["fem_levels"]]
    for i, (cap, per, layers, zr, junc) in enumerate(_progress(levels, "FEM levels", progress)):
        size = min(cap, L / per)
        strip = rf.hinge_mesh(L, d, H, width=FEM_WIDTH, panel_length=FEM_PANEL, element_size=size,
                              layers_per_ply=layers, z_ratio=zr, junction_size=junc * size)
        reps = 1 if i == len(levels) - 1 else cfg["repeats"]
        med, times, res = median_time(lambda: rf.solve_nonlinear(strip, rf.BilayerMaterial()), reps)
        fem_rows.append({"level": f"size {size:.3g} mm, {layers} layers/ply", "elements": int(strip.n_elements),
                         "dofs": int(res.dofs), "seconds": med, "seconds_all": times,
                         "alpha_rad": float(rf.fold_angle(res)), "converged": bool(res.converged)})
    for rows in (gdfe_rows, fem_rows):
        error_against_finest(rows)
    out = {"hinge": {"L_mm": L, "d_mm": d, "h_mm": H, "width_mm": FEM_WIDTH, "panel_mm": FEM_PANEL},
           "gdfe": gdfe_rows, "fem_nonlinear": fem_rows,
           "error_rule": "error = |alpha - alpha at the model's own finest level|; each model's time at "
                         "a common error is interpolated log-log between its non-reference levels; the "
                         "ratio is taken at the smallest error both models reach"}
    g = [(r["error_rad"], r["seconds"]) for r in gdfe_rows[:-1]]
    f = [(r["error_rad"], r["seconds"]) for r in fem_rows[:-1]]
    if not g or not f:
        out["skipped"] = "too few levels for a comparison"
        return out
    lo = max(min(e for e, _ in g), min(e for e, _ in f))
    hi = min(max(e for e, _ in g), max(e for e, _ in f))
    if not 0 < lo <= hi:
        out["skipped"] = (f"the models' error ranges do not overlap (GDFE down to {min(e for e, _ in g):.2e}, "
                          f"FEM down to {min(e for e, _ in f):.2e} rad)")
        return out
    points = sorted({lo, hi, float(np.sqrt(lo * hi))})
    out["at_error"] = [{"error_rad": e, "gdfe_seconds": _time_at_error(g, e), "fem_seconds": _time_at_error(f, e),
                        "ratio": _time_at_error(f, e) / _time_at_error(g, e)} for e in points]
    best = out["at_error"][0]
    out.update({"target_error_rad": best["error_rad"], "fem_seconds": best["fem_seconds"],
                "gdfe_seconds": best["gdfe_seconds"], "ratio": best["ratio"]})
    return out


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
def run(quick=False, sizes=None, fem=None, out=None, progress=None):
    """Run the benchmark; return its results (a JSON-ready dict).

    Parameters
    ----------
    quick : bool
        Tiny sizes and one repeat (seconds): checks that everything runs, measures little.
    sizes : sequence of int, optional
        Sheet sizes [cells]; default 10^3, 10^4, 10^5 (``quick``: 64, 144, 256).
    fem : bool, optional
        Run the FEM comparison (default: not with ``quick``).
    out : path, optional
        Directory for ``bench.json``, ``bench_scaling.png`` and the mask PNGs.
    progress : bool, optional
        Progress bars (default: when stderr is a terminal).
    """
    import sys

    cfg = dict(SETTINGS["quick" if quick else "full"])
    if sizes is not None:
        sizes = [int(s) for s in sizes]
        if not sizes or min(sizes) < 4:
            raise GdfeError(f"sizes: expected cell counts >= 4, got {sizes}")
        cfg["sheet_sizes"] = tuple(sizes)
    if fem is not None:
        cfg["fem"] = bool(fem)
        if fem and not cfg["fem_levels"]:
            cfg["fem_levels"] = tuple(range(len(FEM_LEVELS)))
            cfg["gdfe_levels"] = SETTINGS["full"]["gdfe_levels"]
    if progress is None:
        progress = sys.stderr.isatty()
    t0 = time.perf_counter()
    result = {"mode": "quick" if quick else "full", "machine": _machine()}
    hinge_rows, hinge_verdict = _hinges(cfg)
    result["hinges"] = hinge_rows
    with tempfile.TemporaryDirectory() as tmp:
        mask_dir = Path(out) / "masks" if out is not None else Path(tmp)
        result["sheets"] = _sheets(cfg, cfg["sheet_sizes"], mask_dir, progress)
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


def _verdicts(result, hinge_verdict, cfg):
    sheets = [r for r in result["sheets"] if "skipped" not in r]
    v = {"hinges": hinge_verdict}
    fc = result["fem_comparison"]
    if "ratio" in fc:
        v["fem"] = {"goal": GOALS["fem"], "value": fc["ratio"], "met": bool(fc["ratio"] >= 20)}
    else:
        v["fem"] = {"goal": GOALS["fem"], "value": None, "met": None, "note": fc.get("skipped", "")}
    big = [r for r in sheets if 50_000 <= r["cells"] <= 200_000]
    if big:
        r = big[0]
        v["sheet"] = {"goal": GOALS["sheet"], "value": r["seconds"], "cells": r["cells"],
                      "met": bool(r["converged"] and r["seconds"] <= 30.0),
                      "cores": result["machine"]["cores"]}
    else:
        v["sheet"] = {"goal": GOALS["sheet"], "value": None, "met": None,
                      "note": "no sheet of about 10^5 cells in this run"}
    if sheets:
        r = max(sheets, key=lambda r: r["cells"])
        lb = r["lower_bound"]
        v["lower_bound"] = {"goal": GOALS["lower_bound"], "cells": r["cells"],
                            "value": lb["local_global_ratio"],
                            "solver_iteration_ratio": lb["solver_iteration_ratio"],
                            "met": bool(lb["local_global_ratio"] <= 2.0),
                            "note": "value: one local-global iteration (orientation + assembly) over the "
                                    "bound; solver_iteration_ratio: one outer iteration of the method used"}
    else:
        v["lower_bound"] = {"goal": GOALS["lower_bound"], "value": None, "met": None}
    conv = [r for r in sheets if r["converged"]]
    expo = _fit_exponent([r["cells"] for r in conv], [r["seconds"] for r in conv]) if len(conv) >= 2 else None
    fem_expo = None
    if "fem_nonlinear" in fc:
        rows = fc["fem_nonlinear"]
        fem_expo = _fit_exponent([r["elements"] for r in rows], [r["seconds"] for r in rows])
    v["growth"] = {"goal": GOALS["growth"], "value": expo, "fem_value": fem_expo,
                   "met": None if expo is None else True, "stated": True,
                   "note": "time ~ cells^exponent, least squares in log-log over the converged sheets"}
    if expo is not None and not any(r["cells"] >= 500_000 for r in sheets):
        last = max(conv, key=lambda r: r["cells"])
        scale = 1e6 / last["cells"]
        mem_expo = _fit_exponent([r["cells"] for r in conv], [r["peak_rss_mib"] for r in conv])
        v["growth"]["projected_1e6"] = {"seconds": last["seconds"] * scale ** expo,
                                        "peak_rss_mib": last["peak_rss_mib"] * scale ** max(mem_expo, 1.0),
                                        "note": "not run: extrapolated from the largest sheet with the fitted "
                                                "exponents (memory at least linear)"}
    return v


def _write(result, out):
    from gdfe.io import write_json

    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "bench.json", result)
    try:
        plot(result, out / "bench_scaling.png")
    except ModuleNotFoundError as exc:  # matplotlib is optional
        log.warning("no plot: %s", exc)


def plot(result, path):
    """Time against element count: GDFE sheets and hinge levels, and the nonlinear FEM."""
    from gdfe._plotting import pyplot
    from gdfe.io import save_figure

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    sheets = [r for r in result["sheets"] if "skipped" not in r and r["converged"]]
    if sheets:
        x = np.array([r["cells"] for r in sheets], float)
        y = np.array([r["seconds"] for r in sheets])
        ax.loglog(x, y, "o-", color="C0", label="GDFE, mask sheet (method auto)")
        lb = np.array([r["lower_bound"]["local_global_s"] for r in sheets])
        ax.loglog(x, lb, "s:", color="C0", alpha=0.6, label="GDFE, one local-global iteration")
        expo = result["verdicts"]["growth"]["value"]
        if expo is not None:
            ax.text(x[-1], y[-1], f"  slope {expo:.2f}", va="center", color="C0")
    fc = result["fem_comparison"]
    if "gdfe" in fc:
        ax.loglog([r["elements"] for r in fc["gdfe"]], [r["seconds"] for r in fc["gdfe"]], "^-", color="C2",
                  label=f"GDFE, hinge L = {fc['hinge']['L_mm']} mm")
        ax.loglog([r["elements"] for r in fc["fem_nonlinear"]], [r["seconds"] for r in fc["fem_nonlinear"]],
                  "v-", color="C3", label=f"nonlinear FEM, hinge L = {fc['hinge']['L_mm']} mm")
    ax.set(xlabel="elements", ylabel="seconds to convergence",
           title=f"gdfe bench ({result['machine']['cores']} cores, {result['machine']['factor_backend']})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


# -- text -------------------------------------------------------------------------------------
def _fmt(x, spec=".3g"):
    return "-" if x is None else format(x, spec)


def _verdict_word(v):
    if v.get("stated"):
        return "STATED"
    return {True: "MET", False: "NOT MET", None: "n/a"}[v["met"]]


def format_table(res):
    """The benchmark as text tables."""
    m = res["machine"]
    lines = [f"gdfe bench ({res['mode']}): {m['cores']} cores, {m['platform']}, factorisation {m['factor_backend']},"
             f" load average {_fmt(m['load_average_1min_at_start'], '.2f')} at start,"
             f" {_fmt(m.get('load_average_1min_at_end'), '.2f')} at end", ""]
    lines.append("Figure 6 hinges (d = 0.33 mm, h = 0.29 mm)")
    lines.append(f"  {'L mm':>5} {'cells':>6} {'method':>9} {'conv':>5} {'iter':>6} {'seconds':>8} {'angle rad':>9}")
    for r in res["hinges"]:
        lines.append(f"  {r['L_mm']:5.2g} {r['cells']:6d} {r['method']:>9} {str(r['converged']):>5} "
                     f"{r['iterations']:6d} {r['seconds']:8.3f} {r['fold_angle_rad']:9.4f}")
    lines += ["", "Mask sheets (corrugation, pixel 0.1 mm, R = 0.7, nz = 1); peak = max RSS of a child process"]
    lines.append(f"  {'cells':>7} {'method':>9} {'start':>10} {'conv':>5} {'iter':>4} {'seconds':>8} {'start s':>7} "
                 f"{'peak MiB':>8} "
                 f"{'s/iter':>7} {'orient':>7} {'assemb':>7} {'newton':>7} | {'solve':>7} {'svd':>7} "
                 f"{'bound':>7} {'LG':>7} {'LG/bd':>5} {'it/bd':>6}")
    for r in res["sheets"]:
        if "skipped" in r:
            lines.append(f"  {r['cells']:7d} skipped: {r['skipped']}")
            continue
        sp_, lb = r["split_s"], r["lower_bound"]
        lines.append(f"  {r['cells']:7d} {r['method']:>9} {r.get('init', 'linear'):>10} {str(r['converged']):>5} "
                     f"{r['iterations']:4d} {r['seconds']:8.2f} {r.get('start_s', 0.0):7.2f} "
                     f"{r['peak_rss_mib']:8.0f} {r['per_iteration_s']:7.3f} "
                     f"{sp_.get('orientation', 0):7.3f} {sp_.get('assembly', 0):7.3f} {sp_.get('newton', 0):7.3f} | "
                     f"{lb['solve_3rhs_s']:7.4f} {lb['svd_s']:7.4f} {lb['bound_s']:7.4f} {lb['local_global_s']:7.4f} "
                     f"{lb['local_global_ratio']:5.2f} {lb['solver_iteration_ratio']:6.1f}")
    lines += ["  (start = starting shape; start s = its seconds, inside the total: the coarse levels of the "
              "multilevel start; per-iteration columns in seconds, fine level only; LG = one orientation + "
              "one assembly step; bound = 3-column solve + batched SVD)", "", "Sparse factorisation (median seconds: factorise / solve)"]
    for r in res["sheets"]:
        if "skipped" in r:
            continue
        for kind, backends in r["factorisation"].items():
            cells = ", ".join(f"{k} {v['factorise_s']:.3g} / {v['solve_s']:.3g}" for k, v in backends.items())
            lines.append(f"  {r['cells']:7d} {kind:>10}: {cells}")
    fc = res["fem_comparison"]
    lines += ["", "GDFE against the nonlinear reference FEM (hinge L = 1.6 mm)"]
    if "gdfe" in fc:
        for name in ("gdfe", "fem_nonlinear"):
            for r in fc[name]:
                lines.append(f"  {name:>13} {r['level']:>28} {r['elements']:6d} el {r['seconds']:8.3f} s "
                             f"alpha {r['alpha_rad']:.4f} err {r['error_rad']:.2e}")
    for a in fc.get("at_error", []):
        lines.append(f"  at error {a['error_rad']:.2e} rad: FEM {a['fem_seconds']:.3f} s, GDFE "
                     f"{a['gdfe_seconds']:.4f} s: ratio {a['ratio']:.1f}")
    if "skipped" in fc:
        lines.append(f"  skipped: {fc['skipped']}")
    lines += ["", "Goals"]
    for v in res["verdicts"].values():
        val = v["value"]
        if isinstance(val, dict):
            val = ", ".join(f"{k} {_fmt(x)}" for k, x in val.items())
        else:
            val = _fmt(val)
        extra = ""
        if "newton" in v:
            dn = v["newton"]
            extra = (f" with method {v['method']} (method newton: {dn['max_iterations']} iterations,"
                     f" {dn['max_seconds']:.3g} s)")
        if "solver_iteration_ratio" in v:
            extra = f" (outer iteration of the solver used: {v['solver_iteration_ratio']:.1f}x)"
        if v.get("fem_value") is not None:
            extra = f" (FEM hinge levels: {v['fem_value']:.2f})"
        if "projected_1e6" in v:
            pj = v["projected_1e6"]
            extra += (f"; 10^6 cells not run, extrapolated {pj['seconds']:.3g} s and "
                      f"{pj['peak_rss_mib'] / 1024:.2g} GiB from the fitted exponents")
        note = f" [{v['note']}]" if v.get("note") and (v["met"] is None or "quick" in v["note"]) else ""
        lines.append(f"  {_verdict_word(v):>7}  {v['goal']}: {val}{extra}{note}")
    lines.append(f"\n({res['seconds']:.0f} s in all)")
    return "\n".join(lines)
