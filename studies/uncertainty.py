"""Predictions that say how sure they are: coverage and width of their intervals on held-out tests.

1. **Table 1 held out one test at a time.** For each of the 18 tests the other 17 are
   diagnosed (:func:`gdfe.diagnosis.diagnose`), the model file written and read back with
   its predictive content (:func:`gdfe.predictive.from_diagnosis`: the named set weighted by
   stacking, each member's covariance and noise), and the held-out angle predicted at level
   0.9 (:func:`gdfe.predict.predict`) — what ``gdfe diagnose --model-out`` then
   ``gdfe predict`` do. Beside it, on the same held-out rows: the same with pseudo-BMA
   weights; the paper's principle refitted (Eq. 1, ``gdfe calibrate``) alone; and the
   Kennedy-O'Hagan anchor, that baseline plus a Gaussian-process discrepancy
   (:mod:`gdfe.discrepancy`). RMSE, coverage of the 90 % intervals and their mean width. The
   transfer study's held-out rows are these same 18 tests (there through GDFE, whose fold
   matches the closed form to its discretisation), so this part is its comparison too.
2. **The blind benchmark's data sets** (:mod:`studies.diagnosis_generators`, data the
   diagnoser did not write), noise 0.03 rad: the rows of each data set dealt into three folds,
   each fold predicted from a diagnosis of the other two; coverage and width per class, for
   the named set and for the Kennedy-O'Hagan anchor.
3. **The tube with the Table 1 model.** Draws from the predictive content of the model
   diagnosed from all 18 tests (:func:`gdfe.predict.draw_models`: a member by its weight, its
   parameters from their covariance) fold the Figure 7 tube; the interval of its turn and end
   gap beside the paper model's fold. The noise of a test is not in it (it is the scatter of
   a measured hinge, not of a part's every hinge).

Run ``python -m studies.uncertainty [--out DIR] [--resolution R] [--json]`` or
``gdfe study uncertainty``; writes ``uncertainty.png`` and ``uncertainty.json``.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from gdfe import paper
from studies._common import check_resolution, finish, headline, main_of, pyplot, save_figure

NAME = "uncertainty"
LEVEL = 0.9
#: Noise of the blind data sets [rad] (the benchmark's goal level).
SIGMA = 0.03
#: The blind benchmark's generators predicted at each resolution (all at default; at coarse one
#: data set of each of three classes), repetitions per generator, draws through the tube.
SETTINGS = {
    "coarse": {"generators": ("nominal", "saturation", "reading_offset"), "reps": 1, "draws": 8},
    "default": {"generators": None, "reps": 2, "draws": 32},
    "fine": {"generators": None, "reps": 4, "draws": 64},
}
#: Goal of the Table 1 coverage (the issue's) and of each blind class's.
COVERAGE_GOAL = (0.8, 1.0)
BLIND_GOAL = (0.85, 0.95)
#: Whether the Table 1 coverage of the named set meets its goal (measured; the regression
#: checks expect what was measured, so a change either way is flagged).
TABLE1_GOAL_MET = True
#: Whether every blind class's coverage lies in its goal, per resolution (measured).
BLIND_GOAL_MET = {"coarse": False, "default": True, "fine": True}
#: Whether the Kennedy-O'Hagan anchor's Table 1 coverage meets the goal (measured).
KOH_GOAL_MET = False


def _fold_tests(t, keep):
    import gdfe

    return gdfe.FoldingTests(L=t.L[keep], d=t.d[keep], h=t.h[keep], alpha=t.alpha[keep],
                             extra={k: np.asarray(v)[keep] for k, v in t.extra.items()})


def _specimens(t, idx):
    from gdfe.predict import HingeSpecimens

    return HingeSpecimens(L=t.L[idx], d=t.d[idx], h=t.h[idx], alpha=t.alpha[idx],
                          extra={k: np.asarray(v)[idx] for k, v in t.extra.items()})


def _predictors(train, spec, folder, diagnose_kw=None, with_pseudo=True):
    """Predictions of ``spec`` by every predictor fitted to ``train``: name -> Prediction. A noise
    the diagnosis is told (``diagnose_kw["sigma"]``) is told to the discrepancy too."""
    import gdfe
    from gdfe.diagnosis import diagnose
    from gdfe.discrepancy import fit_discrepancy
    from gdfe.predict import predict
    from gdfe.predictive import from_diagnosis

    out = {}
    diag = diagnose(train, **(diagnose_kw or {}))
    path = from_diagnosis(diag).save(Path(folder) / "m.toml")
    out["named set (stacking)"] = predict(gdfe.load_model(path), spec, LEVEL)
    if with_pseudo:
        out["named set (pseudo-BMA)"] = predict(from_diagnosis(diag, weighting="pseudo-bma"), spec, LEVEL)
    base = gdfe.DeformationModel.from_calibration(gdfe.fit_reading(train, "eq1", n_boot=0), tests=train)
    out["Eq. 1 refitted"] = predict(base, spec, LEVEL)
    noise = (diagnose_kw or {}).get("sigma")
    out["Kennedy-O'Hagan (Eq. 1 + GP)"] = fit_discrepancy(base, train, noise=noise).predict(spec, LEVEL)
    return out, diag


def _score(preds):
    """RMSE, coverage and mean width of every predictor's held-out predictions."""
    out = {}
    for name, ps in preds.items():
        a = np.concatenate([p.specimens.alpha for p in ps])
        m = np.concatenate([p.alpha for p in ps])
        inside = np.concatenate([p.inside for p in ps])
        width = np.concatenate([p.width for p in ps])
        out[name] = {"rmse_rad": float(np.sqrt(np.mean((a - m) ** 2))), "coverage": float(np.mean(inside)),
                     "mean_width_rad": float(np.mean(width)), "median_width_rad": float(np.median(width)),
                     "max_width_rad": float(np.max(width)), "n": int(a.size)}
    return out


