"""Self-contact and the penetration check (issue 13).

References: hand-computed geometry (a plate laid into another by a known depth, a known gap,
segment-triangle and closest-point cases), the barrier's closed form ``b(d)`` (the contact
energy is an integer number of pairs times ``kappa b(d)`` for two parallel plates),
invariants (rigid motions, energy never increasing, no trial shape ever crossing itself),
the contact-free path unchanged (bit-identical), ``contact="auto"`` equal to ``"on"`` where the
film meets itself, the barrier from a step's candidates equal to one built anew, and the IPC
Toolkit's own intersection test.
"""

import json
import math
import sys

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.solver.contact import CCD_TIGHT_INCLUSION, Contact, barrier, contact_patches, default_dhat, require_ipctk
from gdfe.solver.penetration import (PenetrationCheck, check_penetration, point_triangle_closest,
                                     segments_cross_triangles)

H = gdfe.paper.H


def _ipctk():
    return pytest.importorskip("ipctk")


def _plates(gap=None, overlap=None, cells=(3, 3), pixel=0.2, shift=(0.0, 0.0)):
    """Two square rigid plates side by side in the print; the second laid over the first.

    Returns the design and the shape with plate b's bottom face ``gap`` above plate a's top
    face (or ``overlap`` into it), its cells above a's, moved sideways by ``shift`` [mm].
    """
    nx, ny = cells
    rows = ["R" * nx + "." * 2 + "R" * nx] * ny
    des = gdfe.from_rows(rows, R=1.0, h=H, pixel=pixel, nz=1)
    X = des.mesh.points.copy()
    b = X[:, 0] > (nx + 1) * pixel
    dz = H + (gap if gap is not None else -overlap)
    X[b, 0] -= (nx + 2) * pixel - shift[0]
    X[b, 1] += shift[1]
    X[b, 2] += dz
    return des, X


# -- the penetration check (no contact library needed) -----------------------------------------

def test_kernels_against_hand_computed_cases():
    a, b, c = np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]])
    up, down = np.array([[0.2, 0.2, 1.0]]), np.array([[0.2, 0.2, -1.0]])
    assert segments_cross_triangles(up, down, a, b, c)[0]
    assert not segments_cross_triangles(up, up + [0, 0, 1.0], a, b, c)[0]  # stops short of the plane
    assert not segments_cross_triangles(up + [1.0, 1.0, 0], down + [1.0, 1.0, 0], a, b, c)[0]  # misses
    assert not segments_cross_triangles(np.array([[0.1, 0.1, 0.0]]), np.array([[0.3, 0.1, 0.0]]), a, b, c)[0]
    cases = {(0.2, 0.2, 0.5): (0.2, 0.2, 0.0),  # over the face
             (-1.0, -1.0, 0.0): (0.0, 0.0, 0.0),  # vertex region of a
             (0.5, -2.0, 1.0): (0.5, 0.0, 0.0),  # edge ab
             (1.0, 1.0, 0.0): (0.5, 0.5, 0.0),  # edge bc
             (3.0, -1.0, 0.0): (1.0, 0.0, 0.0)}  # vertex b
    for p, q in cases.items():
        np.testing.assert_allclose(point_triangle_closest(np.array([p]), a, b, c)[0], q, atol=1e-15)


def test_flat_sheet_and_open_fold_report_no_penetration():
    sheet = gdfe.from_rows(["RTTTR", "RTTTR", "RBBBR"], R=0.7, pixel=0.2, nz=2)
    p = check_penetration(sheet.mesh.points, sheet)
    assert not p.found and p.intersecting_pairs == 0 and p.depth_mm == 0.0 and p.min_gap_mm is None
    res = gdfe.simulate(gdfe.hinge(2.6, d=0.33), contact="off")  # folds 2.73 rad: the panels stay apart
    assert not res.penetration.found and not res.penetrates
    assert res.summary()["penetration_mm"] == 0.0 and res.summary()["contact"] is False


@pytest.mark.parametrize("shift", [(0.0, 0.0), (0.05, 0.03)])
def test_plate_laid_into_another_by_a_known_depth(shift):
    """Plate b's bottom face 0.05 mm inside plate a: its points there are 0.05 mm from a's top face."""
    des, X = _plates(overlap=0.05, shift=shift)
    p = check_penetration(X, des)
    assert p.found
    # aligned, the side faces only touch (no crossing); moved sideways, b's sides cross a's top
    assert (p.intersecting_pairs > 0) == (shift != (0.0, 0.0))
    assert p.depth_mm == pytest.approx(0.05, abs=1e-12)
    assert p.min_gap_mm == pytest.approx(-0.05, abs=1e-12)
    assert p.penetrated_cells == 18  # every cell of both 3 x 3 plates


