"""Indistinguishable models: the named set, the test that would separate them, and a chosen model
the lack-of-fit test rejects giving way to one within the noise. Synthetic data are the catalogue's
closed forms plus seeded noise, or fits written by hand."""

import json

import numpy as np
import pytest
from scipy import stats

import gdfe
from gdfe.diagnosis import diagnose, model
from gdfe.diagnosis.angles import within_noise_step
from gdfe.diagnosis.fit import EffectFit, evaluate
from gdfe.diagnosis.separate import indistinguishable, separating_test
from gdfe.diagnosis.verdict import LEVEL


@pytest.fixture(scope="module")
def t1():
    return gdfe.load_folding_tests(gdfe.TABLE1)


def _fake(name, held_out, predicted=None):
    m = model(name)
    k = m.n_params
    pred = held_out if predicted is None else predicted
    return EffectFit(model=m, params=np.zeros(k), predicted=pred, residuals=np.zeros_like(pred), rmse=0.0,
                     loo_predicted=held_out, loo_rmse=float(np.sqrt(np.mean(held_out**2))), logo_predicted=None,
                     logo_rmse=None, aicc=0.0, at_bound=[], success=True, se=np.zeros(k), ci95=np.zeros((k, 2)))


def _loo(fit):
    return "loo"


def test_indistinguishable_by_hand():
    """Held-out errors: a single as good as the chosen one is named, one clearly worse is not, a
    pair (more effects) and the baseline never; within the noise: a model outside it is left out."""
    rng = np.random.default_rng(0)
    alpha = np.linspace(0.5, 2.5, 20)
    good = alpha + 0.01 * rng.standard_normal(20)
    chosen = _fake("cure_depth", good)
    same = _fake("film_thickening", good + 1e-4 * rng.standard_normal(20))
    worse = _fake("saturation", alpha + 0.2 * rng.standard_normal(20))
    pair = _fake("cure_depth+hinge_length", good.copy())
    base = _fake("baseline", alpha + 0.3 * rng.standard_normal(20))
    named = indistinguishable(chosen, [base, same, worse, pair], alpha, _loo)
    assert {f.name for f in named} == {"cure_depth", "film_thickening"}
    assert named[0].loo_rmse <= named[1].loo_rmse  # the same effects and parameters: by held-out error
    # the lack-of-fit test rejects film_thickening: it is told apart
    named = indistinguishable(chosen, [same, worse], alpha, _loo, within_of=lambda f: f is not same)
    assert [f.name for f in named] == ["cure_depth"]
    # the baseline's set is the baseline
    assert indistinguishable(base, [chosen, same], alpha, _loo) == [base]


def test_fitted_angles_closer_than_the_noise_are_indistinguishable():
    """Held-out errors apart by many standard errors, but fitted angles whose chi^2 distance is
    below the 1 - LEVEL quantile of chi^2(1): not told apart; just above it: told apart."""
    n = 20
    alpha = np.linspace(0.5, 2.5, n)
    chosen = _fake("cure_depth", alpha.copy())
    crit = stats.chi2.ppf(1 - LEVEL, 1)
    sigma = np.full(n, 0.03)
    step = 0.03 * np.sqrt(crit / n)  # a constant offset whose chi^2 distance is crit
    near = _fake("film_thickening", alpha + 0.05 * np.linspace(-1, 1, n) ** 2 + 0.05,
                 predicted=alpha + 0.99 * step)
    far = _fake("passive_stiffness", alpha + 0.05 * np.linspace(-1, 1, n) ** 2 + 0.05,
                predicted=alpha + 1.01 * step)
    named = indistinguishable(chosen, [near, far], alpha, _loo, sigma=sigma)
    assert {f.name for f in named} == {"cure_depth", "film_thickening"}
    assert [f.name for f in indistinguishable(chosen, [near, far], alpha, _loo)] == ["cure_depth"]


