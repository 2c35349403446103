"""How many folding tests until the diagnosis names the right model alone: planned, random, grid.

Truths come from the blind benchmark's generators of catalogue effects
(:mod:`studies.diagnosis_generators`: a thicker coat and a wider hinge through the reference
FEM, an elastic coat, heating from above through GDFE), each with strengths drawn as the
benchmark draws them, noise 0.03 rad. Each starts from :data:`START` random specimens of the
benchmark's random design (``L`` 1.5-6 mm, ``d`` 0.1-0.5 mm, ``h`` 0.2-0.4 mm) and adds one
test at a time, by one of three rules, until the diagnosis (told the noise) names one model
alone and it is right (:func:`studies.blind_diagnosis.is_right`), or :data:`SETTINGS`'
``max_added`` tests:

* **plan**: the test :func:`gdfe.plan.plan_tests` proposes from the current tests' diagnosis
  (the most expected information about which of the models not yet ruled out is right:
  :func:`gdfe.plan.models_to_tell_apart`);
* **random**: uniform over the same ranges (seeded);
* **grid**: the next point of a 3 x 3 x 3 grid over the ranges, in one seeded order.

Reported: for each rule, over the truths the starting tests do not already resolve, the median
number of added tests to the right model alone (a truth never reached counts as
``max_added + 1``: the median is then a lower bound) and how often it was reached; the goal is
the plan's median at half of random's or fewer.

**Null truths** (:data:`NULLS`: the nominal world, GDFE's hinges with Eq. 3, nothing withheld)
get :data:`SETTINGS`' ``null_added`` tests by every rule whatever the diagnosis says, so that a
rule that chases a spurious effect shows: the share of null truths whose diagnosis names a
model other than the baseline alone at some step (a false credit), and the share right
(``no_gap``) after the last test.

Run ``python -m studies.plan [--out DIR] [--resolution R] [--json]`` or ``gdfe study plan``;
writes ``plan.png`` and ``plan.json``.
"""

from __future__ import annotations

import time

import numpy as np

from studies._common import check_resolution, finish, headline, main_of, pyplot, save_figure

NAME = "plan"
SIGMA = 0.03
#: Random specimens a truth starts from.
START = 8
#: Printable ranges [mm]: the blind benchmark's random design.
RANGES = {"L": (1.5, 6.0), "d": (0.1, 0.5), "h": (0.2, 0.4)}
#: Generators of the truths (catalogue effects), truths per generator, tests added at most.
GENERATORS = ("cure_depth", "hinge_length", "passive_stiffness", "saturation")
#: Null generators: nothing withheld (the right answer is ``no_gap``, the baseline alone).
NULLS = ("nominal",)
SETTINGS = {"coarse": {"truths": 1, "max_added": 2, "generators": ("hinge_length",), "nulls": 1, "null_added": 1},
            "default": {"truths": 8, "max_added": 24, "generators": GENERATORS, "nulls": 6, "null_added": 8},
            "fine": {"truths": 15, "max_added": 24, "generators": GENERATORS, "nulls": 10, "null_added": 12}}
RULES = ("plan", "random", "grid")
#: Whether the plan's median is half of random's or fewer (measured; per resolution).
GOAL_MET = {"coarse": True, "default": True, "fine": False}
#: Whether the plan credits a spurious effect alone on no more null truths than random tests do
#: (measured; per resolution: at the default, 1 of 6 null truths against none).
NULL_GOAL_MET = {"coarse": True, "default": False, "fine": False}


def _grid_order(seed=0):
    axes = [np.linspace(*RANGES[k], 3) for k in ("L", "d", "h")]
    pts = np.array(np.meshgrid(*axes, indexing="ij")).reshape(3, -1).T
    return pts[np.random.default_rng(seed).permutation(len(pts))]


def _truth(generator, rep, seed=0):
    """The starting specimens, strengths and resolution of one generated truth."""
    from studies.blind_diagnosis import _generator
    from studies.diagnosis_generators.nominal import specimens

    rng = np.random.default_rng([seed, (GENERATORS + NULLS).index(generator), rep])
    sp = specimens("random", rng)
    strengths = _generator(generator).draw(rng, sp)
    return sp, strengths, rng


