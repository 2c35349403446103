"""The blind benchmark of the fold-angle diagnoser (studies/blind_diagnosis.py) and its generators
(studies/diagnosis_generators), which must not be the diagnoser's own formulas."""

import json
from pathlib import Path

import numpy as np
import pytest
from imports_of import imported_modules  # a module of tests/, which pytest puts on the path

from studies import blind_diagnosis as bd
from studies.diagnosis_generators import (GENERATORS, KINDS, SENSITIVITY, artefacts, columns, generate, heating,
                                         kinetics, lag, measure, outside)
from studies.diagnosis_generators.nominal import ONE_H, eq3, gdfe_fold, specimens

GEN_DIR = Path(__file__).resolve().parents[1] / "studies" / "diagnosis_generators"
COARSE = {"gdfe": "coarse", "fem": "coarse"}


def test_generators_do_not_import_the_diagnoser():
    """No module of the generators imports gdfe.diagnosis (its catalogue, closed forms, fits), at
    module level or inside a function."""
    files = sorted(GEN_DIR.glob("*.py"))
    assert len(files) >= 9 and {"artefacts.py", "columns.py", "lag.py"} <= {f.name for f in files}
    for f in files:
        for n in imported_modules(f):
            assert not n.startswith("gdfe.diagnosis"), f"{f.name} imports {n}"


def test_classes_and_share_of_null_or_outside():
    assert {g.kind for g in GENERATORS.values()} == set(KINDS)
    assert {"null", "artefact", "column", "d_only", "process", "red_herring"} <= set(KINDS)
    specs = [s for s in bd._specs(bd.SETTINGS["coarse"]) if not s["sensitivity"]]
    share = np.mean([s["kind"] != "catalogue" for s in specs])
    assert share >= 0.4
    assert {g.name for g in GENERATORS.values() if g.kind == "outside"} >= {"hard_cap", "coat_bleed",
                                                                             "hidden_lots", "overheating"}


def test_strengths_are_drawn_in_their_ranges():
    for spec in bd._specs({**bd.SETTINGS["coarse"], "reps": 3, "null_reps": 1}):
        sp, s = bd._draw(spec)
        g = bd._generator(spec["generator"])
        for k, (lo, hi) in g.ranges.items():
            if k in ("prestrain", "thickness") or k not in s:
                continue
            if isinstance(s[k], list):
                assert all(lo - 1e-12 <= x <= hi + 1e-12 for x in s[k]), (k, s[k])
                continue
            v = abs(s[k]) if k == "lambda" else s[k]
            assert lo - 1e-12 <= v <= hi or (k == "lambda" and s[k] < 0 and v <= 0.5 * sp.L.min() + 1e-12), (k, v)
        n = 30 if spec["design"] == "random30" else 18
        assert sp.L.size == n and sp.T_C.size == n and set(sp.batch) == {"b1", "b2", "b3"}


def test_specimens_reach_the_drawn_largest_fold():
    sp = specimens("random", np.random.default_rng(0))
    largest = float(np.max(eq3(sp.K, sp.d, sp.h) * sp.L / sp.h))
    assert 2.5 <= largest <= 3.0 and np.ptp(sp.h) > 0


def test_kinetics_half_point_wlf_shift_and_not_a_logistic():
    """f(T_half) = 1/2; tau shifts by the WLF equation; and the curve is no logistic in T (the
    diagnoser's function leaves a visible misfit)."""
    from scipy.optimize import curve_fit

    T = np.linspace(120.0, 160.0, 81)
    f = kinetics.fraction(T, 135.0, 0.6)
    assert kinetics.fraction(np.array([135.0]), 135.0, 0.6)[0] == pytest.approx(0.5, abs=1e-12)
    assert np.all(np.diff(f) > 0)
    shift = kinetics._log10_shift(150.0) - kinetics._log10_shift(130.0)
    assert shift == pytest.approx(-17.44 * 50 / 101.6 + 17.44 * 30 / 81.6)

    def logistic(x, x50, rate):
        return 0.5 * (1 + np.tanh(0.5 * rate * (x - x50)))

    p, _ = curve_fit(logistic, T, f, p0=[135.0, 0.3])
    assert np.abs(logistic(T, *p) - f).max() > 0.02


