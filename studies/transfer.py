"""A diagnosed deformation model carried through the simulator, to Table 1 and to the paper's parts.

1. **Held out through GDFE.** For each of Table 1's 18 tests, the other 17 are diagnosed
   (:func:`gdfe.diagnosis.diagnose`: the catalogue of effects, the model chosen on held-out
   error), the chosen model is saved as a model file and read back
   (:class:`gdfe.DeformationModel`), and the held-out specimen is simulated with GDFE and that
   model (:func:`gdfe.hinge` with ``model=``; the panels made long enough that they stay rigid
   beyond the model's ``hinge_length`` reach). The held-out RMSE of those simulations is set
   beside the diagnosis's own closed-form held-out RMSE, GDFE with only K refitted (the paper's
   Eq. 3 refitted fold by fold) and the reference FEM calibrated to Table 1 (its
   leave-one-out RMSE, :func:`reference_fem.fit_to_table`).
2. **The paper's parts with the Table 1 model.** The model diagnosed from all 18 tests
   re-simulates the Figure 7 tube and crane, the Figure 8 freeform plates and the Figure 9
   letters, beside the paper's model (Eq. 3, K = 0.3706, d = 0.33 mm): turn and fold angles,
   curvatures, and the distance between the two shapes after the best rigid motion.
3. **Letters designed with the Table 1 model.** The Figure 9 letters planned with the model
   (:func:`gdfe.inverse.plan_strip` with ``model=``: block counts chosen so the model's turn of
   each couple, its spreading included, is the target's) at the thinnest coat Table 1 tested,
   folded with the same model, against the paper's letters under the paper's model.

Run ``python -m studies.transfer [--out DIR] [--resolution R] [--json]`` or
``gdfe study transfer``; writes ``transfer.png``, ``transfer.json`` and the 18 model files
under ``models/``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gdfe import paper
from studies._common import check_resolution, finish, headline, main_of, n_jobs, pyplot

NAME = "transfer"
H = paper.H
D = paper.FIG6_D
#: Cells across the hinge of the held-out specimens, per resolution.
CELLS = {"coarse": 8, "default": 16, "fine": 32}
#: Goal of the held-out RMSE through simulation [rad].
GOAL = 0.13
#: Whether the goal is met (measured by this study; see its JSON): the regression checks expect
#: what was measured, so a change either way is flagged.
GOAL_MET = False
#: How far the held-out RMSE of the model family chosen on all tests (refitted fold by fold) may be
#: through GDFE from the same through its closed form [rad]: what the simulator loses, without the
#: variance of choosing the model again in every fold (the largest single-specimen difference is
#: about 0.014 rad at 16 cells across the hinge).
FAMILY_SIMULATOR_TOL = 0.01
#: Resolution of each part study's designs (the part studies' own presets).
PARTS = {"coarse": "coarse", "default": "coarse", "fine": "default"}


def _cell(L, cells):
    """Cell size of a held-out hinge: ``cells`` across it, and square cells across the 0.5 mm strip."""
    return min(L / cells, 0.25)


def _specimen(L, d, h, model, cells):
    """The held-out hinge: panels that outlast the model's reach (hinge_length / 2, plus 1 mm)."""
    import gdfe

    reach = max(0.0, model.value("lambda") / 2) if "hinge_length" in model.mechanisms else 0.0
    cell = _cell(L, cells)
    return gdfe.hinge(L, d=d, h=h, model=model, panel_length=reach + max(1.0, 4 * cell), cell_size=cell)


