"""The blind benchmark of the fold-angle diagnoser (studies/blind_diagnosis.py) and its generators
(studies/diagnosis_generators), which must not be the diagnoser's own formulas."""

import ast
import json
from pathlib import Path

import numpy as np
import pytest

from studies import blind_diagnosis as bd
from studies.diagnosis_generators import GENERATORS, KINDS, SENSITIVITY, generate, heating, kinetics, outside
from studies.diagnosis_generators.nominal import eq3, gdfe_fold, specimens

GEN_DIR = Path(__file__).resolve().parents[1] / "studies" / "diagnosis_generators"
COARSE = {"gdfe": "coarse", "fem": "coarse"}


def test_generators_do_not_import_the_diagnoser():
    """No module of the generators imports gdfe.diagnosis (its catalogue, closed forms, fits), at
    module level or inside a function."""
    files = sorted(GEN_DIR.glob("*.py"))
    assert len(files) >= 6
    for f in files:
        for node in ast.walk(ast.parse(f.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + [f"{node.module}.{a.name}" for a in node.names]
            for n in names:
                assert not n.startswith("gdfe.diagnosis"), f"{f.name} imports {n}"


def test_classes_and_share_of_null_or_outside():
    assert {g.kind for g in GENERATORS.values()} == set(KINDS)
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
            if k in ("prestrain", "thickness"):
                continue
            v = abs(s[k]) if k == "lambda" else s[k]
            assert lo - 1e-12 <= v <= hi or (k == "lambda" and s[k] < 0 and v <= 0.5 * sp.L.min() + 1e-12), (k, v)
        assert sp.L.size == 18 and sp.T_C.size == 18 and set(sp.batch) == {"b1", "b2", "b3"}


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
