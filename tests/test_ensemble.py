"""Ensembles through the simulator (gdfe/ensemble.py) and ``--uncertainty N`` on hinge, simulate and design."""

import dataclasses
import json

import meshio
import numpy as np
import pytest

import gdfe
from gdfe._validation import GdfeError
from gdfe.cli import main
from gdfe.ensemble import PILOT, align_rigidly, fold_ensemble, has_predictive_content, secant_starts, wilson_interval
from gdfe.model import DeformationModel
from gdfe.predict import draw_models

L, D = 1.6, 0.33


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    """Eq. 1 calibrated on Table 1: one model with its parameter covariance."""
    path = tmp_path_factory.mktemp("model") / "eq1.toml"
    assert main(["-q", "calibrate", str(gdfe.TABLE1), "--model", "eq1", "--model-out", str(path)]) == 0
    return path


@pytest.fixture(autouse=True)
def one_process(monkeypatch):
    monkeypatch.setenv("GDFE_JOBS", "1")  # the draws in this process: fast, and the same numbers


def _hinge(model):
    return gdfe.hinge(L, d=D, model=model)


def _angle(res):
    return [gdfe.fold_angle(res)], {"x_extent_mm": float(np.ptp(res.points[:, 0]))}


# -- the pieces -------------------------------------------------------------------------------------------
def test_rigid_alignment_undoes_a_rotation_and_a_shift():
    rng = np.random.default_rng(1)
    p = rng.normal(size=(50, 3))
    c, s = np.cos(0.7), np.sin(0.7)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, c, s], [0, -s, c]])
    moved = p @ rot.T + [3.0, -1.0, 2.0]
    np.testing.assert_allclose(align_rigidly(moved, p), p, atol=1e-10)
    mirrored = p * [1, 1, -1]  # a reflection is not a rigid motion: it is not undone
    assert np.abs(align_rigidly(mirrored, p) - p).max() > 0.1


def test_wilson_interval():
    lo, hi = wilson_interval(0, 10, level=0.95)
    assert lo == 0.0 and hi == pytest.approx(0.2775, abs=1e-4)  # the textbook value
    lo, hi = wilson_interval(16, 32, level=0.9)
    z = 1.6449
    assert lo < 0.5 < hi and hi - lo == pytest.approx(2 * z * np.sqrt(0.25 / 32 + z**2 / (4 * 32**2)) / (1 + z**2 / 32),
                                                       rel=1e-3)
    assert np.diff(wilson_interval(160, 320, 0.9)) < np.diff(wilson_interval(16, 32, 0.9))


def test_the_secant_start_is_exact_for_a_linear_fold_and_refuses_to_extrapolate():
    rng = np.random.default_rng(2)
    m, v = 40, 30
    M = rng.normal(size=(v, 3, m))  # a fold linear in the contractions
    c0, x0 = rng.uniform(0.5, 0.9, m), rng.normal(size=(v, 3))

    def fold(c):
        return x0 + M @ (c - c0)

    basis = rng.normal(scale=0.01, size=(2, m))  # draws of a two-parameter model
    pilot_c = c0 + rng.normal(size=(3, 2)) @ basis
    targets = c0 + rng.normal(size=(5, 2)) @ basis
    starts = secant_starts(c0, x0, pilot_c, [fold(c) for c in pilot_c], targets)
    np.testing.assert_allclose(starts, [fold(c) for c in targets], atol=1e-10)
    far = c0 + 50 * (pilot_c[0] - c0)  # fifty times a pilot's step: the nominal fold, not an extrapolation
    np.testing.assert_array_equal(secant_starts(c0, x0, pilot_c, [fold(c) for c in pilot_c], [far])[0], x0)
    # no pilot (none converged): the nominal fold
    np.testing.assert_array_equal(secant_starts(c0, x0, np.zeros((0, m)), np.zeros((0, v, 3)), targets[:1])[0], x0)


def test_predicted_starts_fold_as_the_nominal_start_does_in_fewer_iterations(model_file):
    model = gdfe.load_model(model_file)
    design = _hinge(model)
    nominal = gdfe.simulate(design)
    n = PILOT + 4
    by = {s: fold_ensemble(design, model, n, nominal=nominal, measure=_angle, seed=5, start=s)
          for s in ("nominal", "predicted")}
    assert all(e.n_converged == n for e in by.values())
    np.testing.assert_allclose(by["predicted"].angles, by["nominal"].angles, atol=2e-3)  # the same stopping test
    later = slice(PILOT, n)  # the draws after the pilots start from the secant prediction
    assert by["predicted"].iterations[later].sum() < by["nominal"].iterations[later].sum()
    np.testing.assert_array_equal(by["predicted"].iterations[:PILOT], by["nominal"].iterations[:PILOT])
    assert "secant" in by["predicted"].start


