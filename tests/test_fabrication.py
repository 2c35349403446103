"""Drawings in, printer files and shapes out: rasterising, SVG and FOLD designs, masks, packages, exports."""

import json
import math
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.design import Material
from gdfe.fabrication import (crease_angles, export_result, face_masks, fill_polygons, fold_design, read_fold,
                              read_mask_png, read_print_package, svg_design, svg_masks, svg_polyline,
                              write_design_toml, write_masks, write_print_package)

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"
SVG_NS = 'xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"'


def svg(tmp_path, body, size='width="10mm" height="4mm" viewBox="0 0 10 4"', name="part.svg"):
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n<svg {SVG_NS} {size}>\n{body}\n</svg>\n')
    return path


# a strip: panels coated on both faces, one hinge 2 mm wide (x 4..6) coated on the bottom only
STRIP = """
<g inkscape:groupmode="layer" inkscape:label="Both"><rect x="0" y="0" width="4" height="4"/>
<rect x="6" y="0" width="4" height="4"/></g>
<g id="bottom"><rect x="4" y="0" width="2" height="4"/></g>"""


# -- rasterising ----------------------------------------------------------------------------------

def test_fill_counts_pixel_centres_inside():
    # x from 1.2 to 3.7 covers the centres 1.5, 2.5, 3.5; y from 0 to 2 the centres 0.5, 1.5
    img = fill_polygons([np.array([[1.2, 0.0], [3.7, 0.0], [3.7, 2.0], [1.2, 2.0]])], (3, 5))
    expected = np.zeros((3, 5), bool)
    expected[0:2, 1:4] = True
    np.testing.assert_array_equal(img, expected)


def test_fill_rules_on_a_square_with_a_hole():
    outer = np.array([[0, 0], [6, 0], [6, 6], [0, 6]], float)
    inner = np.array([[2, 2], [4, 2], [4, 4], [2, 4]], float)
    ring = np.ones((6, 6), bool)
    ring[2:4, 2:4] = False
    np.testing.assert_array_equal(fill_polygons([outer, inner], (6, 6), "evenodd"), ring)
    # nonzero: a hole only where the inner loop turns the other way
    assert fill_polygons([outer, inner], (6, 6), "nonzero").all()
    np.testing.assert_array_equal(fill_polygons([outer, inner[::-1]], (6, 6), "nonzero"), ring)


def test_fill_circle_area_matches_pi_r2():
    r = 20.0
    t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    img = fill_polygons([np.column_stack([25 + r * np.cos(t), 25 + r * np.sin(t)])], (50, 50))
    # Gauss's circle problem: the count of lattice points is pi r^2 within about the perimeter / 4
    assert abs(img.sum() - np.pi * r * r) < 0.5 * np.pi * r


def test_fill_rule_is_checked():
    with pytest.raises(ValueError, match="rule: expected one of 'nonzero', 'evenodd'"):
        fill_polygons([], (2, 2), "winding")


# -- SVG drawings ---------------------------------------------------------------------------------

def test_svg_layers_give_the_faces(tmp_path):
    m = svg_masks(svg(tmp_path, STRIP), pixel=0.5)
    assert m.top.shape == (20, 8) and m.film.all()
    hinge = np.zeros((20, 8), bool)
    hinge[8:12] = True  # x from 4 to 6 mm
    np.testing.assert_array_equal(m.bottom, np.ones((20, 8), bool))
    np.testing.assert_array_equal(m.top, ~hinge)
    assert m.shapes == {"top": 0, "bottom": 1, "both": 2, "film": 0}
    des = svg_design(tmp_path / "part.svg", 0.5)
    assert (des.material == Material.CONTRACT_TOP).sum() == hinge.sum()
    assert des.R[0] == pytest.approx(float(gdfe.Calibration().ratio(gdfe.paper.FIG6_D)))


