"""Designs, measurements, output files and the command line."""

import json

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.design import Material


# -- designs --------------------------------------------------------------------------------
def test_rows_layout_maps_characters_and_voids():
    des = gdfe.from_rows(["RT.", "BSR"], R=0.8, pixel=0.2, nz=1)
    assert des.n_cells == 5  # one void
    codes = {tuple(ij): int(m) for ij, m in zip(des.mesh.cell_ij, des.material)}
    # first row is the top row (largest y)
    assert codes[(0, 1)] == Material.RIGID and codes[(1, 1)] == Material.CONTRACT_TOP
    assert codes[(0, 0)] == Material.CONTRACT_BOTTOM and codes[(1, 0)] == Material.FREE_SHRINK
    assert (2, 1) not in codes


@pytest.mark.parametrize("rows, match", [
    (["RT", "R"], "same length"),
    (["RX"], "unknown layout character"),
    ("RT", "non-empty list of strings"),
])
def test_rows_layout_errors(rows, match):
    with pytest.raises(ValueError, match=match):
        gdfe.from_rows(rows, R=0.8)


def test_masks_from_arrays_and_png(tmp_path):
    from PIL import Image

    top = np.zeros((4, 3), bool)
    bottom = np.zeros((4, 3), bool)
    top[0] = bottom[0] = True  # rigid
    bottom[1] = True  # top free
    top[2] = True  # bottom free
    des = gdfe.from_masks(top, bottom, pixel=0.1, R=0.7)
    mat = des.material.reshape(3, 4).T  # cells are row-major (j slow)
    assert (mat[0] == Material.RIGID).all() and (mat[1] == Material.CONTRACT_TOP).all()
    assert (mat[2] == Material.CONTRACT_BOTTOM).all() and (mat[3] == Material.FREE_SHRINK).all()
    # the same masks as images: dark = passive; image row 0 is the largest y
    for name, m in (("top", top), ("bottom", bottom)):
        Image.fromarray(np.where(m.T[::-1], 0, 255).astype(np.uint8)).save(tmp_path / f"{name}.png")
    des2 = gdfe.from_masks(tmp_path / "top.png", tmp_path / "bottom.png", pixel=0.1, R=0.7)
    np.testing.assert_array_equal(des2.material, des.material)
    with pytest.raises(ValueError, match=r"bottom: expected a mask of shape \(4, 3\)"):
        gdfe.from_masks(top, bottom[:3], pixel=0.1, R=0.7)
    with pytest.raises(FileNotFoundError, match="top: mask image not found"):
        gdfe.from_masks(tmp_path / "none.png", bottom, pixel=0.1, R=0.7)