# -- the ensemble -----------------------------------------------------------------------------------------
def test_each_draw_folds_as_its_own_model_predicts(model_file):
    model = gdfe.load_model(model_file)
    assert has_predictive_content(model) and not has_predictive_content(gdfe.paper_model())
    design = _hinge(model)
    nominal = gdfe.simulate(design)
    ens = fold_ensemble(design, model, 6, nominal=nominal, measure=_angle, labels=["hinge"], seed=3)
    assert ens.n_converged == 6 and ens.angles.shape == (6, 1)
    # the draws are those of draw_models with the same seed, each folding as its closed form says
    expected = [m.hinge_angle(L, D) for m in draw_models(model, 6, seed=3)]
    np.testing.assert_allclose(ens.angles[:, 0], expected, atol=0.01)
    assert np.ptp(ens.angles[:, 0]) > 0.02  # the covariance moves the fold
    lo, hi = ens.interval(ens.angles[:, 0])
    assert lo < hi and lo <= ens.nominal_angles[0] + 0.01 and hi >= ens.nominal_angles[0] - 0.01
    # the warm start: a draw takes fewer iterations than the nominal fold from its own start
    assert np.median(ens.iterations) <= nominal.iterations
    assert ens.spread_mm.shape == (design.mesh.n_points,) and ens.spread_mm.max() > 1e-3
    p, (plo, phi) = ens.probability_below("x_extent_mm", np.median(ens.measures["x_extent_mm"]))
    assert p == 0.5 and plo < 0.5 < phi
    d = ens.as_dict()
    assert d["n"] == 6 and d["fold_angles"][0]["interval_rad"] == [lo, hi]
    json.dumps(d)


def test_a_model_without_spread_gives_the_nominal_fold_and_no_spread(model_file):
    model = gdfe.load_model(model_file)
    u = model.uncertainty
    still = dataclasses.replace(model, uncertainty=dataclasses.replace(u, covariance=np.zeros_like(u.matrix())))
    design = _hinge(still)
    nominal = gdfe.simulate(design)
    ens = fold_ensemble(design, still, 3, nominal=nominal, measure=_angle)
    np.testing.assert_allclose(ens.angles[:, 0], ens.nominal_angles[0], atol=1e-6)
    assert ens.spread_mm.max() < 1e-5


def test_an_ensemble_needs_predictive_content():
    design = _hinge(gdfe.paper_model())
    with pytest.raises(GdfeError, match="predictive content"):
        fold_ensemble(design, gdfe.paper_model(), 4, nominal=gdfe.simulate(design), measure=_angle)


