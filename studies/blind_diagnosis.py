"""Blind benchmark of the fold-angle diagnoser on data it did not write, and the diagnosis of Table 1.

Synthetic "measured" folding tests come from the generators of
:mod:`studies.diagnosis_generators`, none of which uses the diagnoser's closed forms: the
nominal world is GDFE hinge simulations with Eq. 3's contraction; effects are built into the
reference FEM's specimen (a thicker coat, a wider hinge, an elastic coat, a film that thickens),
into GDFE with directional heating (saturation), shrink kinetics of the film (partial activation
with the oven temperature) or film lots per print batch; and four plausible effects are outside
the catalogue (a fixture stop, resin bleeding with the coat, unrecorded film lots,
overheating). Later classes: nulls of another valid physics (the FEM's stiff-coat elastic
bilayer) and at one film thickness; measurement artefacts (a reading offset, outliers, scatter
growing with the angle, specimens that did not fold); effects carried by a numeric column
nobody declared (the film's anisotropic shrink with the hinge's angle to its draw direction,
the panel's sag with its length); a heating lag of the coat thickness alone at one film
thickness; a real effect (cure depth) beside irrelevant columns (red herrings); and the oven
temperature's partial activation as the ``process`` class. Every data set carries the columns
a lab records (oven temperature ``T_C``, declared as such where the diagnosis takes ``roles``,
and print ``batch``) whether or not its effect uses them. Gaussian noise of standard deviation
sigma is added (read as magnitudes) and :func:`gdfe.diagnosis.diagnose` is told sigma.

Two rules score a diagnosis. The **strict rule** (:func:`strict_right`): right only if no single
wrong physical cause is credited (:func:`wrong_physics_credited`): a model is credited when it is
named alone -- the only model of the named set, with no alternative left open (the diagnosis's
``attribution.not_ruled_out``; one that says an effect outside the catalogue is not ruled out
names its model beside that effect) -- with the verdict ``explained`` or more than half of the
gap removed; with several models named and the verdict ``explained``, the effects all of them
share are credited. A credited physical cause not among the generator's right ones is wrong; a
measurement artefact or a factor is never a wrong physical cause. Besides, no red-herring
column named, and right by the package's rule below. The **package's rule** (:func:`is_right`),
per class:

* **catalogue**: the models the diagnoser names -- its chosen model, and the others the data
  cannot tell from it (:attr:`gdfe.diagnosis.Diagnosis.named`) -- include the effect built in
  (for the FEM's elastic coat also with ``hinge_length``: the FEM's fold spreads past the
  coat's end); the mean size of the named sets is reported beside, so that naming many
  models cannot pass for naming the right one, and so is the looser share in which a named
  model contains the effect built in together with another effect;
* **null**: the verdict is ``no_gap`` (for the stiff-coat bilayer also ``passive_stiffness`` or
  ``hinge_length`` named);
* **outside**, **artefact**, **column**, **d_only**: the verdict is not ``explained`` (or the
  artefact, ``reading_offset``, or the column's factor is named); ``measurement_issue`` (the gap
  reproduced by a reading offset alone, an effect outside the catalogue of the same form left
  open) is not ``explained``, and each summary also counts it as wrong
  (``accuracy_measurement_wrong``) so that the difference can be seen;
* **process**, **red_herring**: as the catalogue's (``partial_activation[T_C]``, ``cure_depth``).

Reported: accuracy per class and per generator against sigma (on all data sets, on the
visible ones and on those a method could get right), the mean size of the named sets,
confusion matrices (class x verdict; generator x named model) at sigma = 0.03 rad, each data
set's *visibility* (RMS of the baseline fitted to its noise-free angles), *aliases*
(catalogue models that reproduce its noise-free angles within sigma) and, for a catalogue
effect, how closely its own catalogue form reproduces them; each miss with its reason
(:func:`miss_reason`); a sensitivity row (the thicker coat with a softer coat,
not counted in the classes), the diagnosis of Table 1 with the noise unknown and at assumed
noise levels, the cost of diagnosing many rows (time and peak memory of a child process), and
the checks of the shape diagnosis that a scan is the part.

Run ``python -m studies.blind_diagnosis [--out DIR] [--resolution R] [--json]`` or
``gdfe study blind-diagnosis``; writes ``blind_diagnosis.png``, ``.json`` and ``.md`` (the
findings). Noise-free data sets are cached under ``DIR/cache``.
"""

from __future__ import annotations

import json
import logging
import os
import time
from pathlib import Path

import numpy as np

from gdfe.io import write_text
from studies.diagnosis_generators.registry import NAMING_KINDS
from studies._common import check_resolution, finish, headline, main_of, pyplot

NAME = "blind_diagnosis"
log = logging.getLogger(__name__)

#: Repetitions per (generator, design set), null repetitions, noise levels [rad], forward
#: resolutions, rows of the cost measurement.
SETTINGS = {
    "coarse": {"reps": 2, "null_reps": 6, "new_reps": 1, "new_designs": 1, "sigmas": (0.01, 0.03, 0.1),
               "gdfe": "coarse", "fem": "coarse", "rows": 2000, "scans": "coarse"},
    "default": {"reps": 6, "null_reps": 18, "new_reps": 4, "sigmas": (0.01, 0.02, 0.03, 0.05, 0.1),
                "gdfe": "coarse", "fem": "coarse", "rows": 10000, "scans": "default"},
    "fine": {"reps": 12, "null_reps": 36, "new_reps": 8, "sigmas": (0.01, 0.02, 0.03, 0.05, 0.1),
             "gdfe": "default", "fem": "default", "rows": 10000, "scans": "default"},
}
#: The generators of the first benchmark (their repetitions: ``reps``, ``null_reps`` for the
#: nominal null); the later ones run ``new_reps`` times per design set, on their first
#: ``new_designs`` design sets (all when not set).
FIRST = ("nominal", "cure_depth", "hinge_length", "passive_stiffness", "film_thickening", "saturation",
         "partial_activation", "batch", "hard_cap", "coat_bleed", "hidden_lots", "overheating",
         "cure_depth_soft_coat")
#: The role of the oven temperature column, declared to the diagnosis where it takes ``roles``.
ROLES = {"T_C": "oven_temperature"}
SIGMA_GOAL = 0.03
ACCURACY_GOAL = 0.9
#: Noise levels assumed for Table 1 [rad].
TABLE1_SIGMAS = (0.03, 0.05, 0.1, 0.15)
#: Version of the generators: part of the cache key, raise it when they change.
GENERATOR_VERSION = 1
#: A data set's effect is visible at sigma when its visibility is at least this many sigma.
VISIBLE = 2.0
#: Where each class's accuracy goal (>= 0.9 at sigma = 0.03 rad) is expected not to hold, and
#: why, by resolution (the same for both rules: at sigma = 0.03 rad they agree on every data set
#: of these runs). A class not listed is expected to meet the goal.
MISSED = {
    "catalogue": "goal not met: the nonlinear FEM's film thickening changes the folds by less than twice the noise "
                 "on 8 of its 12 data sets (below the noise: no method can name it; it alone keeps the class under "
                 "0.9); two FEM cure depths are not reproduced by the catalogue's cure_depth within the noise, two "
                 "are reproduced by a reading offset with another effect (aliased), one gains a spurious oven-"
                 "temperature term. On the visible data sets the class is at 0.90; see accuracy_visible",
    "column": "goal not met: the panel's sag moves the folds by about the noise (visibility 0.03-0.04 rad at sigma "
              "= 0.03), and on 2 of 8 data sets another model within the noise takes it (with a reading offset); "
              "the anisotropic film is named as its column's factor every time",
    "d_only": "goal not met: on 2 of 8 data sets the heating lag is reproduced within the noise by a plausible "
              "catalogue model named alone (cure_depth; hinge_length with a reading offset), which no method can "
              "tell from the lag on these designs",
    "red_herring": "goal not met: the cure depth beside the herring columns is below the noise once and twice not "
                   "reproduced by the catalogue's cure_depth within the noise; no herring column is ever named",
}
#: The classes of :data:`MISSED` whose goal holds at a resolution all the same (the coarse run has
#: one or two data sets of each later class).
HOLDS_AT = {"coarse": ("column", "d_only", "red_herring"), "default": (), "fine": ()}
#: The outside class at the coarse resolution (16 data sets).
MISSED_COARSE = {"outside": "goal not met at this resolution: two of 16 out-of-catalogue data sets are resin "
                            "bleeding reproduced within the noise by hinge_length with a reading offset (once below "
                            "twice the noise, once named alone)"}


