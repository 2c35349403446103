"""Credit in the fold-angle diagnosis: physical ranges, measurement artefacts, honest named sets.

The data are made here from Eq. 1 in closed form, ``alpha = K sqrt(h / d^3) L`` with the
paper's K and film thickness, plus a stated artefact and seeded Gaussian noise; none of it
goes through the diagnoser's models.
"""

import numpy as np
import pytest

from gdfe import paper
from gdfe.calibration import FoldingTests
from gdfe.diagnosis import diagnose
from gdfe.diagnosis.effects import EFFECTS, model
from gdfe.physical_ranges import RANGES, check

SIGMA = 0.03


def _design():
    """A grid of hinge widths and coats at Table 1's film thickness, folds of 0.2-2.5 rad."""
    L, d = np.meshgrid([1.5, 2.5, 3.5, 4.5], [0.15, 0.2, 0.3, 0.45, 0.6])
    L, d = L.ravel(), d.ravel()
    h = np.full(L.size, paper.H)
    return L, d, h, paper.K * np.sqrt(h / d**3) * L / 4.0


def _tests(alpha, L, d, h):
    return FoldingTests(L, d, h, alpha)


def test_one_table_of_ranges_for_model_files_and_diagnosis():
    from gdfe.model import PHYSICAL_RANGES

    for name in ("delta", "lambda", "E_ratio", "mismatch", "beta", "alpha_max", "K", "offset", "scale", "x50"):
        assert name in RANGES and RANGES[name].why
        assert PHYSICAL_RANGES[name] == (RANGES[name].lo, RANGES[name].hi, RANGES[name].why)
    assert check("beta", 4.9)["range"] == [0.0, 2.0]  # 2 keeps the volume
    assert check("beta", 1.9) is None
    assert check("E_ratio", 70.0) is not None and check("offset", 0.15) is None
    assert check("scale[lotB]", 3.0)["name"] == "scale[lotB]"


def test_table1_delta_and_lambda_implausible_and_not_explained():
    diag = diagnose(paper.TABLE1)
    out = diag.as_dict()
    entry = next(e for e in out["effects"] if e["name"] == "cure_depth+hinge_length")
    assert not entry["plausible"]
    assert {p["name"] for p in entry["implausible"]} == {"delta", "lambda"}
    lam = next(p for p in entry["implausible"] if p["name"] == "lambda")
    assert lam["range"] == [-0.5, 1.0] and "hinges tested" in lam["why"]
    assert out["verdict"] != "explained"
    if not diag.best.plausible:
        assert diag.verdict.text.startswith("fits only with implausible parameters")


def test_film_thickening_beta_implausible():
    L, d, h, _ = _design()
    m = model("film_thickening")
    found = m.implausible([0.09, 4.9], L, d, h)
    assert [p["name"] for p in found] == ["beta"] and found[0]["value"] == pytest.approx(4.9)


def test_constant_offset_is_a_measurement_hypothesis():
    L, d, h, alpha = _design()
    rng = np.random.default_rng(1)
    measured = alpha + 0.15 + rng.normal(0.0, SIGMA, alpha.size)
    diag = diagnose(_tests(measured, L, d, h), sigma=SIGMA, pairs=False)
    out = diag.as_dict()
    named = out["named"]
    assert "reading_offset" in named, named
    assert named != ["cure_depth"]  # never credited alone
    off = next(e for e in out["effects"] if e["name"] == "reading_offset")
    assert off["effect_kinds"] == ["measurement"] and off["plausible"]
    assert off["params"]["offset"] == pytest.approx(0.15, abs=0.05)
    assert out["catalogue"]["reading_offset"]["kind"] == "measurement"
    if diag.best.name == "reading_offset":
        assert "measurement issue, not physics" in diag.verdict.text


def test_gross_outliers_flagged_by_row_with_verdict_without_them():
    L, d, h, alpha = _design()
    rng = np.random.default_rng(2)
    measured = alpha + rng.normal(0.0, SIGMA, alpha.size)
    measured[[3, 11]] += [0.6, -0.5]
    diag = diagnose(_tests(measured, L, d, h), sigma=SIGMA, pairs=False)
    art = diag.as_dict()["artefacts"]
    assert art["outliers"]["rows"] == [5, 13]
    without = art["without_flagged"]
    assert without["rows"] == [5, 13] and without["verdict"] == "no_gap"
    assert "With rows 5, 13 left out" in diag.verdict.text


def test_noise_growing_with_the_angle_is_detected_and_weighted():
    L, d, h, alpha = _design()
    L, d, h, alpha = (np.tile(a, 2) for a in (L, d, h, alpha))  # 40 tests
    rng = np.random.default_rng(3)
    measured = alpha * (1.0 + 0.08 * rng.standard_normal(alpha.size))
    diag = diagnose(_tests(measured, L, d, h), sigma=SIGMA, pairs=False)
    grow = diag.as_dict()["artefacts"]["growing_noise"]
    assert grow["detected"] and grow["weighted"] and grow["rho"] > 0
    assert "1/sigma_i^2" in diag.verdict.text and "times larger at the largest fold" in diag.verdict.text


