"""Pairs of points within a distance, in parts of bounded size (:mod:`gdfe.solver.nearby`).

References: SciPy's whole searches, which the parts replace (``cKDTree.query_pairs`` and
``sparse_distance_matrix``): the parts hold every pair of them once, and no part holds more
pairs than its budget unless its query is a single point. The bound is checked against SciPy's
count (``count_neighbors``), on points placed exactly on the faces of its cubes too. And the
penetration check gives the same answer with a budget small enough to cut its searches, on a
strip rolled tightly through itself, and answers its yes-or-no test without searching every part.
"""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial import cKDTree

import gdfe
from gdfe.solver import nearby
from gdfe.solver.penetration import PenetrationCheck
from test_windows import _rolled  # a module of tests/, which pytest puts on the path


def _points(seed, n, spread, on_faces, r):
    """``n`` points: a dense cluster and a spread of others; with ``on_faces``, each coordinate a multiple of ``r / 2``."""
    rng = np.random.default_rng(seed)
    k = n // 3
    p = np.concatenate([rng.normal(0.0, 0.3 * r, (k, 3)), rng.uniform(-spread, spread, (n - k, 3))])
    if on_faces:
        p = np.round(p / (0.5 * r)) * (0.5 * r)
    return p


cases = dict(seed=st.integers(0, 10_000), n=st.integers(1, 120), m=st.integers(1, 90),
             spread=st.floats(0.1, 20.0), on_faces=st.booleans(), r=st.floats(0.05, 3.0))


def _pair_set(i, j):
    return set(zip(i.tolist(), j.tolist()))


@given(shift=st.floats(-30.0, 30.0), **cases)
def test_the_bound_is_at_least_scipy_count(shift, seed, n, m, spread, on_faces, r):
    """Of every point, the query points inside or outside the other tree's cubes, the cubes
    within reach or all 27; and of a :class:`Tree` that keeps its grid for a search at 0.6 of
    the distance."""
    a = _points(seed, n, spread, on_faces, r)
    b = _points(seed + 1, m, spread, on_faces, r) + [shift, 0.0, 0.0]
    ta, tb = cKDTree(a), cKDTree(b)
    each = np.array([len(x) for x in tb.query_ball_point(a, r)])
    quick, fine = nearby.point_bounds(ta, tb, r), nearby.point_bounds(ta, tb, r, fine=True)
    assert np.all(quick >= fine) and np.all(fine >= each)
    assert np.all(nearby.point_bounds(ta, ta, r) >= [len(x) for x in ta.query_ball_point(a, r)])
    kept = nearby.Tree(b)
    assert np.all(nearby.point_bounds(ta, kept, r) >= each)
    assert np.all(nearby.point_bounds(ta, kept, 0.6 * r, fine=True) >= [len(x) for x in tb.query_ball_point(a, 0.6 * r)])
    grid = kept.grid(r)
    assert nearby.point_bounds(ta, kept, 0.6 * r).sum() >= ta.count_neighbors(tb, 0.6 * r)
    assert kept.grid(r) is grid and grid.side >= r
    own = nearby.Tree(b, radius=r)  # a grid of cubes of the search's own distance
    assert own.grid(r).side == r and np.all(nearby.point_bounds(ta, own, r, fine=True) >= each)


def _parts_checked(parts, budget):
    """The parts, each checked against the budget (a part of one query point may hold more)."""
    out = list(parts)
    for i, _ in out:
        assert i.size <= budget or np.unique(i).size == 1
    return out


@given(budget=st.integers(1, 300), **cases)
def test_between_holds_every_pair_once(budget, seed, n, m, spread, on_faces, r):
    a = _points(seed, n, spread, on_faces, r)
    b = _points(seed + 1, m, spread, on_faces, r)
    ta, tb = cKDTree(a), cKDTree(b)
    parts = _parts_checked(nearby.between(ta, tb, r, budget), budget)
    i = np.concatenate([p[0] for p in parts])
    j = np.concatenate([p[1] for p in parts])
    whole = ta.sparse_distance_matrix(tb, r, output_type="ndarray")
    assert i.size == whole.size and _pair_set(i, j) == _pair_set(whole["i"], whole["j"])
    starts = [p[0].min() for p in parts if p[0].size]
    assert starts == sorted(starts)  # in the order of the query points


