"""The Kennedy-O'Hagan anchor: a model's closed form plus a Gaussian-process discrepancy."""

import json
import sys

import numpy as np
import pytest

import gdfe
from gdfe.calibration import FoldingTests
from gdfe.cli import main
from gdfe.discrepancy import fit_discrepancy
from gdfe.model import DeformationModel
from gdfe.predict import HingeSpecimens, predict

pytest.importorskip("sklearn")


def _world(n, rng, sigma=0.03):
    """Folding tests of Eq. 1 (K = 0.06) with a smooth discrepancy in d the law lacks, and noise."""
    L = rng.uniform(1.0, 6.0, n)
    d = rng.uniform(0.11, 0.5, n)
    h = np.full(n, 0.29)
    eq1 = 0.06 * np.sqrt(h / d**3) * L
    truth = eq1 + 0.4 * np.sin(6 * d)  # a bump the law cannot make
    return L, d, h, truth, truth + sigma * rng.standard_normal(n)


def test_the_discrepancy_learns_what_the_law_lacks_and_its_intervals_cover():
    rng = np.random.default_rng(0)
    L, d, h, _, y = _world(40, rng)
    tests = FoldingTests(L, d, h, y)
    model = DeformationModel.from_calibration(gdfe.fit_reading(tests, "eq1", n_boot=0), tests=tests)
    koh = fit_discrepancy(model, tests)
    Lt, dt, ht, truth, yt = _world(200, np.random.default_rng(1))
    spec = HingeSpecimens(Lt, dt, ht, alpha=yt)
    p = koh.predict(spec, 0.9)
    base = predict(model, spec, 0.9)
    rmse, rmse_base = (float(np.sqrt(np.mean((q.alpha - yt) ** 2))) for q in (p, base))
    assert rmse < 0.5 * rmse_base, (rmse, rmse_base)
    assert 0.8 <= p.as_dict()["coverage"] <= 1.0
    assert p.model_part == "discrepancy" and "discrepancy" in p.as_dict()["rows"][0]["parts"]
    assert koh.noise_rad == pytest.approx(0.03, rel=0.5)


def test_far_from_the_tests_the_interval_returns_to_the_prior():
    rng = np.random.default_rng(2)
    L, d, h, _, y = _world(30, rng)
    tests = FoldingTests(L, d, h, y)
    model = DeformationModel.from_calibration(gdfe.fit_reading(tests, "eq1", n_boot=0), tests=tests)
    koh = fit_discrepancy(model, tests)
    near = koh.predict(HingeSpecimens(np.array([3.0]), np.array([0.3]), np.array([0.29])))
    far = koh.predict(HingeSpecimens(np.array([3.0]), np.array([3.0]), np.array([0.29])))  # d ten times the tests'
    assert far.sd_model[0] > 3 * near.sd_model[0]


def test_an_exact_law_leaves_a_small_discrepancy():
    rng = np.random.default_rng(3)
    L = rng.uniform(1.0, 6.0, 30)
    d = rng.uniform(0.11, 0.5, 30)
    h = np.full(30, 0.29)
    y = 0.06 * np.sqrt(h / d**3) * L + 0.05 * rng.standard_normal(30)
    tests = FoldingTests(L, d, h, y)
    model = DeformationModel.from_calibration(gdfe.fit_reading(tests, "eq1", n_boot=0), tests=tests)
    p = fit_discrepancy(model, tests).predict(HingeSpecimens(L, d, h, alpha=y))
    assert np.median(p.sd_model) < 0.05 and np.median(p.sd_noise) == pytest.approx(0.05, rel=0.5)


def test_without_scikit_learn_the_message_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "sklearn.gaussian_process", None)
    tests = gdfe.load_folding_tests(gdfe.TABLE1)
    with pytest.raises(gdfe.GdfeError, match=r"pip install 'gdfe\[uncertainty\]'"):
        fit_discrepancy(gdfe.paper_model(), tests)