# -- the command line -------------------------------------------------------------------------------------
def test_hinge_uncertainty_writes_intervals_spread_and_picture(model_file, tmp_path, capsys):
    out = tmp_path / "h"
    assert main(["hinge", "--length", str(L), "--d", str(D), "--model", str(model_file), "--uncertainty", "4",
                 "--level", "0.8", "--out", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    u = doc["uncertainty"]
    assert u["n"] == 4 and u["level"] == 0.8 and u["n_converged"] == 4
    (angle,) = u["fold_angles"]
    assert angle["fold_angle_rad"] == pytest.approx(doc["fold_angle_rad"])
    assert angle["interval_rad"][0] < angle["interval_rad"][1]
    vtu = meshio.read(doc["files"]["spread_vtu"])
    assert vtu.point_data["spread_mm"].max() == pytest.approx(u["spread_mm"]["max"], rel=1e-6)
    assert (out / "hinge_uncertainty.png").stat().st_size > 1000


def test_simulate_uncertainty_of_a_hinge_file(model_file, tmp_path, capsys):
    path = tmp_path / "hinge.toml"
    path.write_text(f"[film]\nd = {D}\n[hinge]\nlength = {L}\n")
    assert main(["simulate", str(path), "--model", str(model_file), "--uncertainty", "3", "--out",
                 str(tmp_path / "s"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [a["label"] for a in doc["uncertainty"]["fold_angles"]] == ["hinge"]
    assert (tmp_path / "s" / "hinge_uncertainty.png").exists()


@pytest.mark.parametrize("argv, match", [
    (["hinge", "--length", "1.6", "--d", "0.33", "--uncertainty", "4"], "--uncertainty: expected --model"),
    (["hinge", "--length", "1.6", "--d", "0.33", "--uncertainty", "1", "--model", "MODEL"], "--uncertainty"),
    (["hinge", "--length", "1.6", "--d", "0.33", "--uncertainty", "4", "--level", "1.5", "--model", "MODEL"],
     "--level"),
    (["hinge", "--length", "1.6", "--d", "0.33", "--uncertainty", "4", "--model", "PLAIN"], "no predictive content"),
    (["design", "--text", "i", "--out", "OUT", "--uncertainty", "4"], "--uncertainty: an option of --target"),
    (["hinge", "--length", "1.6", "--d", "0.33", "--level", "0.8"], "--level: an option of --uncertainty"),
    (["design", "--target", "dome", "--size", "4", "--out", "OUT", "--uncertainty", "4"],
     "--uncertainty: expected --model"),
])
def test_uncertainty_errors_name_the_option(argv, match, model_file, tmp_path, capsys):
    plain = tmp_path / "plain.toml"
    m = gdfe.load_model(model_file)
    dataclasses.replace(m, uncertainty=None).save(plain)
    subst = {"MODEL": str(model_file), "PLAIN": str(plain), "OUT": str(tmp_path / "o")}
    assert main([subst.get(a, a) for a in argv]) != 0
    err = capsys.readouterr().err
    assert match in err, err


def test_design_target_uncertainty_gives_the_probability_within_tolerance(model_file, tmp_path, capsys):
    out = tmp_path / "d"
    status = main(["design", "--target", "dome", "--size", "3", "--pixel", "0.25", "--iterations", "0",
                   "--tolerance", "5", "--model", str(model_file), "--uncertainty", "3", "--out", str(out), "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert status in (0, 4)
    u = doc["uncertainty"]
    lo, hi = u["measures"]["rms_mm"]["interval"]
    assert 0 < lo <= hi < 5  # every draw within 5 mm RMS of a 3 mm dome
    w = u["within_tolerance"]
    assert w["threshold"] == 5 and w["probability"] == 1.0 and w["interval"][1] == 1.0 and w["draws"] == 3
    assert u["fold_angles"] == []
    vtu = meshio.read(doc["files"]["spread_vtu"])
    assert "spread_mm" in vtu.point_data and (out / "dome_uncertainty.png").exists()


def test_simulate_uncertainty_of_a_strip_measures_its_turn_and_end_gap(model_file, tmp_path, capsys):
    from gdfe.fabrication import face_masks, write_design_toml, write_masks

    row = "RRRR" + "TTRRRR" * 4
    des = gdfe.from_rows([row, row], R=0.9, pixel=0.25, nz=1)
    files = write_masks(face_masks(des), tmp_path, "strip")
    path = write_design_toml(tmp_path / "strip.toml", files, 0.25, {"h": 0.29, "d": 0.33, "nz": 1})
    assert main(["simulate", str(path), "--model", str(model_file), "--uncertainty", "3", "--out",
                 str(tmp_path / "s"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    u = doc["uncertainty"]
    assert len(u["fold_angles"]) == 4 and all(a["label"].startswith("panels") for a in u["fold_angles"])
    turn = u["measures"]["turn_rad"]
    # the strip's turn is the sum of its four folds
    assert turn["nominal"] == pytest.approx(sum(a["fold_angle_rad"] for a in u["fold_angles"]), rel=0.05)
    assert turn["interval"][0] < turn["interval"][1] and u["measures"]["end_gap_mm"]["nominal"] > 0


def test_secant_starts_take_members_with_and_without_a_layout_mechanism(model_file):
    """A named set mixing a member whose mechanism sets per-face contractions (saturation) with one
    that does not: every draw is described by the same vector, and the ensemble folds."""
    from gdfe.ensemble import _contractions

    base = gdfe.load_model(model_file)
    design = _hinge(base)
    sat = DeformationModel(principle="eq1", params={"K": 0.3706, "alpha_max": 1.5}, mechanisms=("saturation",))
    assert sat.geometric and not base.geometric
    assert _contractions(sat.apply(design)).shape == _contractions(base.apply(design)).shape