def test_svg_colours_transforms_units_and_holes(tmp_path):
    body = """<g transform="translate(1,0)"><rect x="0" y="0" width="2" height="1" fill="#ff0000"/></g>
    <path d="M 0 2 H 4 V 4 H 0 Z M 1 2.5 h 2 v 1 h -2 z" fill="blue" fill-rule="evenodd"/>
    <rect x="3" y="0" width="1" height="1" fill="none" stroke="black"/>"""
    m = svg_masks(svg(tmp_path, body, size='width="4mm" height="4mm" viewBox="0 0 4 4"'), 0.5, by="colour")
    top = np.zeros((8, 8), bool)
    top[2:6, 6:8] = True  # red rect x 1..3 (translated), page y 0..1 = design y 3..4
    np.testing.assert_array_equal(m.top, top)
    bottom = np.zeros((8, 8), bool)
    bottom[:, 0:4] = True  # blue: y 2..4 on the page = design y 0..2 ...
    bottom[2:6, 1:3] = False  # ... with its hole x 1..3, page y 2.5..3.5
    np.testing.assert_array_equal(m.bottom, bottom)
    # one inch is 25.4 mm, in user units of 1/96 inch
    m = svg_masks(svg(tmp_path, '<g id="both"><rect width="96" height="48"/></g>',
                      size='width="1in" height="0.5in" viewBox="0 0 96 48"'), 0.254)
    assert m.top.shape == (100, 50) and m.top.all()


def test_svg_film_group_crops_and_places_the_design(tmp_path):
    body = STRIP + '<g id="film"><rect x="2" y="1" width="6" height="2"/></g>'
    m = svg_masks(svg(tmp_path, body), 0.5)
    assert m.film.shape == (12, 4) and m.film.all()
    np.testing.assert_allclose(m.origin, [2.0, 1.0])
    des = svg_design(tmp_path / "part.svg", 0.5)
    np.testing.assert_allclose(des.mesh.points[:, :2].min(0), [2.0, 1.0])


@pytest.mark.parametrize("body, match", [
    ('<g id="top"><rect width="1" height="1"/>', r"not well-formed XML at line 4, column \d+"),
    ('<g id="top"><path id="p7" d="M 0 0 L 1 zz 2"/></g>', r"element <path id='p7'> \(line 3\): path data"),
    ('<g id="top"><path d="M 0 0 C 1 1 2"/></g>', "command 'C' takes numbers in groups of 6, got 3"),
    ('<g id="top"><path d="L 0 0"/></g>', "expected it to start with M or m"),
    ('<rect id="r1" width="1" height="1"/>', r"element <rect id='r1'> \(line 3\): a filled shape outside any group"),
    ('<g id="top"><text x="1" y="1">hi</text></g>', "text is not read; convert it to paths"),
    ('<g id="film"><rect width="1" height="1"/></g>', "no filled shape in a top, bottom or both group"),
])
def test_svg_errors_name_the_line_or_element(tmp_path, body, match):
    with pytest.raises(ValueError, match=match):
        svg_masks(svg(tmp_path, body), 0.5)


def test_svg_colour_and_argument_errors(tmp_path):
    with pytest.raises(ValueError, match="fill colour #00ffff is none of the face colours"):
        svg_masks(svg(tmp_path, '<rect width="1" height="1" fill="cyan"/>'), 0.5, by="colour")
    with pytest.raises(ValueError, match="by: expected one of 'layer', 'colour'"):
        svg_masks(svg(tmp_path, STRIP), 0.5, by="id")
    with pytest.raises(ValueError, match="pixel: expected a positive"):
        svg_masks(svg(tmp_path, STRIP), -1)
    with pytest.raises(FileNotFoundError, match="svg: SVG drawing not found"):
        svg_masks(tmp_path / "none.svg", 0.5)


