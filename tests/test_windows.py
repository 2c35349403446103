"""The crossing test's broad phase: windows of the print where a shape is provably embedded.

References: the criterion's proof (:mod:`gdfe.solver.windows`): a rigid motion of the flat
print keeps every full window good, a fold inside a window makes it not good, and the check
gives the same answer, crossings, depth and gap, with the windows as without them (where
none is good, every pair is tested as before), on shapes that cross themselves and on
shapes that do not.
"""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial import cKDTree

import gdfe
import gdfe.solver.windows as windows
from gdfe.solver import nearby
from gdfe.solver.penetration import PenetrationCheck
from gdfe.solver.windows import EmbeddedWindows

H = gdfe.paper.H


def _good(check, X):
    T = X[check.tris]
    return check.windows.good(X, T.min(axis=1), T.max(axis=1))[0]


def _without_windows(monkeypatch, check, X):
    """The check's answer with no window good: every candidate pair tested."""
    with monkeypatch.context() as m:
        m.setattr(windows, "GOOD_MARGIN", 0.0)
        assert not _good(check, X).any()
        return check(X)


def _rotation(seed):
    Q, _ = np.linalg.qr(np.random.default_rng(seed).standard_normal((3, 3)))
    return Q * np.sign(np.linalg.det(Q))


def test_a_rigid_motion_of_the_print_keeps_every_full_window_good():
    """12 x 12 cells in blocks of 4: 3 x 3 blocks, 16 windows a face, each a rectangle of 1 to 4 blocks."""
    des = gdfe.from_rows(["R" * 12] * 12, R=1.0, h=H, pixel=0.1, nz=2)
    check = PenetrationCheck(des)
    w = check.windows
    assert w.n_blocks == 2 * 9  # top and bottom faces; the sides are in no block
    assert len(w.full) == 2 * 16 and w.full.all()
    X = des.mesh.points @ _rotation(0).T + [3.0, -1.0, 2.0]
    assert np.array_equal(_good(check, X), w.full)
    # blocks of the other face, or two blocks apart, are never covered, however good the windows
    good = np.ones(len(w.full), bool)
    top = w.block[w.block >= 0]
    same_face = w._plane[top[:, None]] == w._plane[top[None, :]]
    far = np.abs(w._bxy[top][:, None, :] - w._bxy[top][None, :, :]).max(axis=2) > 1
    p, q = np.meshgrid(top, top, indexing="ij")
    covered = w.covered(good, p.ravel(), q.ravel()).reshape(p.shape)
    assert not covered[~same_face | far].any() and covered[same_face & ~far].all()


def test_a_window_of_three_blocks_is_not_a_rectangle():
    """8 x 8 cells less a 4 x 4 corner: the window over all four blocks holds three, an L, not convex."""
    rows = ["RRRR...." if k < 4 else "RRRRRRRR" for k in range(8)]
    w = PenetrationCheck(gdfe.from_rows(rows, R=1.0, h=H, pixel=0.1, nz=1)).windows
    assert w.n_blocks == 2 * 3
    middle = np.all(w._wxy == 0, axis=1)
    assert middle.sum() == 2 and not w.full[middle].any() and w.full[~middle].all()


def test_a_surface_cut_along_an_edge_proves_nothing():
    """Two vertices at one place of the print (a cut): the shape may jump across it, which the
    gradients do not see, so no window is good. The same mesh without the cut has every one full."""
    des = gdfe.from_rows(["R" * 12] * 12, R=1.0, h=H, pixel=0.1, nz=1)
    tris = PenetrationCheck(des).tris.copy()
    assert EmbeddedWindows(des.mesh.points, tris).full.all()
    points = np.vstack([des.mesh.points, des.mesh.points[:1]])  # vertex 0 again, as vertex n
    k = np.nonzero((tris == 0).any(axis=1))[0][0]  # a triangle at vertex 0 takes the copy
    tris[k][tris[k] == 0] = len(points) - 1
    assert not EmbeddedWindows(points, tris).full.any()


