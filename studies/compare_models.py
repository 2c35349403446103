"""GDFE against the reference FEM and Eq. 1: fold angles, curl shapes and speed.

Compares, for the paper's Table 1 (18 folding tests, h = 0.29 mm) and the three hinges of its
Figure 6 (h = 0.29 mm, d = 0.33 mm, L = 1, 1.6, 2.6 mm):

- fold angles from Eq. 1 (K = 0.3706 as printed), from GDFE with the paper's calibration (R from
  Eq. 3 with K = 0.3706, only where that gives R > 0, i.e. d > 0.15 mm), from GDFE with K
  refitted to Table 1 (not where that gives R < 0.01, which no film reaches: Table 1's d = 0.15 mm
  specimen, R = 0.0038), from the linear FEM (panel rotation, and kappa L) and the nonlinear FEM
  (both with the Table-1 calibration of the FEM: E_passive/E_active = 8.58, eps* = -0.160),
  against the measured angles;
- curl shapes: GDFE's film mid-surface against the nonlinear FEM's after rigid alignment (RMS and
  largest distance), for the Figure 6 hinges and a freeform S-strip, with GDFE's R from the
  refitted K and with R fitted to the FEM shape;
- speed: GDFE, linear FEM and nonlinear FEM on the L = 1.6 mm hinge at four resolutions each, the
  angle error of each against its own finest solution, medians of repeated runs in one process.

All hinges are 1 mm wide with panels of about 2 mm (a whole number of GDFE cells), the same in
both models. Units: mm and rad.

Run ``python -m studies.compare_models [--resolution coarse|default|fine] [--out DIR]``
(or ``gdfe study compare``); writes ``compare_models.png`` (angles),
``compare_models_shapes.png``, ``compare_models_runtime.png`` and ``compare_models.json``.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

import gdfe
import reference_fem as rf
from gdfe.paper import FIG6_D, FIG6_LENGTHS, FIG6_SIMULATED, H
# FEM mesh levels of the runtime study, the same as the benchmark's: (size cap [mm], elements
# per hinge length, layers per ply, z growth, junction element / size)
from studies.bench import FEM_LEVELS
from studies._common import check_resolution, error_against_finest, finish, headline, main_of, median_time, pyplot

log = logging.getLogger(__name__)

NAME = "compare_models"

WIDTH = 1.0
PANEL = 2.0
#: The freeform strip: (length [mm], passive coat) from left to right, coat thickness FREEFORM_D.
FREEFORM = ((2.0, "both"), (2.4, "bottom"), (1.2, "both"), (3.2, "top"), (2.0, "both"))
FREEFORM_D = 0.24
FREEFORM_PIXEL = 0.1
RUNTIME_HINGE = (1.6, FIG6_D)
#: Angle accuracy [rad] at which the runtime headline compares the models.
SPEED_TOL = 0.01

SETTINGS = {
    "coarse": {"fem": "coarse", "gdfe_cells": 8, "gdfe_levels": (4, 8, 16, 32),
               "fem_levels": (0, 1, 2), "repeats": 1, "fit_tol": 1e-3},
    "default": {"fem": "default", "gdfe_cells": 16, "gdfe_levels": (4, 8, 16, 32, 64),
                "fem_levels": (0, 1, 2, 3), "repeats": 3, "fit_tol": 2e-4},
    "fine": {"fem": "fine", "gdfe_cells": 32, "gdfe_levels": (4, 8, 16, 32, 64),
             "fem_levels": (0, 1, 2, 3), "repeats": 5, "fit_tol": 1e-4},
}


def _progress(iterable, desc):
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        return iterable
    return tqdm(iterable, desc=desc, leave=False, disable=None)


# ---------------------------------------------------------------------------------------------
# models


def _panel(L, cells):
    """Panel length of GDFE's hinge with ``cells`` cells across it (whole cells, near PANEL)."""
    dx = L / cells
    return max(1, round(PANEL / dx)) * dx


def _fem(L, d, preset, nonlinear, material=None, cells=16):
    strip = rf.hinge_mesh(L, d, H, width=WIDTH, panel_length=_panel(L, cells), resolution=preset)
    mat = rf.BilayerMaterial() if material is None else material
    res = rf.solve_nonlinear(strip, mat) if nonlinear else rf.solve_linear(strip, mat)
    return res


