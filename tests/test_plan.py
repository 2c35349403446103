"""``gdfe plan``: the next tests to print, those that best tell the named set apart."""

import dataclasses
import json
import math

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.model import DeformationModel, Member, Uncertainty
from gdfe.plan import parse_range, plan_tests


def _member(params, mechanisms=(), noise=0.05, cov=None):
    names = tuple(params)
    cov = np.diag([1e-10] * len(names)) if cov is None else cov
    m = DeformationModel("eq1", params, mechanisms)
    return dataclasses.replace(m, uncertainty=Uncertainty(names, cov, noise, 10))


def _pair(a, b):
    return dataclasses.replace(a, ensemble=(Member(0.5, a), Member(0.5, b)), weighting="stacking")


def test_the_plan_goes_where_the_members_differ_most():
    # hinge_length with lambda = 1 mm against eq1 with twice its K: equal at L = 1 mm (K (L + 1) = 2 K L),
    # apart by c (L - 1) / h beyond
    c = 0.06 * (0.29 / 0.3) ** 1.5
    for noise, reduction in ((0.4, (0.2, 0.9)), (0.02, (0.99, 1.0))):
        short = _member({"K": 0.06, "lambda": 1.0}, ("hinge_length",), noise=noise)
        long_ = _member({"K": 0.12}, noise=noise)
        plan = plan_tests(_pair(short, long_), 1, (1.0, 6.0), (0.3, 0.3), grid=11, samples=4000)
        assert plan.d[0] == 0.3 and 0 < plan.information[0] <= math.log(2) + 1e-12
        assert reduction[0] < plan.expected_reduction <= reduction[1], (noise, plan.expected_reduction)
        if noise > 0.1:  # not saturated: the longest hinge, where they differ most
            assert plan.L[0] == 6.0
            assert plan.predicted[0] == pytest.approx([c * 7 / 0.29, 2 * c * 6 / 0.29], rel=1e-6)


def test_members_that_agree_everywhere_leave_nothing_to_learn_and_more_tests_never_lose_information():
    a = _member({"K": 0.06})
    plan = plan_tests(_pair(a, a), 3, grid=5, samples=1000)
    assert np.all(np.abs(plan.information) < 1e-9)
    b = _member({"K": 0.063})  # 5 % apart: a little to learn, more with every test
    plan = plan_tests(_pair(a, b), 4, grid=5, samples=3000)
    assert np.all(np.diff(plan.information) >= -0.01) and plan.information[-1] > plan.information[0]


def test_a_replicate_does_not_narrow_the_parameters_part():
    # members that differ by less than their parameters' spread: replicating a test cannot tell them apart
    cov = np.array([[0.004**2]])
    a, b = _member({"K": 0.06}, cov=cov, noise=0.01), _member({"K": 0.062}, cov=cov, noise=0.01)
    plan = plan_tests(_pair(a, b), 3, (3.0, 3.0), (0.3, 0.3), samples=4000)
    assert plan.information[-1] < 0.25  # independent replicates would be worth far more: noise 0.01 rad
    assert plan.information[-1] == pytest.approx(plan.information[0], abs=0.05)


def test_a_single_model_has_nothing_to_plan():
    plan = plan_tests(_member({"K": 0.06}), 2)
    assert plan.L.size == 0 and "no choice of model" in plan.text()


@pytest.mark.parametrize("text, match", [("1:x", "expected LO:HI"), ("5:1", "LO <= HI"), ("-1:2", "positive"),
                                         ("1:2:3", "positive lengths")])
def test_ranges_are_checked(text, match):
    with pytest.raises(gdfe.GdfeError, match=match):
        parse_range("--L", text)


def test_plan_through_the_command_line(capsys):
    assert main(["plan", str(gdfe.TABLE1), "--n", "2", "--L", "1:6", "--d", "0.11:0.5", "--json", "-q"]) == 0
    out = json.loads(capsys.readouterr().out)
    from gdfe.cli._vocabulary import known_keys

    assert not set(out) - known_keys("plan")
    assert len(out["tests"]) == 2 and len(out["members"]) == len(out["named"]) >= 2
    for t in out["tests"]:
        assert 1.0 <= t["L_mm"] <= 6.0 and 0.11 <= t["d_mm"] <= 0.5
    assert 0 < out["expected_reduction"] <= 1.0
    assert main(["plan", str(gdfe.TABLE1), "--n", "0"]) == 1
    assert "n: expected" in capsys.readouterr().err


@pytest.mark.parametrize("rows, match", [
    ([(2, 0.3, 0.29, 0.0), (3, 0.3, 0.29, 0.0), (4, 0.2, 0.29, 0.0), (5, 0.2, 0.29, 0.0), (6, 0.4, 0.29, 0.0)],
     "nothing folded"),
    ([(2, 0.3, 0.29, 1.0)] * 6, "the same row"),
])
def test_plan_refuses_degenerate_tests_as_diagnose_does(tmp_path, capsys, rows, match):
    path = tmp_path / "t.csv"
    path.write_text("L_mm,d_mm,h_mm,alpha_rad\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    assert main(["plan", str(path), "--n", "1"]) == 1
    err = capsys.readouterr().err
    assert "t.csv" in err and match in err