def table1_loo():
    """Part 1: Table 1 held out one test at a time."""
    import gdfe

    t = gdfe.load_folding_tests(gdfe.TABLE1)
    preds, rows, chosen = {}, [], []
    with tempfile.TemporaryDirectory() as folder:
        for i in range(len(t)):
            keep = np.arange(len(t)) != i
            ps, diag = _predictors(_fold_tests(t, keep), _specimens(t, [i]), folder)
            chosen.append(diag.best.name)
            for name, p in ps.items():
                preds.setdefault(name, []).append(p)
            p = ps["named set (stacking)"]
            rows.append({"row": i + 2, "L_mm": float(t.L[i]), "d_mm": float(t.d[i]), "measured_rad": float(t.alpha[i]),
                         "alpha_rad": float(p.alpha[0]), "alpha_interval_rad": [float(v) for v in p.interval[0]],
                         "members": [m["name"] for m in p.members], "inside": bool(p.inside[0])})
    return {"scores": _score(preds), "rows": rows, "chosen": sorted(set(chosen))}


def blind_heldout(settings, seed=0, cache=None):
    """Part 2: the blind benchmark's data sets, three folds each."""
    from gdfe._validation import GdfeError
    from studies import blind_diagnosis as bd
    from studies.diagnosis_generators import measure

    specs = bd._specs({**bd.SETTINGS["coarse"], "reps": settings["reps"], "null_reps": settings["reps"],
                       "new_reps": settings["reps"], "new_designs": 1, "sigmas": (SIGMA,)}, seed=seed, cache=cache)
    wanted = settings["generators"]
    specs = [s for s in specs if (wanted is None or s["generator"] in wanted) and not s["sensitivity"]]
    if wanted is not None:  # one data set per generator at the coarsest resolution
        seen, first = set(), []
        for s in specs:
            if s["generator"] not in seen:
                seen.add(s["generator"])
                first.append(s)
        specs = first
    by_class, skipped = {}, []
    with tempfile.TemporaryDirectory() as folder:
        for spec in specs:
            clean, ok, sp, strengths = bd.simulate_cached(spec)
            rng = np.random.default_rng(list(spec["seed"]) + [7])
            noisy = measure(spec["generator"], clean, strengths, SIGMA, rng)
            t = bd._tests(sp, noisy, bd._columns(spec["generator"], strengths))
            fold = rng.permutation(len(t)) % 3
            for f in range(3):
                try:
                    ps, _ = _predictors(_fold_tests(t, fold != f), _specimens(t, np.nonzero(fold == f)[0]), folder,
                                        {"sigma": SIGMA, "roles": dict(bd.ROLES)}, with_pseudo=False)
                except GdfeError as exc:  # e.g. a held-out row of a batch the fold never saw
                    skipped.append({"generator": spec["generator"], "fold": f, "reason": str(exc)})
                    continue
                for name, p in ps.items():
                    by_class.setdefault(spec["kind"], {}).setdefault(name, []).append(p)
    scores = {kind: _score(preds) for kind, preds in by_class.items()}
    return {"sigma_rad": SIGMA, "n_data_sets": len(specs), "generators": sorted({s["generator"] for s in specs}),
            "by_class": scores, "skipped": skipped}


