"""The compare-shapes study: GDFE against the plate FEM on freeform parts."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("skfem")

import studies.compare_shapes as cs  # noqa: E402


def _shape(seed=0, n=5):
    rng = np.random.default_rng(seed)
    ij = [(i, j) for i in range(n) for j in range(n)]
    pts = np.array([[i, j, 0.1 * (i - 2) ** 2] for i, j in ij], float) + 0.01 * rng.standard_normal((n * n, 3))
    return dict(zip(ij, pts))


def test_distances_ignore_rigid_motions_and_bound_each_other():
    a = _shape(0)
    rng = np.random.default_rng(1)
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    Q *= np.sign(np.linalg.det(Q))
    moved = {k: p @ Q.T + [1.0, -2.0, 3.0] for k, p in a.items()}
    same = cs.compare(a, moved)
    assert same["rms_mm"] < 1e-12 and same["hausdorff_mm"] < 1e-12
    other = cs.compare(a, _shape(2))
    assert 0 < other["rms_mm"] <= other["max_mm"]
    assert other["hausdorff_mm"] <= other["max_mm"] + 1e-12  # the nearest point is no further than the matching one
    assert len(other["keys"]) == 25 and other["deviation"].shape == (25,)


def test_split_design_keeps_the_vertices_of_the_unsplit_grid():
    mat = np.array([[0, 1], [2, 3]])
    film = np.ones((2, 2), bool)
    one = cs.make_design(mat, film, 0.5, 0.8)
    two = cs.make_design(mat, film, 0.5, 0.8, split=2)
    assert two.n_cells == 4 * one.n_cells
    assert np.allclose(two.mesh.spacing[:2], 0.25)
    class Flat:  # a "result" at the flat print
        def __init__(self, des):
            self.points = des.mesh.points

    v1 = cs.gdfe_vertices(Flat(one), one)
    v2 = cs.gdfe_vertices(Flat(two), two, split=2)
    assert set(v1) == set(v2) and len(v1) == 9
    for k in v1:
        assert np.allclose(v1[k], v2[k])


def test_one_small_part_compares_both_models(tmp_path):
    meshio = pytest.importorskip("meshio")
    cfg = {**cs.SETTINGS["coarse"], "fig08_cells": 4}
    row = cs.run_part("saddle", cfg, tmp_path)
    assert row["gdfe_converged"] and row["fem_converged"]
    # the two models agree to a few per cent of the part's size, and fitting R to the FEM brings them closer
    assert 0 < row["rms_rel"] < 0.1, row["rms_rel"]
    assert row["rms_fit_mm"] <= row["rms_mm"] * (1 + 1e-6)
    assert 0.4 <= row["R_fit"] <= 0.99
    assert row["hausdorff_mm"] <= row["max_mm"] + 1e-12
    assert set(row["deviation_by_material_mm"]) <= {"rigid", "contract_top", "contract_bottom", "free_shrink"}
    vtu = meshio.read(tmp_path / row["vtu"])
    dev = vtu.point_data["deviation_mm"]
    assert np.nanmax(dev) == pytest.approx(row["max_mm"], rel=1e-9)
    assert row["fem_cost"]["newton_iterations"] >= 1


def test_panel_folds_read_the_angle_between_two_panels_folded_about_their_hinge():
    import gdfe

    # panels of 3 columns (rigid), a hinge column (coated on one face) between them
    mat = np.full((7, 2), gdfe.Material.RIGID, int)
    mat[3] = gdfe.Material.CONTRACT_TOP
    film = np.ones((7, 2), bool)
    pixel, angle = 0.5, 0.9
    shape = {}
    for i in range(8):
        for j in range(3):
            x, y = i * pixel, j * pixel
            if i >= 4:  # the second panel rotated about the hinge's far edge (x = 2 mm), about y
                u = x - 2.0
                x, z = 2.0 + u * np.cos(angle), u * np.sin(angle)
            else:
                z = 0.0
            shape[(i, j)] = np.array([x, y, z])
    folds = cs.panel_folds(mat, film, pixel, shape)
    assert list(folds) == [(1, 2)]
    assert folds[(1, 2)] == pytest.approx(angle, abs=1e-9)
    rows = cs._fold_rows(folds, {(1, 2): 0.5})
    assert rows["fold_angle_max_diff_rad"] == pytest.approx(0.4) and rows["fold_angles"][0]["fem_rad"] == 0.5
    assert cs._fold_rows({}, {}) == {}


@pytest.mark.slow
def test_the_target_distance_of_an_inverse_design_is_the_designs_own():
    """The study's distance of GDFE's fold of the printed masks to the target equals what the design reports."""
    inv = {"size": 3.0, "pixel": 0.5, "iterations": 2}
    mat, film, pixel, dsg = cs.inverse_masks("dome", inv)
    res, des, _ = cs._gdfe(mat, film, pixel, cs.eq3_ratio())
    assert res.converged
    got = cs.target_distance(dsg, cs.gdfe_vertices(res, des))
    assert got == pytest.approx(dsg.printable_distance.rms_mm, rel=0.02, abs=2e-4)