def _measure(generator, sp, strengths, rows, rng):
    """Measured angles [rad] of specimens ``rows`` ((m, 3): L, d, h) in ``generator``'s world."""
    import dataclasses

    from studies.diagnosis_generators import generate, measure
    from studies.diagnosis_generators.nominal import T_RANGE

    rows = np.atleast_2d(rows)
    m = len(rows)
    new = dataclasses.replace(sp, L=rows[:, 0].copy(), d=rows[:, 1].copy(), h=rows[:, 2].copy(),
                              T_C=rng.uniform(*T_RANGE, m), batch=np.array(["b1"] * m))
    clean, ok = generate(generator, new, strengths, {"gdfe": "coarse", "fem": "coarse"})
    return measure(generator, clean, strengths, SIGMA, rng), bool(np.all(ok))


def _diagnose(rows, alpha):
    import gdfe
    from gdfe.diagnosis import diagnose

    t = gdfe.FoldingTests(L=rows[:, 0], d=rows[:, 1], h=rows[:, 2], alpha=alpha)
    return diagnose(t, sigma=SIGMA)


def _right_alone(generator, diag):
    from studies.blind_diagnosis import is_right

    named = [f.name for f in diag.named] or [diag.best.name]
    return len(named) == 1 and bool(is_right(generator, named, diag.verdict.verdict)), named


def _next(rule, diag, k, rng, grid):
    if rule == "random":
        return np.array([rng.uniform(*RANGES[a]) for a in ("L", "d", "h")])
    if rule == "grid":
        return grid[k % len(grid)]
    from gdfe.plan import models_to_tell_apart, plan_tests
    from gdfe.predictive import from_diagnosis

    p = plan_tests(from_diagnosis(diag, members=models_to_tell_apart(diag)), 1, RANGES["L"], RANGES["d"], RANGES["h"], grid=7, samples=1500, seed=k)
    if p.L.size == 0:  # one model named, but not the right one: any test
        return np.array([rng.uniform(*RANGES[a]) for a in ("L", "d", "h")])
    return np.array([p.L[0], p.d[0], p.h[0]])


def _false_credit(right, named):
    """A model other than the baseline named alone, and wrong."""
    return not right and len(named) == 1 and named[0] != "baseline"


def run_truth(generator, rep, max_added, seed=0, fixed=False):
    """Tests added by each rule until the right model alone (``max_added + 1`` if never); with
    ``fixed``, ``max_added`` tests whatever the diagnosis says (a null truth), recording whether
    a model was named alone wrongly at some step (``false_alone``)."""
    sp, strengths, rng = _truth(generator, rep, seed)
    start = np.column_stack([sp.L[:START], sp.d[:START], sp.h[:START]])
    alpha0, ok = _measure(generator, sp, strengths, start, np.random.default_rng([seed, rep, 1]))
    grid = _grid_order(seed)
    out = {"generator": generator, "rep": rep, "strengths": {k: v for k, v in strengths.items()
                                                              if isinstance(v, (int, float))}}
    for rule in RULES:
        r_rng = np.random.default_rng([seed, rep, 2, RULES.index(rule)])
        rows, alpha = start.copy(), alpha0.copy()
        diag = _diagnose(rows, alpha)
        right, named = _right_alone(generator, diag)
        added, trail = 0, [named]
        false_alone = _false_credit(right, named)
        while (fixed or not right) and added < max_added:
            x = _next(rule, diag, added, r_rng, grid)
            a, c = _measure(generator, sp, strengths, x[None], r_rng)
            ok = ok and c
            rows, alpha = np.vstack([rows, x]), np.append(alpha, a)
            added += 1
            diag = _diagnose(rows, alpha)
            right, named = _right_alone(generator, diag)
            false_alone = false_alone or _false_credit(right, named)
            trail.append(named)
        out[rule] = {"tests": added if right else max_added + 1, "reached": bool(right), "named": trail,
                     "added": rows[START:].tolist(), "false_alone": bool(false_alone), "right_at_end": bool(right)}
    out["converged"] = ok
    return out


def _paired(truths, rule):
    """Truths where ``rule`` needed fewer / more tests than random (ties: equal counts, never
    reached by either counted equal)."""
    if rule == "random":
        return {}
    a = np.array([t[rule]["tests"] for t in truths] or [0])
    b = np.array([t["random"]["tests"] for t in truths] or [0])
    return {"fewer_than_random": int(np.sum(a < b)), "more_than_random": int(np.sum(a > b))} if truths else {}


