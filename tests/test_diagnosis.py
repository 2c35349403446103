"""Fold-angle diagnosis: effect models, fits, held-out errors, selection, residual regimes, CLI."""

import json
import math

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.diagnosis import (EFFECTS, Model, catalogue, diagnose, evaluate, gdfe_check, model,
                            residual_analysis, select, simulate_fold)
from gdfe.diagnosis.fit import aicc, fit_params


@pytest.fixture(scope="module")
def t1():
    return gdfe.load_folding_tests(gdfe.TABLE1)


@pytest.fixture(scope="module")
def t1_diag():
    return diagnose(gdfe.TABLE1)


# -- closed forms -------------------------------------------------------------------------
def test_baseline_is_eq1(t1):
    K = 0.0608
    np.testing.assert_allclose(Model(()).predict([K], t1.L, t1.d, t1.h),
                               gdfe.Calibration(K=K).alpha(t1.L, t1.d, t1.h), rtol=1e-13)


@pytest.mark.parametrize("effect, neutral", [("cure_depth", 0.0), ("hinge_length", 0.0),
                                             ("film_thickening", 0.0), ("saturation", 1e9)])
def test_effect_at_neutral_strength_is_baseline(t1, effect, neutral):
    base = Model(()).predict([0.07], t1.L, t1.d, t1.h)
    np.testing.assert_allclose(model(effect).predict([0.07, neutral], t1.L, t1.d, t1.h), base, rtol=1e-9)


def test_catalogue_names_and_pairs():
    names = [m.name for m in catalogue()]
    for e in ("cure_depth", "hinge_length", "saturation", "passive_stiffness", "film_thickening", "reading_offset"):
        assert e in names and e in EFFECTS
    assert EFFECTS["reading_offset"].kind == "measurement" and EFFECTS["cure_depth"].kind == "physics"
    assert len(names) == 1 + 6 + 15  # five physical effects and a reading offset, each pair
    assert model("cure_depth+hinge_length").param_names == ("K", "delta", "lambda")
    assert model("passive_stiffness").param_names == ("E_ratio", "mismatch")


def test_model_rejects_unknown_and_repeated_effects():
    with pytest.raises(ValueError, match="expected one of"):
        Model(("warping",))
    with pytest.raises(ValueError, match="at most once"):
        Model(("cure_depth", "cure_depth"))


# -- the closed form is the converged GDFE hinge -----------------------------------------------
def test_baseline_closed_form_equals_gdfe(t1):
    """Eq. 2's (1 - R) L / h against GDFE solves of Table 1 (16 cells across each hinge)."""
    idx = [0, 4, 10, 17]  # thinnest coat, a long hinge, a mid one, the thickest coat
    c = gdfe_check("baseline", [0.0608], t1.L[idx], t1.d[idx], t1.h[idx], resolution="coarse")
    assert c["converged"] and c["n_skipped"] == 0
    assert c["max_abs_diff"] < 0.025, c


def test_saturation_mechanism_gives_tanh():
    """The exposure-limited activation in GDFE reproduces alpha_max tanh(alpha / alpha_max)."""
    L, R, h, amax = 3.0, 0.8, 0.29, 1.5
    free = simulate_fold(L, R, h)["alpha"]
    sat = simulate_fold(L, R, h, alpha_max=amax)
    assert sat["converged"]
    assert sat["alpha"] == pytest.approx(amax * math.tanh(free / amax), abs=0.01)
    with pytest.raises(ValueError, match="alpha_max"):
        simulate_fold(L, R, h, alpha_max=-1.0)


# -- fits -----------------------------------------------------------------------------------
@pytest.mark.parametrize("name, params", [
    ("cure_depth", [0.05, 0.1]), ("hinge_length", [0.06, 0.8]), ("saturation", [0.09, 2.2]),
    ("passive_stiffness", [3.0, 0.15]), ("film_thickening", [0.06, 2.0]),
    ("cure_depth+hinge_length", [0.05, 0.1, 0.8]),
])
def test_fit_recovers_noise_free_parameters(t1, name, params):
    m = model(name)
    alpha = m.predict(np.array(params), t1.L, t1.d, t1.h)
    x, rss, ok = fit_params(m, t1.L, t1.d, t1.h, alpha)
    assert math.sqrt(rss / alpha.size) < 1e-6
    np.testing.assert_allclose(x, params, rtol=1e-3)


