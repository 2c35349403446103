"""``gdfe plan --target DESIGN``: the tests that narrow the prediction of a part's fold angles most."""

import dataclasses
import json

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.measure import panel_angles
from gdfe.model import DeformationModel, Member, Uncertainty
from gdfe.plan_target import TargetFolds, expected_for_tests, plan_for_target, target_folds
from gdfe.predict import HingeSpecimens, mixture_interval, predict

TUBE = "docs/examples/tube.toml"
H = 0.29


def _member(params, mechanisms=(), noise=0.05, cov=None):
    names = tuple(params)
    cov = np.diag([1e-10] * len(names)) if cov is None else np.asarray(cov, float)
    m = DeformationModel("eq1", params, mechanisms)
    return dataclasses.replace(m, uncertainty=Uncertainty(names, cov, noise, 10))


def _mixture(*weighted):
    top = weighted[0][1]
    return dataclasses.replace(top, ensemble=tuple(Member(w, m) for w, m in weighted), weighting="stacking")


def _folds(L, d):
    L, d = np.atleast_1d(np.asarray(L, float)), np.atleast_1d(np.asarray(d, float))
    return TargetFolds(labels=tuple(f"fold {i}" for i in range(L.size)),
                       specimens=HingeSpecimens(L, d, np.full(L.size, H)), kind="given")


@pytest.fixture(scope="module")
def table1_model():
    from gdfe.diagnosis import diagnose
    from gdfe.predictive import from_diagnosis

    return from_diagnosis(diagnose(gdfe.TABLE1))


def test_one_member_narrows_as_the_gaussian_update_of_its_parameters():
    # alpha = K (h/d)^1.5 (L + lambda) / h: derivatives by hand, C' = (C^-1 + J^T J / s^2)^-1
    K, lam, s = 0.3706, 0.4, 0.05
    C = np.array([[0.02**2, 0.3 * 0.02 * 0.2], [0.3 * 0.02 * 0.2, 0.2**2]])
    model = _member({"K": K, "lambda": lam}, ("hinge_length",), noise=s, cov=C)
    target = _folds([1.6, 4.0], [0.33, 0.2])
    tests = HingeSpecimens(np.array([5.0, 1.0, 5.0]), np.array([0.15, 0.4, 0.15]), np.full(3, H))

    def grad(L, d):
        c = (H / d) ** 1.5 / H
        return np.column_stack([c * (L + lam), np.full(np.size(L), K) * c])

    J, G = grad(tests.L, tests.d), grad(target.specimens.L, target.specimens.d)
    res = expected_for_tests(model, target, tests, samples=200)
    for m in range(4):
        Cm = np.linalg.inv(np.linalg.inv(C) + J[:m].T @ J[:m] / s**2)
        want = np.einsum("fp,pq,fq->f", G, Cm, G)
        assert res.sd[m] ** 2 == pytest.approx(want, rel=1e-4), m
    assert res.variance[0] > res.variance[1] > res.variance[2] > res.variance[3] > 0
    # one member: its interval is normal, 2 x 1.645 sd wide at level 0.9
    assert res.width[0] == pytest.approx(2 * 1.6448536 * res.sd[0], rel=1e-6)


def test_the_interval_before_is_the_mixture_gdfe_predict_gives_without_the_noise():
    a = _member({"K": 0.30}, cov=[[0.01**2]], noise=0.08)
    b = _member({"K": 0.06, "lambda": 1.0}, ("hinge_length",), cov=np.diag([0.004**2, 0.1**2]), noise=0.08)
    model = _mixture((0.7, a), (0.3, b))
    target = _folds([0.5, 2.0, 4.0], [0.33, 0.2, 0.45])
    plan = plan_for_target(model, target, 1, grid=5, samples=500)
    p = predict(model, target.specimens)
    lo, hi = mixture_interval([0.7, 0.3], p.member_alpha, p.member_sd_parameters, [1e9, 1e9], 0.9)
    np.testing.assert_allclose(plan.interval, np.column_stack([lo, hi]), atol=1e-6)
    np.testing.assert_allclose(plan.alpha, p.alpha, rtol=1e-12)


