"""Predictions with intervals: the model file's predictive content, stacking, ``gdfe predict``."""

import json

import numpy as np
import pytest

import gdfe
from gdfe.calibration import FoldingTests
from gdfe.cli import main
from gdfe.diagnosis.angles import diagnose
from gdfe.model import DeformationModel, Member, Uncertainty, load_model
from gdfe.predict import HingeSpecimens, load_specimens, mixture_interval, predict
from gdfe.predictive import fit_uncertainty, from_diagnosis
from gdfe.stacking import log_score, pseudo_bma_weights, stacking_weights


@pytest.fixture(scope="module")
def table1_diag():
    return diagnose(gdfe.TABLE1)


# -- stacking ---------------------------------------------------------------------------------------
def test_stacking_of_two_equal_models_and_of_a_useless_one():
    rng = np.random.default_rng(0)
    good = -0.5 * rng.normal(size=200) ** 2
    bad = good - 5.0  # every test 150 times less likely
    w = stacking_weights(np.column_stack([good, bad]))
    assert w[0] > 0.999 and w.sum() == pytest.approx(1.0)
    w = stacking_weights(np.column_stack([good, good]))
    assert np.allclose(w, 0.5)


def test_stacking_maximises_the_held_out_log_score_and_mixes_complementary_models():
    # model A predicts the first half well, B the second: the mixture beats either alone
    a = np.r_[np.zeros(50), np.full(50, -4.0)]
    b = np.r_[np.full(50, -4.0), np.zeros(50)]
    lp = np.column_stack([a, b])
    w = stacking_weights(lp)
    assert w == pytest.approx([0.5, 0.5], abs=1e-6)
    best = log_score(lp, w)
    for v in np.linspace(0.01, 0.99, 25):  # no other weight does better
        assert log_score(lp, [v, 1 - v]) <= best + 1e-9
    # pseudo-BMA weighs each by its own score: a tie here too, but a small lead takes nearly all
    assert pseudo_bma_weights(lp + np.r_[[[3.0, 0.0]]]) [0] > 0.95


def test_stacking_rejects_nan():
    with pytest.raises(gdfe.GdfeError, match="log_dens: expected finite"):
        stacking_weights(np.array([[np.nan, 0.0]]))


# -- intervals ----------------------------------------------------------------------------------------
def test_the_mixture_interval_of_one_member_is_students_t():
    from scipy import stats

    lo, hi = mixture_interval([1.0], np.array([[1.0], [2.0]]), np.array([[0.1], [0.2]]), [7], 0.9)
    t = stats.t.ppf(0.95, 7)
    assert lo == pytest.approx([1 - 0.1 * t, 2 - 0.2 * t], rel=1e-9)
    assert hi == pytest.approx([1 + 0.1 * t, 2 + 0.2 * t], rel=1e-9)


def test_the_interval_of_the_straight_line_fit_is_the_textbook_prediction_interval():
    # eq1 is linear in K: alpha = K x; the prediction interval at x0 is K x0 +- t s sqrt(1 + x0^2 / sum x^2)
    from scipy import stats

    tests = gdfe.load_folding_tests(gdfe.TABLE1)
    fit = gdfe.fit_reading(tests, "eq1", n_boot=0)
    model = DeformationModel.from_calibration(fit, tests=tests)
    x = np.sqrt(tests.h / tests.d**3) * tests.L
    K = float(x @ tests.alpha / (x @ x))
    s = np.sqrt(np.sum((tests.alpha - K * x) ** 2) / 17)
    x0 = np.sqrt(0.29 / 0.2**3) * 2.0
    half = stats.t.ppf(0.95, 17) * s * np.sqrt(1 + x0**2 / (x @ x))
    p = predict(model, HingeSpecimens(np.array([2.0]), np.array([0.2]), np.array([0.29])), 0.9)
    assert p.alpha[0] == pytest.approx(K * x0, rel=1e-9)
    assert p.interval[0] == pytest.approx([K * x0 - half, K * x0 + half], rel=1e-6)
    assert p.sd_model[0] == 0.0 and p.sd_noise[0] == pytest.approx(s, rel=1e-9)