def test_outside_effects_by_hand():
    a = np.array([0.5, 1.5, 2.5])
    np.testing.assert_array_equal(outside.hard_cap(a, 2.0), [0.5, 1.5, 2.0])
    T = np.linspace(120, 160, 41)
    f = kinetics.fraction(T, 125.0, 0.8) * np.exp(-(np.maximum(T - 145.0, 0.0) / 10.0) ** 2)
    k = int(np.argmax(f))
    assert 0 < k < T.size - 1  # overheating: the contraction rises, then falls with the temperature


def test_uniform_heating_is_the_nominal_fold_and_directed_heat_saturates():
    """w = 0: every cell is heated alike and reaches full contraction, the nominal GDFE fold; w = 1:
    the cells turning away from the heat stop short and the fold is smaller."""
    L, c, h = 3.0, 0.25, 0.29
    nominal, ok = gdfe_fold(L, 1.0 - c, h)
    even, ok0, a0 = heating.heated_fold(L, c, h, 0.0)
    directed, ok1, a1 = heating.heated_fold(L, c, h, 1.0)
    assert ok and ok0 and ok1
    assert even == pytest.approx(nominal, abs=1e-5) and a0 == pytest.approx(1.0)
    assert directed < even - 0.05 and a1 < 1.0


def test_fem_ratio_of_the_unchanged_specimen_is_the_nominal_fold():
    sp = specimens("table1", np.random.default_rng(1))
    sub = type(sp)(L=sp.L[:3], d=sp.d[:3], h=sp.h[:3], T_C=sp.T_C[:3], batch=sp.batch[:3], K=sp.K, design="table1")
    nominal, _ = generate("nominal", sub, {}, COARSE)
    same, _ = generate("cure_depth", sub, {"delta": 0.0}, COARSE)
    np.testing.assert_allclose(same, nominal, rtol=1e-12)
    thicker, _ = generate("cure_depth", sub, {"delta": 0.1}, COARSE)
    assert np.all(thicker < nominal)  # a thicker coat folds less


def test_one_data_set_is_diagnosed_and_cached(tmp_path):
    spec = next(s for s in bd._specs({**bd.SETTINGS["coarse"], "sigmas": (0.03,)}, cache=tmp_path)
                if s["generator"] == "partial_activation" and s["design"] == "random")
    (rec,) = bd._job(spec)
    assert rec["correct"] and rec["best"] == "partial_activation[T_C]", rec
    assert rec["visible"] and rec["visibility"] > 0.06
    assert len(list(tmp_path.glob("*.npz"))) == 1
    assert [r["best"] for r in bd._job(spec)] == [rec["best"]]


NEW = [n for n in GENERATORS if n not in bd.FIRST]


@pytest.mark.parametrize("name", NEW)
def test_new_generators_are_deterministic_and_finite(name):
    """Each later generator, on a small data set of its first design set: the same seed gives the
    same strengths, noise-free folds and measured folds; the folds are finite, one per specimen."""
    g = GENERATORS[name]
    spec = next(s for s in bd._specs({**bd.SETTINGS["coarse"], "sigmas": (0.03,)}) if s["generator"] == name)
    runs = []
    for _ in range(2):
        sp, strengths = bd._draw(spec)
        alpha, ok = generate(name, sp, strengths, COARSE)
        noisy = measure(name, alpha, strengths, 0.03, np.random.default_rng(5))
        runs.append((strengths, alpha, noisy))
        assert alpha.shape == noisy.shape == (len(sp),) and np.all(np.isfinite(noisy)) and ok.all()
        assert all(len(strengths[c]) == len(sp) for c in g.columns)
        if spec["design"] == "one_h":
            assert np.all(sp.h == ONE_H)
    assert runs[0][0] == runs[1][0]
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    np.testing.assert_array_equal(runs[0][2], runs[1][2])