def test_a_test_that_names_the_member_removes_the_choice_of_model_and_leaves_the_parameters_part():
    # two members apart by more than 1 rad on long hinges, noise 0.01 rad: one long test says which is right
    ca, cb = [[0.002**2]], [[0.003**2]]
    a, b = _member({"K": 0.30}, cov=ca, noise=0.01), _member({"K": 0.15}, cov=cb, noise=0.01)
    model = _mixture((0.5, a), (0.5, b))
    target = _folds([1.0], [0.33])
    plan = plan_for_target(model, target, 1, (1.0, 6.0), (0.3, 0.3), grid=11, samples=2000)
    assert plan.L[0] == 6.0  # where they differ most
    g = (H / 0.33) ** 1.5 * 1.0 / H  # d alpha / d K of the target
    spread = 0.25 * (0.15 * g) ** 2  # the choice of model: w1 w2 (a1 - a2)^2
    params = 0.5 * g**2 * (0.002**2 + 0.003**2)
    assert plan.variance[0] == pytest.approx(spread + params, rel=1e-9)
    # after: the choice gone (the members part by 2 rad at L = 6 mm, the noise is 0.01 rad), each member's
    # parameters narrowed by the test, C' = 1 / (1 / C + j^2 / s^2)
    j = (H / 0.3) ** 1.5 * 6.0 / H
    after = 0.5 * g**2 * sum(1.0 / (1.0 / c[0][0] + j**2 / 0.01**2) for c in (ca, cb))
    assert plan.variance[1] == pytest.approx(after, rel=1e-6)


def test_table1_planned_tests_narrow_the_tube_more_than_random_ones(table1_model):
    plan = plan_for_target(table1_model, TUBE, 3, (1.0, 6.0), (0.11, 0.5), (H, H), samples=2000)
    assert len(plan.target) == 12 and np.all(plan.target.specimens.L == 0.5)
    assert np.all((1.0 <= plan.L) & (plan.L <= 6.0)) and np.all((0.11 <= plan.d) & (plan.d <= 0.5))
    assert np.all(np.diff(plan.variance) <= 1e-9 * plan.variance[0])  # never above the step before
    assert np.all(plan.width[1:] <= plan.width[0] + 1e-9)
    # cure depth with hinge length reaches lambda / 2 = 1.4 mm past a coat edge: across the 0.5 mm panels
    assert [w.split(":")[0] for w in plan.warnings] == ["member cure_depth+hinge_length"]
    rng = np.random.default_rng(7)
    for _ in range(5):
        tests = HingeSpecimens(rng.uniform(1.0, 6.0, 3), rng.uniform(0.11, 0.5, 3), np.full(3, H))
        rand = expected_for_tests(table1_model, TUBE, tests, samples=2000)
        assert rand.variance[-1] <= rand.variance[0]
        assert plan.mean_width[-1] < rand.mean_width[-1], (plan.mean_width, rand.mean_width, tests.L, tests.d)
        assert plan.variance[-1] < rand.variance[-1]


def test_the_folds_of_designs_are_their_hinge_specimens():
    tube = target_folds(TUBE)
    design, _ = gdfe.load_design(TUBE)
    labels = [f"panels {'-'.join(map(str, r['panels']))}" for r in panel_angles(design.mesh.points, design)]
    assert list(tube.labels) == labels and len(labels) == 12
    assert tube.panel_mm == pytest.approx(0.5)  # the panels between the hinges
    np.testing.assert_allclose(tube.specimens.L, 0.5)  # two 0.25 mm characters of T between R
    np.testing.assert_allclose(tube.specimens.d, 0.33)
    box = target_folds("docs/examples/box.toml")
    assert box.labels == ("crease 12", "crease 13", "crease 14", "crease 15")
    np.testing.assert_allclose(box.specimens.L, 0.29 * (np.pi / 2) / (1 - 0.6947), rtol=2e-3)  # Eq. 2
    hinge = target_folds(gdfe.hinge(2.6, d=0.2))
    assert hinge.labels == ("hinge",) and hinge.specimens.L[0] == 2.6 and hinge.specimens.d[0] == 0.2
    assert hinge.panel_mm == np.inf  # a test's panels are the test's own
    # widths of different runs on the two faces: 3 and 5 cells of 0.2 mm
    rows = ["RRTTTRRBBBBBRR"] * 3
    folds = target_folds(gdfe.from_rows(rows, d=0.25, pixel=0.2))
    np.testing.assert_allclose(folds.specimens.L, [0.6, 1.0])