@given(budget=st.integers(1, 300), **cases)
def test_within_holds_every_pair_once(budget, seed, n, m, spread, on_faces, r):
    a = _points(seed, n, spread, on_faces, r)
    t = cKDTree(a)
    parts = _parts_checked(nearby.within(t, r, budget), budget)
    i = np.concatenate([p[0] for p in parts])
    j = np.concatenate([p[1] for p in parts])
    whole = t.query_pairs(r, output_type="ndarray")
    assert np.all(i < j)
    assert i.size == len(whole) and _pair_set(i, j) == _pair_set(whole[:, 0], whole[:, 1])


def test_a_distance_too_small_for_the_cubes_is_counted_instead():
    """Cubes of 1e-9 over 10^6 on each axis cannot be numbered: the bound is infinite, the parts still whole."""
    rng = np.random.default_rng(0)
    a = np.concatenate([np.zeros((40, 3)), rng.uniform(-1e6, 1e6, (40, 3))])
    t = cKDTree(a)
    assert nearby.point_bounds(t, t, 1e-9) is None
    parts = _parts_checked(nearby.within(t, 1e-9, budget=100), 100)
    assert len(parts) > 1 and sum(p[0].size for p in parts) == 40 * 39 // 2


def test_a_film_search_is_made_whole():
    """Few pairs a point, under the budget: one part, SciPy's own search."""
    des = gdfe.from_rows(["R" * 20] * 20, R=1.0, h=gdfe.paper.H, pixel=0.1, nz=1)
    t = cKDTree(des.mesh.points)
    assert len(list(nearby.within(t, 0.15))) == 1
    assert len(list(nearby.between(t, t, 0.15))) == 1


def _spy(monkeypatch, budget):
    """Set the budget and keep the size of every part the searches make."""
    monkeypatch.setattr(nearby, "PAIR_BUDGET", budget)
    sizes = []
    for name in ("between", "within"):
        search = getattr(nearby, name)

        def spied(*args, _search=search, **kw):
            for i, j in _search(*args, **kw):
                assert i.size <= budget or np.unique(i).size == 1
                sizes.append(i.size)
                yield i, j
        monkeypatch.setattr(nearby, name, spied)
    return sizes


@pytest.mark.parametrize("turns, gap", [(1.6, -0.05), (3.0, -0.08), (0.8, 0.02)])
def test_the_check_is_the_same_with_its_searches_cut(monkeypatch, turns, gap):
    """Crossings, cells, depth and gap, and the yes-or-no test, as with the whole searches."""
    des, X = _rolled(turns, gap, seed=2)
    check = PenetrationCheck(des)
    whole, crosses = check(X), check.crosses(X)
    sizes = _spy(monkeypatch, 500)
    assert check(X) == whole
    assert check.crosses(X) == crosses == whole.found
    assert len(sizes) > 10  # cut: of 500 pairs, every one of these checks has more than 10 parts


def test_a_strip_rolled_many_times_through_itself_is_answered_from_its_first_parts(monkeypatch):
    """Ten turns 0.6 of a thickness into each other: every triangle within reach of the turns about it.

    The yes-or-no test ends at the first part with a crossing; the whole check searches every part.
    """
    des, X = _rolled(10.0, -0.6 * gdfe.paper.H, cells=300, width=2)
    check = PenetrationCheck(des)
    sizes = _spy(monkeypatch, 20_000)
    assert check.crosses(X)
    first = len(sizes)
    sizes.clear()
    p = check(X)
    assert p.found and p.intersecting_pairs > 100  # 180 crossing pairs, 1 200 cells, 0.1 mm deep when written
    assert 5 * first < len(sizes)  # 2 parts against 263 when written