# -- the model file ------------------------------------------------------------------------------------
def test_a_diagnosis_model_file_keeps_covariance_noise_and_the_weighted_named_set(table1_diag, tmp_path):
    m = from_diagnosis(table1_diag, data=gdfe.TABLE1)
    assert len(m.ensemble) == len(table1_diag.named) >= 2 and m.weighting == "stacking"
    assert sum(x.weight for x in m.ensemble) == pytest.approx(1.0)
    u = m.uncertainty
    # the covariance's diagonal is the diagnosis's own standard errors
    se = table1_diag.best.se_dict()
    for i, k in enumerate(u.names):
        assert np.sqrt(u.matrix()[i, i]) == pytest.approx(se[k], rel=1e-6), k
    assert u.reading_offset_rad == pytest.approx(table1_diag.best.param_dict()["offset"])
    assert u.noise_rad >= np.sqrt(np.sum(table1_diag.best.residuals**2) / u.dof) - 1e-12
    path = m.save(tmp_path / "m.toml")
    back = load_model(path)
    assert back.uncertainty == u and back.weighting == "stacking"
    assert [(x.model.name, x.weight) for x in back.ensemble] == [(x.model.name, x.weight) for x in m.ensemble]
    assert back.ensemble[1].model.uncertainty == m.ensemble[1].model.uncertainty


def test_the_leverage_of_the_tests_sums_to_the_number_of_parameters(table1_diag):
    f = table1_diag.best
    u, par = fit_uncertainty(f, table1_diag)
    s2 = np.sum(f.residuals**2) / u.dof
    assert np.sum(par / s2) == pytest.approx(f.model.n_params, rel=1e-6)


def test_old_model_files_still_load_and_predict_with_a_noise(tmp_path):
    old = tmp_path / "old.toml"
    old.write_text('format = 1\nname = "eq3"\nprinciple = "eq1"\nsource = "gdfe calibrate"\n'
                   '[parameters.K]\nvalue = 0.0646\nse = 0.005\n'
                   '[data]\nn_tests = 18\nheld_out_rmse_rad = 0.47\n')
    m = load_model(old)
    assert m.uncertainty is None and m.ensemble == ()
    p = predict(m, HingeSpecimens(np.array([3.0]), np.array([0.2]), np.array([0.29])))
    assert p.members[0]["noise_rad"] == 0.47 and "held-out RMSE" in p.members[0]["noise_source"]
    assert p.sd_parameters[0] > 0
    with pytest.raises(gdfe.GdfeError, match="expected a model file with predictive content"):
        predict(gdfe.paper_model(), HingeSpecimens(np.array([3.0]), np.array([0.2]), np.array([0.29])))
    p = predict(gdfe.paper_model(), HingeSpecimens(np.array([3.0]), np.array([0.2]), np.array([0.29])), noise=0.1)
    assert p.sd_parameters[0] == 0.0 and p.sd_noise[0] == 0.1


@pytest.mark.parametrize("body, match", [
    ("[uncertainty]\nnames = [\"K\"]\ncovariance = [[1e-4]]\nnoise_rad = 0.1\n", "missing key 'dof'"),
    ("[uncertainty]\nnames = [\"K\"]\ncovariance = [[1e-4, 0]]\nnoise_rad = 0.1\ndof = 3\n", "1 x 1 matrix"),
    ("[uncertainty]\nnames = [\"K\"]\ncovariance = [[-1e-4]]\nnoise_rad = 0.1\ndof = 3\n", "positive semi-definite"),
    ("[uncertainty]\nnames = [\"Q\"]\ncovariance = [[1e-4]]\nnoise_rad = 0.1\ndof = 3\n", "got Q"),
    ("[ensemble]\nweighting = \"stacking\"\n[[ensemble.members]]\nweight = 0.5\nprinciple = \"eq1\"\n"
     "[ensemble.members.parameters]\nK = 0.1\n", "weights that sum to 1"),
    ("[ensemble]\nweighting = \"votes\"\n[[ensemble.members]]\nweight = 1.0\nprinciple = \"eq1\"\n"
     "[ensemble.members.parameters]\nK = 0.1\n", "weighting: expected one of"),
    ("[ensemble]\nweighting = \"stacking\"\n[[ensemble.members]]\nweight = 1.0\nprinciple = \"eq1\"\n"
     "[ensemble.members.parameters]\nK = -0.1\n", r"members\[0\]: K: expected a positive"),
])
def test_bad_predictive_content_is_a_clear_error(tmp_path, body, match):
    path = tmp_path / "bad.toml"
    path.write_text('principle = "eq1"\n[parameters]\nK = 0.1\n' + body)
    with pytest.raises(gdfe.GdfeError, match=match):
        load_model(path)


