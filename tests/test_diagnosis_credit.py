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
    assert "1/alpha^2" in diag.verdict.text


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