def expected(kind, resolution):
    """``(holds, why_not)``: whether the accuracy goal of class ``kind`` is expected to hold at
    ``resolution`` (:data:`MISSED`, :data:`HOLDS_AT`, :data:`MISSED_COARSE`)."""
    if resolution == "coarse" and kind in MISSED_COARSE:
        return False, MISSED_COARSE[kind]
    if kind in MISSED and kind not in HOLDS_AT.get(resolution, ()):
        return False, MISSED[kind]
    return True, ""


#: Limits of the cost measurement: 10,000 rows in 60 s and 1 GiB.
COST_GOAL = {"rows": 10000, "seconds": 60.0, "rss_mib": 1024.0}


def _names():
    from studies.diagnosis_generators import GENERATORS, SENSITIVITY

    return list(GENERATORS) + list(SENSITIVITY)


def _generator(name):
    from studies.diagnosis_generators import GENERATORS, SENSITIVITY

    return {**GENERATORS, **SENSITIVITY}[name]


def _reps(name, settings):
    if name not in FIRST:
        return settings.get("new_reps", settings["reps"])
    return settings["null_reps"] if _generator(name).kind == "null" else settings["reps"]


def _specs(settings, seed=0, cache=None):
    from studies.diagnosis_generators import SENSITIVITY
    from studies.diagnosis_generators.nominal import DESIGNS

    specs = []
    for ig, name in enumerate(_names()):
        g = _generator(name)
        reps = _reps(name, settings)
        designs = g.designs if name in FIRST else g.designs[:settings.get("new_designs") or len(g.designs)]
        for design in designs:
            ik = DESIGNS.index(design)
            for rep in range(reps):
                specs.append({"generator": name, "kind": g.kind, "sensitivity": name in SENSITIVITY,
                              "design": design, "rep": rep, "seed": [seed, ig, ik, rep],
                              "sigmas": tuple(settings["sigmas"]),
                              "resolution": {"gdfe": settings["gdfe"], "fem": settings["fem"]},
                              "cache": None if cache is None else str(cache)})
    return specs


def _draw(spec):
    from studies.diagnosis_generators.nominal import specimens

    rng = np.random.default_rng(spec["seed"])
    sp = specimens(spec["design"], rng)
    return sp, _generator(spec["generator"]).draw(rng, sp)


def simulate_cached(spec):
    """Noise-free angles, convergence, specimens and strengths of a data set (cached when
    ``spec["cache"]`` is a directory)."""
    import hashlib

    from studies.diagnosis_generators import generate

    sp, strengths = _draw(spec)
    path = None
    if spec.get("cache"):
        key = json.dumps({"g": spec["generator"], "design": spec["design"], "seed": spec["seed"],
                          "res": spec["resolution"], "v": GENERATOR_VERSION}, sort_keys=True)
        path = Path(spec["cache"]) / f"{hashlib.sha256(key.encode()).hexdigest()[:24]}.npz"
        if path.is_file():
            with np.load(path) as f:
                return f["alpha"], f["converged"], sp, strengths
    alpha, ok = generate(spec["generator"], sp, strengths, spec["resolution"])
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.npz")
        np.savez(tmp, alpha=alpha, converged=ok)
        os.replace(tmp, path)
    return alpha, ok, sp, strengths


def _tests(sp, alpha, columns=None):
    """Folding tests of the specimens with their recorded columns (``T_C``, ``batch`` and a
    generator's own, as the strings a CSV holds)."""
    import gdfe

    extra = {"T_C": np.array([f"{t:.1f}" for t in sp.T_C]), "batch": sp.batch}
    for k, v in (columns or {}).items():
        extra[k] = np.array([x if isinstance(x, str) else f"{x:g}" for x in v])
    return gdfe.FoldingTests(L=sp.L, d=sp.d, h=sp.h, alpha=np.asarray(alpha, float), extra=extra)


def _columns(generator, strengths):
    return {k: strengths[k] for k in _generator(generator).columns}


def takes_roles(diagnose=None):
    """Whether :func:`gdfe.diagnosis.diagnose` accepts ``roles=`` (the declared meaning of columns)."""
    import inspect

    if diagnose is None:
        from gdfe.diagnosis import diagnose
    return "roles" in inspect.signature(diagnose).parameters


def clean_fits(sp, alpha):
    """RMS [rad] of every catalogue model (singles, pairs, batch) fitted to noise-free angles."""
    from gdfe.diagnosis import Model, catalogue
    from gdfe.diagnosis.fit import fit_params

    models = catalogue(True, process=["T_C"]) + [Model(("batch",), group="batch", labels=np.unique(sp.batch))]
    out = {}
    for m in models:
        g = m.group_index(sp.batch) if m.group else None
        x = sp.T_C if m.process else None
        _, rss, _ = fit_params(m, sp.L, sp.d, sp.h, alpha, x=x, group=g)
        out[m.name] = float(np.sqrt(rss / alpha.size))
    return out


def is_right(generator, named, verdict):
    """Whether a diagnosis of a data set of ``generator`` is right by the package's rule (see the
    module docstring): the verdict, or a model of the named set, is among the generator's answers.

    ``named``: the models the diagnosis names (its set of indistinguishable models, or one name)."""
    g = _generator(generator)
    named = [named] if isinstance(named, str) else list(named)
    if verdict == "measurement_issue" and "not_explained" in g.answers:
        return True  # no physics credited; a reading error or an effect outside the catalogue left open
    return verdict in g.answers or any(n in g.answers for n in named)


#: Kinds of a model's effects: a physical cause, a measurement artefact, a factor (a column's
#: effect with no physical cause given).
EFFECT_KINDS = ("physics", "measurement", "factor")


def term_kind(term):
    """Kind of a model term from its name alone (when the diagnosis does not say): ``factor[...]``
    a factor, ``reading_offset`` (and other reading terms) a measurement, any other a physical
    cause."""
    if term.startswith("factor["):
        return "factor"
    if term.startswith("reading_") or term.startswith("measurement"):
        return "measurement"
    return "physics"


def model_terms(name, entry=None):
    """``[(term, kind)]`` of a model: its terms (``"cure_depth"``, ``"partial_activation[T_C]"``)
    with the kind the diagnosis gives them (``effect_kinds`` of its entry: a list beside its
    ``effects``, or a dict by effect) or else :func:`term_kind`."""
    if name == "baseline":
        return []
    terms = name.split("+")
    kinds = (entry or {}).get("effect_kinds")
    effects = list((entry or {}).get("effects") or [])
    out = []
    for i, t in enumerate(terms):
        k = None
        if isinstance(kinds, dict):
            k = kinds.get(t, kinds.get(t.split("[")[0]))
        elif isinstance(kinds, (list, tuple)):
            if len(kinds) == len(terms):
                k = kinds[i]
            elif len(kinds) == len(effects) and t.split("[")[0] in effects:
                k = kinds[effects.index(t.split("[")[0])]
        out.append((t, k if k in EFFECT_KINDS else term_kind(t)))
    return out