def test_artefacts_columns_and_lag_by_hand():
    a = np.array([1.0, 2.0, 3.0])
    np.testing.assert_array_equal(artefacts.offset(a, 0.15), a + 0.15)
    np.testing.assert_array_equal(artefacts.outliers(a, [0, 2], [0.5, -0.5]), [1.5, 2.0, 2.5])
    np.testing.assert_array_equal(artefacts.failed(a, [1]), [1.0, 0.0, 3.0])
    # the scatter grows with the angle and has no bias
    rng = np.random.default_rng(0)
    b = np.array([0.5, 2.5])
    x = np.array([artefacts.growing_scatter(b, 0.03, 2.0, rng) for _ in range(4000)]) - b
    assert abs(x.mean(axis=0)).max() < 0.01 and x.std(axis=0)[1] / x.std(axis=0)[0] == pytest.approx(5.0, rel=0.1)
    # the sag: alpha = alpha_0 - C cos(alpha); none at 90 degrees, less below, more above
    s = columns.sag(np.array([0.5 * np.pi, 1.0, 2.5]), np.array([0.2, 0.2, 0.2]))
    assert s[0] == pytest.approx(0.5 * np.pi) and s[1] < 1.0 and s[2] > 2.5
    np.testing.assert_allclose(s - [0.5 * np.pi, 1.0, 2.5] + 0.2 * np.cos(s), 0.0, atol=1e-9)
    # the moment of a 10 mm panel on a 3 mm hinge of hot film (3 MPa): 0.157 rad held level
    assert columns.sag_compliance(3.0, 0.3, 0.29, 10.0, 3.0) == pytest.approx(
        1.1e-6 * 9.81 * 0.59 * 100 / 2 * 12 * 3 / (3.0 * 0.29 ** 3))
    # the heating lag: a thin coat reaches its shrink, a thick one less, by d alone
    f = lag.reached(np.array([0.05, 0.3, 0.5]), 0.006)
    assert f[0] == pytest.approx(1.0) and f[0] > f[1] > f[2] and f[2] == pytest.approx(1 - np.exp(-60 * 0.006 / 0.25))


def _diag(named, verdict, best=None, effects=()):
    return {"named": list(named), "best": best or named[0], "verdict": verdict, "effects": list(effects)}


def test_strict_rule_on_hand_made_diagnoses():
    """A wrong physical cause named alone, with ``explained`` or more than half of the gap, is
    wrong; named alone with less, or beside an alternative the diagnosis leaves open, it is not
    credited; a measurement artefact or a factor is never a wrong physical cause; on an explained
    verdict with several models named, the effects they share are credited."""
    alone = _diag(["cure_depth"], "explained", effects=[{"name": "cure_depth", "shrink": 0.9}])
    assert bd.wrong_physics_credited(alone) == "cure_depth"
    assert bd.wrong_physics_credited(alone, ["cure_depth"]) is None
    assert not bd.strict_right("heating_lag", alone)
    most = _diag(["cure_depth"], "partly_explained", effects=[{"name": "cure_depth", "shrink": 0.6}])
    assert bd.wrong_physics_credited(most) == "cure_depth"
    assert not bd.strict_right("heating_lag", most) and bd.is_right("heating_lag", ["cure_depth"], "partly_explained")
    little = _diag(["cure_depth"], "partly_explained", effects=[{"name": "cure_depth", "shrink": 0.3}])
    assert bd.wrong_physics_credited(little) is None and bd.strict_right("heating_lag", little)
    left_open = {**most, "attribution": {"not_ruled_out": ["outside_catalogue"]}}
    assert bd.credited_model(left_open) is None and bd.strict_right("heating_lag", left_open)
    offset = _diag(["reading_offset"], "explained", effects=[{"name": "reading_offset", "shrink": 0.9}])
    assert bd.wrong_physics_credited(offset) is None and bd.strict_right("reading_offset", offset)
    assert bd.identified(offset)
    # a measurement issue is not an explained verdict for an effect outside the catalogue
    issue = {**offset, "verdict": "measurement_issue"}
    assert bd.is_right("coat_bleed", issue["named"], "measurement_issue") and bd.strict_right("coat_bleed", issue)
    assert not bd.is_right("cure_depth", issue["named"], "measurement_issue")
    # the kind the diagnosis gives wins over the name
    told = _diag(["oddity"], "explained", effects=[{"name": "oddity", "effects": ["oddity"],
                                                      "effect_kinds": ["measurement"], "shrink": 0.9}])
    assert bd.wrong_physics_credited(told) is None
    factor = _diag(["factor[theta_deg]"], "explained", effects=[{"name": "factor[theta_deg]", "shrink": 0.8}])
    assert bd.wrong_physics_credited(factor) is None and bd.strict_right("anisotropic_film", factor)
    undeclared = _diag(["partial_activation[theta_deg]"], "partly_explained",
                       effects=[{"name": "partial_activation[theta_deg]", "shrink": 0.6}])
    assert not bd.strict_right("anisotropic_film", undeclared)
    assert bd.is_right("anisotropic_film", undeclared["named"], "partly_explained")
    several = _diag(["saturation", "cure_depth"], "partly_explained",
                    effects=[{"name": "saturation", "shrink": 0.7}, {"name": "cure_depth", "shrink": 0.65}])
    assert bd.credited_model(several) is None and bd.wrong_physics_credited(several) is None
    assert bd.strict_right("hard_cap", several)
    # explained with several named: what they share is credited, nothing when they share nothing
    assert bd.wrong_physics_credited({**several, "verdict": "explained"}) is None
    shared = _diag(["saturation", "saturation+cure_depth"], "explained")
    assert bd.wrong_physics_credited(shared) == "saturation" and not bd.strict_right("hard_cap", shared)
    # the right cause with a red herring's column named beside it
    herring = _diag(["cure_depth", "partial_activation[humidity_pct]"], "explained",
                    effects=[{"name": "cure_depth", "shrink": 0.8}])
    assert bd.wrong_physics_credited(herring, ["cure_depth"]) is None
    assert bd.is_right("cure_depth_herring", herring["named"], "explained")
    assert not bd.strict_right("cure_depth_herring", herring)
    assert bd.strict_right("cure_depth_herring", _diag(["cure_depth"], "explained"))
    # flagged rows count for outliers; the baseline credits nothing
    assert bd.flagged_rows({"outliers": [{"row": 4}, {"row": 9}]}) == [4, 9]
    found = {"named": ["baseline"], "best": "baseline", "verdict": "explained",
             "artefacts": {"outliers": {"rows": [7, 30]}, "failed_specimens": {"rows": [7, 20]},
                           "growing_noise": {"detected": False}}}
    assert bd.flagged_rows(found) == [7, 20, 30] and bd.identified(found)
    assert bd.strict_right("outliers", found) and not bd.strict_right("reading_offset", found)
    assert bd.growing_noise_detected({"artefacts": {"growing_noise": {"detected": True}}})
    assert bd.credited_model(_diag(["baseline"], "no_gap")) is None
    assert bd.model_terms("cure_depth+factor[T_C]") == [("cure_depth", "physics"), ("factor[T_C]", "factor")]