def test_fit_stays_in_bounds(t1):
    # data that want a thinner-than-physical coat: delta stays above -0.95 min(d)
    m = model("cure_depth")
    alpha = 5.0 * Model(()).predict([0.06], t1.L, t1.d, t1.h)[::-1]
    x, _, _ = fit_params(m, t1.L, t1.d, t1.h, alpha)
    lo, hi = m.bounds(t1.L, t1.d, alpha)
    assert np.all(x >= lo) and np.all(x <= hi)


def test_loo_of_line_through_origin_matches_hat_formula(t1):
    """For alpha = K x the leave-one-out residual is r_i / (1 - x_i^2 / sum x^2)."""
    f = evaluate(Model(()), t1.L, t1.d, t1.h, t1.alpha)
    x = np.sqrt(t1.h / t1.d**3) * t1.L
    K = x @ t1.alpha / (x @ x)
    r = t1.alpha - K * x
    loo = r / (1 - x**2 / (x @ x))
    np.testing.assert_allclose(t1.alpha - f.loo_predicted, loo, rtol=1e-6)
    assert f.params[0] == pytest.approx(gdfe.Calibration.fit(t1, n_boot=0).K, rel=1e-9)


def test_logo_holds_out_whole_groups(t1):
    groups = np.repeat(np.arange(6), 3)
    f = evaluate(model("cure_depth"), t1.L, t1.d, t1.h, t1.alpha, groups=groups)
    assert f.logo_predicted is not None and np.all(np.isfinite(f.logo_predicted))
    g = groups == 2  # refit by hand without group 2
    x, _, _ = fit_params(model("cure_depth"), t1.L[~g], t1.d[~g], t1.h[~g], t1.alpha[~g])
    ref = model("cure_depth").predict(x, t1.L[g], t1.d[g], t1.h[g])
    np.testing.assert_allclose(f.logo_predicted[g], ref, atol=2e-4)


def test_aicc_by_hand():
    n, k, rss = 18, 2, 0.5
    kk = k + 1
    assert aicc(rss, n, k) == pytest.approx(n * math.log(rss / n) + 2 * kk + 2 * kk * (kk + 1) / (n - kk - 1))


@pytest.mark.parametrize("truth, params", [("saturation", [0.09, 2.0]), ("cure_depth", [0.05, 0.12])])
def test_select_names_the_effect_in_noisy_data(t1, truth, params):
    rng = np.random.default_rng(3)
    alpha = model(truth).predict(np.array(params), t1.L, t1.d, t1.h) + 0.01 * rng.standard_normal(18)
    fits = [evaluate(m, t1.L, t1.d, t1.h, alpha) for m in catalogue(pairs=False)]
    best, cands = select(fits, alpha)
    assert best.name == truth
    assert truth in cands


def test_select_keeps_the_baseline_when_no_effect_is_there(t1):
    rng = np.random.default_rng(5)
    alpha = Model(()).predict([0.06], t1.L, t1.d, t1.h) + 0.03 * rng.standard_normal(18)
    fits = [evaluate(m, t1.L, t1.d, t1.h, alpha) for m in catalogue()]
    best, _ = select(fits, alpha)
    assert best.name == "baseline"


# -- where ------------------------------------------------------------------------------------
def test_residual_analysis_names_the_regime():
    rng = np.random.default_rng(0)
    d = rng.uniform(0.1, 0.5, 30)
    L = rng.uniform(1, 6, 30)
    res = np.where(d < 0.2, 0.5, 0.0) + 0.01 * rng.standard_normal(30)  # thin coats missed
    where, regime = residual_analysis(res, {"L_mm": L, "d_mm": d})
    assert where[0]["input"] == "d_mm" and where[0]["spearman_rho"] < -0.5
    assert "thin passive coats" in regime and "under-predicted" in regime
    assert where[0]["bins"][0]["share"] > 0.9


def test_residual_analysis_skips_constant_inputs():
    where, _ = residual_analysis(np.arange(6.0), {"h_mm": np.full(6, 0.29), "L_mm": np.arange(6.0)})
    assert [w["input"] for w in where] == ["L_mm"]