def credited_model(diagnosis):
    """What a diagnosis (:meth:`gdfe.diagnosis.Diagnosis.as_dict`) credits with the gap, or None.

    A model is credited when it is *named alone* -- the only model of the named set, with no
    alternative left open (``attribution.not_ruled_out`` empty: a diagnosis that says an effect
    outside the catalogue is not ruled out names its model beside that effect) -- *and* the
    verdict is ``explained`` or the model removes more than half of the gap. With several models
    named and the verdict ``explained``, the effects every one of them contains are credited
    (returned joined by ``+``)."""
    named = list(diagnosis.get("named") or [diagnosis["best"]])
    open_ = list((diagnosis.get("attribution") or {}).get("not_ruled_out") or [])
    explained = diagnosis["verdict"] in ("explained", "measurement_issue")
    if len(named) == 1 and not open_:
        cand = named[0]
        if cand == "baseline":
            return None
        entry = next((e for e in diagnosis.get("effects", []) if e.get("name") == cand), {})
        shrink = entry.get("shrink")
        if shrink is None and cand == diagnosis["best"]:
            shrink = diagnosis.get("gap_removed")
        return cand if explained or (shrink is not None and shrink > 0.5) else None
    if explained and len(named) > 1:
        sets = [n.split("+") for n in named if n != "baseline"]
        common = [t for t in sets[0] if all(t in s for s in sets[1:])] if sets else []
        return "+".join(common) or None
    return None


def wrong_physics_credited(diagnosis, right=()):
    """The strict rule's test: the model credited with the gap (:func:`credited_model`) when it
    holds a physical cause not in ``right`` (model terms), else None. Measurement artefacts and
    factors are never a wrong physical cause."""
    cand = credited_model(diagnosis)
    if cand is None:
        return None
    entry = next((e for e in diagnosis.get("effects", []) if e.get("name") == cand), {})
    right = set(right)
    wrong = [t for t, k in model_terms(cand, entry) if k == "physics" and t not in right]
    return cand if wrong else None


def flagged_rows(diagnosis):
    """Rows the diagnosis flags (outliers, failed specimens; CSV row numbers, the header being
    row 1), from its ``artefacts`` (``outliers``, ``failed_specimens``: ``rows``) or a top-level
    ``outliers``, ``flagged``, ``flagged_rows`` or ``failed``."""
    rows = set()

    def take(v):
        if isinstance(v, dict):
            for k in ("rows", "outliers", "failed", "flagged"):
                take(v.get(k))
        elif isinstance(v, (list, tuple)):
            for x in v:
                if isinstance(x, dict) and "row" in x:
                    rows.add(int(x["row"]))
                elif isinstance(x, (int, np.integer)) and not isinstance(x, bool):
                    rows.add(int(x))

    art = diagnosis.get("artefacts") or {}
    for src in (diagnosis, art if isinstance(art, dict) else {}):
        for key in ("outliers", "flagged", "flagged_rows", "failed", "failed_specimens"):
            take(src.get(key))
    return sorted(rows)


def growing_noise_detected(diagnosis):
    """Whether the diagnosis finds noise that grows with the angle (``artefacts.growing_noise``)."""
    art = diagnosis.get("artefacts") or {}
    g = art.get("growing_noise") if isinstance(art, dict) else None
    return bool(g.get("detected")) if isinstance(g, dict) else False


def strict_right(generator, diagnosis):
    """Whether a diagnosis is right by the strict rule: right by the package's rule
    (:func:`is_right`; for an artefact the diagnosis can flag, :func:`identified` counts too), no wrong
    physical cause credited (:func:`wrong_physics_credited`) and no model of a red-herring
    column named."""
    g = _generator(generator)
    named = list(diagnosis.get("named") or [diagnosis["best"]])
    ok = is_right(generator, named, diagnosis["verdict"]) or (g.flags and identified(diagnosis))
    if not ok or wrong_physics_credited(diagnosis, g.right_physics()) is not None:
        return False
    return not any(f"[{c}]" in n for n in named + [diagnosis["best"]] for c in g.herrings)


def identified(diagnosis):
    """Whether a diagnosis names a measurement artefact, flags rows or finds noise growing with
    the angle."""
    named = list(diagnosis.get("named") or [diagnosis["best"]])
    entries = {e.get("name"): e for e in diagnosis.get("effects", [])}
    return bool(flagged_rows(diagnosis)) or growing_noise_detected(diagnosis) or any(
        k == "measurement" for n in named for _, k in model_terms(n, entries.get(n)))


def _effects(name):
    return {e.split("[")[0] for e in name.split("+")} - {"baseline"}


def truth_in_a_named_model(generator, named):
    """Whether a model of ``named`` contains the effect built into a catalogue data set, alone or
    with another effect (a looser reading than :func:`is_right`, reported beside it)."""
    g = _generator(generator)
    if g.kind not in NAMING_KINDS:
        return False
    truth = _effects(g.answers[0])  # the effect built in (the first answer)
    return any(truth <= _effects(n) for n in named)


def _aliases(generator, fits, sigma):
    """Models that reproduce a data set's noise-free angles within ``sigma`` though they are not
    its answer (no effect of the answer in them): for a null data set none are counted (every
    model contains the baseline), for an out-of-catalogue one every model that fits."""
    g = _generator(generator)
    if g.kind == "null":
        return []
    truth = {a.split("[")[0] for ans in g.answers for a in ans.split("+")} if g.kind in NAMING_KINDS else set()
    return sorted(n for n, v in fits.items()
                  if n != "baseline" and v <= sigma and not truth & {e.split("[")[0] for e in n.split("+")})


#: Why a diagnosis missed, in the order the reasons are tried (:func:`miss_reason`).
MISSES = ("false alarm", "below the noise", "the catalogue's form misses the effect", "aliased", "diagnoser")
#: Why a diagnosis missed by the strict rule besides those (:func:`strict_miss_reason`).
STRICT_MISSES = ("wrong physical cause credited", "red herring named") + MISSES


def miss_reason(kind, right, visible, truth_rms, aliases, sigma):
    """Why a diagnosis of a data set is wrong (None when it is right).

    ``false alarm``: a null data set not called ``no_gap`` (the tests' level says how often);
    ``below the noise``: the effect's visibility is under :data:`VISIBLE` sigma; ``the
    catalogue's form misses the effect``: no model counted right reproduces the noise-free
    angles within sigma (``truth_rms > sigma``), so the effect built in is not the
    catalogue's effect to within the noise; ``aliased``: another catalogue model reproduces
    them within sigma; ``diagnoser``: none of these -- a method could have been right.
    """
    if right:
        return None
    if kind == "null":
        return "false alarm"
    if not visible:
        return "below the noise"
    if kind in NAMING_KINDS and truth_rms is not None and truth_rms > sigma:
        return "the catalogue's form misses the effect"
    if aliases:
        return "aliased"
    return "diagnoser"


def strict_miss_reason(generator, diagnosis, visible, truth_rms, aliases, sigma):
    """Why a diagnosis is wrong by the strict rule (None when it is right): a wrong physical cause
    credited, a red herring named, else :func:`miss_reason` of the package's rule."""
    if strict_right(generator, diagnosis):
        return None
    g = _generator(generator)
    if wrong_physics_credited(diagnosis, g.right_physics()) is not None:
        return "wrong physical cause credited"
    named = list(diagnosis.get("named") or [diagnosis["best"]])
    if any(f"[{c}]" in n for n in named + [diagnosis["best"]] for c in g.herrings):
        return "red herring named"
    return miss_reason(g.kind, False, visible, truth_rms, aliases, sigma)