def test_roles_are_passed_only_where_the_diagnosis_takes_them():
    def with_roles(tests, *, sigma=None, roles=None):
        return roles

    def without(tests, *, sigma=None):
        return None

    assert bd.takes_roles(with_roles) and not bd.takes_roles(without)
    assert bd.ROLES == {"T_C": "oven_temperature"}


def test_is_right_and_confusions():
    assert bd.is_right("cure_depth", "cure_depth", "explained")
    assert not bd.is_right("cure_depth", "cure_depth+hinge_length", "explained")
    assert bd.is_right("passive_stiffness", "hinge_length+passive_stiffness", "explained")
    assert bd.is_right("nominal", "baseline", "no_gap") and not bd.is_right("nominal", "baseline", "not_explained")
    assert bd.is_right("hard_cap", "saturation", "partly_explained")
    assert not bd.is_right("hard_cap", "saturation", "explained")
    # a named set is right when it holds the answer; the looser reading counts a pair with the truth
    assert bd.is_right("cure_depth", ["film_thickening", "cure_depth"], "explained")
    assert not bd.is_right("cure_depth", ["cure_depth+passive_stiffness"], "explained")
    assert bd.truth_in_a_named_model("cure_depth", ["cure_depth+passive_stiffness"])
    assert bd.truth_in_a_named_model("partial_activation", ["partial_activation[T_C]+batch[batch]"])
    assert not bd.truth_in_a_named_model("cure_depth", ["film_thickening", "hinge_length+saturation"])
    assert not bd.truth_in_a_named_model("nominal", ["baseline"])
    recs = [{"generator": "cure_depth", "kind": "catalogue", "sensitivity": False, "best": "cure_depth",
             "verdict": "explained"},
            {"generator": "cure_depth", "kind": "catalogue", "sensitivity": False, "best": "cure_depth+hinge_length",
             "verdict": "explained"},
            {"generator": "nominal", "kind": "null", "sensitivity": False, "best": "baseline", "verdict": "no_gap"},
            {"generator": "hard_cap", "kind": "outside", "sensitivity": False, "best": "hinge_length+saturation",
             "verdict": "partly_explained"}]
    c = bd.confusions(recs)
    V, G = np.array(c["verdict"]["matrix"]), np.array(c["named"]["matrix"])
    assert V.sum() == 4 and V[c["verdict"]["rows"].index("null"), c["verdict"]["columns"].index("no_gap")] == 1
    rows, cols = c["named"]["rows"], c["named"]["columns"]
    assert G[rows.index("cure_depth"), cols.index("cure_depth")] == 1
    assert G[rows.index("cure_depth"), cols.index("pair with the truth")] == 1
    assert G[rows.index("hard_cap"), cols.index("other pair")] == 1
    assert G[rows.index("nominal"), cols.index("baseline")] == 1


