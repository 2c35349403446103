"""FOLD files whose fold angles or faces cannot be a flat crease pattern are refused, naming the key."""

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gdfe.fabrication.fold import crease_faces, fold_masks, read_fold


def fold_file(tmp_path, name="d.fold", **changes):
    """A 4 x 2 mm rectangle with one valley crease across it at x = 2 mm (``changes`` applied, None dropped)."""
    doc = {"file_spec": 1.1, "frame_unit": "mm",
           "vertices_coords": [[0, 0], [2, 0], [4, 0], [4, 2], [2, 2], [0, 2]],
           "edges_vertices": [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 0], [1, 4]],
           "edges_assignment": ["B"] * 6 + ["V"], "gdfe:hinge_width": 0.6,
           "faces_vertices": [[0, 1, 4, 5], [1, 2, 3, 4]]}
    doc.update(changes)
    path = tmp_path / name
    path.write_text(json.dumps({k: v for k, v in doc.items() if v is not None}))
    return path


@pytest.mark.parametrize("angle", [720, -181, 180.5])
def test_fold_angle_outside_a_half_turn_is_refused(tmp_path, angle):
    assignment = ["B"] * 6 + ["M" if angle < 0 else "V"]
    path = fold_file(tmp_path, edges_foldAngle=[None] * 6 + [angle], edges_assignment=assignment)
    with pytest.raises(ValueError, match=rf"d\.fold: edges_foldAngle\[6\]: expected degrees in \[-180, 180\], "
                                         rf"got {angle}"):
        read_fold(path)


def test_fold_angle_of_a_half_turn_is_read(tmp_path):
    cp = read_fold(fold_file(tmp_path, edges_foldAngle=[0] * 6 + [180]))
    assert cp.fold_angle[6] == pytest.approx(np.pi)


@pytest.mark.parametrize("faces, match", [
    ([[0, 1, 5, 4], [1, 2, 3, 4]], r"d\.fold: faces_vertices\[0\]: expected a simple polygon.*crosses"),  # bow-tie
    ([[0, 1, 4, 5], [1, 2, 4, 3]], r"d\.fold: faces_vertices\[1\]: expected a simple polygon.*crosses"),
    ([[0, 1, 4, 1, 5], [1, 2, 3, 4]], r"d\.fold: faces_vertices\[0\]: expected a simple polygon.*vertex 1 twice"),
    ([[0, 1, 2, 1], [1, 2, 3, 4]], r"d\.fold: faces_vertices\[0\]: expected a simple polygon.*vertex 1 twice"),
    ([[0, 1, 2]], r"d\.fold: faces_vertices\[0\]: expected a simple polygon"),  # three points on a line
])
def test_self_crossing_face_is_refused(tmp_path, faces, match):
    with pytest.raises(ValueError, match=match):
        read_fold(fold_file(tmp_path, faces_vertices=faces))


def test_overlapping_faces_are_refused(tmp_path):
    # the second face is the whole rectangle: it holds the first one
    path = fold_file(tmp_path, faces_vertices=[[0, 1, 4, 5], [0, 2, 3, 5]])
    with pytest.raises(ValueError, match=r"d\.fold: faces_vertices: the faces' areas add up to 12 mm2 but the "
                                         r"boundary \(B\) edges enclose 8 mm2.*overlap"):
        read_fold(path)


def test_faces_leaving_out_part_of_the_outline_are_refused(tmp_path):
    with pytest.raises(ValueError, match=r"faces_vertices: the faces' areas add up to 4 mm2 but the boundary \(B\) "
                                         r"edges enclose 8 mm2.*leave out"):
        read_fold(fold_file(tmp_path, faces_vertices=[[0, 1, 4, 5]]))


def test_overlapping_faces_without_boundary_edges_are_refused(tmp_path):
    path = fold_file(tmp_path, faces_vertices=[[0, 1, 4, 5], [0, 2, 3, 5]], edges_assignment=["U"] * 6 + ["V"])
    with pytest.raises(ValueError, match=r"d\.fold: faces_vertices\[1\]: overlaps faces_vertices\[0\]"):
        read_fold(path)
    # two convex faces that overlap without either holding the other's centre
    shifted = fold_file(tmp_path, vertices_coords=[[0, 0], [2, 0], [4, 0], [4, 2], [2, 2], [0, 2], [0.5, 0],
                                                   [3.5, 0], [3.5, 2], [0.5, 2]],
                        faces_vertices=[[0, 2, 3, 5], [6, 7, 8, 9]], edges_assignment=["U"] * 6 + ["V"])
    with pytest.raises(ValueError, match=r"faces_vertices\[1\]: overlaps faces_vertices\[0\]"):
        read_fold(shifted)