def _job(spec):
    """Simulate one data set (or read it from the cache) and diagnose it at every noise level."""
    from gdfe.diagnosis import diagnose
    from studies.diagnosis_generators import measure

    t0 = time.perf_counter()
    clean, ok, sp, strengths = simulate_cached(spec)
    t_sim = time.perf_counter() - t0
    fits = clean_fits(sp, clean)
    visibility = fits["baseline"]
    g = _generator(spec["generator"])
    truth_rms = (min(fits[a] for a in g.answers if a in fits)
                 if g.kind in NAMING_KINDS and any(a in fits for a in g.answers) else None)
    rng = np.random.default_rng(list(spec["seed"]) + [1])
    roles = {"roles": dict(ROLES)} if takes_roles(diagnose) else {}
    records = []
    for sigma in spec["sigmas"]:
        noisy = measure(spec["generator"], clean, strengths, sigma, rng)
        t1 = time.perf_counter()
        diag = diagnose(_tests(sp, noisy, _columns(spec["generator"], strengths)), sigma=sigma, **roles)
        d = diag.as_dict()
        named = list(d.get("named") or [d["best"]])
        right = is_right(spec["generator"], named, d["verdict"])
        visible = bool(visibility >= VISIBLE * sigma)
        aliases = _aliases(spec["generator"], fits, sigma)
        credited = credited_model(d)
        entry = next((e for e in d.get("effects", []) if e.get("name") == credited), {})
        kinds = {n: [k for _, k in model_terms(n, next((e for e in d.get("effects", []) if e.get("name") == n), None))]
                 for n in dict.fromkeys(named + [d["best"]])}
        records.append({
            "generator": spec["generator"], "kind": spec["kind"], "sensitivity": spec["sensitivity"],
            "design": spec["design"], "rep": spec["rep"], "sigma": sigma,
            "strengths": {k: v for k, v in strengths.items() if not isinstance(v, list) or len(v) <= 3},
            "K": sp.K, "best": d["best"], "selected": d.get("selected", d["best"]), "verdict": d["verdict"],
            "named": named, "set_size": len(named), "term_kinds": kinds,
            "truth_in_a_named_model": truth_in_a_named_model(spec["generator"], named),
            "removed": d.get("gap_removed"), "correct": bool(right),
            "credited": credited, "credited_plausible": entry.get("plausible"),
            "wrong_credited": wrong_physics_credited(d, g.right_physics()),
            "correct_strict": bool(strict_right(spec["generator"], d)),
            "identified": identified(d), "flagged_rows": flagged_rows(d),
            "rows_found": (None if "rows" not in strengths else
                           bool(set(int(i) + 2 for i in strengths["rows"]) <= set(flagged_rows(d)))),
            "confounded": d.get("confounded"),
            "visibility": visibility, "visible": visible, "aliases": aliases, "truth_rms": truth_rms,
            "miss": miss_reason(spec["kind"], right, visible, truth_rms, aliases, sigma),
            "miss_strict": strict_miss_reason(spec["generator"], d, visible, truth_rms, aliases, sigma),
            "baseline_loo_rmse": diag.baseline.loo_rmse, "best_loo_rmse": diag.best.loo_rmse,
            "converged": bool(ok.all()), "seconds_diagnose": time.perf_counter() - t1, "seconds_simulate": t_sim,
        })
    return records


#: Columns of the generator x named-model confusion matrix.
NAMED = ("cure_depth", "hinge_length", "saturation", "passive_stiffness", "film_thickening", "partial_activation",
         "batch", "factor", "measurement", "other", "pair with the truth", "other pair", "baseline")


def _named(generator, best):
    if best == "baseline":
        return "baseline"
    effects = [e.split("[")[0] for e in best.split("+")]
    if len(effects) == 1:
        kind = term_kind(best)
        return effects[0] if effects[0] in NAMED else (kind if kind != "physics" else "other")
    g = _generator(generator)
    truth = {a.split("[")[0] for ans in g.answers for a in ans.split("+")} if g.kind == "catalogue" else set()
    return "pair with the truth" if truth & set(effects) else "other pair"


def confusions(records):
    """``(class x verdict, generator x named model)`` confusion matrices of ``records``."""
    from gdfe.diagnosis import VERDICTS
    from studies.diagnosis_generators import KINDS

    kinds = list(KINDS)
    V = np.zeros((len(kinds), len(VERDICTS)), int)
    gens = [n for n in _names() if any(r["generator"] == n for r in records)]
    G = np.zeros((len(gens), len(NAMED)), int)
    for r in records:
        if not r["sensitivity"]:
            V[kinds.index(r["kind"]), VERDICTS.index(r["verdict"])] += 1
        G[gens.index(r["generator"]), NAMED.index(_named(r["generator"], r["best"]))] += 1
    return {"verdict": {"rows": kinds, "columns": list(VERDICTS), "matrix": V.tolist()},
            "named": {"rows": gens, "columns": list(NAMED), "matrix": G.tolist()}}


def _mean(xs):
    xs = list(xs)
    return float(np.mean(xs)) if xs else None


def _tellable(r):
    """Whether a method could be right on a data set: null data; visible effects whose own
    catalogue form reproduces them within sigma (catalogue) or that no catalogue model
    reproduces within sigma (outside)."""
    if r["kind"] == "null":
        return True
    if not r["visible"]:
        return False
    if r["kind"] in NAMING_KINDS:
        return r.get("truth_rms") is None or r["truth_rms"] <= r["sigma"]
    return not r["aliases"]


def _misses(records, key="miss"):
    out = {}
    for r in records:
        if r.get(key):
            out[r[key]] = out.get(r[key], 0) + 1
    return {m: out[m] for m in STRICT_MISSES if m in out}


def summarise(records, sigmas):
    """Accuracy per class, per generator and per design set at each noise level."""
    from studies.diagnosis_generators import KINDS

    out = {}
    for s in sigmas:
        rs = [r for r in records if r["sigma"] == s]
        main = [r for r in rs if not r["sensitivity"]]
        entry = {"n": len(main),
                 "share_null_or_outside": _mean(r["kind"] != "catalogue" for r in main),
                 "classes": {}, "generators": {}, "designs": {}}
        for k in KINDS:
            kr = [r for r in main if r["kind"] == k]
            vis = [r for r in kr if r["kind"] == "null" or r["visible"]]
            un = [r for r in kr if r["kind"] != "outside" or not r["aliases"]]
            told = [r for r in kr if _tellable(r)]
            entry["classes"][k] = {"n": len(kr), "accuracy": _mean(r["correct"] for r in kr),
                                   "n_visible": len(vis), "accuracy_visible": _mean(r["correct"] for r in vis),
                                   "n_unaliased": len(un), "accuracy_unaliased": _mean(r["correct"] for r in un),
                                   "n_tellable": len(told), "accuracy_tellable": _mean(r["correct"] for r in told),
                                   "mean_set_size": _mean(r.get("set_size", 1) for r in kr),
                                   "ambiguous": _mean(r.get("set_size", 1) > 1 for r in kr),
                                   "misses": _misses(kr),
                                   "accuracy_strict": _mean(r.get("correct_strict", r["correct"]) for r in kr),
                                   "accuracy_strict_tellable": _mean(r.get("correct_strict", r["correct"])
                                                                     for r in told),
                                   "misses_strict": _misses(kr, "miss_strict"),
                                   "accuracy_measurement_wrong": _mean(
                                       r.get("correct_strict", r["correct"]) and r["verdict"] != "measurement_issue"
                                       for r in kr),
                                   "identified": _mean(r.get("identified", False) for r in kr)}
            if k == "catalogue":  # the named set scored right when it holds the answer; the best model alone too
                entry["classes"][k]["accuracy_best_only"] = _mean(is_right(r["generator"], r["best"], r["verdict"])
                                                                  for r in kr)
                entry["classes"][k]["truth_in_a_named_model"] = _mean(r.get("truth_in_a_named_model", False)
                                                                      for r in kr)
        for g in dict.fromkeys(r["generator"] for r in rs):
            gr = [r for r in rs if r["generator"] == g]
            entry["generators"][g] = {
                "n": len(gr), "accuracy": _mean(r["correct"] for r in gr),
                "visible": _mean(r["visible"] for r in gr), "aliased": _mean(bool(r["aliases"]) for r in gr),
                "verdicts": {v: sum(r["verdict"] == v for r in gr) for v in dict.fromkeys(r["verdict"] for r in gr)},
                "accuracy_visible": _mean(r["correct"] for r in gr if r["kind"] == "null" or r["visible"]),
                "misses": _misses(gr),
                "accuracy_strict": _mean(r.get("correct_strict", r["correct"]) for r in gr),
                "misses_strict": _misses(gr, "miss_strict"),
                "identified": _mean(r.get("identified", False) for r in gr),
                "rows_found": _mean(r["rows_found"] for r in gr if r.get("rows_found") is not None),
                "mean_set_size": _mean(r.get("set_size", 1) for r in gr),
                "median_visibility": float(np.median([r["visibility"] for r in gr]))}
        for dset in dict.fromkeys(r["design"] for r in main):
            dr = [r for r in main if r["design"] == dset]
            entry["designs"][dset] = {k: _mean(r["correct"] for r in dr if r["kind"] == k) for k in KINDS}
        entry["confusion"] = confusions(rs)
        out[f"{s:g}"] = entry
    return out