# -- diagnose -----------------------------------------------------------------------------------
def test_table1_diagnosis(t1, t1_diag):
    d = t1_diag.as_dict()
    assert set(d) >= {"baseline", "where", "residuals", "effects", "best"}
    b = d["baseline"]
    assert set(b) >= {"model", "params", "rmse", "loo_rmse"}
    # the baseline is Eq. 1 refitted by least squares through the origin: K = 0.0608 and
    # RMSE 0.464 rad on Table 1 (gdfe.Calibration.fit; studies/fig02_calibration.py)
    ref = gdfe.Calibration.fit(t1, n_boot=0)
    assert b["params"]["K"] == pytest.approx(0.0608, abs=5e-5)
    assert b["params"]["K"] == pytest.approx(ref.K, rel=1e-9)
    assert b["rmse"] == pytest.approx(ref.rmse, rel=1e-9)
    assert b["loo_rmse"] > b["rmse"] > 0.4
    effects = d["effects"]
    assert {"name", "params", "rmse", "loo_rmse", "shrink", "aic"} <= set(effects[0])
    assert effects[0]["name"] == d["best"]  # best first, then by held-out error
    loos = [e["loo_rmse"] for e in effects[1:]]
    assert loos == sorted(loos)
    assert sorted(e["rank"] for e in effects) == list(range(1, len(effects) + 1))
    for e in effects:
        assert e["shrink"] == pytest.approx(1 - e["loo_rmse"] / b["loo_rmse"])
    best = next(e for e in effects if e["name"] == d["best"])
    assert best["loo_rmse"] < 0.5 * b["loo_rmse"]  # the gap shrinks by more than half, held out
    assert len(d["residuals"]) == 18 and d["residuals"][0]["row"] == 2
    assert "predicted" in [w["input"] for w in d["where"]]
    json.dumps(d)


def test_diagnose_rejects_bad_rows(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("L_mm,d_mm,h_mm,alpha_rad\n1.5,0.11,0.29,1.75\n3.2,-0.1,0.29,2.2\n3.4,x,0.29,2.3\n")
    with pytest.raises(ValueError, match=r"row 3, column d_mm: expected a positive.*row 4, column d_mm"):
        diagnose(p)


def test_diagnose_needs_enough_tests(tmp_path):
    p = tmp_path / "few.csv"
    p.write_text("L_mm,d_mm,h_mm,alpha_rad\n" + "\n".join(f"{1 + i},0.2,0.29,{0.5 + i / 3}" for i in range(4)))
    with pytest.raises(ValueError, match="at least 5"):
        diagnose(p)


def _table1_with_columns(tmp_path, t1):
    p = tmp_path / "grouped.csv"
    rows = ["L_mm,d_mm,h_mm,alpha_rad,batch,temperature_C"]
    for i in range(18):
        rows.append(f"{t1.L[i]},{t1.d[i]},{t1.h[i]},{t1.alpha[i]},b{i % 3},{100 + 5 * (i % 4)}")
    p.write_text("\n".join(rows) + "\n")
    return p


def test_group_column_enables_leave_one_group_out(tmp_path, t1):
    p = _table1_with_columns(tmp_path, t1)
    d = diagnose(p, group="batch", pairs=False).as_dict()
    assert d["held_out"] == "leave-one-group-out"
    assert "logo_rmse" in d["baseline"] and "logo_rmse" in d["effects"][0]
    ranked = sorted(d["effects"], key=lambda e: e["rank"])
    logos = [e["logo_rmse"] for e in ranked if e["logo_rmse"] is not None]
    assert logos == sorted(logos)
    # the batch step's models have no LOGO error (a group's own scale cannot be held out by group)
    assert all(e["logo_rmse"] is None for e in d["effects"] if "batch" in e["effects"])
    assert "temperature_C" in [w["input"] for w in d["where"]]  # numeric extra column analysed
    with pytest.raises(ValueError, match="no column 'lot'"):
        diagnose(p, group="lot")


def test_cli_diagnose(tmp_path, capsys):
    out = tmp_path / "d.json"
    rep = tmp_path / "report"
    assert main(["diagnose", str(gdfe.TABLE1), "--json", str(out), "--report", str(rep),
                 "--check", "none"]) == 0
    text = capsys.readouterr().out
    assert "best:" in text and "baseline" in text
    d = json.loads(out.read_text())
    assert d["best"] and d["baseline"]["loo_rmse"] > 0
    for f in ("residual_map.png", "before_after.png", "effects.png", "summary.md", "diagnosis.json"):
        assert (rep / f).is_file()
    assert "Where the gap lies" in (rep / "summary.md").read_text()


def test_cli_diagnose_error_is_one_line(tmp_path, capsys):
    p = tmp_path / "bad.csv"
    p.write_text("L_mm,d_mm,alpha_rad\n1,0.2,1\n")
    assert main(["diagnose", str(p), "--check", "none"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("gdfe diagnose: error:") and "h_mm" in err and "\n" not in err
