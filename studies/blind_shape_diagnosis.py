"""Blind benchmark of the shape diagnosis on scans of parts whose physics GDFE lacks.

The "real parts" are the plate FEM of :mod:`reference_fem` (film and coats meshed from the
design, nonlinear, free-floating) with one effect withheld from the design handed to the
diagnosis, built by the generators of :mod:`studies.shape_generators` (which never import the
diagnosis): none (nulls), a thicker coat (d x 1.3-2) or a stiffer coat (E x 1.5-3) on one
hinge, an anisotropic film (the weaker in-plane contraction 0.7-0.9 times the stronger, their
mean kept), one face's coat printed 1-3 pixels off its mask, and a film whose shrink varies
linearly along x or y (its ends 20-40 % of the mean apart, the mean kept). Each part is scanned
(the film's two faces, a random rigid motion, Gaussian noise of 5 um per coordinate) and
:func:`gdfe.diagnosis.diagnose_shape` is given the scan, the design as designed (two small
designs, :mod:`studies.shape_generators.designs`, with the contraction ratio calibrated on the
FEM's own folding test of a hinge) and the **model floor**: the RMS deviation of a scan of a
separate *calibration* null part of the same design (its own random motion and noise, never
one of the scored scans), as a user would scan one part printed as designed.

Scoring, against the answer each generator declares beforehand
(:mod:`studies.shape_generators.registry`):

* **null**: right ("cannot say" is the right answer) when nothing is credited and the scan
  matches (no gap beyond the floor); "cannot tell which form" says there is a gap: wrong;
* **catalogue**: right when the form of the effect is credited: the hinge with a thicker or
  stiffer coat named alone, bending the way Timoshenko's bilayer says (less: R fitted above the
  design's); the film anisotropy with the weaker axis right; the coat offset of the right face
  along the right axis, its shift of the right sign and within one pixel. Crediting nothing (no
  gap, "cannot tell which", no match) is a *miss*; crediting another form, region or direction
  is *wrong*;
* **outside** (the shrink varying along the part): no form reproduces it; right only when
  nothing is credited (a right "cannot say"), wrong when a form is.

Reported per kind, per generator and per design: the share right with its Wilson interval
(95 %), the counts of right (form and parameters) / right "cannot say" / missed / wrong, and
per scan the effect's *visibility* (RMS distance, after rigid alignment, between the
noise-free film of the part and of the null part of the same design) beside the floor, so
that a miss can be read against what the scan could show.

Resolutions: coarse, the strip design, one scan each of the null, the thicker coat, the
anisotropic film and the shrink gradient; default, both designs, four scans per generator and
design; fine, twelve. Units: mm, s. The measured accuracy is in ``docs/reference_fem_plates.md``
and the study's output.

Run ``python -m studies.blind_shape_diagnosis [--resolution R] [--out DIR] [--json]`` or
``gdfe study blind-shape-diagnosis``; writes ``blind_shape_diagnosis.png`` and ``.json``.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from studies._common import check_resolution, finish, headline, main_of, progress, pyplot, save_figure

log = logging.getLogger(__name__)

NAME = "blind_shape_diagnosis"
#: Confidence level of the accuracy intervals.
LEVEL = 0.95
SETTINGS = {
    "coarse": {"designs": ("strip",), "reps": 1,
               "generators": ("null", "thicker_coat", "anisotropic_film", "contraction_gradient")},
    "default": {"designs": ("strip", "ell"), "reps": 4},
    "fine": {"designs": ("strip", "ell"), "reps": 12},
}
#: Outcomes of a scored diagnosis: the right region and effect named; right to name none (a null,
#: or an effect outside the catalogue); a catalogue effect left unnamed; a wrong region or effect
#: credited (or a gap invented on a null).
OUTCOMES = ("right", "right_cannot_say", "missed", "wrong")


def said(diagnosis):
    """What a shape diagnosis says: ``{"says": "no match" | "no gap" | "cannot tell" | "named",
    "form": None | "region" | "anisotropy" | "offset", "named": [...], "bends": {region: "less" |
    "more"}, "params": {...}}`` (a region bends less when its fitted contraction ratio is above
    the design's; ``params`` those of a credited anisotropy or offset)."""
    out = {"says": "no gap", "form": None, "named": [], "bends": {}, "params": {}}
    if not diagnosis.matches:
        return dict(out, says="no match")
    if diagnosis.outcome == "cannot_tell":
        return dict(out, says="cannot tell", named=list(diagnosis.not_ruled_out))
    credited = diagnosis.credited
    if credited is None:
        return out
    if credited["kind"] != "region":
        return dict(out, says="named", form=credited["kind"], params=dict(credited["params"]))
    rows = diagnosis.regions_by_name()
    bends = {n: "less" if diagnosis.corrected_R[n] > rows[n]["R_design"] else "more" for n in diagnosis.named}
    return dict(out, says="named", form="region", named=list(diagnosis.named), bends=bends)


def _right_form(answer, says):
    p = says["params"]
    if answer["form"] == "region":
        r = answer["region"]
        return says["form"] == "region" and says["named"] == [r] and says["bends"][r] == answer["bends"]
    if answer["form"] == "anisotropy":
        return says["form"] == "anisotropy" and p["weak_axis"] == answer["weak_axis"]
    return (says["form"] == "offset" and p["face"] == answer["face"] and p["axis"] == answer["axis"]
            and p["pixels"] * answer["pixels"] > 0 and abs(p["pixels"] - answer["pixels"]) <= 1)


def score(answer, says):
    """One of :data:`OUTCOMES` for a diagnosis (:func:`said`) against a declared answer
    (:meth:`studies.shape_generators.ShapeGenerator.answer`): ``"right"`` (the form with its
    region and direction, weaker axis, or face, axis and shift within a pixel),
    ``"right_cannot_say"`` (nothing credited where nothing should be), ``"missed"`` (nothing
    credited where a form should be) or ``"wrong"``."""
    if answer["says"] == "no gap":
        return "right_cannot_say" if says["says"] == "no gap" else "wrong"
    if answer["says"] == "cannot say":
        return "right_cannot_say" if says["says"] in ("no gap", "no match", "cannot tell") else "wrong"
    if says["says"] != "named":
        return "missed"
    return "right" if _right_form(answer, says) else "wrong"


def visibility(part, part_reference, null, null_reference):
    """RMS distance [mm] between two noise-free scans of the same design's film after rigid
    alignment, point by point: each point is matched by where it was in the flat print."""
    import gdfe

    a, b = np.lexsort(part_reference.T[::-1]), np.lexsort(null_reference.T[::-1])
    if part_reference.shape != null_reference.shape or not np.allclose(part_reference[a], null_reference[b]):
        raise ValueError("the two scans are not of the same film nodes")
    return float(gdfe.shape_distance(null[b], part[a])["rms"])


def _rng(seed, g, d, rep):
    return np.random.default_rng([seed, g, d, rep])


def calibration_floor(design, rng, cache):
    """The model floor [mm] of ``design``: the RMS deviation of one scan of a null part (the part
    as designed) from GDFE's shape, as a user measures it on a part printed as designed; with
    the seconds it took."""
    from gdfe.diagnosis import diagnose_shape
    from studies.shape_generators import generate, plate_design

    t0 = time.perf_counter()
    sample = generate("null", design, rng, solved=cache)
    dg = diagnose_shape(plate_design(design).gdfe_design(sample.R), sample.scan.points, correct=False)
    return {"floor_mm": float(dg.rms_before), "noise_mm": dg.noise, "matches": bool(dg.matches),
            "converged": bool(dg.converged and sample.fem["converged"]), "seconds": time.perf_counter() - t0}


def diagnose_one(name, design, rng, cache, floor=None):
    """Generate one scanned part and diagnose it (given the model ``floor`` [mm]); the record of
    the scan."""
    from gdfe.diagnosis import diagnose_shape
    from studies.shape_generators import GENERATORS, generate, plate_design
    from studies.shape_generators.registry import solve_key

    t0 = time.perf_counter()
    sample = generate(name, design, rng, solved=cache)
    t1 = time.perf_counter()
    des = plate_design(design).gdfe_design(sample.R)
    dg = diagnose_shape(des, sample.scan.points, floor=floor)
    t2 = time.perf_counter()
    says = said(dg)
    null = cache.get(solve_key("null", design, {}, sample.R))
    vis = None
    if null is not None:
        from studies.shape_generators.scan import film_faces

        vis = visibility(sample.scan.clean, sample.scan.reference, *film_faces(null, reference=True))
    return {"generator": name, "kind": GENERATORS[name].kind, "design": design, "strengths": sample.strengths,
            "answer": sample.answer, "says": says, "outcome": score(sample.answer, says),
            "verdict": dg.verdict, "rms_before_mm": dg.rms_before, "rms_after_mm": dg.rms_after,
            "floor_mm": floor, "noise_estimate_mm": dg.noise, "level_mm": dg.level, "gain_beyond_floor": dg.gain,
            "forms": dg.forms, "not_ruled_out": dg.not_ruled_out,
            "match_relative_residual": dg.match.get("relative_residual"), "match_factor": dg.match.get("factor"),
            "corrected_R": dg.corrected_R, "R_design": sample.R, "visibility_mm": vis,
            "n_points": int(len(sample.scan.points)), "noise_mm": sample.scan.noise_mm,
            "fem": sample.fem, "fem_seconds": t1 - t0, "diagnosis_seconds": t2 - t1,
            "diagnosis_converged": bool(dg.converged), "n_simulations": int(dg.n_simulations)}


def accuracy(records, level=LEVEL):
    """Share right (``right`` and ``right_cannot_say``) with its Wilson interval, and the count of
    each outcome."""
    from gdfe.ensemble import wilson_interval

    n = len(records)
    counts = {o: sum(r["outcome"] == o for r in records) for o in OUTCOMES}
    k = counts["right"] + counts["right_cannot_say"]
    lo, hi = wilson_interval(k, n, level)
    return {"n": n, **counts, "n_right": k, "accuracy": k / n if n else float("nan"),
            "accuracy_interval": [lo, hi], "level": level}


def run(resolution="default", out=None, seed=0):
    """Generate the scans, diagnose each and score them."""
    from studies.shape_generators import GENERATORS, KINDS
    from studies.shape_generators.calibration import calibrated_R, folding_test

    check_resolution(resolution)
    cfg = SETTINGS[resolution]
    t0 = time.perf_counter()
    alpha, cal_seconds, cal_ok = folding_test()
    cache, records = {}, []
    names, designs = list(GENERATORS), list(cfg["designs"])
    # the floor from a calibration null part of each design: a random stream no scored scan uses
    floors = {d: calibration_floor(d, np.random.default_rng([seed, 1000, i]), cache) for i, d in enumerate(designs)}
    used = [g for g in names if g in cfg.get("generators", names)]
    jobs = [(g, d, rep) for d in designs for g in used for rep in range(cfg["reps"])]
    for g, d, rep in progress(jobs, "scans"):
        rng = _rng(seed, names.index(g), designs.index(d), rep)
        rec = diagnose_one(g, d, rng, cache, floor=floors[d]["floor_mm"])
        log.info("%s on %s: %s (%s)", g, d, rec["verdict"], rec["outcome"])
        records.append(rec)
    by_kind = {k: accuracy([r for r in records if r["kind"] == k]) for k in KINDS}
    by_gen = {g: accuracy([r for r in records if r["generator"] == g]) for g in used}
    by_design = {d: {g: accuracy([r for r in records if r["generator"] == g and r["design"] == d])
                     for g in used} for d in designs}
    floor = {d: floors[d]["floor_mm"] for d in designs}
    null_rms = {d: float(np.median([r["rms_before_mm"] for r in records if r["generator"] == "null"
                                    and r["design"] == d] or [np.nan])) for d in designs}
    converged = cal_ok and all(f["converged"] for f in floors.values()) and all(
        r["fem"]["converged"] and r["diagnosis_converged"] for r in records)
    wrong_named = sum(r["outcome"] == "wrong" and r["says"]["says"] == "named" for r in records
                      if r["kind"] == "catalogue")
    hl = [
        headline("null scans: no gap localised (share)", by_kind["null"]["accuracy"], None, 0.8, "ge",
                 note="a diagnosis that invents a gap on the part as designed would be worse than none"),
        headline("catalogue effects: a wrong region or direction credited (share)",
                 wrong_named / max(1, by_kind["catalogue"]["n"]), None, 0.25, "le",
                 note="a coat on one hinge, an anisotropic film, a coat offset; a miss (nothing credited) is not "
                      "counted here"),
    ]
    result = {
        "study": NAME, "figure": "issue 26", "title": "Blind benchmark of the shape diagnosis",
        "resolution": resolution, "seed": seed, "level": LEVEL, "designs": designs, "reps": cfg["reps"],
        "calibration": {"fold_rad": alpha, "R": calibrated_R(), "seconds": cal_seconds, "converged": cal_ok},
        "noise_mm": records[0]["noise_mm"] if records else None, "floor_mm": floor, "calibration_nulls": floors,
        "null_rms_mm": null_rms,
        "by_kind": by_kind, "by_generator": by_gen, "by_design": by_design, "records": records,
        "headlines": hl, "converged": converged, "seconds": time.perf_counter() - t0,
        "summary": {"ours": "; ".join(f"{g}: {a['n_right']}/{a['n']} right ({a['missed']} missed, {a['wrong']} wrong)"
                                      for g, a in by_gen.items()),
                    "verdict": _verdict(by_kind)},
    }
    return finish(result, out, plot)


def _verdict(by_kind):
    parts = []
    for k, a in by_kind.items():
        if a["n"]:
            lo, hi = a["accuracy_interval"]
            parts.append(f"{k} {a['n_right']}/{a['n']} right ({100 * lo:.0f}-{100 * hi:.0f} %)")
    return "; ".join(parts)


def plot(result, out):
    """Accuracy per generator with Wilson intervals, and each scan's visibility against the floor."""
    plt = pyplot()
    gens = list(result["by_generator"])
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    acc = [result["by_generator"][g]["accuracy"] for g in gens]
    lo = [result["by_generator"][g]["accuracy_interval"][0] for g in gens]
    hi = [result["by_generator"][g]["accuracy_interval"][1] for g in gens]
    x = np.arange(len(gens))
    ax.bar(x, acc, color="tab:blue", alpha=0.7, label="share right")
    ax.errorbar(x, acc, yerr=[np.subtract(acc, lo), np.subtract(hi, acc)], fmt="none", ecolor="k", capsize=4,
                label=f"Wilson {100 * result['level']:.0f} %")
    ax.set_xticks(x, [f"{g}\n(n={result['by_generator'][g]['n']})" for g in gens], fontsize=7, rotation=20)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("share right")
    ax.legend(fontsize=8)
    ax.set_title("shape diagnosis, per withheld effect")
    colours = {"right": "tab:green", "right_cannot_say": "tab:olive", "missed": "tab:orange", "wrong": "tab:red"}
    for o, c in colours.items():
        rs = [r for r in result["records"] if r["outcome"] == o and r["visibility_mm"] is not None]
        bx.scatter([gens.index(r["generator"]) + 0.1 * (r["design"] != "strip") for r in rs],
                   [1e3 * r["visibility_mm"] for r in rs], c=c, label=o, s=25)
    for d, f in result["floor_mm"].items():
        bx.axhline(1e3 * f, ls="--", lw=0.8, color="grey")
        bx.text(-0.4, 1e3 * f, f"{d}: calibration null scan to GDFE (floor)", fontsize=7, ha="left", va="bottom")
    bx.set_xticks(x, gens, fontsize=8, rotation=15)
    bx.set_ylabel("effect: RMS distance to the null part [um]")
    bx.legend(fontsize=8)
    bx.set_title("each scan's effect against the floor")
    fig.suptitle(f"blind shape diagnosis: {result['summary']['verdict']}", fontsize=9)
    save_figure(fig, out, NAME)


main = main_of(__name__)

if __name__ == "__main__":
    raise SystemExit(main())