def _fold(job):
    """One test held out: diagnose the others, save and read back the model, simulate the test."""
    import gdfe
    from gdfe.diagnosis import diagnose

    i, cells, out, family = job
    tests = gdfe.load_folding_tests(gdfe.TABLE1)
    n = len(tests)
    keep = np.arange(n) != i
    sub = gdfe.FoldingTests(L=tests.L[keep], d=tests.d[keep], h=tests.h[keep], alpha=tests.alpha[keep],
                            extra={k: v[keep] for k, v in tests.extra.items()})
    diag = diagnose(sub, check=None)
    model = gdfe.DeformationModel.from_effect_fit(diag.best, n_tests=n - 1)
    if out is not None:  # through the file, as a user would
        from pathlib import Path

        path = model.save(Path(out) / "models" / f"without_test_{i + 1:02d}.toml")
        model = gdfe.load_model(path)
    L, d, h = float(tests.L[i]), float(tests.d[i]), float(tests.h[i])
    res = gdfe.simulate(_specimen(L, d, h, model, cells))
    refit = gdfe.paper_model(gdfe.fit_reading(sub, "eq1", n_boot=0).K)
    res_k = gdfe.simulate(gdfe.hinge(L, d=d, h=h, model=refit, cell_size=_cell(L, cells)))
    # the model family chosen on all 18 tests, its parameters refitted to these 17
    fixed_fit = next((f for f in diag.fits if f.name == family), None)
    if fixed_fit is None:
        raise RuntimeError(f"the family {family!r} chosen on all tests is not among the fits of fold {i + 1}")
    fixed = gdfe.DeformationModel.from_effect_fit(fixed_fit, n_tests=n - 1)
    res_f = gdfe.simulate(_specimen(L, d, h, fixed, cells))
    return {"test": i + 1, "L_mm": L, "d_mm": d, "h_mm": h, "measured_rad": float(tests.alpha[i]),
            "reading_offset_rad": reading_offset(diag.best), "family_reading_offset_rad": reading_offset(fixed_fit),
            "model": model.name, "params": {k: p.value for k, p in model.params.items()},
            "warnings": len(model.warnings),
            "closed_form_rad": float(model.hinge_angle(L, d, h)),
            "gdfe_rad": float(gdfe.fold_angle(res)), "gdfe_converged": bool(res.converged),
            "refit_K_gdfe_rad": float(gdfe.fold_angle(res_k)), "refit_K_converged": bool(res_k.converged),
            "family_gdfe_rad": float(gdfe.fold_angle(res_f)), "family_converged": bool(res_f.converged),
            "family_closed_form_rad": float(fixed.hinge_angle(L, d, h)),
            "n_cells": int(res.design.n_cells)}


def reading_offset(fit):
    """The reading offset [rad] a diagnosed model was fitted with (0 without ``reading_offset``): how the
    tests were read, not how the parts fold, so it is not carried to parts (the model file leaves it out)
    but it is added back where a model's fold is compared with a test's reading."""
    return float(fit.param_dict()["offset"]) if "reading_offset" in fit.model.effects else 0.0


def held_out(resolution, out=None):
    """Part 1: each test predicted by the model diagnosed from the others, through GDFE."""
    import gdfe
    from gdfe.diagnosis import diagnose
    from gdfe.parallel import parallel_map

    n = len(gdfe.load_folding_tests(gdfe.TABLE1))
    cells = CELLS[resolution]
    full = diagnose(gdfe.TABLE1, check=None)
    family = full.best.name
    rows = parallel_map(_fold, [(i, cells, None if out is None else str(out), family) for i in range(n)],
                        n_jobs=n_jobs(resolution), desc="transfer: Table 1 folds")
    y = np.array([r["measured_rad"] for r in rows])

    def rmse(key, offset=None):
        """RMSE of the readings: the part's fold plus the reading offset its model was fitted with."""
        read = np.array([r[key] + (r[offset] if offset else 0.0) for r in rows])
        return float(np.sqrt(np.mean((read - y) ** 2)))

    return {"rows": rows, "rmse_gdfe_rad": rmse("gdfe_rad", "reading_offset_rad"),
            "rmse_closed_form_nested_rad": rmse("closed_form_rad", "reading_offset_rad"),
            "rmse_refit_K_gdfe_rad": rmse("refit_K_gdfe_rad"), "family": family,
            "rmse_family_gdfe_rad": rmse("family_gdfe_rad", "family_reading_offset_rad"),
            "rmse_family_closed_form_rad": rmse("family_closed_form_rad", "family_reading_offset_rad"),
            "diagnosis_best": full.best.name, "diagnosis_loo_rmse_rad": float(full.best.loo_rmse),
            "models_chosen": {m: sum(r["model"] == m for r in rows) for m in sorted({r["model"] for r in rows})},
            "converged": all(r["gdfe_converged"] and r["refit_K_converged"] and r["family_converged"] for r in rows),
            "cells": cells}


def _fem_held_out():
    """The reference FEM calibrated to Table 1: its leave-one-out RMSE (coarse meshes)."""
    try:
        import reference_fem as rf

        import gdfe

        t = gdfe.load_folding_tests(gdfe.TABLE1)
        fit = rf.fit_to_table(t.L, t.d, t.h, t.alpha, resolution="coarse", progress=False)
    except ModuleNotFoundError as exc:  # scikit-fem is an extra
        return {"skipped": f"reference FEM not available ({exc})"}
    return {"loo_rmse_rad": float(fit.loo_rmse), "rmse_rad": float(fit.rmse), "E_ratio": float(fit.E_ratio),
            "eigenstrain": float(fit.eigenstrain), "resolution": "coarse"}