def test_uncertainty_and_members_check_their_values():
    with pytest.raises(gdfe.GdfeError, match="dof: expected a whole number"):
        Uncertainty(names=("K",), covariance=[[1.0]], noise_rad=0.1, dof=0)
    with pytest.raises(gdfe.GdfeError, match="member weight"):
        Member(1.5, gdfe.paper_model())


# -- predictions -----------------------------------------------------------------------------------------
def test_parts_add_up_and_the_model_choice_part_is_the_members_spread(table1_diag):
    m = from_diagnosis(table1_diag)
    t = gdfe.load_folding_tests(gdfe.TABLE1)
    p = predict(m, HingeSpecimens(t.L, t.d, t.h, alpha=t.alpha), 0.9)
    w = np.array([x["weight"] for x in p.members])
    assert p.alpha == pytest.approx(p.member_alpha @ w)
    assert p.sd_model == pytest.approx(np.sqrt(((p.member_alpha - p.alpha[:, None]) ** 2) @ w))
    assert np.all(p.interval[:, 0] < p.alpha) and np.all(p.alpha < p.interval[:, 1])
    # a wider level gives a wider interval; the fitted tests mostly fall inside
    wide = predict(m, HingeSpecimens(t.L, t.d, t.h, alpha=t.alpha), 0.99)
    assert np.all(wide.width > p.width)
    assert p.as_dict()["coverage"] >= 0.8


def test_the_closed_form_agrees_with_a_gdfe_solve_within_the_interval(table1_diag):
    m = from_diagnosis(table1_diag)
    spec = HingeSpecimens(np.array([3.0]), np.array([0.24]), np.array([0.29]))
    closed = predict(m, spec)
    solved = predict(m, spec, simulate="coarse")
    assert solved.converged and solved.method == "GDFE (coarse)"
    assert abs(solved.alpha[0] - closed.alpha[0]) < 0.1 * closed.width[0]


def test_specimen_files_are_checked(tmp_path):
    bad = tmp_path / "s.csv"
    bad.write_text("L_mm,d_mm\n3,0.2\n2,abc\n")
    with pytest.raises(gdfe.GdfeError, match="row 3, column d_mm: expected a number, got 'abc'"):
        load_specimens(bad)
    bad.write_text("L_mm,h_mm\n3,0.2\n")
    with pytest.raises(gdfe.GdfeError, match="missing column"):
        load_specimens(bad)
    bad.write_text("L_mm,d_mm\n3,-0.2\n")
    with pytest.raises(gdfe.GdfeError, match="positive length"):
        load_specimens(bad)
    with pytest.raises(gdfe.GdfeError, match="level"):
        predict(gdfe.paper_model(), HingeSpecimens(np.array([3.0]), np.array([0.2]), np.array([0.29])), 1.5, noise=0.1)