def test_bad_inputs_are_clear_errors():
    tests = gdfe.load_folding_tests(gdfe.TABLE1)
    with pytest.raises(gdfe.GdfeError, match="expected at least one design variable that varies"):
        fit_discrepancy(gdfe.paper_model(), tests, inputs=())
    with pytest.raises(gdfe.GdfeError, match="at least 4 tests"):
        fit_discrepancy(gdfe.paper_model(), FoldingTests(tests.L[:3], tests.d[:3], tests.h[:3], tests.alpha[:3]))


def test_predict_with_a_discrepancy_through_the_command_line(tmp_path, capsys):
    model = tmp_path / "c.toml"
    assert main(["calibrate", str(gdfe.TABLE1), "--boot", "0", "--model-out", str(model)]) == 0
    capsys.readouterr()
    assert main(["predict", str(model), str(gdfe.TABLE1), "--discrepancy", str(gdfe.TABLE1), "--json", "-q"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"].startswith("closed form + Gaussian-process discrepancy")
    assert set(out["rows"][0]["parts"]) == {"parameters", "discrepancy", "noise"}
    # on its own tests the discrepancy follows the data far closer than Eq. 1 alone (RMSE 0.46 rad)
    assert out["rmse_rad"] < 0.2
    assert main(["predict", str(model), str(gdfe.TABLE1), "--discrepancy", str(gdfe.TABLE1), "--simulate"]) == 1
    assert "--discrepancy: expected no --simulate" in capsys.readouterr().err
    assert main(["predict", str(model), str(gdfe.TABLE1), "--discrepancy", str(gdfe.TABLE1), "--noise", "-1"]) == 1
    assert "--noise" in capsys.readouterr().err
    # a known noise: the white kernel is fixed at it
    assert main(["predict", str(model), str(gdfe.TABLE1), "--discrepancy", str(gdfe.TABLE1), "--noise", "0.1",
                 "--json", "-q"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["rows"][0]["parts"]["noise"]["sd_rad"] == pytest.approx(0.1 * out["members"][0]["loo_scale"], rel=1e-6)


def test_the_leave_one_out_scale_is_that_of_refits_without_each_test():
    """The closed form equals the process refitted (same kernel) without each test in turn."""
    from sklearn.gaussian_process import GaussianProcessRegressor

    from gdfe.discrepancy import loo_scale

    rng = np.random.default_rng(3)
    L, d, h, _, alpha = _world(14, rng)
    base = DeformationModel.from_calibration(gdfe.fit_reading(FoldingTests(L=L, d=d, h=h, alpha=alpha), "eq1",
                                                              n_boot=0))
    D = fit_discrepancy(base, FoldingTests(L=L, d=d, h=h, alpha=alpha))
    X, y = D.gp.X_train_, D.gp.y_train_
    z = []
    for i in range(len(y)):
        keep = np.arange(len(y)) != i
        g = GaussianProcessRegressor(kernel=D.gp.kernel_, optimizer=None).fit(X[keep], y[keep])
        m, s = g.predict(X[[i]], return_std=True)
        z.append((y[i] - m[0]) / s[0])
    assert D.loo_scale == pytest.approx(max(1.0, float(np.sqrt(np.mean(np.square(z))))), rel=1e-6)
    assert D.loo_scale >= 1.0


def test_an_overconfident_fit_is_widened_by_its_leave_one_out_scale():
    """A process that interpolates its tests (noise on its lower bound) gets a scale above 1, and the
    process's part of the interval is multiplied by it."""
    import dataclasses

    rng = np.random.default_rng(0)
    L, d, h, _, alpha = _world(12, rng, sigma=0.15)
    tests = FoldingTests(L=L, d=d, h=h, alpha=alpha)
    D = fit_discrepancy(DeformationModel.from_calibration(gdfe.fit_reading(tests, "eq1", n_boot=0)), tests)
    spec = HingeSpecimens(L=np.array([2.0]), d=np.array([0.3]), h=np.array([0.29]))
    plain = dataclasses.replace(D, loo_scale=1.0).predict(spec)
    scaled = D.predict(spec)
    assert scaled.sd_model[0] == pytest.approx(D.loo_scale * plain.sd_model[0])
    assert scaled.sd_noise[0] == pytest.approx(D.loo_scale * plain.sd_noise[0])
    assert scaled.width[0] >= plain.width[0]
