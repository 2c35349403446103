"""Tests of gdfe.inverse: couples, patterns, quantisation, segmentation, curve comparison."""

import itertools
import math

import numpy as np
import pytest

import gdfe
from gdfe import inverse as inv

H = 0.29


# -- couples and curves -----------------------------------------------------------------------

def test_couple_angle_and_straight():
    c = inv.Couple(3.0, 2.0)
    assert c.angle == pytest.approx(1.5)
    assert inv.Couple(3.0, 0.0).angle == 0.0
    assert inv.Couple(3.0, math.inf).curvature == 0.0
    assert inv.Couple(3.0, -2.0).angle == pytest.approx(-1.5)


@pytest.mark.parametrize("L", [0.0, -1.0, math.nan])
def test_couple_rejects_non_positive_length(L):
    with pytest.raises(ValueError, match="positive segment length"):
        inv.Couple(L, 1.0)
    with pytest.raises(ValueError, match=r"couples\[1\]: L"):
        inv.as_couples([(1.0, 0.0), (L, 1.0)])


def test_as_couples_rejects_empty_and_malformed():
    with pytest.raises(ValueError, match="at least one"):
        inv.as_couples([])
    with pytest.raises(TypeError, match="pair"):
        inv.as_couples([(1.0, 2.0, 3.0)])


def test_full_circle_closes_and_has_the_right_radius():
    r = 3.0
    P, s = inv.arc_points([(2 * math.pi * r, r)], ds=0.01)
    assert np.linalg.norm(P[-1] - P[0]) < 1e-9
    centre = np.array([0.0, r])  # anticlockwise from heading +u: centre on the left
    assert np.allclose(np.linalg.norm(P - centre, axis=1), r, atol=1e-9)
    assert s[-1] == pytest.approx(2 * math.pi * r)


def test_clockwise_arc_turns_right_and_chain_is_tangent_continuous():
    P, _ = inv.arc_points([(2 * math.pi, -2.0), (1.0, 0.0)], ds=0.01)
    # half circle clockwise of radius 2 from heading +u ends 4 mm below, heading -u
    end_arc = inv.arc_points([(2 * math.pi, -2.0)], s=[2 * math.pi])[0][0]
    assert np.allclose(end_arc, [0.0, -4.0], atol=1e-12)
    assert np.allclose(P[-1], [-1.0, -4.0], atol=1e-12)


def test_turns_rotate_the_rest_of_the_curve():
    P, _ = inv.arc_points([(1.0, 0.0), (1.0, 0.0)], ds=0.5, turns=[0.0, math.pi / 2])
    assert np.allclose(P[-1], [1.0, 1.0], atol=1e-12)


def test_contracting_length_and_max_curvature():
    assert inv.contracting_length(math.pi, h=H, R=0.7) == pytest.approx(math.pi * H / 0.3)
    assert inv.max_curvature(H, 0.7) == pytest.approx(0.3 / H)


@pytest.mark.parametrize("R", [0.0, 1.0, -0.2, 1.3])
def test_ratio_outside_open_interval_is_rejected(R):
    with pytest.raises(ValueError, match="strictly between 0 and 1"):
        inv.strip_pattern([(5.0, 5.0)], R=R)
    with pytest.raises(ValueError, match="strictly between 0 and 1"):
        inv.contracting_length(1.0, R=R)


# -- patterns -------------------------------------------------------------------------------

def test_pattern_contracting_length_is_spread_uniformly():
    R, cell = 0.7, 0.1
    pat = inv.strip_pattern([(2 * math.pi * 5, 5.0)], h=H, R=R, cell=cell)
    n_c = int(math.floor(2 * math.pi * H / (1 - R) / cell + 0.5))
    assert (pat.material == gdfe.Material.CONTRACT_TOP).sum() == n_c
    pos = np.nonzero(pat.material)[0]
    gaps = np.diff(pos)
    assert gaps.max() - gaps.min() <= 1  # uniform to within one cell
    assert pat.angle_printed[0] == pytest.approx(n_c * cell * (1 - R) / H)