# -- the command line --------------------------------------------------------------------------------------
def test_diagnose_model_out_then_predict_through_the_command_line(tmp_path, capsys):
    t = gdfe.load_folding_tests(gdfe.TABLE1)
    train = tmp_path / "train.csv"
    held = tmp_path / "held.csv"
    keep = np.arange(len(t)) != 4
    train.write_text("L_mm,d_mm,h_mm,alpha_rad\n" + "".join(
        f"{a},{b},{c},{e}\n" for a, b, c, e in zip(t.L[keep], t.d[keep], t.h[keep], t.alpha[keep])))
    held.write_text(f"L_mm,d_mm,h_mm,alpha_rad\n{t.L[4]},{t.d[4]},{t.h[4]},{t.alpha[4]}\n")
    model = tmp_path / "m.toml"
    assert main(["diagnose", str(train), "--check", "none", "--model-out", str(model), "-q"]) == 0
    assert "gdfe predict reads it" in capsys.readouterr().out
    out = tmp_path / "p.json"
    assert main(["predict", str(model), str(held), "--level", "0.9", "--json", str(out), "-q"]) == 0
    row = json.loads(out.read_text())["rows"][0]
    lo, hi = row["alpha_interval_rad"]
    assert lo < row["alpha_rad"] < hi and row["level"] == 0.9
    assert set(row["parts"]) == {"parameters", "model_choice", "noise"}
    assert row["inside"] == (lo <= t.alpha[4] <= hi)
    # the predict command speaks the vocabulary
    from gdfe.cli._vocabulary import known_keys

    assert not set(json.loads(out.read_text())) - known_keys("predict")


def test_calibrate_model_out_carries_its_covariance(tmp_path, capsys):
    model = tmp_path / "c.toml"
    assert main(["calibrate", str(gdfe.TABLE1), "--boot", "0", "--model", "power", "--model-out", str(model)]) == 0
    m = load_model(model)
    assert m.uncertainty is not None and m.uncertainty.names == ("K", "p") and m.uncertainty.dof == 16
    capsys.readouterr()
    assert main(["predict", str(model), str(gdfe.TABLE1), "--json", "-q"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["members"][0]["weight"] == 1.0 and 0.0 < out["coverage"] <= 1.0


def test_a_model_whose_noise_cannot_be_estimated_is_saved_without_predictive_content(table1_diag, monkeypatch):
    import gdfe.predictive as pv

    real = pv.fit_uncertainty

    def failing(fit, diag):
        if fit is diag.best:
            raise gdfe.GdfeError(f"{fit.name}: 3 parameters on 3 tests leave no degrees of freedom for the noise")
        return real(fit, diag)

    monkeypatch.setattr(pv, "fit_uncertainty", failing)
    m = pv.from_diagnosis(table1_diag)
    assert m.uncertainty is None and m.ensemble == ()
    assert any("no predictive content" in w and "degrees of freedom" in w for w in m.warnings)
    # a member other than the chosen one is left out of the set instead
    other = table1_diag.named[1]

    def failing_other(fit, diag):
        if fit is other:
            raise gdfe.GdfeError("no degrees of freedom")
        return real(fit, diag)

    monkeypatch.setattr(pv, "fit_uncertainty", failing_other)
    m = pv.from_diagnosis(table1_diag)
    assert other.name not in [x.model.name for x in m.ensemble] and m.uncertainty is not None


def test_parameters_the_tests_do_not_pin_down_are_said_not_hidden_in_a_wide_interval(tmp_path):
    """A member whose linearised parameter spread exceeds half a turn (pi rad: a fold lies in
    [0, 2 pi]) makes no meaningful interval: the prediction says so, by member and row. With
    alpha = K sqrt(h / d^3) L, d alpha / d K = alpha / K = sqrt(0.29 / 0.008) 3 = 18.06, so a
    standard error of 0.5 on K spreads the angle by 9.0 rad, one of 0.005 by 0.09 rad."""
    spec = HingeSpecimens(np.array([3.0]), np.array([0.2]), np.array([0.29]))
    for se, warned in ((0.5, True), (0.005, False)):
        f = tmp_path / f"se{se}.toml"
        f.write_text('format = 1\nname = "eq3"\nprinciple = "eq1"\nsource = "gdfe calibrate"\n'
                     f'[parameters.K]\nvalue = 0.0646\nse = {se}\n[data]\nn_tests = 18\nheld_out_rmse_rad = 0.1\n')
        p = predict(load_model(f), spec)
        assert p.sd_parameters[0] == pytest.approx(np.sqrt(0.29 / 0.2**3) * 3.0 * se, rel=1e-3)
        assert bool(p.warnings) == warned and (not warned or "row 2" in p.warnings[0])
        assert p.as_dict()["warnings"] == list(p.warnings)