def _with_d(design, d=paper.FIG6_D):
    """``design`` (made with R) with the passive thickness its one-side-coated cells were printed with."""
    import dataclasses

    import gdfe

    mat = design.material
    one = (mat == gdfe.Material.CONTRACT_TOP) | (mat == gdfe.Material.CONTRACT_BOTTOM)
    return dataclasses.replace(design, d=np.where(one, d, np.nan), meta={**design.meta, "d_mm": d})


def tube_interval(draws, seed=0):
    """Part 3: the Figure 7 tube folded by draws of the Table 1 model's predictive content."""
    import gdfe
    from gdfe import inverse as inv
    from gdfe._validation import GdfeError
    from gdfe.diagnosis import diagnose
    from gdfe.predict import draw_models
    from gdfe.predictive import from_diagnosis
    from studies import fig07_crease_fold as f7

    model = from_diagnosis(diagnose(gdfe.TABLE1))
    R = float(gdfe.paper_model().ratio(paper.FIG6_D))
    design = _with_d(f7.tube_design(R, f7.TUBE["coarse"]["div"], 1, 1.0))

    def fold(m):
        res = inv.simulate_strip(m.apply(design), max_iter=3000)
        _, uv, _ = inv.strip_midline(res)
        return float(gdfe.curvature_profile(res)["turn"]), float(np.linalg.norm(uv[-1] - uv[0])), bool(res.converged)

    t0 = time.perf_counter()
    paper_turn, paper_gap, ok = fold(gdfe.paper_model())
    nominal_turn, nominal_gap, ok_n = fold(model)
    t_one = time.perf_counter() - t0
    turns, gaps, converged, failed = [], [], ok and ok_n, 0
    t0 = time.perf_counter()
    for m in draw_models(model, draws, seed=seed):
        try:
            turn, gap, c = fold(m)
        except GdfeError:  # R <= 0 at the tube's coat: a film that cannot exist
            failed += 1
            continue
        turns.append(turn)
        gaps.append(gap)
        converged = converged and c
    q = [(1 - LEVEL) / 2, (1 + LEVEL) / 2]
    return {"paper_turn_rad": paper_turn, "paper_gap_mm": paper_gap, "model": model.name,
            "members": {m.model.name: m.weight for m in model.ensemble},
            "nominal_turn_rad": nominal_turn, "nominal_gap_mm": nominal_gap,
            "turn_interval_rad": [float(v) for v in np.quantile(turns, q)],
            "gap_interval_mm": [float(v) for v in np.quantile(gaps, q)], "draws": len(turns), "failed_draws": failed,
            "turns_rad": turns, "gaps_mm": gaps, "converged": converged,
            "seconds_per_solve": t_one / 2, "seconds_draws": time.perf_counter() - t0}


def run(resolution="default", out=None):
    check_resolution(resolution)
    s = SETTINGS[resolution]
    t0 = time.perf_counter()
    loo = table1_loo()
    t1 = time.perf_counter()
    blind = blind_heldout(s, cache=None if out is None or resolution == "coarse" else Path(out) / "cache")
    t2 = time.perf_counter()
    tube = tube_interval(s["draws"])
    named = loo["scores"]["named set (stacking)"]
    koh = loo["scores"]["Kennedy-O'Hagan (Eq. 1 + GP)"]
    lo, hi = COVERAGE_GOAL
    in_goal = {k: BLIND_GOAL[0] <= v["named set (stacking)"]["coverage"] <= BLIND_GOAL[1]
               for k, v in blind["by_class"].items()}
    heads = [
        headline("Table 1 LOO coverage of the 90 % intervals (named set, stacking)", named["coverage"], tol=lo,
                 kind="ge", expect=TABLE1_GOAL_MET, note=f"goal {lo:g}-{hi:g}"),
        headline("Table 1 LOO mean width of the 90 % intervals [rad] (named set)", named["mean_width_rad"], tol=0.6,
                 kind="le", unit="rad", note="narrower than the Kennedy-O'Hagan anchor's and Eq. 1's"),
        headline("Table 1 LOO RMSE [rad] (named set) below Eq. 1 refitted",
                 named["rmse_rad"], tol=loo["scores"]["Eq. 1 refitted"]["rmse_rad"], kind="le", unit="rad"),
        headline("Table 1 LOO coverage (Kennedy-O'Hagan)", koh["coverage"], tol=lo, kind="ge", expect=KOH_GOAL_MET,
                 note="measured below the goal: the discrepancy's noise falls to its bound on 17 tests"),
        headline("blind classes whose coverage lies in 0.85-0.95 (named set)", sum(in_goal.values()),
                 tol=len(in_goal), kind="ge", expect=BLIND_GOAL_MET[resolution],
                 note=f"of {len(in_goal)} classes; few rows per class at coarse resolution"),
        headline("tube turn interval contains the paper model's turn", float(
            tube["turn_interval_rad"][0] <= tube["paper_turn_rad"] <= tube["turn_interval_rad"][1]), tol=1, kind="ge",
            expect=False, note="the Table 1 model folds the tube far less than the paper's model"),
    ]
    result = {
        "study": NAME, "figure": "issue: predictions that say how sure they are",
        "title": "coverage and width of 90 % prediction intervals on held-out tests", "resolution": resolution,
        "level": LEVEL, "table1_loo": loo, "blind": blind, "blind_classes_in_goal": in_goal, "tube": tube,
        "seconds": {"table1": t1 - t0, "blind": t2 - t1, "tube": time.perf_counter() - t2},
        "headlines": heads, "converged": bool(tube["converged"]),
        "summary": {
            "paper": "the paper gives single numbers, no intervals",
            "ours": (f"Table 1 LOO at level {LEVEL:g}: named set coverage {named['coverage']:.2f}, mean width "
                     f"{named['mean_width_rad']:.3f} rad, RMSE {named['rmse_rad']:.3f} rad; Kennedy-O'Hagan coverage "
                     f"{koh['coverage']:.2f}, width {koh['mean_width_rad']:.3f} rad, RMSE {koh['rmse_rad']:.3f} rad; tube "
                     f"turn {tube['turn_interval_rad'][0]:.2f}-{tube['turn_interval_rad'][1]:.2f} rad with the Table 1 "
                     f"model against {tube['paper_turn_rad']:.2f} rad with the paper's"),
            "verdict": "", "discrepancy": ""},
    }
    return finish(result, out, plot)