def test_svg_stroke_is_a_sketch(tmp_path):
    path = svg(tmp_path, '<path id="s" d="M 1 1 L 3 1 L 3 3" fill="none" stroke="black"/>')
    P = svg_polyline(path)
    np.testing.assert_allclose(P, [[1, -1], [3, -1], [3, -3]])  # y up
    arc = svg(tmp_path, '<path id="a" d="M 0 0 A 2 2 0 0 1 4 0" fill="none" stroke="black"/>', name="a.svg")
    Q = svg_polyline(arc, spacing=0.1)
    assert len(Q) > 60  # a half circle of 2 mm radius (6.28 mm) at 0.1 mm
    np.testing.assert_allclose(np.linalg.norm(Q - [2.0, 0.0], axis=1), 2.0, atol=1e-6)
    two = svg(tmp_path, '<path id="a" d="M 0 0 L 1 1"/><path id="b" d="M 0 0 L 1 2 L 2 2"/>', name="t.svg")
    with pytest.raises(ValueError, match="expected one stroke to read"):
        svg_polyline(two)
    with pytest.raises(ValueError, match="no path with id 'c'"):
        svg_polyline(two, element_id="c")
    assert len(svg_polyline(two, element_id="b")) == 3


# -- FOLD crease patterns ---------------------------------------------------------------------------

def fold_file(tmp_path, name="one.fold", **changes):
    """Two 4 x 2 mm faces joined by one valley crease at x = 4 mm."""
    doc = {"file_spec": 1.1, "frame_unit": "mm",
           "vertices_coords": [[0, 0], [4, 0], [8, 0], [8, 2], [4, 2], [0, 2]],
           "edges_vertices": [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 0], [1, 4]],
           "edges_assignment": ["B"] * 6 + ["V"], "edges_gdfe:width": [None] * 6 + [1.0],
           "faces_vertices": [[0, 1, 4, 5], [1, 2, 3, 4]]}
    doc.update(changes)
    doc = {k: v for k, v in doc.items() if v is not None}
    path = tmp_path / name
    path.write_text(json.dumps(doc, indent=1))
    return path


def test_fold_crease_becomes_a_hinge_on_the_right_face(tmp_path):
    des = fold_design(fold_file(tmp_path), pixel=0.25)
    i = des.mesh.cell_ij[:, 0]
    hinge = (i >= 14) & (i < 18)  # centres within 0.5 mm of x = 4: 3.625 .. 4.375
    assert set(des.material[hinge]) == {int(Material.CONTRACT_TOP)}  # valley: top face free
    assert set(des.material[~hinge]) == {int(Material.RIGID)}
    assert sorted(des.regions) == ["face_0", "face_1", "hinge_6", "panels"]
    mountain = fold_design(fold_file(tmp_path, edges_assignment=["B"] * 6 + ["M"]), pixel=0.25)
    assert set(mountain.material[hinge]) == {int(Material.CONTRACT_BOTTOM)}
    coated = fold_design(fold_file(tmp_path, **{"edges_gdfe:coated": [None] * 6 + ["top"]}), pixel=0.25)
    assert set(coated.material[hinge]) == {int(Material.CONTRACT_BOTTOM)}
    # without faces the film comes from the boundary loop: the same design
    loop = fold_design(fold_file(tmp_path, faces_vertices=None), pixel=0.25)
    np.testing.assert_array_equal(loop.material, des.material)


def test_fold_of_a_crease_is_the_fan_of_its_cells(tmp_path):
    # uniaxial shrink across the crease: n trapezoids turn by 2n atan((1 - R) L / (2 n h)) (README)
    des = fold_design(fold_file(tmp_path), pixel=0.25, isotropy=0.0)
    res = gdfe.simulate(des).check()
    (crease,) = crease_angles(res)
    R, n, L, h = des.R[0], 4, 1.0, des.h
    assert crease["angle_rad"] == pytest.approx(2 * n * math.atan((1 - R) * L / (2 * n * h)), abs=1e-5)


def test_fold_width_from_fold_angle_by_eq2_and_units(tmp_path):
    path = fold_file(tmp_path, frame_unit="cm", **{"edges_gdfe:width": None, "edges_foldAngle": [0] * 6 + [60]},
                     vertices_coords=[[0, 0], [0.4, 0], [0.8, 0], [0.8, 0.2], [0.4, 0.2], [0, 0.2]])
    des = fold_design(path, pixel=0.1)
    (h,) = des.meta["hinges"]
    R = float(gdfe.Calibration().ratio(gdfe.paper.FIG6_D))
    assert h["width_mm"] == pytest.approx(math.radians(60) * 0.29 / (1 - R))
    assert h["width_from"] == "edges_foldAngle (Eq. 2)"
    assert des.mesh.points[:, 0].max() == pytest.approx(8.0)  # cm -> mm
    cp = read_fold(fold_file(tmp_path, frame_unit=None, **{"gdfe:scale": 2.0}))
    assert cp.vertices.max() == pytest.approx(16.0)