def table1_findings(resolution="coarse"):
    """Diagnose Table 1 with the noise unknown (the paper states none) and at assumed noise
    levels, and say what each verdict rests on."""
    import gdfe
    from gdfe.diagnosis import diagnose

    diag = diagnose(gdfe.TABLE1, check=resolution)
    d = diag.as_dict()
    b, best = diag.baseline, diag.best
    params = ", ".join(f"{p['name']} = {p['value']:.3g}" + (f" +- {p['se']:.2g}" if p["se"] is not None else "")
                       for p in best.parameters())
    assumed = {}
    for s in TABLE1_SIGMAS:
        ds = diagnose(gdfe.TABLE1, sigma=s)
        assumed[f"{s:g}"] = {"verdict": ds.verdict.verdict, "best": ds.best.name,
                             "named": [f.name for f in ds.named], "text": ds.verdict.text}
    need_b = diag.lack_of_fit["baseline"]["sigma_needed"]
    need = diag.lack_of_fit["best"]["sigma_needed"]
    text = [
        f"Table 1 with the noise unknown (the paper reports none, and no test is repeated): verdict "
        f"{diag.verdict.verdict}. {diag.verdict.text}",
        f"Baseline (Eq. 1-3 refitted, K = {b.params[0]:.4f} +- {b.se[0]:.2g}): RMSE {b.rmse:.3f} rad, LOO RMSE "
        f"{b.loo_rmse:.3f} rad, R^2 {d['baseline']['r2']:.2f}; its closed form equals GDFE solves of the tests "
        f"within {d['gdfe_check']['baseline']['max_abs_diff']:.3f} rad.",
        f"Best: {best.name} ({params}): LOO RMSE {best.loo_rmse:.3f} rad, {100 * diag.shrink(best):.0f} % of the "
        f"baseline's held-out RMSE removed; not ruled out: {', '.join(diag.candidates)}.",
        "What it says about the noise: the baseline is within the noise only if sigma >= "
        f"{need_b:.3g} rad, {best.name} only if sigma >= {need:.3g} rad. Assumed noise: "
        + "; ".join(f"sigma = {s} rad -> {v['verdict']} ({', '.join(v['named'])})" for s, v in assumed.items())
        + ". The paper states no measurement error, so which of these holds is for the noise of the "
          "angle measurement to say (give it with --sigma).",
        "Where: " + diag.regime,
        "After the best model: " + diag.regime_best,
    ]
    for w in diag.warnings:
        text.append("Warning: " + w)
    return {**d, "assumed_noise": assumed}, text


def cost(rows, out, sigma=0.03, seed=0):
    """Time and peak memory of ``gdfe diagnose`` on ``rows`` random tests, in a child process.

    The tests are random designs (``L`` 1.5-6 mm, ``d`` 0.1-0.5 mm, ``h`` 0.2-0.4 mm) with an
    oven temperature column and three batches, angles of a cure-depth world plus noise. The
    child runs ``python -m gdfe diagnose FILE --sigma S --check none --json OUT`` and reports
    its own wall time, processor time (user + system, ``resource.getrusage``: on a machine
    shared with other work the wall time also counts their share) and peak resident memory (the
    kernel's high-water mark of the child's own memory, ``VmHWM``: Linux carries ``ru_maxrss``
    over an exec, so a child started from a large parent, such as a long test session, reported
    the parent's 1 056 MiB for a diagnosis that peaks at 147 MiB).

    Returns
    -------
    dict
        ``rows``, ``seconds`` (wall), ``cpu_seconds``, ``peak_rss_mib``, ``verdict``, ``best``,
        ``named``, ``load`` (1-minute load average before the run), ``cores``, ``command``.
    """
    import subprocess
    import sys

    rng = np.random.default_rng(seed)
    L = rng.uniform(1.5, 6.0, rows)
    d = np.exp(rng.uniform(np.log(0.1), np.log(0.5), rows))
    h = rng.uniform(0.2, 0.4, rows)
    T = rng.uniform(120.0, 160.0, rows)
    batch = rng.choice(["b1", "b2", "b3"], rows)
    alpha = 0.05 * (h / (d + 0.08)) ** 1.5 * L / h + sigma * rng.standard_normal(rows)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    csv = out / f"cost_{rows}.csv"
    lines = ["L_mm,d_mm,h_mm,alpha_rad,T_C,batch"]
    lines += [f"{a:.5f},{b:.5f},{c:.5f},{e:.6f},{t:.2f},{g}" for a, b, c, e, t, g in zip(L, d, h, alpha, T, batch)]
    write_text(csv, "\n".join(lines) + "\n")
    js = out / f"cost_{rows}.json"
    child = ("import json, resource, sys, time\n"
             "from gdfe.cli import main\n"
             "t0 = time.perf_counter()\n"
             "u0 = resource.getrusage(resource.RUSAGE_SELF)\n"
             "rc = main(sys.argv[1:])\n"
             "dt = time.perf_counter() - t0\n"
             "u = resource.getrusage(resource.RUSAGE_SELF)\n"
             "cpu = u.ru_utime - u0.ru_utime + u.ru_stime - u0.ru_stime\n"
             "peak = u.ru_maxrss / 1024.0\n"
             "try:\n"
             "    with open('/proc/self/status') as f:\n"
             "        peak = next(int(l.split()[1]) for l in f if l.startswith('VmHWM:')) / 1024.0\n"
             "except (OSError, StopIteration, ValueError):\n"
             "    pass\n"
             "print(json.dumps({'rc': rc, 'seconds': dt, 'cpu_seconds': cpu, 'peak_rss_mib': peak}))\n")
    args = ["diagnose", str(csv), "--sigma", f"{sigma:g}", "--check", "none", "--json", str(js)]
    load = os.getloadavg()[0]
    done = subprocess.run([sys.executable, "-c", child, *args], capture_output=True, text=True, check=True)
    m = json.loads(done.stdout.strip().splitlines()[-1])
    d = json.loads(js.read_text())
    return {"rows": rows, "seconds": m["seconds"], "cpu_seconds": m["cpu_seconds"], "peak_rss_mib": m["peak_rss_mib"],
            "rc": m["rc"], "verdict": d["verdict"], "best": d["best"], "named": d["named"], "load": load,
            "cores": os.cpu_count(),
            "command": "gdfe " + " ".join(args)}