def plot(result, out):
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    ax = axes[0]
    rows = result["table1_loo"]["rows"]
    x = np.arange(len(rows))
    lo = [r["alpha_interval_rad"][0] for r in rows]
    hi = [r["alpha_interval_rad"][1] for r in rows]
    mid = [r["alpha_rad"] for r in rows]
    ax.errorbar(x, mid, yerr=[np.subtract(mid, lo), np.subtract(hi, mid)], fmt="o", color="C0", capsize=3,
                label="predicted, 90 % interval (other 17 tests)")
    ax.plot(x, [r["measured_rad"] for r in rows], "k*", label="measured")
    s = result["table1_loo"]["scores"]["named set (stacking)"]
    ax.set_title(f"Table 1 held out: coverage {s['coverage']:.2f}, width {s['mean_width_rad']:.2f} rad")
    ax.set_xlabel("Table 1 row")
    ax.set_xticks(x, [str(r["row"]) for r in rows], fontsize=7)
    ax.set_ylabel("fold angle [rad]")
    ax.legend(fontsize=8)
    ax = axes[1]
    names = list(result["table1_loo"]["scores"])
    cls = sorted(result["blind"]["by_class"])
    groups = ["Table 1"] + cls
    width = 0.8 / len(names)
    for j, name in enumerate(names):
        vals = [result["table1_loo"]["scores"][name]["coverage"]]
        vals += [result["blind"]["by_class"][c].get(name, {}).get("coverage", math.nan) for c in cls]
        ax.bar(np.arange(len(groups)) + j * width, vals, width, label=name)
    ax.axhspan(*BLIND_GOAL, color="0.85", zorder=0, label="goal of the blind classes")
    ax.axhline(LEVEL, color="k", lw=0.8, ls="--", label=f"level {LEVEL:g}")
    ax.set_xticks(np.arange(len(groups)) + 0.4 - width / 2, groups, rotation=30, fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("coverage of the 90 % intervals")
    ax.set_title("coverage on held-out rows")
    ax.legend(fontsize=7, loc="lower left")
    ax = axes[2]
    tube = result["tube"]
    ax.scatter(tube["turns_rad"], tube["gaps_mm"], s=12, color="C0", label=f"{tube['draws']} draws, Table 1 model")
    ax.axvspan(*tube["turn_interval_rad"], color="C0", alpha=0.15, label="90 % interval of the turn")
    ax.plot([tube["paper_turn_rad"]], [tube["paper_gap_mm"]], "r*", ms=12, label="paper's model")
    ax.set_xlabel("tube turn [rad]")
    ax.set_ylabel("end gap [mm]")
    ax.set_title(f"tube: turn {tube['turn_interval_rad'][0]:.2f}-{tube['turn_interval_rad'][1]:.2f} rad "
                 f"(paper's {tube['paper_turn_rad']:.2f})")
    ax.legend(fontsize=8)
    save_figure(fig, out, NAME)


main = main_of(__name__)

if __name__ == "__main__":
    raise SystemExit(main())
