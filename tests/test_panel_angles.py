"""Fold angles between a layout's panels (gdfe.measure.panel_angles): signed as a strip's fold, unwrapped
beyond pi, whatever the hinge's direction in the plane."""

import math

import numpy as np
import pytest

import gdfe
from gdfe.material import Material
from gdfe.measure import curvature_profile, panel_angles

R, T, B = Material.RIGID, Material.CONTRACT_TOP, Material.CONTRACT_BOTTOM
RATIO, H = 0.6947, 0.29


def _eq2(cells, pixel=0.1):
    """Eq. 2's fold of a fully contracting hinge of ``cells`` columns: (1 - R) L / h (GDFE folds a hinge between
    rigid panels to it within 0.2 % at these sizes)."""
    return (1.0 - RATIO) * cells * pixel / H


def _strip(codes, rows=3, pixel=0.1, R_=RATIO):
    """A strip along x of the material ``codes`` (one per column), ``rows`` cells wide."""
    mat = np.repeat(np.asarray(codes, int)[:, None], rows, axis=1)
    return gdfe.grid_design(mat, R_, h=H, pixel=pixel)


def _fold(codes, **kw):
    res = gdfe.simulate(_strip(codes, **kw))
    assert res.converged
    return res, panel_angles(res)


def test_a_hinge_coated_on_the_other_face_folds_the_other_way():
    _, (top,) = _fold([R] * 4 + [T] * 8 + [R] * 4)
    _, (bottom,) = _fold([R] * 4 + [B] * 8 + [R] * 4)
    assert top["angle_rad"] == pytest.approx(_eq2(8), rel=5e-3)
    assert bottom["angle_rad"] == pytest.approx(-top["angle_rad"], abs=1e-6)
    _, (a, b) = _fold([R] * 4 + [T] * 6 + [R] * 4 + [B] * 6 + [R] * 4)
    assert a["panels"] == [1, 2] and b["panels"] == [2, 3]
    assert a["angle_rad"] > 0 > b["angle_rad"] and a["angle_rad"] == pytest.approx(-b["angle_rad"], abs=1e-6)


def test_a_fold_beyond_pi_is_unwrapped():
    """A 4 mm hinge folds about 4.2 rad: the panels' rotation alone reads 2 pi - 4.2 = 2.06 rad; the
    strip's turn column by column says which."""
    res, (row,) = _fold([R] * 6 + [T] * 40 + [R] * 6, pixel=0.1)
    turn = curvature_profile(res)["turn"]
    assert turn > math.pi + 0.5
    assert row["angle_rad"] == pytest.approx(_eq2(40), rel=5e-3)
    assert row["angle_rad"] == pytest.approx(turn, abs=5e-3)  # whole panels against the columns' frames
    res, (row,) = _fold([R] * 6 + [B] * 40 + [R] * 6, pixel=0.1)
    assert row["angle_rad"] == pytest.approx(-turn, abs=5e-3)


def test_the_hinge_direction_in_the_plane_does_not_matter():
    """The same part drawn along y, and with its panels swapped end for end, folds by the same angle."""
    codes = [R] * 4 + [T] * 16 + [R] * 4
    res, (along_x,) = _fold(codes)
    mat = np.repeat(np.asarray(codes, int)[None, :], 3, axis=0)
    (along_y,) = panel_angles(gdfe.simulate(gdfe.grid_design(mat, RATIO, h=H, pixel=0.1)))
    (reversed_,) = panel_angles(gdfe.simulate(_strip(codes[::-1])))
    assert along_x["angle_rad"] == pytest.approx(_eq2(16), rel=5e-3)
    assert along_y["angle_rad"] == pytest.approx(along_x["angle_rad"], abs=1e-6)
    assert reversed_["angle_rad"] == pytest.approx(along_x["angle_rad"], abs=1e-6)