def _gdfe_hinge(L, R, cells=16):
    des = gdfe.hinge(L, R=R, h=H, width=WIDTH, panel_length=PANEL, cell_size=L / cells)
    return gdfe.simulate(des)


def _gdfe_freeform(R):
    codes = {"both": gdfe.Material.RIGID, "bottom": gdfe.Material.CONTRACT_TOP,
             "top": gdfe.Material.CONTRACT_BOTTOM}
    cols = []
    for length, coat in FREEFORM:
        cols += [int(codes[coat])] * int(round(length / FREEFORM_PIXEL))
    ny = int(round(WIDTH / FREEFORM_PIXEL))
    mat2d = np.repeat(np.array(cols)[:, None], ny, axis=1)
    des = gdfe.grid_design(mat2d, R, h=H, pixel=FREEFORM_PIXEL, nz=1)
    return gdfe.simulate(des)


def _fem_freeform(preset):
    size = rf.HINGE_RESOLUTIONS[preset]["size_cap"]
    strip = rf.layered_strip(FREEFORM, H, FREEFORM_D, width=WIDTH, element_size=size,
                             layers_per_ply=rf.HINGE_RESOLUTIONS[preset]["layers_per_ply"],
                             junction_size=size * rf.HINGE_RESOLUTIONS[preset]["junction"],
                             z_ratio=rf.HINGE_RESOLUTIONS[preset]["z_ratio"],
                             meta={"kind": "freeform"})
    return rf.solve_nonlinear(strip, rf.BilayerMaterial())


# ---------------------------------------------------------------------------------------------
# shapes


def _gdfe_midsurface(result, shift):
    """GDFE film mid-surface: mean of matching bottom and top vertices, in FEM coordinates."""
    P = result.design.mesh.points
    V = result.points
    h = result.design.h
    bot = np.nonzero(np.abs(P[:, 2]) < 1e-9)[0]
    top = np.nonzero(np.abs(P[:, 2] - h) < 1e-9)[0]
    bot = bot[np.lexsort((P[bot, 1], P[bot, 0]))]
    top = top[np.lexsort((P[top, 1], P[top, 0]))]
    if len(bot) != len(top) or not np.allclose(P[bot, :2], P[top, :2]):
        raise RuntimeError("GDFE mesh: bottom and top vertices do not pair up")
    ref = 0.5 * (P[bot] + P[top]) + shift
    return ref, 0.5 * (V[bot] + V[top])


def _fem_interpolator(result):
    """Deformed FEM mid-surface as a function of reference (x, y)."""
    from scipy.interpolate import RegularGridInterpolator

    X, x = rf.midsurface(result)
    xs = np.unique(np.round(X[:, 0], 9))
    ys = np.unique(np.round(X[:, 1], 9))
    ix = np.searchsorted(xs, np.round(X[:, 0], 9))
    iy = np.searchsorted(ys, np.round(X[:, 1], 9))
    grid = np.full((xs.size, ys.size, 3), np.nan)
    grid[ix, iy] = x
    if np.isnan(grid).any():
        raise RuntimeError("FEM mid-surface is not a full tensor grid")
    method = "pchip" if min(xs.size, ys.size) >= 4 else "linear"
    return RegularGridInterpolator((xs, ys), grid, method=method, bounds_error=False,
                                   fill_value=None)


def _distance(fem_at, gdfe_result, shift):
    ref, pts = _gdfe_midsurface(gdfe_result, shift)
    target = fem_at(ref[:, :2])
    d = gdfe.shape_distance(target, pts)
    return d["rms"], d["max"], target, d["aligned"], ref


def _fit_R(simulate, fem_at, shift, tol):
    """R whose GDFE shape is closest (RMS after alignment) to the FEM shape."""
    from scipy.optimize import minimize_scalar

    cache = {}

    def rms(R):
        res = simulate(R)
        cache[R] = res
        return _distance(fem_at, res, shift)[0] if res.converged else np.inf

    opt = minimize_scalar(rms, bounds=(0.5, 0.995), method="bounded", options={"xatol": tol})
    return float(opt.x), cache.get(opt.x) or simulate(opt.x)