def _with_d(design, d=D):
    """A design made with R, given the passive thickness its one-side-coated cells were printed with."""
    import gdfe

    mat = design.material
    one = (mat == gdfe.Material.CONTRACT_TOP) | (mat == gdfe.Material.CONTRACT_BOTTOM)
    meta = {**design.meta, "d_mm": d}
    return dataclasses.replace(design, d=np.where(one, d, np.nan), meta=meta)


def _compare(name, res_paper, res_model, **extra):
    import gdfe

    dist = gdfe.shape_distance(res_paper.points, res_model.points)
    return {"part": name, "rms_mm": dist["rms"], "max_mm": dist["max"],
            "converged": bool(res_paper.converged and res_model.converged), **extra}


def parts(model, resolution):
    """Part 2: the Figure 7-9 parts with the paper's model and with ``model``."""
    import gdfe
    from gdfe import inverse as inv
    from studies import fig07_crease_fold as f7
    from studies import fig08_freeform as f8

    R = float(gdfe.paper_model().ratio(D))
    res_part = PARTS[resolution]
    rows = []
    # the tube (isotropic shrink, one cell across: the fig07 headline specimen)
    des = f7.tube_design(R, f7.TUBE[res_part]["div"], 1, 1.0)
    tubes = []
    for m in (gdfe.paper_model(), model):
        dm = m.apply(_with_d(des))
        res = inv.simulate_strip(dm, max_iter=3000)
        _, uv, _ = inv.strip_midline(res)
        tubes.append((res, float(gdfe.curvature_profile(res)["turn"]), float(np.linalg.norm(uv[-1] - uv[0]))))
    rows.append(_compare("tube (Fig. 7)", tubes[0][0], tubes[1][0], paper_turn_rad=tubes[0][1],
                         model_turn_rad=tubes[1][1], paper_gap_mm=tubes[0][2], model_gap_mm=tubes[1][2]))
    # the crane
    des, _ = f7.crane_design(R, f7.CRANE_PIXEL[res_part])
    cranes = [gdfe.simulate(m.apply(_with_d(des)), max_iter=400) for m in (gdfe.paper_model(), model)]
    folds = []
    for name, a, b, direction, _target in f7.CRANE_FOLDS:
        folds.append({"fold": name, "paper_rad": f7.panel_angle(cranes[0].points, des, a, b, direction),
                      "model_rad": f7.panel_angle(cranes[1].points, des, a, b, direction)})
    rows.append(_compare("crane (Fig. 7)", *cranes, folds=folds))
    # the freeform plates
    pixel = f8.PIXEL[res_part]
    nmask = int(round(f8.SIZE / pixel))
    for pattern in f8.PATTERNS:
        top, bottom, film = f8.masks(pattern, nmask, pixel)
        plates, curv = [], []
        for m in (gdfe.paper_model(), model):
            des = gdfe.from_masks(top, bottom, pixel, h=H, nz=1, film=film, d=D, model=m)
            res = gdfe.simulate(des, init="flat", max_iter=400)
            XY, M = f8.midsurface(res.points, des)
            curv.append(f8.curvatures(XY, M, np.array([f8.SIZE / 2, f8.SIZE / 2]), f8.RHO))
            plates.append(res)
        rows.append(_compare(f"{pattern} plate (Fig. 8)", *plates,
                             paper_curvature={k: curv[0][k] for k in ("k_xx", "k_xy", "k_yy")},
                             model_curvature={k: curv[1][k] for k in ("k_xx", "k_xy", "k_yy")}))
    # the letters, printed by the paper's rule for the paper's R, folded by each model
    cell = {"coarse": 0.25, "default": 0.125}[res_part]
    for glyph in dict.fromkeys("Concordia"):
        plan = inv.plan_strip(inv.target_from_letter(glyph), h=H, R=R, cell=cell)
        des = plan.design(width=0.5, ny=1, nz=1)
        checks = [inv.check_strip(plan, design=m.apply(_with_d(des))) for m in (gdfe.paper_model(), model)]
        dev = [c.deviation for c in checks]
        rows.append(_compare(f"letter {glyph} (Fig. 9)", checks[0].result, checks[1].result,
                             paper_max_dev_mm=None if dev[0] is None else dev[0].max,
                             model_max_dev_mm=None if dev[1] is None else dev[1].max))
    return rows