def test_designs_without_folds_or_without_d_are_refused():
    with pytest.raises(gdfe.GdfeError, match=r"--target: expected a design with folds .*none"):
        target_folds(gdfe.from_rows(["TTTTTTTT"] * 3, d=0.33, pixel=0.25), "--target")
    with pytest.raises(gdfe.GdfeError, match=r"--target: expected the passive thickness d of every fold"):
        target_folds(gdfe.from_rows(["RRTTRR"] * 3, R=0.7, pixel=0.25), "--target")
    with pytest.raises(gdfe.GdfeError, match="target: expected a gdfe.Design"):
        target_folds(3.0)


def test_plan_target_through_the_command_line(capsys, tmp_path):
    assert main(["plan", str(gdfe.TABLE1), "--n", "2", "--target", TUBE, "--json", "-q"]) == 0
    out = json.loads(capsys.readouterr().out)
    from gdfe.cli._vocabulary import known_keys

    assert not set(out) - known_keys("plan")
    assert len(out["folds"]) == 12 and len(out["tests"]) == 2 and len(out["expected_width_rad"]) == 3
    assert out["expected_width_rad"][-1] < out["expected_width_rad"][0]
    for f in out["folds"]:
        assert f["width_after_rad"] < f["width_before_rad"]
        lo, hi = f["interval_before_rad"]
        assert lo < f["fold_angle_rad"] < hi
    assert 0 < out["expected_reduction"] <= 1
    flat = tmp_path / "flat.toml"
    flat.write_text('[film]\nh = 0.29\nd = 0.33\n\n[layout]\npixel = 0.25\nrows = ["TTTTTTTT", "TTTTTTTT"]\n')
    for argv, match in ((["--target", str(flat)], "--target: expected a design with folds"),
                        (["--target", TUBE, "--L", "5:1"], "--L: expected LO <= HI"),
                        (["--target", TUBE, "--d", "0:0.5"], "--d: expected LO:HI or a value of positive"),
                        (["--level", "0.8"], "--level: an option of --target"),
                        (["--target", TUBE, "--level", "1.5"], "--level: expected")):
        assert main(["plan", str(gdfe.TABLE1), "--n", "1", *argv]) == 1, argv
        assert match in capsys.readouterr().err, argv


# -- the plan's expectation against simulated outcomes (a check inside the model) ---------------------
def _fits_of(diag, members):
    """The diagnosis's fit of each member (same parameters, same values): its vectorised closed form."""
    out = []
    for m in members:
        u = m.model.uncertainty
        vals = [u.reading_offset_rad if k == "offset" else m.model.value(k) for k in u.names]
        out.append(next(f for f in [diag.best, diag.baseline, *diag.fits] if tuple(f.model.param_names) == u.names
                        and np.allclose(f.params, vals, rtol=1e-9)))
    return out


def _draws(diag, model, tests, fold, n, rng):
    """Per member: ``n`` parameter draws from its covariance (those with finite angles kept), the tests' angles
    (reading offset in) and the fold's (offset out), by the diagnosis's own nonlinear closed form."""
    members = [m for m in model.ensemble if m.weight > 1e-9]
    w = np.array([m.weight for m in members])
    out = []
    for m, f in zip(members, _fits_of(diag, members)):
        u = m.model.uncertainty
        th = rng.multivariate_normal(np.asarray(f.params, float), u.matrix(), n, method="eigh")
        P = f.model.predict(th.T[:, :, None], tests.L, tests.d, tests.h, None, None)
        th[:, [i for i, k in enumerate(u.names) if k == "offset"]] = 0.0
        Q = f.model.predict(th.T[:, :, None], fold.L, fold.d, fold.h, None, None)[:, 0]
        ok = np.all(np.isfinite(P), axis=1) & np.isfinite(Q)
        out.append((P[ok], Q[ok], u.noise_rad))
    return w / w.sum(), out