def test_strips_crossing_like_an_x_have_a_depth():
    """Two strips of 1 mm cells crossing at 30 degrees: no vertex inside the other, still found and deep.

    Strip b's edges run h / sin 30 = 0.58 mm through strip a; the points sampled along them
    nearest a's mid-plane are nearly h / 2 from a's surface.
    """
    rows = ["RRR.RRR"]
    des = gdfe.from_rows(rows, R=1.0, h=H, pixel=1.0, nz=1)
    X = des.mesh.points.copy()
    b = X[:, 0] > 3.5
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    xb, zb = X[b, 0] - 5.5, X[b, 2] - H / 2  # strip b about its centre
    X[b, 0], X[b, 2] = 1.5 + c * xb - s * zb, H / 2 + s * xb + c * zb
    p = check_penetration(X, des)
    assert p.found and p.intersecting_pairs > 0
    assert 0.25 * H < p.depth_mm <= 0.5 * H


@pytest.mark.parametrize("gap", [0.01, 0.05])
def test_gap_between_facing_plates(gap):
    des, X = _plates(gap=gap)
    p = check_penetration(X, des)
    assert not p.found and p.min_gap_mm == pytest.approx(gap, abs=1e-12)
    far = check_penetration(_plates(gap=0.5)[1], des)
    assert far.min_gap_mm is None  # beyond the search range (h / 4)


def _spiral(gap, cells=60, pixel=0.1, width=4):
    """A strip rolled one and a fifth turns: its last fifth lies ``gap`` inside its first, both curved."""
    des = gdfe.from_rows(["R" * cells] * width, R=1.0, h=H, pixel=pixel, nz=1)
    X = des.mesh.points
    rho0 = cells * pixel / (2 * math.pi * 1.2)
    theta = X[:, 0] / rho0
    rho = rho0 - (H + gap) * theta / (2 * math.pi) + (X[:, 2] - H / 2)
    return des, np.column_stack([rho * np.cos(theta), X[:, 1], -rho * np.sin(theta)])  # orientation kept


