"""The stopping test at scale: how far from the solution a solve stops, against ``tol`` (not in the paper).

Two mask sheets of the benchmark (:mod:`studies.bench`): the corrugation (0.1 mm pixels,
R = 0.7, a buckling, frustrated sheet) and the Figure 8 dome (the 8 mm disc with rings,
at the pixel that gives the cell count). Each is solved once far past round-off
(``tol = REFERENCE_TOL``) and then at every ``tol`` of :data:`TOLS` and at the default
(``tol=None``, :func:`gdfe.solver.default_tol`). For every solve: the iterations, the
seconds, the solver's estimate of its distance to the solution and the distance it really
stopped at (largest vertex distance from the reference after a rigid alignment), beside
the accuracy it was asked for, ``STEP_TOL_FACTOR tol h``, and the part's size.

Run ``python -m studies.stopping [--out DIR] [--resolution R]`` or ``gdfe study stopping``
(cells: coarse 10^3, default 10^4, fine 10^5); writes ``stopping.png`` and ``stopping.json``.
"""

from __future__ import annotations

import numpy as np

from studies._common import check_resolution, finish, headline, main_of, pyplot

NAME = "stopping"
CELLS = {"coarse": 1_000, "default": 10_000, "fine": 100_000}
TOLS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
REFERENCE_TOL = 1e-10
#: The tolerances (units of h) whose solves are checked against the accuracy they asked for.
TIGHT = 1e-4
DESIGNS = ("corrugation", "fig08-dome")


def _design(kind, n_cells):
    import gdfe
    from gdfe.paper import H
    from studies.bench import SHEET_PIXEL, SHEET_R, freeform_sheet, mask_sheet

    if kind == "corrugation":
        return gdfe.from_masks(*mask_sheet(n_cells), SHEET_PIXEL, SHEET_R, h=H, nz=1)
    top, bottom, film, pixel, R = freeform_sheet(n_cells, kind.split("-", 1)[1])
    return gdfe.from_masks(top, bottom, pixel, R, h=H, nz=1, film=None if film.all() else film)


def _solves(kind, n_cells):
    import gdfe
    from gdfe.solver import STEP_TOL_FACTOR

    des = _design(kind, n_cells)
    size = float(np.linalg.norm(np.ptp(des.mesh.points, axis=0)))
    ref = gdfe.simulate(des, tol=REFERENCE_TOL, on_drift="stop")
    rows = []
    for tol in (None,) + TOLS:
        res = gdfe.simulate(des, tol=tol)
        d = gdfe.shape_distance(ref.points, res.points)
        rows.append({"tol": res.tol, "default": tol is None, "asked_mm": STEP_TOL_FACTOR * res.tol * des.h,
                     "iterations": res.iterations, "seconds": res.seconds, "converged": res.converged,
                     "estimate_mm": res.error_estimate_mm, "distance_max_mm": d["max"], "distance_rms_mm": d["rms"],
                     "energy": res.energy, "drift": res.drift})
    return {"design": kind, "cells": des.n_cells, "size_mm": size, "h_mm": des.h,
            "reference": {"tol": REFERENCE_TOL, "iterations": ref.iterations, "seconds": ref.seconds,
                          "converged": ref.converged, "residual": ref.residual, "energy": ref.energy,
                          "drift": ref.drift, "estimate_mm": ref.error_estimate_mm},
            "solves": rows}