@pytest.mark.parametrize("changes, match", [
    ({"vertices_coords": [[0, 0, 1]] + [[4, 0], [8, 0], [8, 2], [4, 2], [0, 2]]},
     r"vertices_coords\[0\]: expected a flat crease pattern"),
    ({"edges_vertices": [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 9], [1, 4]]},
     r"edges_vertices\[5\]: expected two different vertices in 0..5"),
    ({"edges_assignment": ["B"] * 6 + ["C"]}, r"edges_assignment\[6\]: 'C' \(cut\) is not supported"),
    ({"edges_assignment": ["B"] * 6 + ["X"]}, r"edges_assignment\[6\]: expected one of B, M, V, F, U"),
    ({"edges_foldAngle": [0] * 6 + [45], "edges_assignment": ["B"] * 6 + ["M"]},
     r"edges_foldAngle\[6\]: a mountain fold needs a negative angle"),
    ({"edges_gdfe:width": [None] * 6 + [-1]}, r"edges_gdfe:width\[6\]: expected a positive width"),
    ({"edges_gdfe:width": [None] * 6}, r"edges_gdfe:width: expected 7 entries"),
    ({"edges_gdfe:width": [None] * 7}, r"edges_vertices\[6\] \(V\): no hinge width"),
    ({"edges_gdfe:width": [None] * 6 + [0.05]}, r"edges_vertices\[6\]: a hinge 0.05 mm wide covers no pixel"),
    ({"frame_unit": None}, "frame_unit is 'unit' .*give the scale"),
    ({"frame_unit": "furlong"}, "frame_unit: expected one of unit, mm"),
    ({"frame_unit": ["mm"]}, r"frame_unit: expected one of unit, mm.*got \['mm'\]"),
    ({"frame_unit": 2}, "frame_unit: expected one of unit, mm.*got 2"),
    ({"faces_vertices": [[0, 1]]}, r"faces_vertices\[0\]: expected at least 3 vertex indices"),
    ({"edges_gdfe:coated": [None] * 6 + ["left"]}, r"edges_gdfe:coated\[6\]: expected 'top', 'bottom' or null"),
])
def test_fold_errors_name_the_key_and_entry(tmp_path, changes, match):
    with pytest.raises(ValueError, match=match):
        fold_design(fold_file(tmp_path, **changes), pixel=0.25)


def test_fold_json_errors_name_the_line(tmp_path):
    path = tmp_path / "bad.fold"
    path.write_text('{\n  "vertices_coords": [[0, 0],\n  "edges_vertices": []\n}\n')
    with pytest.raises(ValueError, match=r"bad.fold: not valid JSON at line 3, column \d+"):
        read_fold(path)


# -- design files: .svg, .fold, [svg], [fold] ------------------------------------------------------

def test_load_design_reads_drawings_and_their_tables(tmp_path):
    des, opts = gdfe.load_design(svg(tmp_path, STRIP))
    assert opts == {} and des.meta["kind"] == "svg" and des.mesh.spacing[0] == pytest.approx(0.1)
    fold_file(tmp_path)
    (tmp_path / "one.toml").write_text('[film]\nh = 0.29\nR = 0.8\n\n[fold]\nfile = "one.fold"\npixel = 0.5\n'
                                       '\n[simulate]\nsteps = 2\n')
    des, opts = gdfe.load_design(tmp_path / "one.toml")
    assert opts == {"steps": 2} and des.mesh.spacing[0] == 0.5 and np.allclose(des.R, 0.8)
    (tmp_path / "part.toml").write_text('[film]\nd = 0.33\n[svg]\nfile = "part.svg"\npixel = 0.5\n')
    des, _ = gdfe.load_design(tmp_path / "part.toml")
    assert des.n_cells == 20 * 8
    (tmp_path / "bad.toml").write_text('[film]\nd = 0.33\n[svg]\nfile = "part.svg"\npixels = 0.5\n')
    with pytest.raises(ValueError, match=r"bad.toml: \[svg\]: unknown key 'pixels' \(did you mean 'pixel'\?\)"):
        gdfe.load_design(tmp_path / "bad.toml")
    (tmp_path / "bad2.toml").write_text('[film]\nd = 0.33\n[svg]\nfile = "part.svg"\n')
    with pytest.raises(ValueError, match=r"bad2.toml: \[svg\] is missing 'pixel'"):
        gdfe.load_design(tmp_path / "bad2.toml")