def _shape_case(name, fem_res, shift, simulate_R, R_refit, tol, fem_angle):
    fem_at = _fem_interpolator(fem_res)
    row = {"case": name, "fem_nonlinear_converged": fem_res.converged,
           "fem_alpha_rad": fem_angle}
    curves = {}
    for label, R in (("refit", R_refit), ("fitted", None)):
        if R is None:
            R, g = _fit_R(simulate_R, fem_at, shift, tol)
        else:
            g = simulate_R(R)
        rms, mx, target, aligned, ref = _distance(fem_at, g, shift)
        row[f"gdfe_{label}_R"] = R
        row[f"gdfe_{label}_rms_mm"] = rms
        row[f"gdfe_{label}_max_mm"] = mx
        row[f"gdfe_{label}_converged"] = bool(g.converged)
        if "hinge" in name:
            row[f"gdfe_{label}_alpha_rad"] = float(gdfe.fold_angle(g))
        centre = np.abs(ref[:, 1] - ref[np.argmin(np.abs(ref[:, 1])), 1]) < 1e-9
        order = np.argsort(ref[centre, 0])
        curves[label] = aligned[centre][order][:, [0, 2]]
        curves["fem"] = target[centre][order][:, [0, 2]]
    return row, curves


# ---------------------------------------------------------------------------------------------
# study


def _simulable_ratio(cal, d, h):
    """Eq. 3's contraction ratio of ``cal`` at ``d``, ``h`` and None, or the ratio (None where Eq. 3 gives
    R <= 0) and why GDFE does not simulate it: below ``gdfe._validation.R_MIN`` no shrink film contracts so far
    (Eq. 1 refitted to Table 1 gives R = 0.0038 at its d = 0.15 mm specimen)."""
    from gdfe._validation import R_MIN

    try:
        R = float(cal.ratio(d, h))
    except ValueError:
        return None, f"Eq. 3 gives R <= 0 at d = {d:g} mm"
    if R < R_MIN:
        return R, f"Eq. 3 gives R = {R:.2g} at d = {d:g} mm, below the {R_MIN:g} that any shrink film reaches"
    return R, None


def _angle_table(cfg):
    tests = gdfe.load_folding_tests(gdfe.TABLE1)
    paper = gdfe.Calibration()
    refit = gdfe.Calibration.fit(tests)
    specimens = [("table1", float(L), float(d), float(h), float(a))
                 for L, d, h, a in zip(tests.L, tests.d, tests.h, tests.alpha)]
    specimens += [("fig6", L, FIG6_D, H, None) for L in FIG6_LENGTHS]
    rows, fem_nl = [], {}
    for source, L, d, h, measured in _progress(specimens, "specimens"):
        row = {"source": source, "L_mm": L, "d_mm": d, "h_mm": h, "measured_rad": measured,
               "eq1_paper_rad": float(paper.alpha(L, d, h))}
        for key, cal in (("gdfe_paper", paper), ("gdfe_refit", refit.calibration)):
            R, why = _simulable_ratio(cal, d, h)
            row[f"{key}_R"], row[f"{key}_rad"], row[f"{key}_not_simulated"] = R, None, why
            row[f"{key}_converged"] = None
            if why is None:
                g = _gdfe_hinge(L, R=R, cells=cfg["gdfe_cells"])
                row[f"{key}_converged"] = bool(g.converged)
                row[f"{key}_rad"] = float(gdfe.fold_angle(g)) if g.converged else None
        lin = _fem(L, d, cfg["fem"], False, cells=cfg["gdfe_cells"])
        row["fem_linear_rad"] = rf.fold_angle(lin)
        row["fem_linear_kappa_L_rad"] = rf.curvature(lin) * L
        nl = _fem(L, d, cfg["fem"], True, cells=cfg["gdfe_cells"])
        row["fem_nonlinear_rad"] = rf.fold_angle(nl) if nl.converged else None
        row["fem_nonlinear_converged"] = nl.converged
        row["fem_nonlinear_iterations"] = nl.iterations
        if source == "fig6":
            row["paper_gdfe_rad"] = FIG6_SIMULATED[FIG6_LENGTHS.index(L)]
            fem_nl[L] = nl
        rows.append(row)
    summary = {}
    t1 = [r for r in rows if r["source"] == "table1"]
    for key in ("eq1_paper_rad", "gdfe_paper_rad", "gdfe_refit_rad", "fem_linear_rad",
                "fem_linear_kappa_L_rad", "fem_nonlinear_rad"):
        pairs = [(r[key], r["measured_rad"]) for r in t1 if r[key] is not None]
        err = np.array([p - m for p, m in pairs])
        summary[key] = {"n": len(pairs), "rmse_rad": float(np.sqrt(np.mean(err**2))),
                        "mean_error_rad": float(err.mean()),
                        "max_abs_error_rad": float(np.abs(err).max())}
    return rows, summary, {"paper_K": paper.K, "refit_K": refit.K}, fem_nl