def test_variance_function_of_the_growing_noise():
    """The weights of a growing noise come from the residuals: noise proportional to the angle
    gives weights that follow it; a constant noise (a growth detected by chance) gives weights
    close to uniform, so that small folds do not earn weights they do not have."""
    from gdfe.diagnosis.artefacts import relative_noise

    rng = np.random.default_rng(11)
    p = np.linspace(0.2, 3.0, 400)
    proportional = relative_noise(p, 0.05 * p * rng.standard_normal(p.size))
    constant = relative_noise(p, 0.05 * rng.standard_normal(p.size))
    for rel in (proportional, constant):
        assert np.isclose(np.mean(rel**2), 1.0)
    ratio = proportional[-1] / proportional[0]
    assert 3.0 < ratio < 15.0, ratio  # below p's own ratio, 3.0 / 0.2: the constant part is floored
    assert constant[-1] / constant[0] < 1.6, constant[-1] / constant[0]


def test_failed_specimen_flagged():
    L, d, h, alpha = _design()
    rng = np.random.default_rng(4)
    measured = alpha + rng.normal(0.0, SIGMA, alpha.size)
    measured[7] = 0.01
    diag = diagnose(_tests(measured, L, d, h), sigma=SIGMA, pairs=False)
    art = diag.as_dict()["artefacts"]
    assert art["failed_specimens"]["rows"] == [9]
    assert 9 in art["without_flagged"]["rows"]
    assert "failed specimens" in diag.text()


def test_every_effect_has_a_kind_in_the_json():
    L, d, h, alpha = _design()
    rng = np.random.default_rng(5)
    diag = diagnose(_tests(alpha + rng.normal(0.0, SIGMA, alpha.size), L, d, h), sigma=SIGMA, pairs=False)
    out = diag.as_dict()
    assert {v["kind"] for v in out["catalogue"].values()} <= {"physics", "measurement", "factor"}
    for e in out["effects"]:
        assert len(e["effect_kinds"]) == len(e["effects"]) and isinstance(e["plausible"], bool)
    assert all(EFFECTS[e].kind for e in EFFECTS)


def test_attribution_credits_only_a_model_the_data_prove():
    """The attribution's rules, one verdict at a time."""
    from gdfe.diagnosis.attribution import OUTSIDE, attribute

    kinds = {"cure_depth": [("cure_depth", "physics")],
             "cure_depth+hinge_length": [("cure_depth", "physics"), ("hinge_length", "physics")],
             "cure_depth+reading_offset": [("cure_depth", "physics"), ("reading_offset", "measurement")],
             "saturation": [("saturation", "physics")], "reading_offset": [("reading_offset", "measurement")]}
    alone = attribute("explained", "cure_depth", ["cure_depth"], kinds)
    assert alone.credited == "cure_depth" and alone.kind == "physics" and not alone.not_ruled_out
    shared = attribute("explained", "cure_depth", ["cure_depth", "cure_depth+hinge_length"], kinds)
    assert shared.credited is None and shared.effects == ["cure_depth"] and "cure_depth+hinge_length" in shared.not_ruled_out
    apart = attribute("explained", "saturation", ["saturation", "reading_offset"], kinds)
    assert apart.credited is None and apart.effects == [] and "share no effect" in apart.text
    offset = attribute("explained", "reading_offset", ["reading_offset"], kinds)
    assert offset.kind == "measurement" and "not physics" in offset.text
    for verdict in ("partly_explained", "not_explained", "structure_remains"):
        a = attribute(verdict, "saturation", ["saturation"], kinds, why_open="structure remains after it")
        assert a.credited is None and OUTSIDE in a.not_ruled_out and "structure remains" in a.text
    none = attribute("no_gap", "baseline", ["baseline"], {})
    assert none.credited is None and none.not_ruled_out == []


def test_table1_credits_no_cause():
    """Table 1 fits only with implausible parameters: nothing is credited, and an effect outside
    the catalogue is among what the data leave open, in the JSON and in the verdict's text."""
    diag = diagnose(paper.TABLE1)
    att = diag.as_dict()["attribution"]
    assert att["credited"] is None and "outside_catalogue" in att["not_ruled_out"]
    assert "No cause is credited" in diag.verdict.text and "an effect outside the catalogue" in diag.verdict.text


def test_clean_catalogue_effect_is_credited_alone():
    """A cure depth built into Eq. 1 (the coat acting thicker by 0.05 mm) at two film
    thicknesses, with small noise: the diagnosis credits cure_depth and nothing else."""
    L, d, h, _ = _design()
    L, d, h = np.tile(L, 2), np.tile(d, 2), np.concatenate([h, h / 2])
    alpha = paper.K * np.sqrt(h / (d + 0.05) ** 3) * L / 4.0
    rng = np.random.default_rng(5)
    measured = alpha + rng.normal(0.0, 0.01, alpha.size)
    diag = diagnose(_tests(measured, L, d, h), sigma=0.01, pairs=False)
    att = diag.as_dict()["attribution"]
    assert diag.verdict.verdict == "explained", diag.verdict.text
    assert att["credited"] == "cure_depth" or att["effects"] == ["cure_depth"], att
    assert "Credited: cure_depth" in diag.verdict.text