#: Passive thickness the letters are designed with under the Table 1 model [mm]: the thinnest
#: coat Table 1 tested, the strongest contraction the data support (no extrapolation).
DESIGN_D = 0.11


def designed_letters(model, resolution):
    """Part 3: the Figure 9 letters designed with ``model`` (at :data:`DESIGN_D`) and simulated
    with it, beside the letters the paper's model designs and folds (d = 0.33 mm)."""
    import gdfe
    from gdfe import inverse as inv

    cell = {"coarse": 0.25, "default": 0.125}[PARTS[resolution]]
    R = float(gdfe.paper_model().ratio(D))
    rows = []
    for glyph in dict.fromkeys("Concordia"):
        target = inv.target_from_letter(glyph)
        paper_plan = inv.plan_strip(target, h=H, R=R, cell=cell)
        plan = inv.plan_strip(target, h=H, cell=cell, model=model, d=DESIGN_D, clamp=True)
        checks = [inv.check_strip(paper_plan), inv.check_strip(plan)]
        dev = [None if c.deviation is None else c.deviation.max for c in checks]
        rows.append({"letter": glyph, "paper_max_dev_mm": dev[0], "model_max_dev_mm": dev[1],
                     "model_clamped": bool(plan.pattern.clamped.any()),
                     "model_turns_rad": plan.pattern.angle_printed.tolist(),
                     "target_turns_rad": plan.pattern.angle.tolist(),
                     "converged": bool(checks[0].converged and checks[1].converged)})
    return {"d_mm": DESIGN_D, "contraction": float(model.contraction(DESIGN_D, H)),
            "paper_contraction": float(1 - R), "rows": rows}