def _folded(angle, cells=16, fold_at=6, pixel=0.1, width=8):
    """A strip folded by ``angle`` about the line across it ``fold_at`` cells along, at mid-thickness."""
    des = gdfe.from_rows(["R" * cells] * width, R=1.0, h=H, pixel=pixel, nz=2)
    X = des.mesh.points.copy()
    x0, z0 = fold_at * pixel, H / 2
    b = X[:, 0] > x0 + 1e-9
    c, s = math.cos(angle), math.sin(angle)
    dx, dz = X[b, 0] - x0, X[b, 2] - z0
    X[b, 0], X[b, 2] = x0 + c * dx - s * dz, z0 + s * dx + c * dz
    return des, X


@pytest.mark.parametrize("angle", [math.radians(200), math.radians(260)])
def test_a_fold_through_itself_inside_a_window_is_found_as_without_windows(monkeypatch, angle):
    """Folded past 180 degrees 6 cells along, inside the windows over cells 4-11: they are not good."""
    des, X = _folded(angle)
    check = PenetrationCheck(des)
    w = check.windows
    good = _good(check, X)
    across = w._wxy[:, 0] == 1  # the windows of blocks 1 and 2 along the strip: cells 4-11
    assert w.full[across].any() and not good[across].any()
    assert good[w.full & ~across].any()  # the flat ends still are
    p = check(X)
    assert p.found and p.intersecting_pairs > 0
    assert p == _without_windows(monkeypatch, check, X)


def test_a_fold_short_of_itself_is_found_clear_as_without_windows(monkeypatch):
    """Folded by 60 degrees the strip is embedded: no crossing, and the same answer with no window good."""
    des, X = _folded(math.radians(60))
    check = PenetrationCheck(des)
    p = check(X)
    assert not p.found and p.intersecting_pairs == 0
    assert _good(check, X).any()
    assert p == _without_windows(monkeypatch, check, X)


def _rolled(turns, gap, cells=48, pixel=0.1, width=4, seed=0):
    """A strip rolled ``turns`` times with its turns ``gap`` apart (negative: inside each other), moved rigidly."""
    des = gdfe.from_rows(["R" * cells] * width, R=1.0, h=H, pixel=pixel, nz=2)
    X = des.mesh.points
    length = cells * pixel
    theta = X[:, 0] / length * 2 * math.pi * turns
    rho0 = length / (2 * math.pi * turns)
    rho = rho0 - (H + gap) * theta / (2 * math.pi) + (X[:, 2] - H / 2)
    Y = np.column_stack([rho * np.cos(theta), X[:, 1], -rho * np.sin(theta)])
    return des, Y @ _rotation(seed).T + [1.0, 2.0, -0.5]


@given(turns=st.floats(0.3, 1.6), gap=st.floats(-0.08, 0.06), seed=st.integers(0, 50))
def test_rolled_strips_get_the_same_answer_with_and_without_windows(turns, gap, seed):
    """Embedded or through themselves: windows change what is tested, never the answer."""
    des, X = _rolled(turns, gap, seed=seed)
    check = PenetrationCheck(des)
    with_windows = check(X)
    saved = windows.GOOD_MARGIN
    windows.GOOD_MARGIN = 0.0  # hypothesis runs examples in one test call: no fixture between them
    try:
        without = check(X)
    finally:
        windows.GOOD_MARGIN = saved
    assert with_windows == without
    if turns > 1.05 and gap < -0.01:  # the second turn lies in the first
        assert with_windows.found


def test_a_tight_roll_crosses_itself_where_its_windows_are_good(monkeypatch):
    """1.6 turns 0.05 mm into each other: crossings found, most windows good, the answer as without them."""
    des, X = _rolled(1.6, -0.05)
    check = PenetrationCheck(des)
    good = _good(check, X)
    assert 0.5 * good.size < good.sum() < good.size
    p = check(X)
    assert p.intersecting_pairs > 0 and p.depth_mm == pytest.approx(0.05, rel=1e-3)
    assert p == _without_windows(monkeypatch, check, X)


def test_the_9mm_hinge_overlap_is_found_as_without_windows(monkeypatch):
    """The hinge's second turn lies in its first: the same crossings, cells and depth; the flat panels' windows good."""
    res = gdfe.simulate(gdfe.hinge(9.0, d=0.33), contact="off")
    check = PenetrationCheck(res.design)
    good = _good(check, res.points)
    assert good.any() and not good.all()
    p = check(res.points)
    assert p.found and p.intersecting_pairs > 100
    assert p == _without_windows(monkeypatch, check, res.points)