def _shapes(cfg, fem_nl, refit_K):
    refit = gdfe.Calibration(K=refit_K)
    rows, curves = [], {}
    for L in FIG6_LENGTHS:
        res = fem_nl[L]
        shift = np.array([-0.5 * L, -0.5 * WIDTH, 0.0])
        row, c = _shape_case(f"hinge L={L:g}", res, shift,
                             lambda R, L=L: _gdfe_hinge(L, R=R, cells=cfg["gdfe_cells"]),
                             float(refit.ratio(FIG6_D, H)), cfg["fit_tol"],
                             rf.fold_angle(res) if res.converged else None)
        rows.append(row)
        curves[row["case"]] = c
    ff = _fem_freeform(cfg["fem"])
    total = sum(length for length, _ in FREEFORM)
    row, c = _shape_case("freeform S-strip", ff, np.array([-0.5 * total, -0.5 * WIDTH, 0.0]),
                         _gdfe_freeform, float(refit.ratio(FREEFORM_D, H)), cfg["fit_tol"], None)
    row["fem_turning_angle_rad"] = rf.turning_angle(ff)
    row["segments"] = [list(s) for s in FREEFORM]
    row["d_mm"] = FREEFORM_D
    rows.append(row)
    curves[row["case"]] = c
    return rows, curves


def _runtime(cfg, R_gdfe):
    L, d = RUNTIME_HINGE
    mat = rf.BilayerMaterial()
    models = {}

    def gdfe_run(n):
        res = _gdfe_hinge(L, R=R_gdfe, cells=n)
        return float(gdfe.fold_angle(res)), res.converged, res.design.mesh.n_points * 3

    def fem_run(level, nonlinear):
        cap, per, layers, zr, junc = FEM_LEVELS[level]
        size = min(cap, L / per)
        strip = rf.hinge_mesh(L, d, H, width=WIDTH, panel_length=PANEL, element_size=size,
                              layers_per_ply=layers, z_ratio=zr, junction_size=junc * size)
        res = rf.solve_nonlinear(strip, mat) if nonlinear else rf.solve_linear(strip, mat)
        return rf.fold_angle(res), res.converged, res.dofs

    plans = {"gdfe": [(f"{n} cells across the hinge", lambda n=n: gdfe_run(n))
                      for n in cfg["gdfe_levels"]],
             "fem_linear": [(f"level {k}", lambda k=k: fem_run(k, False)) for k in cfg["fem_levels"]],
             "fem_nonlinear": [(f"level {k}", lambda k=k: fem_run(k, True))
                               for k in cfg["fem_levels"]]}
    for name, plan in plans.items():
        rows = []
        for i, (label, fn) in enumerate(_progress(plan, name)):
            finest = i == len(plan) - 1
            med, times, (alpha, ok, dofs) = median_time(fn, 1 if finest else cfg["repeats"])
            rows.append({"resolution": label, "dofs": int(dofs), "seconds_median": med,
                         "seconds_all": times, "alpha_rad": alpha, "converged": bool(ok)})
        models[name] = error_against_finest(rows, out="error_vs_finest_rad")
    return {"hinge": {"L_mm": L, "d_mm": d, "h_mm": H, "gdfe_R": R_gdfe},
            "fem_levels": [dict(zip(("size_cap_mm", "per_hinge", "layers_per_ply", "z_ratio",
                                     "junction_fraction"), lv)) for lv in FEM_LEVELS],
            "repeats": cfg["repeats"], "models": models}