def test_miss_reasons():
    """A miss is put down to the first reason that holds: a null data set's is a false alarm; an
    effect under two sigma is below the noise; one whose own catalogue form misses it by more than
    sigma is not the catalogue's; one another model reproduces within sigma is aliased."""
    assert bd.miss_reason("catalogue", True, False, 1.0, ["x"], 0.03) is None
    assert bd.miss_reason("null", False, True, None, [], 0.03) == "false alarm"
    assert bd.miss_reason("catalogue", False, False, 0.01, [], 0.03) == "below the noise"
    assert bd.miss_reason("catalogue", False, True, 0.05, ["saturation"], 0.03) == \
        "the catalogue's form misses the effect"
    assert bd.miss_reason("catalogue", False, True, 0.02, ["saturation"], 0.03) == "aliased"
    assert bd.miss_reason("outside", False, True, None, ["cure_depth+hinge_length"], 0.03) == "aliased"
    assert bd.miss_reason("outside", False, True, None, [], 0.03) == "diagnoser"
    recs = [{"kind": "catalogue", "sigma": 0.03, "visible": True, "truth_rms": 0.02, "aliases": []},
            {"kind": "catalogue", "sigma": 0.03, "visible": True, "truth_rms": 0.05, "aliases": []},
            {"kind": "outside", "sigma": 0.03, "visible": True, "aliases": ["saturation"]},
            {"kind": "outside", "sigma": 0.03, "visible": False, "aliases": []},
            {"kind": "null", "sigma": 0.03, "visible": True, "aliases": []}]
    assert [bd._tellable(r) for r in recs] == [True, False, False, False, True]


def test_cost_is_measured_in_a_child_process(tmp_path):
    c = bd.cost(300, tmp_path)
    assert c["rows"] == 300 and c["seconds"] > 0 and 20 < c["peak_rss_mib"] < 2048
    assert c["verdict"] in ("explained", "partly_explained") and c["rc"] == 0
    assert c["command"].startswith("gdfe diagnose")


def test_sensitivity_generators_are_not_counted():
    assert SENSITIVITY and not set(SENSITIVITY) & set(GENERATORS)
    recs = [{"generator": "cure_depth_soft_coat", "kind": "catalogue", "sensitivity": True, "sigma": 0.03,
             "correct": False, "visible": True, "aliases": [], "visibility": 0.1, "verdict": "no_gap",
             "best": "baseline", "design": "table1"},
            {"generator": "nominal", "kind": "null", "sensitivity": False, "sigma": 0.03, "correct": True,
             "visible": True, "aliases": [], "visibility": 0.0, "verdict": "no_gap", "best": "baseline",
             "design": "table1"}]
    s = bd.summarise(recs, (0.03,))["0.03"]
    assert s["classes"]["catalogue"]["n"] == 0 and s["classes"]["null"]["accuracy"] == 1.0
    assert s["generators"]["cure_depth_soft_coat"]["accuracy"] == 0.0


@pytest.mark.slow
def test_blind_benchmark_coarse(coarse_study):
    """The benchmark at coarse resolution: the classes, the confusion matrices, Table 1, the cost and
    the scan checks are all there, and every headline is as expected."""
    res, tmp_path = coarse_study("blind-diagnosis")
    acc = res["accuracy"]["0.03"]
    assert acc["share_null_or_outside"] >= 0.4
    assert set(acc["classes"]) == set(KINDS)
    assert acc["classes"]["null"]["accuracy"] >= 0.9
    assert all(h["passed"] for h in res["headlines"]), [h for h in res["headlines"] if not h["passed"]]
    assert res["table1"]["verdict"] in ("explained", "partly_explained", "not_explained", "no_gap")
    assert all(c["right"] for c in res["scan_checks"]["cases"])
    assert res["cost"]["rows"] == bd.SETTINGS["coarse"]["rows"]
    for f in ("blind_diagnosis.png", "blind_diagnosis.json", "blind_diagnosis.md"):
        assert (tmp_path / f).is_file()
    json.loads((tmp_path / "blind_diagnosis.json").read_text())