def test_example_drawings_load():
    des, _ = gdfe.load_design(EXAMPLES / "box.toml")
    assert len(des.meta["hinges"]) == 4 and des.mesh.spacing[0] == 0.25
    des, _ = gdfe.load_design(EXAMPLES / "zigzag.svg")
    counts = des.summary()["cells_by_material"]
    assert counts["contract_top"] == 2 * counts["contract_bottom"]  # two valley hinges, one mountain


# -- masks, design files, print packages -------------------------------------------------------------

def test_masks_are_1bit_pngs_with_dpi_that_read_back(tmp_path):
    from PIL import Image

    des = svg_design(svg(tmp_path, STRIP), 0.125)
    masks = face_masks(des)
    files = write_masks(masks, tmp_path, "strip")
    with Image.open(files["top"]) as img:
        assert img.mode == "1" and img.size == (80, 32)
        assert img.info["dpi"][0] == pytest.approx(203.2)  # 25.4 / 0.125
        assert np.asarray(img)[0, 0] == 0  # black = passive (a panel)
    top, pixel = read_mask_png(files["top"])
    np.testing.assert_array_equal(top, masks.top)
    assert pixel == pytest.approx(0.125)
    path = write_design_toml(tmp_path / "strip.toml", files, masks.pixel, {"h": 0.29, "d": 0.33, "nz": 1})
    back, _ = gdfe.load_design(path)
    np.testing.assert_array_equal(back.material, des.material)
    with pytest.raises(ValueError, match="expected square cells for printer masks"):
        face_masks(gdfe.from_rows(["RT"], R=0.7, pixel=(0.1, 0.2), nz=1))


def test_print_package_round_trip_and_atomic(tmp_path):
    des = fold_design(fold_file(tmp_path), pixel=0.25)
    pkg = write_print_package(tmp_path / "out" / "print.zip", {"one": des}, d=0.33, K=gdfe.PAPER_K,
                              source=tmp_path / "one.fold")
    with zipfile.ZipFile(pkg) as zf:
        assert sorted(zf.namelist()) == ["one.toml", "one_bottom.png", "one_top.png", "print.json"]
        info = json.loads(zf.read("print.json"))
    assert info["pixel_mm"] == 0.25 and info["dpi"] == pytest.approx(101.6) and info["d_mm"] == 0.33
    assert info["source"]["sha256"] and info["parts"][0]["nx"] == 32 and info["parts"][0]["ny"] == 8
    assert info["R"] == pytest.approx(float(gdfe.Calibration().ratio(0.33)))  # of the free faces
    designs, _ = read_print_package(pkg)
    np.testing.assert_array_equal(designs["one"].material, des.material)
    np.testing.assert_allclose(designs["one"].R, des.R)
    # a failing package leaves nothing behind
    other = fold_design(fold_file(tmp_path), pixel=0.5)
    with pytest.raises(ValueError, match=r"designs\['b'\]: expected the printer pixel 0.25 mm"):
        write_print_package(tmp_path / "new" / "p.zip", {"a": des, "b": other})
    assert not (tmp_path / "new" / "p.zip").exists()
    with pytest.raises(ValueError, match="path: expected a .zip file name"):
        write_print_package(tmp_path / "p.tar", des)
    (tmp_path / "junk.zip").write_text("not a zip")
    with pytest.raises(ValueError, match="junk.zip: not a zip file"):
        read_print_package(tmp_path / "junk.zip")