def run(resolution="default", out=None):
    """Compute the angle table, the shape distances and the runtime comparison.

    Writes ``compare_models.json`` and the three PNGs into ``out`` (when given).

    Parameters
    ----------
    resolution : {"coarse", "default", "fine"}
        Mesh presets of both models and the number of timing repeats.
    out : str or Path, optional
        Folder for the JSON and PNG files.

    Returns
    -------
    dict
        ``angles`` (one row per specimen), ``angle_rmse`` (per model against Table 1),
        ``calibration``, ``shapes`` (per case), ``runtime`` (per model and resolution),
        ``headlines``, ``summary`` and ``converged`` (the shared study plumbing).
    """
    check_resolution(resolution)
    cfg = SETTINGS[resolution]
    t0 = time.perf_counter()
    rows, summary, cal, fem_nl = _angle_table(cfg)
    shapes, curves = _shapes(cfg, fem_nl, cal["refit_K"])
    R_run = next(s["gdfe_fitted_R"] for s in shapes if s["case"] == f"hinge L={RUNTIME_HINGE[0]:g}")
    runtime = _runtime(cfg, R_run)
    mat = rf.BilayerMaterial()
    converged = (all(r["fem_nonlinear_converged"] for r in rows)
                 and all(r["fem_nonlinear_rad"] is not None for r in rows)
                 and all(r[f"{k}_converged"] is not False for r in rows for k in ("gdfe_paper", "gdfe_refit"))
                 and all(s[f"gdfe_{m}_converged"] and s["fem_nonlinear_converged"]
                         for s in shapes for m in ("refit", "fitted"))
                 and all(r["converged"] for rs in runtime["models"].values() for r in rs))
    result = {
        "study": NAME, "figure": "Table 1, Fig. 6",
        "title": "GDFE against the reference FEM: angles, shapes, speed", "resolution": resolution,
        "fem_material": {"E_ratio": mat.E_ratio, "eigenstrain": mat.eigenstrain,
                         "nu": mat.nu_active, "nonlinear_model": "neohookean"},
        "calibration": cal, "geometry": {"width_mm": WIDTH, "panel_length_mm": PANEL, "h_mm": H},
        "angles": rows, "angle_rmse": summary, "shapes": shapes,
        "shape_curves": {k: {m: v.tolist() for m, v in c.items()} for k, c in curves.items()},
        "runtime": runtime, "converged": bool(converged), "seconds": time.perf_counter() - t0,
    }
    result["headlines"], result["summary"] = _headlines(result)
    return finish(result, out, plot)


def time_to_accuracy(rows, tol):
    """Shortest median time [s] of a resolution whose angle is within ``tol`` [rad] of the finest."""
    ok = [r["seconds_median"] for r in rows[:-1] if r["error_vs_finest_rad"] <= tol]
    return min(ok) if ok else None


def _speedup(runtime, model, tol=SPEED_TOL):
    """Time ``model`` needs for an angle within ``tol`` of its finest, over GDFE's time."""
    m = runtime["models"]
    t_model, t_gdfe = time_to_accuracy(m[model], tol), time_to_accuracy(m["gdfe"], tol)
    return float("nan") if t_model is None or t_gdfe is None else t_model / t_gdfe