def test_pattern_sign_maps_to_faces():
    pat = inv.strip_pattern([(3.0, 2.0), (2.0, 0.0), (3.0, -2.0)], R=0.7, cell=0.1)
    seg = pat.segment
    assert set(pat.material[seg == 0]) == {int(gdfe.Material.RIGID), int(gdfe.Material.CONTRACT_TOP)}
    assert set(pat.material[seg == 1]) == {int(gdfe.Material.RIGID)}
    assert set(pat.material[seg == 2]) == {int(gdfe.Material.RIGID), int(gdfe.Material.CONTRACT_BOTTOM)}
    assert pat.rows().count("T") == pat.rows().count("B")


@pytest.mark.parametrize("w_min", [0.25, 0.5, 1.0, 2.0])
def test_quantised_blocks_are_whole_multiples_of_w_min(w_min):
    R = 0.8
    pat = inv.strip_pattern([(2 * math.pi * 5, 5.0)], h=H, R=R, w_min=w_min)
    L_c = 2 * math.pi * H / (1 - R)
    assert pat.blocks[0] == int(math.floor(L_c / w_min + 0.5))
    assert pat.L_c_printed[0] == pytest.approx(pat.blocks[0] * w_min)
    m = pat.material != 0
    runs = np.diff(np.r_[0, m.astype(int), 0])
    lengths = (np.nonzero(runs == -1)[0] - np.nonzero(runs == 1)[0]) * pat.cell
    assert np.allclose(np.round(lengths / w_min) * w_min, lengths)


def test_rounding_modes():
    kw = dict(h=H, R=0.8, w_min=2.0)
    circle = [(2 * math.pi * 5, 5.0)]  # L_c / w_min = 4.55
    assert inv.strip_pattern(circle, rounding="nearest", **kw).blocks[0] == 5
    assert inv.strip_pattern(circle, rounding="floor", **kw).blocks[0] == 4
    assert inv.strip_pattern(circle, rounding="ceil", **kw).blocks[0] == 5
    with pytest.raises(ValueError, match="rounding: expected one of 'nearest', 'floor', 'ceil', 'carry', got 'up'"):
        inv.strip_pattern(circle, rounding="up", **kw)


def test_carry_rounding_keeps_the_accumulated_turn():
    # many short couples each needing less than half a cell of contraction
    couples = [(0.5, 20.0)] * 20
    near = inv.strip_pattern(couples, h=H, R=0.7, cell=0.25, rounding="nearest")
    carry = inv.strip_pattern(couples, h=H, R=0.7, cell=0.25, rounding="carry")
    target = sum(c.angle for c in inv.as_couples(couples))
    step = 0.25 * 0.3 / H
    assert near.angle_printed.sum() == 0.0
    assert abs(carry.angle_printed.sum() - target) <= step / 2 + 1e-12


@pytest.mark.parametrize("w_min", [0.0, -1.0, math.nan])
def test_w_min_must_be_positive(w_min):
    with pytest.raises(ValueError, match="w_min: expected a positive printer resolution"):
        inv.strip_pattern([(5.0, 5.0)], w_min=w_min)


def test_w_min_must_be_whole_cells():
    with pytest.raises(ValueError, match="whole number of cells"):
        inv.strip_pattern([(5.0, 5.0)], w_min=0.3, cell=0.25)


def test_too_tight_couple_raises_unless_clamped():
    with pytest.raises(ValueError, match=r"couples\[0\]: radius 0.5 mm .* h/\(1-R\) = 0.9667"):
        inv.strip_pattern([(1.0, 0.5)], h=H, R=0.7, cell=0.1)
    pat = inv.strip_pattern([(1.0, 0.5)], h=H, R=0.7, cell=0.1, clamp=True)
    assert pat.clamped[0] and (pat.material != 0).all()


def test_with_hinges_inserts_maximum_curvature_couples():
    out = inv.with_hinges([(2.0, 0.0), (2.0, 0.0)], [0.3, -0.5], h=H, R=0.7)
    assert len(out) == 3  # the first turn only rotates the curve
    assert out[1].angle == pytest.approx(-0.5)
    assert abs(out[1].r) == pytest.approx(H / 0.3)