# -- shapes out --------------------------------------------------------------------------------------

def _trimesh():
    return pytest.importorskip("trimesh")


def test_flat_export_is_closed_with_the_film_volume(tmp_path):
    trimesh = _trimesh()
    des = fold_design(fold_file(tmp_path), pixel=0.25)
    res = gdfe.simulate(des, steps=2).check()
    paths = export_result(res, tmp_path, "flat", ("stl", "ply", "obj", "fold"), frame=0)
    mesh = trimesh.load(paths["stl"])
    assert mesh.is_watertight and mesh.euler_number == 2
    assert mesh.volume == pytest.approx(des.n_cells * 0.25 * 0.25 * des.h, rel=1e-6)  # the flat print
    # PLY: meshio reads a material code per triangle
    import meshio

    ply = meshio.read(paths["ply"])
    n_v, n_f = len(ply.points), len(ply.cells[0].data)
    assert n_f == len(mesh.faces) and set(ply.cell_data["material"][0]) == {0, 1}
    obj = paths["obj"].read_text()
    assert "mtllib flat.mtl" in obj and "usemtl rigid" in obj and "usemtl contract_top" in obj
    assert "newmtl contract_top" in (tmp_path / "flat.mtl").read_text()
    fold = json.loads(paths["fold"].read_text())
    assert len(fold["file_frames"]) == 2 and fold["frame_gdfe:activation"] == 0.0
    assert len(fold["vertices_coords"]) == n_v and len(fold["faces_vertices"]) == n_f // 2
    with pytest.raises(ValueError, match=r"frame: expected an integer in \[-3, 2\]"):
        export_result(res, tmp_path, "x", ("stl",), frame=3)
    with pytest.raises(ValueError, match="export: expected one of 'stl'"):
        export_result(res, tmp_path, "x", ("step",))


def test_round_trip_svg_to_masks_to_stl(tmp_path):
    """SVG drawing -> design -> printer masks -> design read from the masks -> simulate -> closed STL."""
    trimesh = _trimesh()
    des = svg_design(svg(tmp_path, STRIP), 0.5)
    files = write_masks(face_masks(des), tmp_path, "strip")
    back = gdfe.from_masks(files["top"], files["bottom"], 0.5, des.R[0])
    np.testing.assert_array_equal(back.material, des.material)
    res = gdfe.simulate(back).check()
    stl = export_result(res, tmp_path, "strip", ("stl",))["stl"]
    mesh = trimesh.load(stl)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.euler_number == 2
    # the hinge bent the strip: its ends rose towards +z (valley: top face free)
    assert res.points[:, 2].max() - res.points[:, 2].min() > 1.0
    assert 0 < mesh.volume < des.n_cells * 0.25 * des.h


def test_simulate_exports_beside_the_series(tmp_path, capsys):
    path = fold_file(tmp_path)
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--out", str(out), "--export", "stl,ply,obj,fold,html,zip",
                 "--steps", "2"]) == 0
    text = capsys.readouterr().out
    for suffix in ("stl", "ply", "obj", "fold", "html", "pvd"):
        assert (out / f"one.{suffix}").is_file(), suffix
    designs, info = read_print_package(out / "one_print.zip")
    assert info["d_mm"] == 0.33 and designs["one"].n_cells == 80 * 20  # the paper's film, 0.1 mm pixels
    assert "exported" in text
    assert "exported" in json.loads((out / "result.json").read_text())
    with pytest.raises(SystemExit):
        main(["simulate", str(path), "--out", str(out), "--export", "stl,step"])
    assert "expected formats among stl, obj, ply, fold, html, zip" in capsys.readouterr().err


def test_stl_binary_header_counts_triangles(tmp_path):
    des = svg_design(svg(tmp_path, STRIP), 1.0)
    res = gdfe.simulate(des).check()
    stl = export_result(res, tmp_path, "s", ("stl",))["stl"].read_bytes()
    (n,) = struct.unpack("<I", stl[80:84])
    assert len(stl) == 84 + 50 * n and n == 2 * len(gdfe.io.surface_faces(des)[0])
