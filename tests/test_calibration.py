"""Eq. 1-3 and their calibration."""

import math

import numpy as np
import pytest

import gdfe


def test_eq1_eq3_figure6_values():
    cal = gdfe.Calibration()
    # paper, Sec. 3.2: h = 0.29, d = 0.33 gives R = 0.7 and Eq. 1 angles 1.05, 1.68, 2.73 rad
    assert cal.ratio(0.33) == pytest.approx(0.6947, abs=5e-4)
    np.testing.assert_allclose(cal.alpha([1.0, 1.6, 2.6], 0.33), [1.05, 1.68, 2.73], atol=0.01)


def test_eq2_inverts_eq1():
    cal = gdfe.Calibration()
    L, d, h = 2.0, 0.3, 0.29
    R = gdfe.ratio_from_angle(cal.alpha(L, d, h), L, h)
    assert R == pytest.approx(cal.ratio(d, h), rel=1e-12)
    assert gdfe.angle_from_ratio(R, L, h) == pytest.approx(cal.alpha(L, d, h), rel=1e-12)


def test_thin_passive_layer_is_an_error_not_a_simulation():
    cal = gdfe.Calibration()
    assert cal.d_min() == pytest.approx(0.29 * 0.3706 ** (2 / 3))
    with pytest.raises(ValueError, match=r"d=0.11 mm gives R=-0.58.*needs d > 0.149"):
        cal.ratio(0.11)
    with pytest.raises(ValueError, match="d=0.11 mm gives R="):
        gdfe.hinge(1.0, d=0.11)


@pytest.mark.parametrize("kwargs, match", [
    (dict(K=-1.0), "K: expected a positive"),
    (dict(h=0.0), "h: expected a positive"),
    (dict(K="a"), "K: expected a positive finite number, got 'a'"),
])
def test_calibration_rejects_bad_parameters(kwargs, match):
    with pytest.raises((ValueError, TypeError), match=match):
        gdfe.Calibration(**kwargs)


def test_alpha_rejects_bad_lengths():
    with pytest.raises(ValueError, match="L: expected a positive"):
        gdfe.Calibration().alpha(-1.0, 0.3)
    with pytest.raises(ValueError, match="d: expected a positive"):
        gdfe.Calibration().alpha(1.0, 0.0)


def test_refit_table1(table1):
    fit = gdfe.Calibration.fit(table1, n_boot=500)
    tests = gdfe.load_folding_tests(table1)
    x = np.sqrt(tests.h / tests.d**3) * tests.L
    # least squares through the origin, by hand
    assert fit.K == pytest.approx((x @ tests.alpha) / (x @ x), rel=1e-12)
    assert fit.n == 18
    assert fit.K_ci[0] < fit.K < fit.K_ci[1]
    res = tests.alpha - fit.K * x
    assert fit.rmse == pytest.approx(math.sqrt((res**2).mean()))
    # the printed K = 0.3706 is NOT the least-squares K of the printed Eq. 1 on Table 1
    assert fit.K == pytest.approx(0.0608, abs=5e-4)
    assert fit.r2 == pytest.approx(0.576, abs=5e-3)


def test_fit_recovers_a_known_K():
    rng = np.random.default_rng(1)
    L = rng.uniform(1, 5, 40)
    d = rng.uniform(0.2, 0.5, 40)
    h = np.full(40, 0.29)
    alpha = 0.2 * np.sqrt(h / d**3) * L
    fit = gdfe.Calibration.fit(gdfe.FoldingTests(L=L, d=d, h=h, alpha=alpha))
    assert fit.K == pytest.approx(0.2, rel=1e-12)
    assert fit.r2 == pytest.approx(1.0)


def test_csv_errors_name_row_and_column(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("L_mm,d_mm,h_mm,alpha_rad\n1.5,0.11,0.29,1.75\n2.0,abc,0.29,1.0\n2.0,0.2,-0.29,1.0\n")
    with pytest.raises(ValueError, match=r"row 3, column d_mm: expected a number, got 'abc'.*"
                                         r"row 4, column h_mm: expected a positive"):
        gdfe.load_folding_tests(p)
    q = tmp_path / "missing.csv"
    q.write_text("L_mm,alpha_rad\n1,1\n")
    with pytest.raises(ValueError, match="missing column"):
        gdfe.load_folding_tests(q)
    with pytest.raises(FileNotFoundError, match="not found"):
        gdfe.load_folding_tests(tmp_path / "nope.csv")


def test_csv_keeps_extra_columns(tmp_path):
    p = tmp_path / "g.csv"
    p.write_text("L_mm,d_mm,h_mm,alpha_rad,group\n1.5,0.2,0.29,1.0,a\n2.0,0.3,0.29,1.1,b\n")
    t = gdfe.load_folding_tests(p)
    assert list(t.extra["group"]) == ["a", "b"]
    assert len(t) == 2