def test_design_regions_cover_the_strip():
    pat = inv.strip_pattern([(2.0, 0.0), (3.0, 4.0)], R=0.7, cell=0.25)
    des = pat.design(width=0.5, ny=2)
    assert des.n_cells == pat.material.size * 2
    assert sum(len(v) for v in des.regions.values()) == des.n_cells


# -- simulation of strips ---------------------------------------------------------------------

def test_bent_start_of_a_flat_strip_is_the_print():
    pat = inv.strip_pattern([(3.0, 0.0)], R=0.7, cell=0.25)
    des = pat.design()
    assert np.allclose(inv.bent_start(des), des.mesh.points)


def test_simulated_circle_turns_by_its_printed_angle_and_matches_the_target():
    R = 0.8
    couples = [(2 * math.pi * 4, 4.0)]
    pat = inv.strip_pattern(couples, h=H, R=R, cell=0.25)
    res = inv.simulate_strip(pat.design()).check()
    turn = gdfe.curvature_profile(res)["turn"]
    # each contracting cell turns a little less than Eq. 2 says; within 2 % here
    assert turn == pytest.approx(pat.angle_printed[0], rel=0.02)
    s, uv, off = inv.strip_midline(res)
    assert off < 1e-8
    target, s_t = inv.arc_points(couples, ds=0.02)
    cmp = inv.compare_curves(uv, target, s=s, s_target=s_t)
    assert cmp["max"] < 0.5, f"deviation {cmp['max']:.3f} mm"


def test_simulate_strip_agrees_with_simulate():
    des = inv.strip_pattern([(3.0, 3.0)], h=H, R=0.7, cell=0.25).design()
    a = inv.simulate_strip(des).check()
    b = gdfe.simulate(des).check()
    # same fixed point, up to a rigid motion (the two starts hold the pinned cell differently)
    assert gdfe.shape_distance(a.points, b.points)["max"] < 1e-5


# -- curve comparison ---------------------------------------------------------------------

def test_compare_curves_is_invariant_to_rigid_motion_but_not_to_mirroring():
    P, _ = inv.arc_points([(3.0, 0.0), (4.0, 2.0), (2.0, -1.5)], ds=0.05)
    th = 0.7
    Q = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    moved = P @ Q.T + [3.0, -1.0]
    assert inv.compare_curves(moved, P)["max"] < 1e-6
    mirrored = P * [1.0, -1.0]
    assert inv.compare_curves(mirrored, P)["max"] > 0.5


# -- segmentation ---------------------------------------------------------------------------

def test_tangent_graph_of_a_circle_is_a_line_of_slope_one_over_r():
    r = 2.5
    P, _ = inv.arc_points([(1.5 * math.pi * r, r)], ds=0.1)
    s, tau = inv.tangent_graph(P)
    slope = np.polyfit(s[1:-1], tau[1:-1], 1)[0]
    assert slope == pytest.approx(1 / r, rel=1e-3)
    assert np.all(np.diff(tau) > 0)  # unwrapped


@pytest.mark.parametrize("pts", [[[0, 0]], [[0, 0], [1, 0]]])
def test_sketch_needs_three_points(pts):
    with pytest.raises(ValueError, match="at least 3 points, got"):
        inv.tangent_graph(pts)
    with pytest.raises(ValueError, match="at least 3 points"):
        inv.fit_sketch(pts, 0.1)


def test_sketch_rejects_repeated_points_and_bad_penalty():
    with pytest.raises(ValueError, match="consecutive points 1 and 2 coincide"):
        inv.tangent_graph([[0, 0], [1, 0], [1, 0], [2, 1]])
    with pytest.raises(ValueError, match="penalty: expected a non-negative number, got -1"):
        inv.fit_segments(np.arange(5.0), np.zeros(5), -1.0)


