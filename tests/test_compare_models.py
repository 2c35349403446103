"""The GDFE/FEM comparison study: its shape-distance machinery, and a coarse run (slow)."""

import numpy as np
import pytest

import gdfe
import reference_fem as rf
from studies import compare_models as cm


def test_fem_mid_surface_interpolates_its_own_nodes_exactly():
    res = rf.solve_linear(rf.hinge_mesh(1.6, 0.33, resolution="coarse"), rf.BilayerMaterial())
    X, x = rf.midsurface(res)
    at = cm._fem_interpolator(res)
    assert np.abs(at(X[:, :2]) - x).max() < 1e-8


def test_flat_gdfe_and_flat_fem_are_zero_distance_apart():
    L, cells = 1.6, 8
    fem = rf.solve_linear(rf.hinge_mesh(L, 0.33, width=cm.WIDTH, panel_length=cm._panel(L, cells),
                                        resolution="coarse"), rf.BilayerMaterial(eigenstrain=0.0))
    g = gdfe.simulate(gdfe.hinge(L, R=1.0, h=cm.H, width=cm.WIDTH, panel_length=cm.PANEL,
                                 cell_size=L / cells))
    rms, mx, *_ = cm._distance(cm._fem_interpolator(fem), g, np.array([-0.5 * L, -0.5 * cm.WIDTH, 0]))
    assert rms < 1e-9 and mx < 1e-9


def test_bad_resolution():
    with pytest.raises(ValueError, match=r"resolution: expected one of 'coarse', 'default', 'fine', got 'medium'"):
        cm.run("medium")


@pytest.mark.slow
def test_coarse_run_headline_numbers(coarse_study):
    res, tmp_path = coarse_study("compare")
    for name in ("compare_models.png", "compare_models_shapes.png", "compare_models_runtime.png",
                 "compare_models.json"):
        assert (tmp_path / name).is_file()
    assert len(res["angles"]) == 18 + 3
    rmse = res["angle_rmse"]
    # the FEM's Table-1 calibration: RMSE 0.264 rad at the default mesh
    assert rmse["fem_linear_rad"]["rmse_rad"] < 0.30
    assert rmse["fem_nonlinear_rad"]["rmse_rad"] < 0.35
    # Eq. 3 with the paper's K gives R <= 0 for d < 0.1496 mm, and R = 0.0038 at d = 0.15 mm: below
    # the 1 % that any shrink film reaches, so that specimen is recorded as not simulated, with why
    assert rmse["gdfe_paper_rad"]["n"] == 13
    thin = next(r for r in res["angles"] if r["source"] == "table1" and r["d_mm"] == 0.15)
    assert thin["gdfe_paper_rad"] is None and thin["gdfe_paper_R"] == pytest.approx(0.0038, abs=1e-4)
    assert "below the 0.01" in thin["gdfe_paper_not_simulated"]
    assert rmse["gdfe_refit_rad"]["n"] == 18
    fig6 = [r for r in res["angles"] if r["source"] == "fig6"]
    # GDFE with the paper's calibration reproduces the paper's Figure 6. Budget at L = 2.6
    # (README, refinement study): Eq. 1 lies 0.037 above the paper's 2.70 (R rounded to 0.7),
    # 8 cells across the hinge fold 0.034 less than Eq. 1 and a 1 mm strip 0.054 less than
    # the 0.5 mm one: about 0.05 below the paper; 0.12 is that with the terms' magnitudes summed
    for r in fig6:
        assert r["gdfe_paper_rad"] == pytest.approx(r["paper_gdfe_rad"], abs=0.12)
    assert len(res["shapes"]) == 4
    for s in res["shapes"]:
        assert s["gdfe_fitted_rms_mm"] <= s["gdfe_refit_rms_mm"] + 1e-9
        assert s["gdfe_fitted_max_mm"] < 0.5
    for rows in res["runtime"]["models"].values():
        assert len(rows) >= 3 and all(r["converged"] for r in rows)
    assert res["converged"]
    assert all(h["passed"] for h in res["headlines"]), [h for h in res["headlines"] if not h["passed"]]