def _headlines(res):
    rm = res["angle_rmse"]
    fitted = max(s["gdfe_fitted_rms_mm"] for s in res["shapes"])
    hl = [
        headline("RMSE of the linear FEM against Table 1", rm["fem_linear_rad"]["rmse_rad"], None,
                 0.30, "le", unit="rad", paper_text="Eq. 1 fits Table 1 with R^2 about 0.8",
                 note="two parameters (E ratio, eigenstrain) fitted to the same 18 tests; "
                      "leave-one-out RMSE 0.301 rad (gdfe fem calibrate)"),
        headline("RMSE of the nonlinear FEM (same parameters) against Table 1",
                 rm["fem_nonlinear_rad"]["rmse_rad"], None, 0.35, "le", unit="rad"),
        headline("RMSE of Eq. 1 with K = 0.3706 against Table 1", rm["eq1_paper_rad"]["rmse_rad"],
                 None, 0.5, "le", unit="rad", expect=False,
                 paper_text="K = 0.3706 from a fit to Table 1",
                 note="the printed K overshoots {} of {} tests (mean error {:+.1f} rad): it does not "
                      "reproduce Table 1".format(
                          sum(r["eq1_paper_rad"] > r["measured_rad"] for r in res["angles"]
                              if r["source"] == "table1"),
                          rm["eq1_paper_rad"]["n"], rm["eq1_paper_rad"]["mean_error_rad"])),
        headline("largest RMS distance GDFE (R fitted) - nonlinear FEM mid-surface", fitted, None,
                 0.15, "le", unit="mm"),
        headline(f"nonlinear FEM time / GDFE time for an angle within {SPEED_TOL:g} rad of the finest",
                 _speedup(res["runtime"], "fem_nonlinear"), None, 1.0, "ge",
                 note="wall time, medians of repeated runs in one process, on the L = 1.6 mm hinge; "
                      "linear FEM / GDFE: {:.3g}".format(_speedup(res["runtime"], "fem_linear"))),
    ]
    f6 = [r for r in res["angles"] if r["source"] == "fig6"]
    ours = ("Table 1 RMSE: FEM linear {:.3f}, FEM nonlinear {:.3f}, GDFE (K refitted) {:.3f}, "
            "Eq. 1 (K = 0.3706) {:.2f} rad; Fig. 6 hinges fold {} rad in the nonlinear FEM; "
            "GDFE-FEM RMS shape distance {} mm with R fitted").format(
        rm["fem_linear_rad"]["rmse_rad"], rm["fem_nonlinear_rad"]["rmse_rad"],
        rm["gdfe_refit_rad"]["rmse_rad"], rm["eq1_paper_rad"]["rmse_rad"],
        ", ".join(f"{r['fem_nonlinear_rad']:.2f}" for r in f6 if r["fem_nonlinear_rad"] is not None),
        ", ".join(f"{s['gdfe_fitted_rms_mm']:.3f}" for s in res["shapes"]))
    summary = {
        "paper": "Fig. 6: GDFE 1.04, 1.66, 2.70 rad against Eq. 1's 1.05, 1.68, 2.73 rad "
                 "(h = 0.29, d = 0.33 mm, R = 0.7)",
        "ours": ours,
        "verdict": "the calibrated FEM fits Table 1 better than Eq. 1 refitted; GDFE's shapes match "
                   "the FEM's within a tenth of a millimetre once R is fitted",
        "discrepancy": "With the FEM calibrated to Table 1, the Fig. 6 hinges fold far less than the "
                       "paper's Fig. 6 angles: Table 1's own tests near d = 0.33 mm fold 0.65-1.05 "
                       "rad, while Eq. 1 with K = 0.3706 gives 1.05-2.73 rad for L = 1-2.6 mm.",
    }
    return hl, summary


_MODELS = (("eq1_paper_rad", "Eq. 1 (K = 0.3706)", "k", "x"),
           ("gdfe_paper_rad", "GDFE, paper's R (Eq. 3)", "tab:orange", "s"),
           ("gdfe_refit_rad", "GDFE, K refitted to Table 1", "tab:red", "D"),
           ("fem_linear_rad", "FEM linear", "tab:blue", "o"),
           ("fem_nonlinear_rad", "FEM nonlinear", "tab:green", "^"))
YMAX = 4.0