def _brute_force(s, tau, penalty, min_points):
    n = len(s)
    C = inv.segment_cost_matrix(s, tau)
    best = (math.inf, None)
    for k in range(n):
        for cuts in itertools.combinations(range(1, n), k):
            b = (0,) + cuts + (n,)
            if min(np.diff(b)) < min_points:
                continue
            F = sum(C[b[i], b[i + 1]] for i in range(len(b) - 1)) + penalty * (len(b) - 1)
            if F < best[0] - 1e-12:
                best = (F, b)
    return best


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("min_points", [1, 2])
def test_dynamic_programming_matches_brute_force(seed, min_points):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 11))
    s = np.cumsum(rng.uniform(0.2, 1.0, n))
    tau = np.cumsum(rng.normal(0, 0.6, n))
    penalty = float(rng.choice([0.01, 0.1, 0.5, 2.0]))
    seg = inv.fit_segments(s, tau, penalty, min_points=min_points)
    F, cuts = _brute_force(s, tau, penalty, min_points)
    assert seg.cost == pytest.approx(F, abs=1e-9)
    assert tuple(np.r_[seg.start, seg.stop[-1]]) == cuts


def test_segment_cost_matrix_matches_direct_fits():
    rng = np.random.default_rng(3)
    s = np.cumsum(rng.uniform(0.1, 1, 12))
    tau = rng.normal(size=12)
    C = inv.segment_cost_matrix(s, tau)
    for a, b in [(0, 12), (2, 7), (5, 6), (3, 5)]:
        r = tau[a:b] - np.polyval(np.polyfit(s[a:b], tau[a:b], 1), s[a:b]) if b - a > 1 else np.zeros(1)
        assert C[a, b] == pytest.approx(float(r @ r), abs=1e-10)


def test_fit_sketch_recovers_the_couples_of_a_two_arc_curve():
    couples = [(6.0, 3.0), (5.0, -2.0)]
    P, _ = inv.arc_points(couples, ds=0.1, heading=0.3)
    fit = inv.fit_sketch(P, penalty=0.05)
    assert fit.segmentation.m == 2
    assert fit.couples[0].r == pytest.approx(3.0, rel=0.05)
    assert fit.couples[1].r == pytest.approx(-2.0, rel=0.05)
    assert sum(c.L for c in fit.couples) == pytest.approx(11.0, rel=0.01)
    assert inv.compare_curves(fit.curve(), P)["max"] < 0.1


def test_more_penalty_never_gives_more_segments():
    rng = np.random.default_rng(1)
    P = np.cumsum(rng.normal(size=(30, 2)), axis=0)
    ms = [inv.fit_sketch(P, pen).segmentation.m for pen in (0.01, 0.1, 1.0, 10.0)]
    assert ms == sorted(ms, reverse=True)


def test_closest_on_polyline_by_hand():
    poly = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    d, c = inv.closest_on_polyline([[1.0, 1.0], [3.0, 3.0], [-1.0, 0.0]], poly)
    np.testing.assert_allclose(d, [1.0, math.sqrt(2.0), 1.0])
    np.testing.assert_allclose(c, [[1.0, 0.0], [2.0, 2.0], [0.0, 0.0]], atol=1e-15)


@pytest.mark.parametrize("call, match", [
    (lambda: inv.compare_curves(np.zeros((3, 3)), np.zeros((4, 2))),
     r"points: expected an array of shape \(n, 2\), got shape \(3, 3\)"),
    (lambda: inv.align_2d(np.zeros((3, 2)), np.zeros((4, 2))),
     r"target: expected an array of shape \(3, 2\), got shape \(4, 2\)"),
    (lambda: inv.with_hinges([(1.0, 0.0), (1.0, 0.0)], [0.0]),
     r"turns: expected an array of shape \(2,\), got shape \(1,\)"),
    (lambda: inv.fit_segments(np.arange(5.0), np.zeros(4), 0.1),
     r"tau: expected an array of shape \(5,\), got shape \(4,\)"),
    (lambda: inv.fit_sketch([[0, 0], [1, 0], [2, 1]], 0.1, weights="area"),
     "weights: expected None, 'length' or an array, got 'area'"),
])
def test_shape_and_choice_checks_name_the_argument(call, match):
    from gdfe._validation import GdfeError

    with pytest.raises(GdfeError, match=match):
        call()


def test_every_public_name_resolves():
    assert all(hasattr(inv, name) for name in inv.__all__)
