"""FOLD files whose fold angles or faces cannot be a flat crease pattern are refused, naming the key."""

import json

import numpy as np
import pytest

from gdfe.fabrication.fold import fold_masks, read_fold


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