def plot(result, out):
    """Write the angle, shape and runtime figures of a :func:`run` result into ``out``."""
    plt = pyplot()
    out = Path(out)
    rows = result["angles"]
    t1 = [r for r in rows if r["source"] == "table1"]
    f6 = [r for r in rows if r["source"] == "fig6"]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 5))
    for key, label, colour, marker in _MODELS:
        pts = [(r["measured_rad"], r[key]) for r in t1 if r[key] is not None]
        if not pts:
            continue
        m, p = np.array(pts).T
        rmse = result["angle_rmse"][key]["rmse_rad"]
        off = int((p > YMAX).sum())
        a1.scatter(m, np.minimum(p, YMAX), c=colour, marker=marker, s=28, alpha=0.8,
                   label=f"{label}: RMSE {rmse:.2f} rad (n = {len(pts)})"
                         + (f", {off} above {YMAX:g} rad drawn at the top" if off else ""))
        f = [(r["L_mm"], r[key]) for r in f6 if r[key] is not None]
        if f:
            a2.plot(*np.array(f).T, marker=marker, color=colour, label=label)
    a2.plot([r["L_mm"] for r in f6], [r["paper_gdfe_rad"] for r in f6], "k*", ms=11,
            label="GDFE in the paper's Fig. 6")
    lim = [0, 3.6]
    a1.plot(lim, lim, "k:", lw=1)
    a1.set(xlim=lim, ylim=[0, YMAX * 1.03], xlabel="measured fold angle [rad]",
           ylabel="predicted fold angle [rad]", title="Table 1 (18 tests, h = 0.29 mm)")
    a1.legend(fontsize=7, loc="upper left")
    a2.set(xlabel="hinge width L [mm]", ylabel="fold angle [rad]",
           title="Figure 6 hinges (h = 0.29, d = 0.33 mm)")
    a2.legend(fontsize=7)
    for a in (a1, a2):
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "compare_models.png", dpi=120)
    plt.close(fig)

    cases = result["shapes"]
    ncol = 2
    nrow = -(-len(cases) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(12, 2.6 * nrow), squeeze=False)
    for ax in axes.flat[len(cases):]:
        ax.set_visible(False)
    for ax, case in zip(axes.flat, cases):
        c = result["shape_curves"][case["case"]]
        fem = np.array(c["fem"])
        ax.plot(*fem.T, "k-", lw=2.5, label="FEM nonlinear")
        for label, style in (("refit", "r--"), ("fitted", "b-.")):
            g = np.array(c[label])
            ax.plot(*g.T, style, lw=1.5,
                    label=f"GDFE R = {case[f'gdfe_{label}_R']:.3f} ({label}): RMS "
                          f"{case[f'gdfe_{label}_rms_mm']:.3f} mm")
        ax.set_aspect("equal")
        ax.set(title=f"{case['case']}: film mid-line, GDFE aligned onto FEM",
               xlabel="x [mm]", ylabel="z [mm]")
        ax.legend(fontsize=7, loc="best")
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "compare_models_shapes.png", dpi=120)
    plt.close(fig)

    rt = result["runtime"]
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    names = {"gdfe": ("GDFE", "tab:red"), "fem_linear": ("FEM linear", "tab:blue"),
             "fem_nonlinear": ("FEM nonlinear", "tab:green")}
    for key, rows_m in rt["models"].items():
        pts = [(r["seconds_median"], r["error_vs_finest_rad"]) for r in rows_m[:-1]]
        t, e = np.array(pts).T
        ax.loglog(t, np.maximum(e, 1e-9), "o-", color=names[key][1], label=names[key][0])
        for r in rows_m[:-1]:
            ax.annotate(f"{r['dofs']}", (r["seconds_median"], max(r["error_vs_finest_rad"], 1e-9)),
                        fontsize=6, xytext=(3, 3), textcoords="offset points")
    hg = rt["hinge"]
    ax.set(xlabel="median wall time per solve [s]", ylabel="|alpha - alpha_finest| [rad]",
           title=f"hinge L = {hg['L_mm']:g}, d = {hg['d_mm']:g} mm (labels: unknowns)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "compare_models_runtime.png", dpi=120)
    plt.close(fig)


#: ``python -m studies.compare_models [--out DIR] [--resolution R] [--json]``.
main = main_of(__name__)


def format_table(res):
    """The angle table, the shape distances and the runtime as text."""
    def f(x):
        return "   -  " if x is None else f"{x:6.3f}"

    lines = [f"{'src':6} {'L':>5} {'d':>5} {'meas':>6} {'Eq.1':>6} {'GDFEp':>6} {'GDFEr':>6} "
             f"{'FEMlin':>6} {'kL':>6} {'FEMnl':>6}"]
    for r in res["angles"]:
        lines.append(f"{r['source']:6} {r['L_mm']:5.2f} {r['d_mm']:5.2f} {f(r['measured_rad'])} "
                     f"{f(r['eq1_paper_rad'])} {f(r['gdfe_paper_rad'])} {f(r['gdfe_refit_rad'])} "
                     f"{f(r['fem_linear_rad'])} {f(r['fem_linear_kappa_L_rad'])} "
                     f"{f(r['fem_nonlinear_rad'])}")
    lines.append("RMSE against Table 1 [rad]: " + ", ".join(
        f"{k.replace('_rad', '')} {v['rmse_rad']:.3f} (n={v['n']})"
        for k, v in res["angle_rmse"].items()))
    for s in res["shapes"]:
        lines.append(f"{s['case']:18} GDFE refit R={s['gdfe_refit_R']:.3f}: RMS "
                     f"{s['gdfe_refit_rms_mm']:.3f} max {s['gdfe_refit_max_mm']:.3f} mm | "
                     f"fitted R={s['gdfe_fitted_R']:.3f}: RMS {s['gdfe_fitted_rms_mm']:.3f} max "
                     f"{s['gdfe_fitted_max_mm']:.3f} mm")
    for name, rows in res["runtime"]["models"].items():
        lines.append(name + ": " + "; ".join(
            f"{r['dofs']} dofs {r['seconds_median']:.3g} s err {r['error_vs_finest_rad']:.1e}"
            for r in rows))
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