def scan_checks(resolution="default"):
    """The cases the shape diagnosis's scan-is-the-part thresholds rest on, and the exact-copy floor.

    Scans (surface samples of GDFE shapes) of the three-hinge strip of the shape tests, the
    Figure 6 hinge (L = 1.6 mm) and (at ``"default"``) the tube example, each with its own
    region(s) changed, and scans of one part against another's design; for each, the relative
    residual and the coverage against the nominal shape and after the common-factor search
    (:func:`gdfe.diagnosis.diagnose_shape`). Then the exact copy of the 1.6 mm hinge's vertices
    with two cell layers: its ICP residual with and without the vertices inside the film.
    """
    import gdfe
    from gdfe.diagnosis import Surface, align_icp, design_regions, diagnose_shape
    from gdfe.diagnosis import shape as shp
    from gdfe.io import surface_faces

    strip = gdfe.from_rows(["RRRTTRRRRRTTRRTTRRRRRR"] * 2, R=0.8, pixel=0.25, nz=1)
    hinge = gdfe.hinge(1.6, d=gdfe.paper.FIG6_D)
    parts = {"strip": strip, "hinge": hinge}
    if resolution != "coarse":
        parts["tube"] = gdfe.load_design(Path(__file__).resolve().parents[1] / "docs/examples/tube.toml")[0]
    rng = np.random.default_rng(0)

    def scan(des, R=None, n=700):
        pts = gdfe.simulate(des if R is None else des.with_R(R)).points
        smp = Surface(pts, des, per_edge=6).samples
        return smp[rng.choice(len(smp), min(n, len(smp)), replace=False)]

    def changed(des, region, R):
        Rc = des.R.copy()
        Rc[design_regions(des)[region]] = R
        return Rc

    cases = [("strip", "strip, hinge_2 R 0.8 -> 1.0", scan(strip, changed(strip, "hinge_2", 1.0)), True),
             ("strip", "strip, hinge_2 R 0.8 -> 0.6", scan(strip, changed(strip, "hinge_2", 0.6)), True),
             ("strip", "strip, hinge_2 R 0.8 -> 0.4", scan(strip, changed(strip, "hinge_2", 0.4)), True),
             ("hinge", "hinge, R 0.69 -> 0.5", scan(hinge, changed(hinge, "hinge", 0.5)), True),
             ("hinge", "hinge, R 0.69 -> 0.9", scan(hinge, changed(hinge, "hinge", 0.9)), True),
             ("strip", "the hinge against the strip", gdfe.simulate(hinge).points, False),
             ("hinge", "the strip against the hinge", gdfe.simulate(strip).points, False)]
    if "tube" in parts:
        tube = parts["tube"]
        cases += [("tube", "tube, hinge_3 unfolded", scan(tube, changed(tube, "hinge_3", 1.0), 1500), True),
                  ("tube", "tube, every hinge at R 0.8", scan(tube, np.where(tube.R < 1, 0.8, 1.0), 1500), True),
                  ("tube", "the hinge against the tube", gdfe.simulate(hinge).points, False),
                  ("tube", "the strip against the tube", scan(strip), False),
                  ("strip", "the tube against the strip", scan(tube, None, 1500), False)]
    rows = []
    for part, label, cloud, same in cases:
        t0 = time.perf_counter()
        res = diagnose_shape(parts[part], cloud, correct=False)
        rows.append({"case": label, "same_part": same, "matches": res.matches,
                     "relative_residual": res.match["relative_residual"], "coverage": res.match["coverage"],
                     "factor": res.match["factor"], "simulations": res.n_simulations,
                     "seconds": time.perf_counter() - t0, "right": res.matches == same})
    des = gdfe.hinge(1.6, d=gdfe.paper.FIG6_D, nz=2)
    pts = gdfe.simulate(des).points
    surf = Surface(pts, des)
    on = np.unique(surface_faces(des)[0])
    floor = {"n_vertices": int(len(pts)), "n_surface_vertices": int(on.size),
             "icp_rms_all_vertices_mm": align_icp(pts, surf)[2], "icp_rms_surface_vertices_mm": align_icp(pts[on], surf)[2],
             "half_thickness_mm": float(des.mesh.spacing[2] * 1.0)}
    return {"cases": rows, "exact_copy": floor,
            "thresholds": {"residual": shp.MATCH_RESIDUAL, "coverage": shp.MATCH_COVERAGE,
                           "clear_mismatch": list(shp.CLEAR_MISMATCH), "factors": list(shp.FACTORS)}}


def run(resolution="default", out=None, n_jobs=None, reps=None, sigmas=None, cache=True, parts=None):
    """Run the blind benchmark, the Table 1 diagnosis, the cost measurement and the scan checks.

    Parameters
    ----------
    resolution : {"coarse", "default", "fine"}
        Repetitions, noise levels, forward resolutions and rows of the cost run (:data:`SETTINGS`).
    out : path, optional
        Directory for ``blind_diagnosis.png``, ``.json``, ``.md`` and the cache.
    n_jobs : int, optional
        Worker processes (default: all cores).
    reps, sigmas : optional
        Override the repetitions per (generator, design set) (the null gets three times as many)
        and the noise levels [rad].
    cache : bool or path
        Keep the noise-free data sets in ``out/cache`` (or the directory given) and reuse them.
    parts : set of str, optional
        Parts to run among ``{"benchmark", "table1", "cost", "scans"}`` (default all).
    """
    from gdfe.parallel import parallel_map

    check_resolution(resolution)
    parts = {"benchmark", "table1", "cost", "scans"} if parts is None else set(parts)
    settings = dict(SETTINGS[resolution])
    if reps is not None:
        settings["reps"], settings["null_reps"] = int(reps), 3 * int(reps)
    if sigmas is not None:
        settings["sigmas"] = tuple(float(s) for s in sigmas)
    t0 = time.perf_counter()
    cache_dir = None
    if cache:
        cache_dir = Path(cache) if cache is not True else (Path(out) / "cache" if out is not None else None)
    result = {"study": NAME, "figure": "issue 12", "resolution": resolution,
              "title": "blind benchmark of the fold-angle diagnoser on independent generators; Table 1",
              "settings": {**settings, "visible": VISIBLE, "generator_version": GENERATOR_VERSION}}
    heads = []
    goal = f"{SIGMA_GOAL:g}"
    if "cost" in parts:  # first, so that no worker of the benchmark shares the machine with it
        c = cost(settings["rows"], Path(out) if out is not None else Path("out") / NAME)
        result["cost"] = c
        heads.append(headline(f"diagnosis of {c['rows']} rows, processor time [s]", c["cpu_seconds"],
                              tol=COST_GOAL["seconds"], kind="le", unit="s", goal=True,
                              paper_text="issue 12 goal: 10,000 rows in <= 60 s on 2 cores",
                              note=f"wall {c['seconds']:.1f} s at load {c['load']:.1f} on {c['cores']} cores"))
        heads.append(headline(f"peak memory of the {c['rows']}-row diagnosis [MiB]", c["peak_rss_mib"],
                              tol=COST_GOAL["rss_mib"], kind="le", unit="MiB",
                              paper_text="issue 12 goal: <= 1 GiB"))
    records = []
    if "benchmark" in parts:
        from studies.diagnosis_generators import GENERATORS, SENSITIVITY

        specs = _specs(settings, cache=cache_dir)
        records = [r for rs in parallel_map(_job, specs, n_jobs=n_jobs, desc="blind data sets") for r in rs]
        summary = summarise(records, settings["sigmas"])
        result.update(accuracy=summary, records=records,
                      generators={n: {"kind": g.kind, "answers": list(g.answers), "forward": g.forward,
                                      "ranges": {k: list(v) for k, v in g.ranges.items()},
                                      "sensitivity": n in SENSITIVITY}
                                  for n, g in {**GENERATORS, **SENSITIVITY}.items()})
        if goal in summary:
            for k, v in summary[goal]["classes"].items():
                if not v["n"]:
                    continue
                holds, why = expected(k, resolution)
                heads.append(headline(f"accuracy at sigma = {goal} rad, strict rule: {k}", v["accuracy_strict"],
                                      tol=ACCURACY_GOAL, kind="ge",
                                      paper_text="issue 12 goal: >= 0.9 in every class, no wrong physical cause "
                                                 "credited", expect=holds, note=why))
                heads.append(headline(f"accuracy at sigma = {goal} rad: {k}", v["accuracy"], tol=ACCURACY_GOAL,
                                      kind="ge", paper_text="issue 12 goal: >= 0.9 in every class",
                                      expect=holds, note=why))
            heads.append(headline("share of null or out-of-catalogue data sets", summary[goal]["share_null_or_outside"],
                                  tol=0.4, kind="ge", paper_text="issue 12: >= 40 %"))
    if "table1" in parts:
        t1, findings = table1_findings(settings["gdfe"])
        result["table1"], result["findings"] = t1, findings
        heads.append(headline("Table 1 baseline LOO RMSE [rad]", t1["baseline"]["loo_rmse"], tol=1.0, kind="le",
                              unit="rad", paper_text="K = 0.3706, R^2 ~ 0.8 (paper)"))
    if "scans" in parts:
        sc = scan_checks(settings["scans"])
        result["scan_checks"] = sc
        heads.append(headline("scans told apart (the part or not)", float(np.mean([c["right"] for c in sc["cases"]])),
                              paper=1.0, kind="eq"))
    result["headlines"] = heads
    result["converged"] = all(r["converged"] for r in records)
    result["seconds"] = time.perf_counter() - t0
    result["summary"] = _summary_sentences(result)
    if out is None:
        return result
    finish(result, out, plot)
    _write_md(result, out)
    return result