def _brute_force_facing(check, X):
    """The facing pairs of the module docstring from every boundary vertex and triangle, no search, no prefilter."""
    r = check.gap_range
    tris = check.tris
    A, B, C = X[tris[:, 0]], X[tris[:, 1]], X[tris[:, 2]]
    N = np.cross(B - A, C - A)
    vn = np.zeros_like(X)
    for k in range(3):
        np.add.at(vn, tris[:, k], N)
    vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-300)
    out = []
    for part in np.array_split(check.surface, max(1, check.surface.size // 200)):  # every pair, in bounded memory
        vi, tj = (a.ravel() for a in np.meshgrid(part, np.arange(len(tris)), indexing="ij"))
        p = X[vi]
        q = point_triangle_closest(p, A[tj], B[tj], C[tj])
        dist = np.linalg.norm(p - q, axis=1)
        s = np.einsum("ij,ij->i", p - A[tj], N[tj] / np.linalg.norm(N[tj], axis=1, keepdims=True))
        ok = ((s > 1e-9 * r) & (s <= r) & (np.einsum("ij,ij->i", p - q, N[tj]) > 0) & (dist <= r)
              & (np.einsum("ij,ij->i", q - p, vn[vi]) >= 0.5 * dist * dist / r)
              & ~check.neighbours(vi, check.owner[tj]))
        out.append((vi[ok], tj[ok], dist[ok]))
    return tuple(np.concatenate(a) for a in zip(*out))


@pytest.mark.parametrize("quads", [True, False])
@pytest.mark.parametrize("gap, pixel", [(0.012, 0.1), (0.04, 0.1), (0.012, 0.03)])
def test_gap_of_a_rolled_strip_equals_the_brute_force_one(gap, pixel, quads):
    """Curved faces facing each other across ``gap``: the searches (by the boundary's quadrilaterals, as the
    check makes them, or by its triangles) and their prefilter lose no facing pair, on pixels wider than the
    search range and on pixels so fine that the range reaches past a vertex's neighbours (two pixels) into
    its own face."""
    import gdfe.solver.penetration as pen

    des, X = _spiral(gap, cells=round(6.0 / pixel), pixel=pixel, width=4 if pixel > 0.05 else 2)
    check = PenetrationCheck(des)
    assert (2 * pixel < check.gap_range) == (pixel < 0.05)
    p = check(X)
    assert not p.found
    v, t, d = _brute_force_facing(check, X)
    assert v.size > 100
    tri = pen._Triangles(X[check.tris[:, 0]], X[check.tris[:, 1]], X[check.tris[:, 2]], quads=quads)
    v2, t2, d2 = check._facing_search(X, tri)(check.surface)
    assert sorted(zip(v2.tolist(), t2.tolist())) == sorted(zip(v.tolist(), t.tolist()))
    assert p.min_gap_mm == pytest.approx(d.min(), rel=1e-12)
    assert p.min_gap_mm == pytest.approx(gap, rel=0.05)  # the facing faces are two nearly parallel arcs


@pytest.mark.parametrize("quads", [True, False])
def test_facing_search_within_a_bound_keeps_every_pair_as_near(quads):
    """The gap search's bound (the nearest pair found so far) drops only pairs further than it."""
    import gdfe.solver.penetration as pen

    des, X = _spiral(0.012)
    check = PenetrationCheck(des)
    v, t, d = _brute_force_facing(check, X)
    tri = pen._Triangles(X[check.tris[:, 0]], X[check.tris[:, 1]], X[check.tris[:, 2]], quads=quads)
    find = check._facing_search(X, tri)
    full = find(check.surface)[2].size
    for bound in (d.min(), float(np.median(d)), 0.5 * check.gap_range, 2.0 * check.gap_range):
        v2, t2, d2 = find(check.surface, within=bound)
        near = d <= bound
        assert sorted(zip(v2.tolist(), t2.tolist())) == sorted(zip(v[near].tolist(), t[near].tolist()))
        assert np.array_equal(np.sort(d2), np.sort(d[near]))
    assert 0 < find(check.surface, within=d.min())[2].size < full


def test_the_check_searches_by_quadrilaterals_only_where_the_triangles_are_their_halves():
    import gdfe.solver.penetration as pen

    des, X = _spiral(0.02)
    check = PenetrationCheck(des)
    assert check._triangles(X).quads
    tris = check.tris
    assert pen._halves_of_quadrilaterals(tris)
    assert not pen._halves_of_quadrilaterals(tris[::-1])  # first halves' a with second halves' a, but b for c
    assert not pen._halves_of_quadrilaterals(tris[1:])
    assert not pen._halves_of_quadrilaterals(np.concatenate([tris[:, [0, 1, 2]], tris[:, [1, 2, 0]]]))


def test_check_answers_the_same_in_any_chunks_and_threads(monkeypatch):
    """The 9 mm hinge's overlap and a rolled strip's gap, whole and in small chunks, on one thread and on three."""
    import gdfe.solver.penetration as pen
    from gdfe.solver import threads

    res = gdfe.simulate(gdfe.hinge(9.0, d=0.33), contact="off")
    cases = [(res.design, res.points), _spiral(0.02)]
    answers = []
    for workers, chunk, gap_chunk in ((1, pen._CHUNK, pen._GAP_CHUNK), (3, 97, 13)):
        monkeypatch.setattr(threads, "WORKERS", workers)
        monkeypatch.setattr(pen, "_CHUNK", chunk)
        monkeypatch.setattr(pen, "_GAP_CHUNK", gap_chunk)
        answers.append([PenetrationCheck(des)(X) for des, X in cases])
    assert answers[0][0].found and answers[0][0].intersecting_pairs > 100 and answers[0][1].min_gap_mm is not None
    assert answers[0] == answers[1]


def test_check_is_invariant_under_rigid_motions():
    des, X = _plates(overlap=0.05)
    rng = np.random.default_rng(3)
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    Q *= np.sign(np.linalg.det(Q))
    a, b = check_penetration(X, des), check_penetration(X @ Q.T + [1.0, -2.0, 3.0], des)
    assert a.intersecting_pairs == b.intersecting_pairs and a.penetrated_cells == b.penetrated_cells
    assert a.depth_mm == pytest.approx(b.depth_mm, abs=1e-12)


def test_check_finds_the_9mm_hinge_overlap():
    """Without contact the 9 mm hinge folds 9.41 rad on one radius: its second turn lies in the first."""
    res = gdfe.simulate(gdfe.hinge(9.0, d=0.33), contact="off")
    p = res.penetration
    assert p.found and res.penetrates and p.intersecting_pairs > 100
    # a vertex inside a film of thickness h is at most h/2 from its surface: the turns overlap
    # through most of the thickness
    assert 0.3 * H < p.depth_mm <= 0.5 * H * 1.05 and p.min_gap_mm == -p.depth_mm
    assert res.summary()["penetration_mm"] == pytest.approx(p.depth_mm)
    ipctk = pytest.importorskip("ipctk")
    c = Contact(res.design)
    assert ipctk.has_intersections(c.mesh, np.asfortranarray(res.points[c.surface]))


def test_crossing_test_alone_is_the_checks_first_test():
    """``PenetrationCheck.crosses``, the test ``contact="auto"`` makes during a solve, says what the check's
    crossing pairs say: plates laid into each other only touch at their aligned sides, moved sideways they cross."""
    strip = gdfe.from_rows(["RRR.RRR"], R=1.0, h=H, pixel=1.0, nz=1)
    X = strip.mesh.points.copy()
    b = X[:, 0] > 3.5
    X[b, 0], X[b, 2] = X[b, 2] - H / 2 + 1.5, X[b, 0] - 5.5 + H / 2  # strip b stood upright through strip a
    hinge = gdfe.simulate(gdfe.hinge(9.0, d=0.33), contact="off")
    cases = [_plates(overlap=0.05), _plates(overlap=0.05, shift=(0.05, 0.03)), _plates(gap=0.02), (strip, X),
             (hinge.design, hinge.points), (hinge.design, hinge.design.mesh.points)]
    said = []
    for des, Y in cases:
        check = PenetrationCheck(des)
        said.append(check.crosses(Y))
        assert said[-1] == (check(Y).intersecting_pairs > 0)
    assert said == [False, True, False, True, True, False]
    with pytest.raises(ValueError, match=r"points: expected an array of shape \(64, 3\)"):
        PenetrationCheck(cases[0][0]).crosses(cases[0][1][:, :2])


def test_check_agrees_with_ipctk():
    ipctk = _ipctk()
    for des, X in (_plates(overlap=0.05), _plates(gap=0.02)):
        c = Contact(des)
        assert check_penetration(X, des).found == ipctk.has_intersections(c.mesh, np.asfortranarray(X[c.surface]))


def test_penetration_check_input():
    des, X = _plates(gap=0.1)
    with pytest.raises(ValueError, match=r"points: expected an array of shape \(64, 3\), got shape \(64, 2\)"):
        check_penetration(X[:, :2], des)
    with pytest.raises(ValueError, match="gap_range: expected a positive"):
        PenetrationCheck(des, gap_range=-1.0)
    with pytest.raises(TypeError, match="design: expected"):
        check_penetration(X, "design")


# -- the contact term --------------------------------------------------------------------------

def test_barrier_closed_form_and_forces_vanish_beyond_the_gap():
    _ipctk()
    des, _ = _plates(gap=0.1)
    c = Contact(des)
    dhat = c.dhat
    ratios = []
    for g in (0.3 * dhat, 0.7 * dhat):
        s = c.evaluate(_plates(gap=g)[1])
        assert s.active > 0 and s.min_distance == pytest.approx(g, rel=1e-9)
        # parallel plates: every active pair is g apart, so B = pairs * kappa * b(g)
        ratios.append(s.energy / (c.stiffness * barrier(g, dhat)))
        X = _plates(gap=g)[1]
        grad = c.gradient(s)
        top = X[:, 2] > H + g + 1e-9  # plate b's top face: not in contact
        lifted = np.abs(X[:, 2] - (H + g)) < 1e-9  # plate b's bottom face
        assert np.all(grad[lifted, 2] <= 0) and grad[lifted, 2].min() < 0  # pushes plate b up, away
        # nothing acts on plate b's top face (round-off of the edge-edge pairs' closest points)
        assert np.abs(grad[top]).max() <= 1e-12 * np.abs(grad).max()
    assert ratios[0] == pytest.approx(round(ratios[0]), abs=1e-6) and ratios[0] == pytest.approx(ratios[1])
    for g in (1.01 * dhat, 0.2):
        s = c.evaluate(_plates(gap=g)[1])
        assert s.active == 0 and s.energy == 0.0 and not np.any(c.gradient(s)) and c.hessian(s) is None


def test_barrier_is_invariant_under_rigid_motions():
    """A rigid motion of the shape and the step changes no energy, rotates forces and Hessian, keeps the step limit."""
    _ipctk()
    des, X = _plates(gap=0.01)
    c = Contact(des)
    rng = np.random.default_rng(5)
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    Q *= np.sign(np.linalg.det(Q))
    Y = X @ Q.T + [0.3, 0.2, -1.0]
    a, b = c.evaluate(X), c.evaluate(Y)
    assert b.energy == pytest.approx(a.energy, rel=1e-10)
    np.testing.assert_allclose(c.gradient(b), c.gradient(a) @ Q.T, atol=1e-12 * np.abs(c.gradient(a)).max())
    # Hessian: H_Y = (I (x) Q) H_X (I (x) Q)^T, vertex-major; plate b tilted by 0.02 rad and moved
    # sideways, as parallel edges' closest-point type is decided by round-off (and with it the Hessian)
    des, X = _plates(gap=0.01, shift=(0.05, 0.03))
    b = X[:, 2] > H + 0.005
    yb, zb = X[b, 1] - X[b, 1].mean(), X[b, 2] - X[b, 2].min()
    X[b, 1], X[b, 2] = X[b, 1].mean() + math.cos(0.02) * yb - math.sin(0.02) * zb, \
        X[b, 2].min() + math.sin(0.02) * yb + math.cos(0.02) * zb
    Y = X @ Q.T + [0.3, 0.2, -1.0]
    a, b = c.evaluate(X), c.evaluate(Y)
    assert a.active > 0 and b.energy == pytest.approx(a.energy, rel=1e-10)
    R = np.kron(np.eye(X.shape[0]), Q)
    for project in (False, True):
        Ha, Hb = c.hessian(a, project=project).toarray(), c.hessian(b, project=project).toarray()
        np.testing.assert_allclose(Hb, R @ Ha @ R.T, rtol=0, atol=1e-12 * np.abs(Ha).max())
    X = _plates(gap=0.01)[1]
    Y = X @ Q.T + [0.3, 0.2, -1.0]
    # the step limit: plate b moves 0.11 mm down onto a, 0.01 mm away: first contact at 1/11 of the move;
    # both limits below it and apart by less than the CCD's tolerance (1e-3 mm) over the move
    _, X1 = _plates(overlap=0.1)
    ax, ay = c.max_step(X, X1), c.max_step(Y, X1 @ Q.T + [0.3, 0.2, -1.0])
    assert 0.5 / 11 < min(ax, ay) and max(ax, ay) < 1 / 11 and abs(ax - ay) * 0.11 <= CCD_TIGHT_INCLUSION[0]


def test_step_limit_stops_plates_before_they_cross():
    _ipctk()
    des, X0 = _plates(gap=0.1)
    _, X1 = _plates(overlap=0.1)  # straight through plate a
    c = Contact(des)
    a = c.max_step(X0, X1)
    assert 0.35 < a < 0.5  # contact at 0.5 of the move; the CCD stops at 0.8 of (a bound below) it
    assert not check_penetration(X0 + a * (X1 - X0), des).found
    assert c.max_step(X0, X0 + [0.0, 0.0, 0.01], c.evaluate(X0)) == 1.0  # moving apart (and far): whole


def test_barrier_along_a_step_from_its_candidates_equals_a_fresh_one(monkeypatch):
    """The barrier at trial shapes on a step, built from the step's swept candidates, is the one built anew."""
    _ipctk()
    import gdfe.solver.contact as contact_module

    des, X0 = _plates(gap=0.1)
    _, X1 = _plates(overlap=0.1, shift=(0.03, 0.02))
    c, fresh = Contact(des), Contact(des)
    a = c.max_step(X0, X1)
    assert c._swept is None  # on two small plates the step sweeps over all of them: more candidates than kept
    monkeypatch.setattr(contact_module, "SWEEP_REUSE", np.inf)
    a = c.max_step(X0, X1)
    assert c._swept is not None and 0.35 < a < 0.5
    for t in (0.5 * a, 0.95 * a, a):  # plate b's bottom 0.1 - 0.2 t above a's top: within dhat beyond t = 0.36
        X = X0 + t * (X1 - X0)
        s, f = c.evaluate(X), fresh.evaluate(X)
        assert s.active == f.active and s.min_distance == f.min_distance and s.active > 0 or t < 0.3
        assert s.energy == pytest.approx(f.energy, rel=1e-12)
        g = fresh.gradient(f)
        np.testing.assert_allclose(c.gradient(s), g, rtol=0, atol=1e-12 * np.abs(g).max())
    # a shape off the step (plate b moved sideways beyond its swept box) gets a broad phase of its own
    Y = X0 + 0.5 * a * (X1 - X0)
    Y[X0[:, 2] > H + 0.05, 0] += 0.1
    assert c.evaluate(Y).energy == pytest.approx(fresh.evaluate(Y).energy, rel=1e-12)


def test_neighbours_and_thickness_never_repel():
    """The default gap stays below the film's thickness and its cells' contracted sides."""
    _ipctk()
    shrink = gdfe.from_rows(["SSSS", "SSSS", "SSSS"], R=0.3, pixel=0.1, nz=2)
    assert default_dhat(shrink) == pytest.approx(0.25 * 0.3 * min(0.1, H / 2))
    res = gdfe.simulate(shrink, contact="on")  # every cell shrinks to 0.3 of its size
    assert res.converged and res.contact.used and res.contact.pairs == 0
    folded = gdfe.simulate(gdfe.hinge(2.6, d=0.33), contact="off")
    c = Contact(folded.design)
    assert c.evaluate(folded.points).active == 0 and c.evaluate(folded.design.mesh.points).active == 0
    assert c.dhat == pytest.approx(0.25 * 0.6947 * 2.6 / 16, rel=1e-3) and c.dhat < 0.1 * H


def test_patches_are_rigid_regions_and_small_blocks():
    des = gdfe.hinge(9.0, d=0.33)  # rigid panels of 4 columns, a 36-column hinge of 0.25 mm cells
    patch = contact_patches(des)
    cells = des.mesh.cells
    for name in ("panel_a", "panel_b"):
        assert np.unique(patch[cells[des.region_cells(name)]]).size <= 2
    # blocks: a quarter turn of the tightest curl on the diagonal, pi rho / (2 sqrt 2), rho = h / (1 - R)
    side = math.pi * H / (1 - des.R.min()) / (2 * math.sqrt(2))
    assert int(side // 0.25) == 4
    hinge_patches = np.unique(patch[cells[des.region_cells("hinge")]])
    assert 9 <= hinge_patches.size <= 11


def test_plates_folded_together_never_interpenetrate():
    """A 5 mm hinge folds its 1 mm panels onto each other: no trial shape the solver accepts crosses itself."""
    _ipctk()
    des = gdfe.hinge(5.0, d=0.33, cell_size=0.5)
    free = gdfe.simulate(des, contact="off")
    assert free.penetration.found  # the panels pass through each other without contact
    solver, c = gdfe.Solver(des), Contact(des)
    seen = []
    evaluate = c.evaluate

    def recording(V):
        s = evaluate(V)
        if np.isfinite(s.energy):
            seen.append(np.array(V))
        return s

    c.evaluate = recording
    V = solver.linearised_start(des.mesh.points.copy(), 0.5)
    stats = [solver.solve(V, 0.5, contact=c)]
    stats.append(solver.solve(stats[0].points, 1.0, contact=c))
    check = PenetrationCheck(des)
    assert len(seen) > 20 and not any(check(X).found for X in seen)
    assert all(s.converged for s in stats) and stats[1].contact_pairs > 0
    for s in stats:  # the energy (Eq. 5 plus the barrier) never increases
        e = np.array(s.energies)
        assert np.all(np.diff(e) <= 1e-12 * np.abs(e[:-1])), np.diff(e).max()


# -- simulate, design files, the command line ---------------------------------------------------

def test_contact_free_path_is_unchanged():
    des = gdfe.hinge(1.6, d=0.33)
    off, auto = gdfe.simulate(des, contact="off", steps=2), gdfe.simulate(des, steps=2)
    assert np.array_equal(off.points, auto.points) and off.iterations == auto.iterations
    assert np.array_equal(off.energy_history, auto.energy_history)
    assert not auto.contact.used and auto.contact.mode == "auto"


def test_auto_stops_the_contact_free_solve_where_it_crosses_itself():
    """contact="auto" switches at the first checked iterate that crosses itself; its result is contact="on"'s."""
    _ipctk()
    des = gdfe.hinge(5.0, d=0.33, cell_size=0.5)
    off = gdfe.simulate(des, contact="off")
    assert off.penetrates
    for steps in (1, 3):
        auto, on = gdfe.simulate(des, steps=steps), gdfe.simulate(des, contact="on", steps=steps)
        assert auto.contact.used and "where it stopped" in auto.contact.reason
        assert np.array_equal(auto.points, on.points) and auto.iterations == on.iterations
        assert not auto.penetrates
    # the contact-free solve of the first frame crosses itself between iterations 4 and 8 of its 19
    assert "iteration 8 of frame 1" in gdfe.simulate(des).contact.reason and off.iterations > 8


def test_auto_checks_every_frame_once(monkeypatch):
    """The watch's check at the end of a frame is that frame's check after the solve: each of three frames is
    tested for crossings once, and its check says what a fresh check of the frame says."""
    _ipctk()
    tested = []  # every shape the crossing test ran on, whether for the watch or for the check
    crossing = PenetrationCheck._crossing_pairs
    monkeypatch.setattr(PenetrationCheck, "_crossing_pairs", lambda self, X, tri, **kw: tested.append(X.copy())
                        or crossing(self, X, tri, **kw))
    res = gdfe.simulate(gdfe.hinge(2.6, d=0.33), steps=3)
    assert not res.contact.used
    for V in res.frames[1:]:
        assert sum(np.array_equal(V, X) for X in tested) == 1
    fresh = PenetrationCheck(res.design)
    assert [fresh(V) for V in res.frames[1:]] == res.frame_penetration


def test_auto_above_the_watch_limit_tests_only_the_solved_shape(monkeypatch):
    """Above WATCH_MAX_CELLS no surface is made during the solve; the check of the result leads to contact."""
    _ipctk()
    from gdfe.solver import simulation

    des = gdfe.hinge(5.0, d=0.33, cell_size=0.5)
    on = gdfe.simulate(des, contact="on")
    made = []
    monkeypatch.setattr(simulation, "WATCH_MAX_CELLS", 0)
    monkeypatch.setattr(simulation, "Contact", lambda *a: made.append(a) or Contact(*a))
    auto = gdfe.simulate(des)
    assert len(made) == 1  # for the contact solve, after the contact-free one has finished
    assert auto.contact.used and auto.contact.reason.startswith("the contact-free solve penetrated itself")
    assert np.array_equal(auto.points, on.points) and not auto.penetrates
    assert auto.timings["contact_free_solve"] > 0


def test_auto_solves_with_contact_when_only_the_final_check_finds_a_crossing(monkeypatch):
    """No test during the solve: the penetration check still leads to contact, and the contact solve's check
    is the same check, made once (after the contact-free solve, with the solver's caches dropped)."""
    _ipctk()
    from gdfe.solver import simulation

    monkeypatch.setattr(simulation, "AUTO_CHECK_EVERY", 10**6)
    checks = []  # whether the solver still held its Hessian when each penetration check began
    check = simulation.PenetrationCheck

    def spy(design):
        checks.append(any("reduced_hessian" in vars(s) for s in solvers))
        return check(design)
    solvers = []
    solver = simulation.Solver
    monkeypatch.setattr(simulation, "Solver", lambda *a, **k: solvers.append(solver(*a, **k)) or solvers[-1])
    monkeypatch.setattr(simulation, "PenetrationCheck", spy)
    res = gdfe.simulate(gdfe.hinge(5.0, d=0.33, cell_size=0.5))
    assert res.contact.used and res.contact.reason.startswith("the contact-free solve penetrated itself")
    assert not res.penetrates and res.contact.pairs > 0
    assert checks == [False]


def test_hinge_9mm_with_contact_has_no_penetration():
    _ipctk()
    des = gdfe.hinge(9.0, d=0.33)
    res = gdfe.simulate(des)  # auto: the contact-free solve penetrates, so contact
    assert res.converged and res.contact.used and "the contact-free solve crossed itself" in res.contact.reason
    p = res.penetration
    assert not res.penetrates and 0.0 < p.min_gap_mm <= res.contact.dhat_mm
    alpha = gdfe.fold_angle(res)
    assert 2 * math.pi * 0.9 < alpha < 9.41  # meets itself after about a turn, short of the free 9.41 rad
    assert res.contact.pairs > 0 and res.energy == pytest.approx(res.energy_history[-1])
    again = gdfe.simulate(des, contact="on")
    assert np.array_equal(again.points, res.points)  # repeats exactly (one ipctk thread)


def test_frames_with_contact_never_penetrate():
    _ipctk()
    res = gdfe.simulate(gdfe.hinge(5.0, d=0.33, cell_size=0.5), contact="on", steps=3)
    assert res.converged and len(res.frame_penetration) == 3
    assert not any(p.found for p in res.frame_penetration)
    assert res.contact.pairs > 0  # the last frame is in contact


def test_simulate_contact_input_checks(tmp_path):
    des = gdfe.hinge(1.0, d=0.33)
    with pytest.raises(ValueError, match="contact: expected one of 'auto', 'on', 'off', got 'maybe'"):
        gdfe.simulate(des, contact="maybe")
    with pytest.raises(ValueError, match="dhat: expected a positive"):
        gdfe.simulate(des, dhat=-0.01)
    with pytest.raises(ValueError, match="contact: the contact solve needs a Newton method"):
        gdfe.simulate(des, contact="on", method="plain")
    f = tmp_path / "part.toml"
    f.write_text('[film]\nh = 0.29\nR = 0.7\n[layout]\npixel = 0.2\nrows = ["RTR"]\n[simulate]\ncontact = "yes"\n')
    with pytest.raises(ValueError, match=r"part.toml: \[simulate\] contact: expected one of"):
        gdfe.load_design(f)
    f.write_text('[film]\nh = 0.29\nR = 0.7\n[layout]\npixel = 0.2\nrows = ["RTR"]\n[simulate]\ncontact = "off"\n')
    assert gdfe.load_design(f)[1]["contact"] == "off"


def test_without_ipctk(monkeypatch):
    monkeypatch.setitem(sys.modules, "ipctk", None)
    with pytest.raises(ValueError, match=r"IPC Toolkit, which is not installed; pip install 'gdfe\[contact\]'"):
        require_ipctk()
    des = gdfe.hinge(5.0, d=0.33, cell_size=0.5)
    with pytest.raises(ValueError, match="IPC Toolkit"):
        gdfe.simulate(des, contact="on")
    res = gdfe.simulate(des)  # auto: checked, reported, not solved again
    assert res.penetration.found and not res.contact.used and not res.contact.available
    assert "not installed" in res.contact.reason


def test_cli_exit_status_and_json(tmp_path, capsys, monkeypatch):
    argv = ["hinge", "--length", "5", "--d", "0.33", "--cells", "10", "--json"]
    assert main(argv + ["--no-contact"]) == 4
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["penetration_mm"] > 0 and out["contact"] is False and out["converged"]
    assert "--contact" in captured.err and "--allow-penetration" in captured.err
    assert main(argv + ["--no-contact", "--allow-penetration"]) == 0
    capsys.readouterr()
    monkeypatch.setitem(sys.modules, "ipctk", None)
    assert main(argv) == 4
    assert "pip install 'gdfe[contact]'" in capsys.readouterr().err


def test_cli_contact_json_and_series(tmp_path, capsys):
    _ipctk()
    out_dir = tmp_path / "h"
    argv = ["hinge", "--length", "5", "--d", "0.33", "--cells", "10", "--contact", "--json", "--steps", "2",
            "--out", str(out_dir)]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["converged"] and out["contact"] is True and out["penetration_mm"] == 0.0
    assert out["iterations"] > 0 and math.isfinite(out["alpha_rad"])
    assert out["contact_info"]["pairs"] > 0 and out["penetration"]["min_gap_mm"] >= 0
    assert (out_dir / "hinge.pvd").is_file() and len(list(out_dir.glob("hinge_*.vtu"))) == 3


def test_contact_study_coarse(tmp_path):
    """The study at coarse resolution: every headline holds, its files are written."""
    from studies import contact

    r = contact.run("coarse", tmp_path)
    assert r["converged"] and all(h["passed"] for h in r["headlines"]), [h for h in r["headlines"] if not h["passed"]]
    assert (tmp_path / "contact.png").stat().st_size > 10_000
    data = json.loads((tmp_path / "contact.json").read_text())
    # no specimen of Table 1 folds far enough to meet itself, so self-contact stops none
    assert not any(s["saturates"] for s in data["table1"]["specimens"])
    assert data["table1"]["onset"]["alpha_meets_rad"] > contact.ALPHA_MAX
    for row in data["cost"]["rows"]:  # timed, not asserted: recorded with the machine's load
        assert row["off"]["converged"] and row["on"]["converged"] and row["on"]["penetration_mm"] == 0.0