def _simulated_width(diag, model, tests, fold, outcomes=200, pool=20000, seed=0, level=0.9):
    """Mean width of the fold's interval at ``level`` after the tests, over outcomes drawn from the model (a member
    by its weight, its parameters from their covariance, the noise), each posterior by importance sampling of
    the nonlinear closed forms (a pool of prior draws weighed by the outcome's likelihood); and the median
    effective sample size."""
    rng = np.random.default_rng(seed)
    w, pools = _draws(diag, model, tests, fold, pool, rng)
    _, truths = _draws(diag, model, tests, fold, outcomes, np.random.default_rng(seed + 1000))
    Q = np.concatenate([q for _, q, _ in pools])
    order = np.argsort(Q)
    widths, ess = [], []
    for _ in range(outcomes):
        t = rng.choice(len(w), p=w)
        P, _, s = truths[t]
        y = P[rng.integers(len(P))] + s * rng.standard_normal(P.shape[1])
        lw = np.concatenate([np.log(w[k]) - np.log(len(Pk)) - 0.5 * np.sum((y - Pk) ** 2, axis=1) / sk**2
                             - Pk.shape[1] * np.log(sk) for k, (Pk, _, sk) in enumerate(pools)])
        wt = np.exp(lw - lw.max())
        wt /= wt.sum()
        ess.append(1.0 / np.sum(wt**2))
        c = np.cumsum(wt[order])
        lo, hi = np.interp([(1 - level) / 2, (1 + level) / 2], c, Q[order])
        widths.append(hi - lo)
    return float(np.mean(widths)), float(np.median(ess))


@pytest.mark.slow
def test_planned_tests_narrow_the_tube_more_than_random_ones_by_simulated_outcomes(capsys):
    # a check inside the model: outcomes drawn from the model file, posteriors of its nonlinear closed forms
    from gdfe.diagnosis import diagnose
    from gdfe.predictive import from_diagnosis

    diag = diagnose(gdfe.TABLE1)
    model = from_diagnosis(diag)
    folds = target_folds(TUBE)
    fold = HingeSpecimens(folds.specimens.L[:1], folds.specimens.d[:1], folds.specimens.h[:1])  # all 12 alike
    plan = plan_for_target(model, folds, 3, (1.0, 6.0), (0.11, 0.5), (H, H))
    planned, ess = _simulated_width(diag, model, HingeSpecimens(plan.L, plan.d, plan.h), fold)
    rng = np.random.default_rng(11)
    lin, sim = [], []
    for r in range(10):
        tests = HingeSpecimens(rng.uniform(1.0, 6.0, 3), rng.uniform(0.11, 0.5, 3), np.full(3, H))
        lin.append(expected_for_tests(model, folds, tests).mean_width[-1])
        sim.append(_simulated_width(diag, model, tests, fold, seed=r + 1)[0])
    with capsys.disabled():
        print(f"\ntube, 3 tests: width before {plan.mean_width[0]:.3f} rad; planned {plan.L} x {plan.d} mm: expected "
              f"{plan.mean_width[-1]:.3f}, simulated {planned:.3f} (median ESS {ess:.0f}); random (10 sets): "
              f"expected {np.mean(lin):.3f}, simulated {np.mean(sim):.3f}")
    assert planned < min(sim)  # the plan beats every random set in simulated outcomes too
    assert planned == pytest.approx(plan.mean_width[-1], rel=0.35)  # the linearisation holds for the plan's tests
    assert np.mean(sim) == pytest.approx(np.mean(lin), rel=0.15)
    assert ess > 1000
