"""The transfer study: a diagnosed model carried through GDFE to held-out tests and to the paper's parts."""

import numpy as np
import pytest

import gdfe
from studies import transfer


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    return transfer.run("coarse", out=tmp_path_factory.mktemp("transfer"))


def test_every_held_out_specimen_is_simulated_with_its_own_model(result, tmp_path_factory):
    ho = result["held_out"]
    assert len(ho["rows"]) == 18 and ho["converged"]
    # the model files were written and read back
    out = result["files"]["json"]
    assert out == "transfer.json"
    # the simulated hinge reproduces each model's closed form: the mechanisms act on the design as the
    # diagnosis's stages say (GDFE's discretisation at 8 cells across a hinge: ~1 % of the angle)
    for r in ho["rows"]:
        assert r["gdfe_rad"] == pytest.approx(r["closed_form_rad"], abs=0.02), r
    # so the held-out error through the simulator is that of the closed form, to the same margin
    assert ho["rmse_gdfe_rad"] == pytest.approx(ho["rmse_closed_form_nested_rad"], abs=0.01)
    # the family chosen on all tests, refitted per fold: through GDFE as its closed form, and that
    # closed form is the diagnosis's own held-out error of its best model (same fits, same folds)
    for r in ho["rows"]:
        assert r["family_gdfe_rad"] == pytest.approx(r["family_closed_form_rad"], abs=0.02), r
    assert ho["rmse_family_closed_form_rad"] == pytest.approx(ho["diagnosis_loo_rmse_rad"], rel=1e-6)
    assert ho["rmse_family_gdfe_rad"] == pytest.approx(ho["rmse_family_closed_form_rad"], abs=0.01)
    # and both are far below the paper's principle refitted (Eq. 3 with K: 0.51 rad held out)
    assert ho["rmse_gdfe_rad"] < 0.6 * ho["rmse_refit_K_gdfe_rad"]


def test_refit_k_baseline_is_the_calibration_held_out():
    # GDFE with K refitted equals the eq1 reading's leave-one-out RMSE up to discretisation
    from gdfe.calibration import held_out_rmse

    assert held_out_rmse(gdfe.TABLE1, "eq1") == pytest.approx(0.5148, abs=1e-4)


def test_parts_are_compared_with_the_paper_model(result):
    names = [p["part"] for p in result["parts"]]
    assert names[:2] == ["tube (Fig. 7)", "crane (Fig. 7)"] and sum("plate" in n for n in names) == 3
    assert sum(n.startswith("letter") for n in names) == 8
    tube = result["parts"][0]
    # the paper's model closes the tube (12 hinges of (1 - R) L / h: one turn, fig07)
    assert tube["paper_turn_rad"] == pytest.approx(2 * np.pi, abs=0.1)
    assert all(np.isfinite(p["rms_mm"]) for p in result["parts"])