def run(resolution="default", out=None):
    """Part 1 (held-out Table 1 through GDFE) and part 2 (the paper's parts with the Table 1 model)."""
    from pathlib import Path

    import gdfe
    from gdfe.diagnosis import diagnose

    check_resolution(resolution)
    out = None if out is None else Path(out)
    ho = held_out(resolution, out)
    fem = _fem_held_out()
    full = diagnose(gdfe.TABLE1, check=None)
    model = gdfe.DeformationModel.from_effect_fit(full.best, data=gdfe.TABLE1, n_tests=18)
    if out is not None:
        model.save(out / "models" / "table1.toml")
    rows = parts(model, resolution)
    letters = designed_letters(model, resolution)
    converged = (ho["converged"] and all(r["converged"] for r in rows)
                 and all(r["converged"] for r in letters["rows"]))
    tube = rows[0]
    hl = [
        headline("held-out RMSE through GDFE with the diagnosed model", ho["rmse_gdfe_rad"], None, GOAL, "le",
                 unit="rad", paper_text="(the paper holds nothing out)", expect=GOAL_MET,
                 note=f"each of 18 tests simulated with the model diagnosed from the other 17; goal {GOAL} rad"),
        headline("the same, through the model's closed form (model chosen per fold)",
                 ho["rmse_closed_form_nested_rad"], None, GOAL, "le", unit="rad", expect=GOAL_MET,
                 note="the diagnosis's own held-out RMSE of its chosen model, "
                      f"{ho['diagnosis_loo_rmse_rad']:.3f} rad, chooses the model on all 18 tests first"),
        headline(f"the model family chosen on all 18 tests ({ho['family']}), refitted per fold: held-out RMSE "
                 "through GDFE minus through its closed form",
                 abs(ho["rmse_family_gdfe_rad"] - ho["rmse_family_closed_form_rad"]), None, FAMILY_SIMULATOR_TOL,
                 "le", unit="rad",
                 note=f"through GDFE {ho['rmse_family_gdfe_rad']:.4f} rad, closed form "
                      f"{ho['rmse_family_closed_form_rad']:.4f} rad (the diagnosis's own held-out figure, "
                      f"{ho['diagnosis_loo_rmse_rad']:.4f} rad): what the simulator loses; no goal line, because "
                      "the choice of the family saw the held-out test"),
        headline("GDFE with only K refitted, held out", ho["rmse_refit_K_gdfe_rad"], None, GOAL, "le", unit="rad",
                 expect=False, note="Eq. 3 refitted fold by fold: what the paper's principle can do"),
        headline("largest |GDFE - closed form| of a held-out specimen",
                 max(abs(r["gdfe_rad"] - r["closed_form_rad"]) for r in ho["rows"]), None, 0.02, "le", unit="rad",
                 note="the model's mechanisms on the simulated hinge reproduce its closed form"),
    ]
    if "loo_rmse_rad" in fem:
        hl.append(headline("reference FEM calibrated to Table 1, leave-one-out RMSE", fem["loo_rmse_rad"], None,
                           GOAL, "le", unit="rad", expect=False, note="coarse FEM meshes (gdfe fem calibrate)"))
    worst_paper = max(r["paper_max_dev_mm"] for r in letters["rows"])
    worst_model = max(r["model_max_dev_mm"] for r in letters["rows"])
    hl.append(headline("letters designed and folded with the Table 1 model: largest deviation", worst_model, None,
                       worst_paper, "le", unit="mm", expect=False,
                       note=f"designed at d = {DESIGN_D} mm; the paper's model's letters reach "
                            f"{worst_paper:.3f} mm (the bound); clamped letters: "
                            + (", ".join(r["letter"] for r in letters["rows"] if r["model_clamped"]) or "none")))
    warned = model.warnings
    summary = {
        "paper": "K = 0.3706 calibrated on Table 1 and used for every part; no held-out error",
        "ours": (f"held out through GDFE: {ho['rmse_gdfe_rad']:.3f} rad (closed form nested "
                 f"{ho['rmse_closed_form_nested_rad']:.3f}; the family {ho['family']} refitted per fold "
                 f"{ho['rmse_family_gdfe_rad']:.3f}, diagnosis LOO of its chosen model "
                 f"{ho['diagnosis_loo_rmse_rad']:.3f}), K refitted {ho['rmse_refit_K_gdfe_rad']:.3f}, FEM "
                 + (f"{fem['loo_rmse_rad']:.3f}" if "loo_rmse_rad" in fem else "not run")
                 + f" rad; Table 1 model {model.name}: tube turn {tube['paper_turn_rad']:.2f} -> "
                   f"{tube['model_turn_rad']:.2f} rad"),
        "verdict": ("the diagnosed model transfers through the simulator" if ho["rmse_gdfe_rad"] <= GOAL
                    else "the diagnosed model does not reach the goal through the simulator"),
        "discrepancy": ("The Table 1 model's parameters are physically doubtful: " + "; ".join(warned)
                        if warned else "none"),
    }
    result = {"study": NAME, "figure": "Table 1, Figs. 7-9", "title": "a diagnosed deformation model through the simulator",
              "resolution": resolution, "headlines": hl, "converged": bool(converged), "summary": summary,
              "held_out": ho, "fem": fem, "table1_model": model.as_dict(), "parts": rows,
              "designed_letters": letters}
    return finish(result, out, plot)


def plot(result, out):
    from gdfe.io import save_figure

    plt = pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.8))
    rows = result["held_out"]["rows"]
    y = np.array([r["measured_rad"] for r in rows])
    a = ax[0]
    for key, label, mk in (("gdfe_rad", "GDFE + diagnosed model", "o"), ("closed_form_rad", "closed form", "x"),
                           ("family_gdfe_rad", "GDFE + the all-data family, refitted", "^"),
                           ("refit_K_gdfe_rad", "GDFE, K refitted", "s")):
        a.scatter(y, [r[key] for r in rows], marker=mk, label=label, zorder=3)
    lim = [0, max(3.0, float(y.max()) * 1.1)]
    a.plot(lim, lim, "k-", lw=0.7)
    a.set(xlim=lim, ylim=lim, xlabel="measured fold angle [rad]", ylabel="held-out prediction [rad]",
          title="(a) Table 1, each test held out")
    a.legend(fontsize=8)
    a = ax[1]
    parts = result["parts"]
    names = [p["part"] for p in parts]
    a.barh(np.arange(len(parts)), [p["rms_mm"] for p in parts], color="C0", label="RMS")
    a.barh(np.arange(len(parts)), [p["max_mm"] for p in parts], color="C0", alpha=0.3, label="max")
    a.set_yticks(np.arange(len(parts)), names, fontsize=7)
    a.set(xlabel="distance, paper's model vs Table 1 model, after alignment [mm]",
          title=f"(b) the paper's parts with the Table 1 model ({result['table1_model']['name']})")
    a.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, out / f"{NAME}.png", dpi=110)


main = main_of(__name__)


if __name__ == "__main__":
    raise SystemExit(main())
