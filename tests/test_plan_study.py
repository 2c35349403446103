"""The plan study at its coarsest resolution: one generated truth, the planned test against random and grid."""

import pytest


@pytest.mark.slow
def test_the_planned_test_names_the_right_model_before_random_and_grid_tests(coarse_study):
    result, out = coarse_study("plan")
    assert result["n_open"] == 1 and result["converged"]
    rules = result["rules"]
    assert rules["plan"]["median_tests"] < rules["random"]["median_tests"]
    assert rules["plan"]["median_tests"] < rules["grid"]["median_tests"]
    assert (out / "plan.png").is_file()


@pytest.mark.slow
def test_null_truths_get_a_fixed_number_of_tests_by_every_rule(coarse_study):
    result, _ = coarse_study("plan")
    assert len(result["nulls"]) == 1
    null = result["nulls"][0]
    assert null["generator"] == "nominal"
    for rule in ("plan", "random", "grid"):
        assert len(null[rule]["added"]) == 1  # the coarse null budget, whatever the diagnosis said
        assert 0.0 <= result["rules"][rule]["null_false_alone"] <= 1.0