@pytest.mark.parametrize("kwargs, match", [
    (dict(length=-1.0, d=0.33), "length: expected a positive"),
    (dict(length=1.0), "give the passive thickness d"),
    (dict(length=1.0, R=1.5), r"R: expected a contraction ratio in \[0\.01, 1\]"),
    (dict(length=1.0, R=0.0), r"R: expected a contraction ratio in \[0\.01, 1\]"),
    (dict(length=1.0, R=0.8, width=0.0), "width: expected a positive"),
    (dict(length=1.0, R=0.8, face="left"), "face: expected one of 'top', 'bottom', got 'left'"),
    (dict(length=1.0, R=0.8, isotropy=2.0), r"isotropy: expected a number in \[0, 1\]"),
    (dict(length=1.0, R=0.8, nz=0), "nz: expected an integer >= 1"),
])
def test_hinge_input_checks(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gdfe.hinge(**kwargs)


def test_design_rejects_bad_material_codes():
    des = gdfe.hinge(1.0, R=0.8)
    with pytest.raises(ValueError, match="material: expected codes"):
        gdfe.Design(mesh=des.mesh, material=np.full(des.n_cells, 7), R=0.8, h=0.29)


def _write(tmp_path, text, name="d.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_toml_designs(tmp_path):
    des, opts = gdfe.load_design(_write(tmp_path, "[film]\nd = 0.33\n[hinge]\nlength = 1.6\n"
                                                  "[simulate]\nsteps = 3\n"))
    assert des.meta["R"] == pytest.approx(gdfe.Calibration().ratio(0.33))
    assert opts == {"steps": 3}
    des, _ = gdfe.load_design(_write(tmp_path, '[film]\nR = 0.7\nnz = 1\n[layout]\npixel = 0.2\n'
                                               'rows = ["RRTTRR", "RRTTRR"]\n'))
    assert des.n_cells == 12 and (des.material == Material.CONTRACT_TOP).sum() == 4


@pytest.mark.parametrize("text, match", [
    ("[hinge]\nlength = 1\n", r"missing \[film\] table"),
    ("[film]\nR = 0.7\nfoo = 1\n[hinge]\nlength = 1\n", r"\[film\]: unknown key 'foo'"),
    ("[film]\nh = 0.29\n[hinge]\nlength = 1\n", "needs R .* or d"),
    ("[film]\nR = 0.7\n", r"exactly one of \[hinge\], \[layout\], \[masks\]"),
    ("[film]\nR = 0.7\n[hinge]\nwidth = 1\n", r"\[hinge\] is missing 'length'"),
    ("[film]\nR = 0.7\n[hinge]\nlength = 1\n[simulate]\nspeed = 2\n", r"\[simulate\]: unknown key 'speed'"),
    ("[film\nR = 0.7\n", "not valid TOML"),
    ("[film]\nd = 0.11\n[hinge]\nlength = 1\n", "d=0.11 mm gives R="),
])
def test_toml_errors(tmp_path, text, match):
    with pytest.raises(ValueError, match=match):
        gdfe.load_design(_write(tmp_path, text))


# -- measurements ---------------------------------------------------------------------------
def test_curvature_of_a_uniaxial_hinge_is_the_eq2_curvature():
    R, h = 0.7, 0.29
    res = gdfe.simulate(gdfe.hinge(2.0, R=R, h=h, isotropy=0.0)).check()
    prof = gdfe.curvature_profile(res, cells=res.design.region_cells("hinge"))
    # the coated face (length l per cell) lies at radius r + h, the free one (R l) at r:
    # r = R h / (1 - R), and the mid-surface, where column centroids lie, has curvature
    # 1 / (r + h/2) = 2 (1 - R) / (h (1 + R)); centroid chords differ from arcs at O(dx^2)
    np.testing.assert_allclose(prof["kappa"], 2 * (1 - R) / (h * (1 + R)), rtol=1e-3)
    assert prof["turn"] == pytest.approx(gdfe.fold_angle(res), rel=0.1)


def test_fold_angle_beyond_pi():
    res = gdfe.simulate(gdfe.hinge(4.0, R=0.7, isotropy=0.0, width=0.25, cell_size=4.0 / 16)).check()
    assert gdfe.fold_angle(res) == pytest.approx(2 * 16 * np.arctan(0.3 * 4 / (2 * 16 * 0.29)), abs=1e-4)
    assert gdfe.fold_angle(res) > np.pi


def test_shape_distance_ignores_rigid_motions():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((30, 3))
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    Q *= np.linalg.det(Q)
    d = gdfe.shape_distance(a, a @ Q.T + [1, 2, 3])
    assert d["max"] < 1e-12
    assert gdfe.shape_distance(a, a + [[0, 0, 0.1]] * np.eye(30)[:, :1])["max"] > 0.05
    with pytest.raises(ValueError, match=r"expected two \(n, 3\) arrays"):
        gdfe.shape_distance(a, a[:5])


# -- output files ---------------------------------------------------------------------------
def test_vtu_series_and_png(tmp_path):
    import meshio

    from gdfe.io import _render_matplotlib, render_png, surface_faces, write_series

    res = gdfe.simulate(gdfe.hinge(1.0, d=0.33), steps=2).check()
    pvd = write_series(res, tmp_path, "h")
    text = pvd.read_text()
    assert text.count("<DataSet") == 3 and 'timestep="1"' in text
    m = meshio.read(tmp_path / "h_002.vtu")
    np.testing.assert_allclose(m.points, res.points)
    np.testing.assert_array_equal(m.cell_data["material"][0], res.design.material)
    png = render_png(res, tmp_path / "h.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    faces, _ = surface_faces(res.design)
    colours = np.zeros((len(faces), 3), np.uint8)
    _render_matplotlib(res.points, faces, colours, tmp_path / "m.png", "t", (300, 200))
    assert (tmp_path / "m.png").stat().st_size > 1000
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary leftovers


# -- the command line -----------------------------------------------------------------------
def test_cli_hinge_json(capsys):
    assert main(["hinge", "--length", "1.6", "--d", "0.33", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("fold_angle_rad", "fold_angle_eq1_rad", "R", "iterations", "converged", "seconds", "n_cells"):
        assert key in out
    assert out["converged"] is True
    assert abs(out["fold_angle_rad"] - out["fold_angle_eq1_rad"]) < 0.03
    assert out["fold_angle_eq1_rad"] == pytest.approx(1.684, abs=1e-3)


def test_cli_hinge_writes_files(tmp_path, capsys):
    assert main(["hinge", "-L", "1", "--R", "0.8", "--steps", "2", "--out", str(tmp_path)]) == 0
    assert "converged" in capsys.readouterr().out
    for name in ("hinge.pvd", "hinge_002.vtu", "hinge.png", "result.json"):
        assert (tmp_path / name).is_file()


@pytest.mark.parametrize("argv, match", [
    (["hinge", "--length", "1", "--d", "0.11"], "d=0.11 mm gives R="),
    (["hinge", "--length", "-1", "--d", "0.33"], "length: expected a positive"),
    (["hinge", "--length", "1"], "give --d"),
    (["simulate", "nope.toml", "--out", "x"], "design file not found"),
])
def test_cli_errors_are_one_line(argv, match, capsys):
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert pytest.importorskip("re").search(match, err)


def test_cli_non_convergence_exits_nonzero(capsys):
    assert main(["hinge", "--length", "1", "--d", "0.33", "--method", "plain", "--max-iter", "3"]) == 3
    assert "did not converge" in capsys.readouterr().err


def test_cli_simulate(tmp_path, capsys):
    design = _write(tmp_path, '[film]\nR = 0.7\nnz = 1\n[layout]\npixel = 0.25\n'
                              'rows = ["RRRTTTRRR", "RRRTTTRRR"]\n[simulate]\nsteps = 2\n', "strip.toml")
    assert main(["simulate", str(design), "--out", str(tmp_path / "o"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["converged"] and out["frames"] == 3
    assert (tmp_path / "o" / "strip.pvd").is_file() and (tmp_path / "o" / "strip.png").is_file()
