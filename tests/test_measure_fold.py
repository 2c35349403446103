"""Fold angles measured on the panels' outer parts (``gdfe.fold_angle(..., panel_fraction=...)``)."""

import numpy as np
import pytest

import gdfe


def _trapezoid_fan(R, L, h, n):
    """Exact fold of n isosceles trapezoids (sides l, R l, height h): they tile a fan."""
    return 2 * n * np.arctan((1 - R) * L / (2 * n * h))


def test_outer_panel_frames_give_the_exact_fan_of_a_uniaxial_hinge():
    des = gdfe.hinge(1.0, R=0.7, isotropy=0.0, cell_size=0.125, width=0.25)
    res = gdfe.simulate(des, tol=1e-10).check()
    exact = _trapezoid_fan(0.7, 1.0, des.h, 8)
    for fraction in (0.25, 0.5, 1.0):
        assert gdfe.fold_angle(res, panel_fraction=fraction) == pytest.approx(exact, abs=1e-6)


def test_outer_measure_keeps_sign_and_unwraps_beyond_pi():
    des = gdfe.hinge(4.0, d=0.33, cell_size=0.25, width=0.5)
    res = gdfe.simulate(des).check()
    a = gdfe.fold_angle(res, panel_fraction=0.5)
    assert a > np.pi  # a fold beyond pi is not wrapped
    assert a == pytest.approx(gdfe.fold_angle(res), abs=0.02)  # close to the columns' measure
    assert gdfe.fold_angle(res, a="panel_b", b="panel_a", panel_fraction=0.5) == pytest.approx(-a, abs=1e-12)


@pytest.mark.parametrize("bad", [0.0, 1.5, -0.2, float("nan")])
def test_bad_panel_fraction(bad):
    res = gdfe.simulate(gdfe.hinge(1.0, d=0.33, cell_size=0.25, width=0.5)).check()
    with pytest.raises(ValueError, match=r"panel_fraction: expected a number in \(0, 1\], got"):
        gdfe.fold_angle(res, panel_fraction=bad)


@pytest.mark.slow
def test_outer_measure_converges_faster_on_the_isotropic_hinge():
    # hinge L = 1.6 mm, 1 mm wide: the panel columns next to the hinge warp with it, and the
    # fold measured there converges at a falling order; the outer frames keep it (measured
    # 1.64 / 1.76 against 1.60 / 1.40 for 8-16-32-64 cells across the hinge)
    cols, outer = [], []
    for n in (8, 16, 32, 64):
        res = gdfe.simulate(gdfe.hinge(1.6, d=0.33, width=1.0, panel_length=0.5, cell_size=1.6 / n),
                            tol=1e-9).check()
        cols.append(gdfe.fold_angle(res))
        outer.append(gdfe.fold_angle(res, panel_fraction=0.5))

    def orders(a):
        d = np.abs(np.diff(a))
        return np.log2(d[:-1] / d[1:])
    o_cols, o_outer = orders(cols), orders(outer)
    assert o_outer[-1] > 1.6, f"outer frames: observed orders {o_outer}"
    assert o_outer[-1] > o_cols[-1] + 0.2, f"outer {o_outer}, columns {o_cols}"