def test_a_check_with_every_triangle_proved_apart_finds_nothing(monkeypatch):
    """No triangle left to the crossing test (none involved): an answer, not an empty concatenation."""
    des = gdfe.from_rows(["R" * 8] * 8, R=1.0, h=H, pixel=0.1, nz=1)
    monkeypatch.setattr(EmbeddedWindows, "involved", lambda self, *args: np.zeros(len(self.tris), bool))
    p = PenetrationCheck(des)(des.mesh.points)
    assert not p.found and p.intersecting_pairs == 0


def test_a_design_with_no_face_in_a_plane_of_the_print_has_no_blocks():
    """Triangles standing on edge in the print (no up or down face) are all tested."""
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1]])
    w = EmbeddedWindows(pts, np.array([[0, 1, 2], [1, 3, 2]]))
    assert w.n_blocks == 0 and (w.block == -1).all()
    good, boxes = w.good(pts, pts[:2], pts[2:])
    assert good.size == 0 and w.involved(good, boxes, pts[:2], pts[2:]).all()


def _involved_by_every_pair(w, good, boxes, lo, hi):
    """The definition of :meth:`EmbeddedWindows.involved`: every pair of boxes whose centres are
    within the largest diameter, searched at once; those that overlap and share no good window."""
    loose = np.nonzero(w.block < 0)[0]
    plo, phi = np.concatenate([boxes[0], lo[loose]]), np.concatenate([boxes[1], hi[loose]])
    blocks = np.concatenate([np.arange(w.n_blocks), np.full(loose.size, -1)])
    centre, half = 0.5 * (plo + phi), 0.5 * np.linalg.norm(phi - plo, axis=1)
    i, j = cKDTree(centre).query_pairs(2.0 * half.max(), output_type="ndarray").T
    near = np.all((plo[i] <= phi[j]) & (plo[j] <= phi[i]), axis=1) & ~w.covered(good, blocks[i], blocks[j])
    hit = np.zeros(len(plo), bool)
    hit[i[near]] = hit[j[near]] = True
    hit[:w.n_blocks] |= ~good[w._win].any(axis=1)
    hit[w.n_blocks:] = True
    out = np.ones(len(w.block), bool)  # a triangle in no block is always involved
    out[w.block >= 0] = hit[w.block[w.block >= 0]]
    return out


def _involved_both_ways(des, X, budget):
    """The involved triangles of the shape ``X``, searched in parts of ``budget`` pairs, and by every pair."""
    check = PenetrationCheck(des)
    T = X[check.tris]
    lo, hi = T.min(axis=1), T.max(axis=1)
    good, boxes = check.windows.good(X, lo, hi)
    saved = nearby.PAIR_BUDGET
    nearby.PAIR_BUDGET = budget  # hypothesis runs examples in one test call: no fixture between them
    try:
        got = check.windows.involved(good, boxes, lo, hi)
    finally:
        nearby.PAIR_BUDGET = saved
    return got, _involved_by_every_pair(check.windows, good, boxes, lo, hi), check.windows.block >= 0


@given(turns=st.floats(0.3, 3.0), gap=st.floats(-0.2, 0.06), seed=st.integers(0, 50), budget=st.sampled_from([50, 10**9]))
def test_the_involved_triangles_are_those_every_pair_gives(turns, gap, seed, budget):
    """Searched among the blocks not yet involved, in parts (of 50 pairs, or whole): the same triangles."""
    des, X = _rolled(turns, gap, width=12, seed=seed)  # windows of 8 pixels across the strip
    got, want, in_block = _involved_both_ways(des, X, budget)
    assert np.array_equal(got, want)


@pytest.mark.parametrize("budget", [50, 10**9])
def test_a_flat_strip_leaves_blocks_out_as_every_pair_does(budget):
    """The print itself: the faces' boxes apart across the thickness, the middle's blocks left out
    (those at the strip's edges are in windows that are not rectangles)."""
    des = gdfe.from_rows(["R" * 48] * 12, R=1.0, h=H, pixel=0.1, nz=2)
    got, want, in_block = _involved_both_ways(des, des.mesh.points, budget)
    assert np.array_equal(got, want)
    assert 0 < got[in_block].sum() < in_block.sum()