def _summary_sentences(result):
    goal = f"{SIGMA_GOAL:g}"
    s = result.get("accuracy")
    parts = []
    if isinstance(s, dict) and goal in s:
        acc = s[goal]["classes"]
        parts.append("accuracy at sigma = 0.03 rad by the strict rule (no wrong physical cause credited): "
                     + ", ".join(f"{k} {_fmt(v.get('accuracy_strict'))}" for k, v in acc.items() if v["n"]))
        parts.append("by the package's rule: " + ", ".join(
            f"{k} {v['accuracy']:.2f}" + (f" (visible {v['accuracy_visible']:.2f}, mean named set "
                                          f"{v['mean_set_size']:.2f}, the best model alone "
                                          f"{_fmt(v.get('accuracy_best_only'))})" if k == "catalogue" else "")
            for k, v in acc.items() if v["n"]))
    if "table1" in result:
        parts.append(f"Table 1: {result['table1']['verdict']} with the noise unknown")
    if "cost" in result:
        parts.append(f"{result['cost']['rows']} rows in {result['cost']['cpu_seconds']:.1f} s of processor time "
                     f"({result['cost']['seconds']:.1f} s wall), {result['cost']['peak_rss_mib']:.0f} MiB")
    return {"paper": "The paper fits Eq. 1 to Table 1 and diagnoses nothing.", "ours": "; ".join(parts),
            "verdict": (result.get("findings") or [""])[0], "discrepancy": ""}


def _fmt(x):
    return "-" if x is None else f"{x:.2f}"


def _write_md(result, out):
    """The benchmark's tables as Markdown, ``out/blind_diagnosis.md``."""
    lines = [f"# Blind diagnosis benchmark ({result['resolution']})", ""]
    s = result.get("accuracy")
    if s:
        goal = f"{SIGMA_GOAL:g}"
        lines += _md_generators(result["generators"]) + _md_accuracy(s, goal)
        if goal in s:
            lines += _md_strict(s[goal], goal, result["records"]) + _md_misses(s[goal], goal)
            lines += _md_confusion(s[goal]["confusion"], goal)
    if "cost" in result:
        lines += _md_cost(result["cost"])
    if "scan_checks" in result:
        lines += _md_scan_checks(result["scan_checks"])
    if "findings" in result:
        lines += ["", "## Table 1", ""] + [f"- {t}" for t in result["findings"]]
    write_text(Path(out, f"{NAME}.md"), "\n".join(lines) + "\n")


def _md_generators(generators):
    lines = ["## Generators", ""]
    for n, g in generators.items():
        lines.append(f"- `{n}` ({g['kind']}{', sensitivity' if g['sensitivity'] else ''}): {g['forward']}; "
                     f"right: {', '.join(g['answers'])}; ranges {g['ranges']}")
    return lines


def _md_accuracy(s, goal):
    """Accuracy per class and per generator against sigma."""
    first = s[next(iter(s))]
    lines = ["", "## Accuracy per class against sigma", "",
             "| sigma | " + " | ".join(first["classes"]) + " | share null/outside |",
             "|---|" + "---|" * (len(first["classes"]) + 1)]
    for sig, e in s.items():
        lines.append(f"| {sig} | " + " | ".join(
            f"{_fmt(c['accuracy'])} ({c['n']}; visible {_fmt(c['accuracy_visible'])} of {c['n_visible']}, "
            f"tellable {_fmt(c.get('accuracy_tellable'))} of {c.get('n_tellable')}; "
            f"mean named set {_fmt(c.get('mean_set_size'))}"
            + (f"; truth in a named model {_fmt(c['truth_in_a_named_model'])}"
               if "truth_in_a_named_model" in c else "") + ")" for c in e["classes"].values())
            + f" | {e['share_null_or_outside']:.2f} |")
    lines += ["", "## Accuracy per generator against sigma", "",
              "Accuracy on all data sets (on the visible ones, visibility >= "
              f"{VISIBLE:g} sigma, in brackets), the median visibility, the share of data sets with an "
              f"alias and the mean size of the named sets at sigma = {SIGMA_GOAL:g} rad.", "",
              "| generator | " + " | ".join(s) + " | median visibility [rad] | aliased | mean named set |",
              "|---|" + "---|" * (len(s) + 3)]
    for g in first["generators"]:
        vis = first["generators"][g]["median_visibility"]
        al = s[goal]["generators"][g]["aliased"] if goal in s else None
        size = s[goal]["generators"][g].get("mean_set_size") if goal in s else None
        lines.append(f"| {g} | " + " | ".join(
            f"{_fmt(e['generators'][g]['accuracy'])} ({_fmt(e['generators'][g].get('accuracy_visible'))})"
            for e in s.values()) + f" | {vis:.3f} | {_fmt(al)} | {_fmt(size)} |")
    return lines