def run(resolution="default", out=None):
    """Solve each design at every tolerance; return the distances, estimates, iterations and seconds."""
    from gdfe.solver import SHAPE_ACCURACY

    check_resolution(resolution)
    n = CELLS[resolution]
    designs = [_solves(kind, n) for kind in DESIGNS]
    # where the reference itself is not past the tightest tol, the distances below it are not measured
    asked, bounded, loose, default_rel, saved = 0.0, 0.0, 0.0, 0.0, []
    for dsg in designs:
        ref_floor = dsg["reference"]["estimate_mm"] or 0.0
        for r in dsg["solves"]:
            r["measured"] = r["distance_max_mm"] > 2.0 * ref_floor
            if not r["measured"]:
                continue
            if r["default"] or r["tol"] <= TIGHT:
                asked = max(asked, r["distance_max_mm"] / r["asked_mm"])
            if r["estimate_mm"]:
                ratio = r["distance_max_mm"] / r["estimate_mm"]
                if r["default"] or r["tol"] <= TIGHT / 10:
                    bounded = max(bounded, ratio)
                else:
                    loose = max(loose, ratio)
        dflt = next(r for r in dsg["solves"] if r["default"])
        default_rel = max(default_rel, dflt["distance_max_mm"] / dsg["size_mm"])
        old = next(r for r in dsg["solves"] if not r["default"] and r["tol"] == 1e-7)
        saved.append(old["seconds"] / max(dflt["seconds"], 1e-9))
    hl = [
        headline(f"distance from the solution over the accuracy asked, tol <= {TIGHT:g} and the default", asked,
                 None, 1.0, "le", note="asked: STEP_TOL_FACTOR tol h"),
        headline(f"distance from the solution over the solver's estimate, tol <= {TIGHT / 10:g} and the default",
                 bounded, None, 2.0, "le",
                 note="near the solution the estimate (rigid motions left out) is right within a factor 2"),
        headline("default tol: distance from the solution over the part's size", default_rel, None,
                 SHAPE_ACCURACY, "le", note="gdfe.solver.SHAPE_ACCURACY"),
    ]
    converged = all(r["converged"] for d in designs for r in d["solves"])
    summary = {
        "paper": "the paper stops its alternation on the plain step's residual; it gives no study of the tolerance",
        "ours": "; ".join(
            f"{d['design']} ({d['cells']} cells, {d['size_mm']:.1f} mm): default tol {next(r for r in d['solves'] if r['default'])['tol']:.2g} "
            f"stops {next(r for r in d['solves'] if r['default'])['distance_max_mm']:.2g} mm from the solution in "
            f"{next(r for r in d['solves'] if r['default'])['iterations']} iterations" for d in designs),
        "verdict": ("near the solution the shape stops within the accuracy asked and about the solver's estimate; the "
                    "default (1e-6 of the part's size) is far below a printer's or a scan's resolution"),
        "discrepancy": (f"at looser tol the solve is still in its damped steps and the estimate falls short of the "
                        f"distance by up to {loose:.3g}x (the asked accuracy itself is met below tol {TIGHT:g}); time "
                        f"at tol = 1e-7 over time at the default: {', '.join(f'{x:.2f}' for x in saved)}"),
    }
    result = {"study": NAME, "figure": "not in the paper (issue 14)", "title": "the stopping test against tol",
              "resolution": resolution, "designs": designs, "headlines": hl, "converged": converged,
              "summary": summary}
    return finish(result, out, plot)


def plot(result, out):
    from studies._draw import save_figure

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for k, d in enumerate(result["designs"]):
        rows = [r for r in d["solves"] if not r["default"]]
        asked = np.array([r["asked_mm"] for r in rows])
        dist = np.array([r["distance_max_mm"] for r in rows])
        est = np.array([r["estimate_mm"] or np.nan for r in rows])
        lab = f"{d['design']} ({d['cells']} cells)"
        axes[0].loglog(asked, np.maximum(dist, 1e-16), "o-", color=f"C{k}", label=f"{lab}: distance")
        axes[0].loglog(asked, est, "x:", color=f"C{k}", label=f"{lab}: estimate")
        dflt = next(r for r in d["solves"] if r["default"])
        axes[0].loglog([dflt["asked_mm"]], [max(dflt["distance_max_mm"], 1e-16)], "*", ms=12, color=f"C{k}")
        axes[1].semilogx([r["tol"] for r in rows], [r["seconds"] for r in rows], "o-", color=f"C{k}", label=lab)
        axes[1].semilogx([dflt["tol"]], [dflt["seconds"]], "*", ms=12, color=f"C{k}")
    lim = axes[0].get_xlim()
    axes[0].loglog(lim, lim, "k--", lw=0.8, label="asked")
    axes[0].set(xlabel="asked accuracy STEP_TOL_FACTOR tol h [mm]", ylabel="largest distance from the solution [mm]",
                title="where the solve stops (star: default tol)")
    axes[0].legend(fontsize=7)
    axes[1].set(xlabel="tol [h]", ylabel="seconds", title="cost")
    axes[1].legend(fontsize=7)
    save_figure(fig, out, NAME, title="The stopping test against tol")


main = main_of(__name__)


if __name__ == "__main__":
    raise SystemExit(main())
