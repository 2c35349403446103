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