def test_within_noise_step_by_hand():
    """A chosen single the lack-of-fit test rejects gives way to a pair within the noise that beats it
    on held-out tests by more than one standard error, to a single within the noise it does not beat
    before that, and to nothing when neither exists."""
    rng = np.random.default_rng(1)
    alpha = np.linspace(0.5, 2.5, 30)
    chosen = _fake("saturation", alpha + 0.05 * rng.standard_normal(30))
    pair = _fake("cure_depth+hinge_length", alpha + 0.01 * rng.standard_normal(30))
    away = np.sign(chosen.loo_predicted - alpha)
    slightly = _fake("hinge_length+passive_stiffness", chosen.loo_predicted + 1e-3 * away)  # worse in every test
    ok = {pair.name, slightly.name}
    step = within_noise_step(chosen, [chosen, pair, slightly], alpha, lambda f: f.name in ok, _loo)
    assert step is pair
    # a pair that is within the noise but no better on held-out tests does not replace it
    assert within_noise_step(chosen, [chosen, slightly], alpha, lambda f: f.name in ok, _loo) is chosen
    # a single within the noise, as good on held-out tests: fewer effects than the pair, preferred
    single = _fake("cure_depth", chosen.loo_predicted.copy())
    ok.add(single.name)
    assert within_noise_step(chosen, [chosen, pair, single], alpha, lambda f: f.name in ok, _loo) is single
    # nothing within the noise: the choice stands
    assert within_noise_step(chosen, [chosen, pair, single], alpha, lambda f: False, _loo) is chosen


def test_separating_test_by_hand(t1):
    """Two fitted models on Table 1's single film thickness: moving h separates them, the spread is
    the difference of their closed forms at the named test, and on the tests made it is the largest
    difference of their fitted angles."""
    alpha = model("cure_depth").predict([0.1, 0.08], t1.L, t1.d, t1.h)
    a = evaluate(model("cure_depth"), t1.L, t1.d, t1.h, alpha)
    b = evaluate(model("film_thickening"), t1.L, t1.d, t1.h, alpha)
    sep = separating_test([a, b], t1.L, t1.d, t1.h, lambda m: None, lambda m: None, sigma=0.03)
    assert sep["input"] == "h_mm" and sep["value"] != pytest.approx(0.29)
    t = sep["test"]
    pa = a.model.predict(a.params, np.array([t["L_mm"]]), np.array([t["d_mm"]]), np.array([t["h_mm"]]))[0]
    pb = b.model.predict(b.params, np.array([t["L_mm"]]), np.array([t["d_mm"]]), np.array([t["h_mm"]]))[0]
    assert sep["spread"] == pytest.approx(abs(pa - pb), rel=1e-12)
    assert sep["sigmas"] == pytest.approx(sep["spread"] / 0.03)
    assert sep["on_data"] == pytest.approx(np.max(np.abs(a.predicted - b.predicted)), rel=1e-12)
    assert sep["spread"] > 5 * sep["on_data"]
    assert separating_test([a], t1.L, t1.d, t1.h, lambda m: None, lambda m: None) is None


@pytest.mark.parametrize("seed", [0, 2])
def test_one_film_thickness_names_the_aliases_and_asks_for_another(t1, seed):
    """A thicker coat on Table 1's designs (h = 0.29 mm in every test): a film that thickens softens the
    d-dependence alike, so both are named, and the verdict asks for another film thickness; with h
    varied across the tests, the same effect is named alone."""
    noise = 0.03 * np.random.default_rng(seed).standard_normal(18)
    alpha = model("cure_depth").predict([0.1, 0.08], t1.L, t1.d, t1.h) + noise
    diag = diagnose(gdfe.FoldingTests(L=t1.L, d=t1.d, h=t1.h, alpha=alpha), sigma=0.03)
    assert diag.verdict.verdict == "explained"
    names = [f.name for f in diag.named]
    assert set(names) == {"cure_depth", "film_thickening"} and diag.verdict.ambiguous
    assert diag.separation["input"] == "h_mm" and diag.separation["sigmas"] > 2
    assert "cannot tell" in diag.verdict.text and "film thickness h" in diag.verdict.text
    d = json.loads(json.dumps(diag.as_dict()))
    assert d["named"] == names and d["separation"]["input"] == "h_mm"
    h = np.random.default_rng(5).uniform(0.2, 0.4, 18)
    alpha = model("cure_depth").predict([0.1, 0.08], t1.L, t1.d, h) + noise
    diag = diagnose(gdfe.FoldingTests(L=t1.L, d=t1.d, h=h, alpha=alpha), sigma=0.03)
    assert [f.name for f in diag.named] == ["cure_depth"] and diag.separation is None
    assert not diag.verdict.ambiguous and "cannot tell" not in diag.verdict.text