def test_faces_with_a_hole_in_the_outline_are_read(tmp_path):
    # a 6 x 6 mm square with a 2 x 2 mm hole, in four faces around the hole
    V = [[0, 0], [6, 0], [6, 6], [0, 6], [2, 2], [4, 2], [4, 4], [2, 4]]
    E = [[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [2, 6]]
    faces = [[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    path = fold_file(tmp_path, vertices_coords=V, edges_vertices=E, edges_assignment=["B"] * 8 + ["V", "V"],
                     faces_vertices=faces)
    cp = read_fold(path)
    assert len(cp.faces) == 4
    with pytest.raises(ValueError, match=r"add up to 36 mm2 but the boundary \(B\) edges enclose 32 mm2"):
        read_fold(fold_file(tmp_path, vertices_coords=V, edges_vertices=E, faces_vertices=faces + [[4, 5, 6, 7]],
                            edges_assignment=["B"] * 8 + ["V", "V"]))


def test_valid_faces_give_the_masks_of_the_boundary_loop(tmp_path):
    with_faces = fold_masks(read_fold(fold_file(tmp_path, "a.fold")), 0.25, R=0.5, h=0.3)
    loop = fold_masks(read_fold(fold_file(tmp_path, "b.fold", faces_vertices=None)), 0.25, R=0.5, h=0.3)
    assert with_faces.film.sum() == loop.film.sum() == 16 * 8
    for key in ("film", "top", "bottom", "owner"):
        np.testing.assert_array_equal(getattr(with_faces, key), getattr(loop, key))
    assert [h["faces"] for h in with_faces.hinges] == [[0, 1]]
    # a face through a straight-through vertex (vertex 1 on the edge 0-2) is a simple polygon
    whole = read_fold(fold_file(tmp_path, "c.fold", faces_vertices=[[0, 1, 2, 3, 4, 5]]))
    np.testing.assert_array_equal(fold_masks(whole, 0.25, R=0.5, h=0.3).film, loop.film)


def pattern_file(tmp_path, V, faces, outline=None, name="d.fold"):
    """A FOLD file of ``faces`` over the vertices ``V``: their sides flat (F) edges, the sides of the loop
    ``outline`` (vertex indices) boundary (B) edges; no B edges without it."""
    outline = outline or []
    boundary = {frozenset(e) for e in zip(outline, outline[1:] + outline[:1])}
    edges = {}
    for loop in [*faces, outline]:
        for a, b in zip(loop, loop[1:] + loop[:1]):
            edges.setdefault(frozenset((a, b)), [a, b])
    assignment = ["B" if key in boundary else "F" for key in edges]
    return fold_file(tmp_path, name, vertices_coords=[list(map(float, p)) for p in V],
                     edges_vertices=list(edges.values()), edges_assignment=assignment, faces_vertices=faces)


#: An L-shaped face (vertices 0 to 5), 3 mm2: the square 0..2 x 0..2 mm less its notch 1..2 x 1..2 mm.
L_SHAPE = [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]


def with_l_shape(second, outline=None):
    """The L-shaped face 0 and a second face at the points ``second`` (vertices 6 on), with the
    boundary loop ``outline`` given by its points (new vertices where not already there)."""
    V = [list(p) for p in L_SHAPE + second]
    for p in outline or []:
        if p not in V:
            V.append(p)
    loop = [V.index(p) for p in outline] if outline else None
    return V, [list(range(6)), list(range(6, 6 + len(second)))], loop


@pytest.mark.parametrize("second, outline", [
    # the same L moved by (1, 0.5) mm: neither holds the point inside the other's lowest, leftmost corner
    ([[x + 1, y + 0.5] for x, y in L_SHAPE], None),
    # likewise, in a boundary loop enclosing 6 mm2, the two faces' areas: a gap makes up for the overlap
    ([[x + 1, y + 0.5] for x, y in L_SHAPE], [[0, 0], [3, 0], [3, 2], [0, 2]]),
    # the L turned upside down and moved by -0.5 mm along x: 1.5 mm2 in common
    ([[-0.5, 0], [0.5, 0], [0.5, 1], [1.5, 1], [1.5, 2], [-0.5, 2]], None),
    # a square reaching from the notch into the L
    ([[0.9, 0.9], [1.9, 0.9], [1.9, 1.9], [0.9, 1.9]], None),
], ids=["L-over-L", "L-over-L-areas-add-up", "L-over-flipped-L", "square-into-the-notch"])
def test_partly_overlapping_non_convex_faces_are_refused(tmp_path, second, outline):
    V, faces, loop = with_l_shape(second, outline)
    with pytest.raises(ValueError, match=rf"d\.fold: faces_vertices\[1\]: overlaps faces_vertices\[0\] \(expected "
                                         rf"faces that meet only along their edges, got \[6, 7, 8, 9(, 10, 11)?\] and "
                                         rf"\[0, 1, 2, 3, 4, 5\]\)"):
        read_fold(pattern_file(tmp_path, V, faces, loop))


@pytest.mark.parametrize("second, outline", [
    # the other L of the 3 x 2 mm rectangle: they share three edges, one at each's notch
    ([[2, 0], [3, 0], [3, 2], [1, 2], [1, 1], [2, 1]], [[0, 0], [3, 0], [3, 2], [0, 2]]),
    # the square filling the notch
    ([[1, 1], [2, 1], [2, 2], [1, 2]], [[0, 0], [2, 0], [2, 2], [0, 2]]),
    # a smaller square in the notch, along parts of its two edges
    ([[1, 1], [1.5, 1], [1.5, 1.5], [1, 1.5]], None),
    # a rectangle outside, along part of the L's side x = 2 mm (no vertex in common)
    ([[2, 0.25], [3, 0.25], [3, 0.75], [2, 0.75]], None),
], ids=["two-Ls", "square-in-the-notch", "small-square-in-the-notch", "along-a-side"])
def test_non_convex_faces_meeting_along_edges_are_read(tmp_path, second, outline):
    V, faces, loop = with_l_shape(second, outline)
    cp = read_fold(pattern_file(tmp_path, V, faces, loop))
    assert [f.tolist() for f in cp.faces] == faces


@pytest.mark.parametrize("V, faces", [
    ([[0, 0], [1, 0], [1, 1], [0, 1], [2, 1], [2, 2], [1, 2]], [[0, 1, 2, 3], [2, 4, 5, 6]]),  # corner to corner
    (L_SHAPE + [[2, 1.5], [1.5, 2]], [[0, 1, 2, 3, 4, 5], [3, 6, 7]]),  # in the notch, at its inner corner
    (L_SHAPE + [[3, 0], [3, -1]], [[0, 1, 2, 3, 4, 5], [1, 6, 7]]),  # an edge in line with the L's bottom edge
], ids=["squares", "in-the-notch", "in-line"])
def test_faces_meeting_at_a_vertex_are_read(tmp_path, V, faces):
    cp = read_fold(pattern_file(tmp_path, V, faces))
    assert len(cp.faces) == 2


@st.composite
def bent_grids(draw, smallest=2):
    """A tiling of an m x m grid of 1 mm cells: corners moved by up to 0.05 mm, each side bent at its
    middle by up to 0.2 mm (non-convex cells; straight-through vertices where not bent), each cell one
    face or two (split along a diagonal). Returns (vertices, faces, boundary loop, m)."""
    m = draw(st.integers(smallest, 4))
    n = (m + 1) ** 2
    move = draw(st.lists(st.floats(-0.05, 0.05), min_size=2 * n, max_size=2 * n))
    C = np.stack(np.meshgrid(np.arange(m + 1.0), np.arange(m + 1.0), indexing="ij"), -1).reshape(-1, 2)
    C = C + np.reshape(move, (-1, 2))

    def corner(i, j):
        return i * (m + 1) + j

    sides = [(corner(i, j), corner(i + 1, j)) for i in range(m) for j in range(m + 1)] \
        + [(corner(i, j), corner(i, j + 1)) for i in range(m + 1) for j in range(m)]
    bend = draw(st.lists(st.floats(-0.2, 0.2), min_size=len(sides), max_size=len(sides)))
    start, end = C[[s[0] for s in sides]], C[[s[1] for s in sides]]
    normal = (end - start)[:, ::-1] * [-1, 1] / np.hypot(*(end - start).T)[:, None]
    V = np.vstack([C, (start + end) / 2 + np.array(bend)[:, None] * normal])
    middle = {s: n + k for k, s in enumerate(sides)}  # the vertex bending each side (lower corner first)
    split = draw(st.booleans())
    faces = []
    for i in range(m):
        for j in range(m):
            c0, c1, c2, c3 = corner(i, j), corner(i + 1, j), corner(i + 1, j + 1), corner(i, j + 1)
            ring = [c0, middle[c0, c1], c1, middle[c1, c2], c2, middle[c3, c2], c3, middle[c0, c3]]
            faces += [ring[:5], ring[4:] + ring[:1]] if split else [ring]
    outline = [(corner(i, 0), corner(i + 1, 0)) for i in range(m)] \
        + [(corner(m, j), corner(m, j + 1)) for j in range(m)] \
        + [(corner(i + 1, m), corner(i, m)) for i in reversed(range(m))] \
        + [(corner(0, j + 1), corner(0, j)) for j in reversed(range(m))]
    loop = [v for a, b in outline for v in (a, middle[min(a, b), max(a, b)])]
    return V.tolist(), faces, loop, m


@given(grid=bent_grids(), with_outline=st.booleans())
def test_bent_grid_faces_are_read(tmp_path, grid, with_outline):
    V, faces, loop, m = grid
    cp = read_fold(pattern_file(tmp_path, V, faces, loop if with_outline else None))
    assert len(cp.faces) == len(faces)


@given(grid=bent_grids(smallest=3), with_outline=st.booleans(), pick=st.integers(0, 10 ** 6),
       angle=st.floats(0, 2 * np.pi), length=st.floats(0.05, 0.3))
def test_a_face_moved_over_its_neighbours_is_refused(tmp_path, grid, with_outline, pick, angle, length):
    # a face of an inner cell, moved (on vertices of its own) by up to 0.3 mm: it overlaps a neighbour,
    # its area unchanged (the boundary loop's test does not see it)
    V, faces, loop, m = grid
    per_cell = len(faces) // m ** 2
    inner = [(i * m + j) * per_cell + h for i in range(1, m - 1) for j in range(1, m - 1) for h in range(per_cell)]
    k = inner[pick % len(inner)]
    moved = np.array(V)[faces[k]] + length * np.array([np.cos(angle), np.sin(angle)])
    faces = faces[:k] + [list(range(len(V), len(V) + len(moved)))] + faces[k + 1:]
    V = V + moved.tolist()
    with pytest.raises(ValueError, match=r"d\.fold: faces_vertices\[\d+\]: overlaps faces_vertices\[\d+\]") as info:
        read_fold(pattern_file(tmp_path, V, faces, loop if with_outline else None))
    assert f"faces_vertices[{k}]" in str(info.value)


def test_a_crease_running_through_a_face_joins_no_face_and_is_said(tmp_path, caplog):
    """A crease from corner to corner of a face that is not split along it was matched to that face (it holds
    both ends), and its hinge measured against the wrong faces: it joins none, and the reader says so."""
    edges = [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 0], [1, 4], [0, 4]]
    with caplog.at_level("WARNING", logger="gdfe.fabrication.fold"):
        cp = read_fold(fold_file(tmp_path, edges_vertices=edges, edges_assignment=["B"] * 6 + ["V", "M"]))
    assert "d.fold: edges_vertices[7] (M) runs through faces_vertices[0] from corner to corner" in caplog.text
    assert crease_faces(cp) == {6: [0, 1], 7: []}
    assert {h["edge"]: h["faces"] for h in fold_masks(cp, 0.1, 0.7, 0.29).hinges} == {6: [0, 1], 7: []}
    # split along it, the same crease joins the two triangles
    caplog.clear()
    cp = read_fold(fold_file(tmp_path, name="split.fold", edges_vertices=edges, edges_assignment=["B"] * 6 + ["V", "M"],
                             faces_vertices=[[0, 1, 4], [0, 4, 5], [1, 2, 3, 4]]))
    assert "runs through" not in caplog.text
    assert crease_faces(cp) == {6: [0, 2], 7: [0, 1]}
    assert {h["edge"]: h["faces"] for h in fold_masks(cp, 0.1, 0.7, 0.29).hinges} == {6: [0, 2], 7: [0, 1]}