def run(resolution="default", out=None):
    check_resolution(resolution)
    s = SETTINGS[resolution]
    t0 = time.perf_counter()
    truths = [run_truth(g, rep, s["max_added"]) for g in s["generators"] for rep in range(s["truths"])]
    nulls = [run_truth(g, rep, s["null_added"], fixed=True) for g in NULLS for rep in range(s["nulls"])]
    open_ = [t for t in truths if t["plan"]["tests"] > 0]  # not named alone and right from the start
    summary = {}
    for rule in RULES:
        n = np.array([t[rule]["tests"] for t in open_] or [0])
        summary[rule] = {"median_tests": float(np.median(n)), "mean_tests": float(np.mean(n)),
                         "reached": float(np.mean([t[rule]["reached"] for t in open_])) if open_ else 1.0,
                         "tests": n.tolist(), **_paired(open_, rule),
                         "null_false_alone": float(np.mean([t[rule]["false_alone"] for t in nulls])) if nulls else None,
                         "null_right_at_end": float(np.mean([t[rule]["right_at_end"] for t in nulls])) if nulls else None}
    ratio = summary["plan"]["median_tests"] / summary["random"]["median_tests"] if open_ else float("nan")
    heads = [
        headline("median tests to the right model alone: plan / random", ratio, tol=0.5, kind="le",
                 expect=GOAL_MET[resolution],
                 note=f"{len(open_)} of {len(truths)} truths not resolved by the starting tests; never reached "
                      f"counts as {s['max_added'] + 1}"),
        headline("truths not resolved by the starting tests", len(open_), tol=1, kind="ge"),
        headline("null truths with a model other than the baseline named alone at some step: plan",
                 summary["plan"]["null_false_alone"], tol=summary["random"]["null_false_alone"], kind="le",
                 expect=NULL_GOAL_MET[resolution],
                 note=f"{len(nulls)} null truths, {s['null_added']} tests each; the bound is random's share"),
    ]
    result = {"study": NAME, "figure": "issue: the next tests to print",
              "title": "tests until the diagnosis names the right model alone", "resolution": resolution,
              "sigma_rad": SIGMA, "start": START, "ranges_mm": RANGES, "max_added": s["max_added"],
              "summary": {"paper": "", "ours": ", ".join(f"{r}: median {summary[r]['median_tests']:g} tests, reached "
                                                            f"{100 * summary[r]['reached']:.0f} %" for r in RULES),
                          "verdict": "", "discrepancy": "",
                          "nulls": ", ".join(f"{r}: {100 * summary[r]['null_false_alone']:.0f} % named a model "
                                             f"alone wrongly, {100 * summary[r]['null_right_at_end']:.0f} % no_gap at "
                                             f"the end" for r in RULES) if nulls else ""},
              "rules": summary, "truths": truths, "nulls": nulls, "n_open": len(open_), "headlines": heads,
              "converged": all(t["converged"] for t in truths + nulls), "seconds": time.perf_counter() - t0}
    return finish(result, out, plot)


def plot(result, out):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    m = result["max_added"]
    ks = np.arange(m + 2)
    width = 0.27

    def median_text(v):
        return "never" if v > m else f"{v:g}"

    for i, rule in enumerate(RULES):
        n = np.array(result["rules"][rule]["tests"], int)
        counts = np.bincount(np.minimum(n, m + 1), minlength=m + 2)
        ax.bar(ks + (i - 1) * width, counts, width,
               label=f"{rule}: median {median_text(result['rules'][rule]['median_tests'])}, "
                     f"reached {100 * result['rules'][rule]['reached']:.0f} %")
    ax.set_xticks(ks, [str(k) for k in range(m + 1)] + [f"never\n(> {m})"])
    ax.set_xlabel("tests added until the diagnosis names the right model alone")
    ax.set_ylabel("generated truths")
    r = result["rules"]
    ax.set_title(f"{result.get('n_open', len(result['truths']))} truths not settled by {result['start']} tests "
                 f"(noise {result['sigma_rad']:g} rad): plan median {median_text(r['plan']['median_tests'])}, "
                 f"random {median_text(r['random']['median_tests'])}", fontsize=10)
    ax.legend()
    save_figure(fig, out, NAME)


main = main_of(__name__)

if __name__ == "__main__":
    raise SystemExit(main())