def _md_strict(at_goal, goal, records):
    """The strict rule at the goal's sigma, per class and per generator, and its every miss."""
    lines = ["", f"## Strict rule at sigma = {goal} rad", "",
             "Right only if no single wrong physical cause is credited (studies.blind_diagnosis."
             "wrong_physics_credited), beside the package's rule; identified: a measurement artefact "
             "named or rows flagged.", "",
             "| class | n | strict | package's rule | strict, tellable | identified | strict misses |",
             "|---|---|---|---|---|---|---|"]
    for k, c in at_goal["classes"].items():
        if c["n"]:
            lines.append(f"| {k} | {c['n']} | {_fmt(c.get('accuracy_strict'))} | {_fmt(c['accuracy'])} | "
                         f"{_fmt(c.get('accuracy_strict_tellable'))} | {_fmt(c.get('identified'))} | "
                         + ", ".join(f"{m} {n}" for m, n in c.get("misses_strict", {}).items()) + " |")
    lines += ["", "| generator | n | strict | package's rule | identified | its rows flagged | strict misses |",
              "|---|---|---|---|---|---|---|"]
    for g, e in at_goal["generators"].items():
        lines.append(f"| {g} | {e['n']} | {_fmt(e.get('accuracy_strict'))} | {_fmt(e['accuracy'])} | "
                     f"{_fmt(e.get('identified'))} | {_fmt(e.get('rows_found'))} | "
                     + ", ".join(f"{m} {n}" for m, n in e.get("misses_strict", {}).items()) + " |")
    missed = [r for r in records if r["sigma"] == float(goal) and r.get("miss_strict")]
    lines += ["", f"### Every miss by the strict rule at sigma = {goal} rad", "",
              "Plausible: whether the diagnosis finds the credited model's parameters in their physical "
              "ranges (- where it does not say).", "",
              "| generator | design | rep | verdict | named | credited | plausible | reason |",
              "|---|---|---|---|---|---|---|---|"]
    for r in missed:
        pl = r.get("credited_plausible")
        lines.append(f"| {r['generator']} | {r['design']} | {r['rep']} | {r['verdict']} | "
                     f"{', '.join(r['named'])} | {r.get('credited') or '-'} | {'-' if pl is None else pl} | "
                     f"{r['miss_strict']} |")
    return lines


def _md_misses(at_goal, goal):
    """The package's rule's misses at the goal's sigma, by reason."""
    lines = ["", f"## Misses at sigma = {goal} rad by reason (package's rule)", "",
             "Tellable data sets: null ones; visible effects whose own catalogue form reproduces the "
             "noise-free angles within sigma (catalogue), or that no catalogue model reproduces within "
             "sigma (outside). Reasons (studies.blind_diagnosis.miss_reason): " + "; ".join(MISSES) + ".", "",
             "| generator | n | right | " + " | ".join(MISSES) + " |", "|---|---|---|" + "---|" * len(MISSES)]
    for g, e in at_goal["generators"].items():
        m = e.get("misses", {})
        lines.append(f"| {g} | {e['n']} | {round(e['accuracy'] * e['n'])} | "
                     + " | ".join(str(m.get(k, 0)) for k in MISSES) + " |")
    return lines


def _md_confusion(confusion, goal):
    lines = []
    for key, title in (("verdict", "class x verdict"), ("named", "generator x named model")):
        m = confusion[key]
        lines += ["", f"## Confusion at sigma = {goal} rad: {title}", "",
                  "| | " + " | ".join(m["columns"]) + " |", "|---|" + "---|" * len(m["columns"])]
        for row, vals in zip(m["rows"], m["matrix"]):
            lines.append(f"| {row} | " + " | ".join(str(v) for v in vals) + " |")
    return lines


def _md_cost(c):
    return ["", "## Cost", "", f"`{c['command']}`: {c['rows']} rows in {c['seconds']:.1f} s wall, "
            f"{c['cpu_seconds']:.1f} s of processor time, peak RSS {c['peak_rss_mib']:.0f} MiB (load "
            f"{c['load']:.2f} on {c['cores']} cores before the run); verdict {c['verdict']}, best {c['best']}."]


def _md_scan_checks(sc):
    lines = ["", "## Is the scan the part?", "", "| case | same part | matches | relative residual | coverage | "
             "factor | simulations | s |", "|---|---|---|---|---|---|---|---|"]
    for r in sc["cases"]:
        lines.append(f"| {r['case']} | {r['same_part']} | {r['matches']} | {r['relative_residual']:.3f} | "
                     f"{r['coverage']:.2f} | {r['factor']:.2f} | {r['simulations']} | {r['seconds']:.1f} |")
    f = sc["exact_copy"]
    lines += ["", f"Exact copy of the 1.6 mm hinge's {f['n_vertices']} vertices (nz = 2) through ICP: RMS "
              f"{1000 * f['icp_rms_all_vertices_mm']:.1f} um; its {f['n_surface_vertices']} surface vertices "
              f"alone: {f['icp_rms_surface_vertices_mm']:.2g} mm (the others lie inside the film, "
              f"{1000 * f['half_thickness_mm']:.0f} um from either face)."]
    return lines


def plot(result, out):
    """Class x verdict confusion at sigma = 0.03 rad, accuracy per class and per generator
    against sigma."""
    plt = pyplot()
    s = result.get("accuracy")
    fig, axes = plt.subplots(1, 3, figsize=(19, 6.4), gridspec_kw={"width_ratios": [1, 1.15, 1.1]})
    if s:
        goal = f"{SIGMA_GOAL:g}" if f"{SIGMA_GOAL:g}" in s else next(iter(s))
        m = s[goal]["confusion"]["verdict"]
        M = np.array(m["matrix"])
        ax = axes[0]
        ax.imshow(M, cmap="Blues")
        for i in range(M.shape[0]):
            for j in range(M.shape[1]):
                ax.text(j, i, str(M[i, j]), ha="center", va="center",
                        color="white" if M[i, j] > M.max() / 2 else "black")
        ax.set_xticks(range(len(m["columns"])), m["columns"], rotation=30, ha="right", fontsize=8)
        ax.set_yticks(range(len(m["rows"])), m["rows"], fontsize=9)
        ax.set_title(f"class x verdict at sigma = {goal} rad", fontsize=10)
        sig = [float(k) for k in s]
        ax = axes[1]
        for k, mk in zip(s[goal]["classes"], "os^vD<>p"):
            if s[goal]["classes"][k]["n"]:
                ax.plot(sig, [s[f"{x:g}"]["classes"][k]["accuracy_strict"] for x in sig], marker=mk, label=k)
        ax.axhline(ACCURACY_GOAL, color="0.5", ls="--", lw=0.8, label=f"goal {ACCURACY_GOAL:g}")
        ax.set(xscale="log", xlabel="noise sigma [rad]", ylabel="accuracy, strict rule", ylim=(0, 1.02))
        ax.set_title("accuracy per class", fontsize=10)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
        # per generator: a table of colours and numbers (22 lines on one axis are unreadable)
        ax = axes[2]
        gens = list(s[goal]["generators"])
        A = np.array([[np.nan if (v := s[f"{x:g}"]["generators"].get(g, {}).get("accuracy_strict")) is None else v
                       for x in sig] for g in gens], float)
        ax.imshow(A, cmap="RdYlGn", vmin=0.0, vmax=1.0, aspect="auto")
        for i in range(A.shape[0]):
            for j in range(A.shape[1]):
                if np.isfinite(A[i, j]):
                    ax.text(j, i, f"{A[i, j]:.2f}", ha="center", va="center", fontsize=7,
                            color="white" if A[i, j] < 0.15 or A[i, j] > 0.85 else "black")
        ax.set_xticks(range(len(sig)), [f"{x:g}" for x in sig], fontsize=8)
        ax.set_yticks(range(len(gens)), gens, fontsize=7)
        ax.set_xlabel("noise sigma [rad]")
        ax.set_title("accuracy per generator, strict rule", fontsize=10)
    fig.tight_layout()
    fig.savefig(Path(out) / f"{NAME}.png", dpi=110)
    plt.close(fig)


main = main_of(__name__)

if __name__ == "__main__":
    import sys

    sys.exit(main())
