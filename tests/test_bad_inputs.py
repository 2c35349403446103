"""Every example of bad input from the hardening issue, each with the message it now gives.

Silent wrong answers become refusals, tracebacks become one-line errors naming the file,
key or argument, slow runs get an estimate first, and the papercuts are gone.
"""

import json
import logging
import math

import numpy as np
import pytest

import gdfe
from gdfe.cli import main


def _run(capsys, argv):
    """``main(argv)``: (exit status, stdout, stderr); a traceback anywhere fails the test."""
    rc = main(argv)
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err
    return rc, cap.out, cap.err


def _error(capsys, argv, match):
    rc, _, err = _run(capsys, argv)
    assert rc == 1, err
    assert err.count("\n") == 1, err  # one line
    assert pytest.importorskip("re").search(match, err), err
    return err


def _toml(tmp_path, text, name="d.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


HINGE = "[film]\nh = 0.29\nR = 0.7\n[hinge]\nlength = 1\n"


# -- silent wrong answers -------------------------------------------------------------------------
def test_loose_tol_is_refused_not_printed_as_converged(capsys):
    _error(capsys, ["hinge", "--length", "2.6", "--d", "0.33", "--tol", "0.1"],
           r"gdfe hinge: error: --tol: expected at most 0\.0001 \(units of h; the default scales with the part\), "
           r"got 0\.1: a looser tolerance can stop far from the shape")


def test_loose_tol_in_a_design_file_is_refused(tmp_path, capsys):
    path = _toml(tmp_path, HINGE + "[simulate]\ntol = 0.01\n")
    _error(capsys, ["simulate", str(path), "--out", str(tmp_path / "o")],
           r"d\.toml: \[simulate\] tol: expected at most 0\.0001")


@pytest.mark.parametrize("text, match", [
    ("[film]\nh = 0.29\nR = 0.7\n[hinge]\nlength = 1\nwidht = 2\n",
     r"d\.toml: \[hinge\]: unknown key 'widht' \(did you mean 'width'\?\); expected some of length, width"),
    ("[film]\nh = 0.29\nR = 0.7\n[layout]\npixle = 0.2\nrows = [\"RRTT\"]\n",
     r"d\.toml: \[layout\]: unknown key 'pixle' \(did you mean 'pixel'\?\)"),
    (HINGE + "[simulte]\nsteps = 2\n",
     r"d\.toml: unknown section \[simulte\] \(did you mean \[simulate\]\?\); expected some of \[film\]"),
    ("[film]\nh = 0.29\nR = \"0.7\"\n[hinge]\nlength = 1\n",
     r"d\.toml: \[film\] R: expected a contraction ratio in \[0\.01, 1\], got '0\.7'"),
    ("[film]\nh = \"0.29\"\nR = 0.7\n[hinge]\nlength = 1\n",
     r"d\.toml: \[film\] h: expected a positive finite number, got '0\.29'"),
    ("[film]\nh = 0.29\nR = true\n[hinge]\nlength = 1\n",
     r"d\.toml: \[film\] R: expected a contraction ratio in \[0\.01, 1\], got True"),
    ("[film]\nh = 0.29\nR = 0.7\nnz = true\n[hinge]\nlength = 1\n",
     r"d\.toml: \[film\] nz: expected an integer >= 1, got True"),
    ("R = 0.7\n[film]\nh = 0.29\n[hinge]\nlength = 1\n",
     r"d\.toml: R = 0\.7 stands outside any section: put it under \[film\]"),
])
def test_design_file_keys_and_values_are_checked(tmp_path, text, match):
    with pytest.raises(gdfe.GdfeError, match=match):
        gdfe.load_design(_toml(tmp_path, text))


def test_a_16_bit_mask_reads_like_an_8_bit_one(tmp_path):
    from PIL import Image

    grey = np.full((3, 4), round(0.24 * 65535), np.uint16)  # 24 % grey: dark, so coated
    grey[0] = 65535  # one white row (the top row of the picture, the largest y)
    Image.fromarray(grey).save(tmp_path / "top16.png")
    Image.fromarray((grey // 257).astype(np.uint8)).save(tmp_path / "top8.png")
    assert Image.open(tmp_path / "top16.png").mode == "I;16"
    white = np.zeros((4, 3), bool)
    a = gdfe.from_masks(tmp_path / "top16.png", white, pixel=0.1, R=0.7)
    b = gdfe.from_masks(tmp_path / "top8.png", white, pixel=0.1, R=0.7)
    np.testing.assert_array_equal(a.material, b.material)
    coated = (a.material == gdfe.Material.CONTRACT_BOTTOM).reshape(3, 4)  # cells j-major: rows are y
    assert coated[:2].all() and not coated[2].any()  # y = 0, 1 coated; the white picture row is y = 2


def test_an_array_of_pixels_means_what_the_same_image_means(tmp_path):
    from PIL import Image

    black = np.zeros((4, 3), np.uint8)  # an all-black picture: passive material everywhere
    Image.fromarray(black.T).save(tmp_path / "black.png")
    white = np.full((4, 3), 255, np.uint8)
    from_array = gdfe.from_masks(black, white, pixel=0.1, R=0.7)
    from_file = gdfe.from_masks(tmp_path / "black.png", white, pixel=0.1, R=0.7)
    np.testing.assert_array_equal(from_array.material, from_file.material)
    assert (from_array.material == gdfe.Material.CONTRACT_BOTTOM).all()
    # booleans are the mask itself; 0/1 integers could mean either, so they are refused
    assert (gdfe.from_masks(np.ones((4, 3), bool), white, 0.1, R=0.7).material == gdfe.Material.CONTRACT_BOTTOM).all()
    with pytest.raises(TypeError, match=r"top: expected a boolean mask \(True = set\) or pixels of type uint8, "
                                        r"uint16 or float in \[0, 1\] \(dark = set\), got an array of int64"):
        gdfe.from_masks(np.zeros((4, 3), np.int64), white, 0.1, R=0.7)
    with pytest.raises(ValueError, match=r"top: expected pixel values in \[0, 1\]"):
        gdfe.from_masks(np.full((4, 3), 255.0), white, 0.1, R=0.7)


def test_calibrate_boot_1_is_refused(capsys):
    _error(capsys, ["calibrate", str(gdfe.TABLE1), "--boot", "1", "--json"],
           r"--boot: expected 0 \(no interval\) or at least 100 resamples for a 95 % interval, got 1")


def test_fem_hinge_refuses_an_expanding_film(capsys):
    _error(capsys, ["fem", "hinge", "--length", "1.6", "--d", "0.33", "--eigenstrain=5", "--nonlinear",
                    "--resolution", "coarse"],
           r"gdfe fem hinge: error: --eigenstrain: expected the film's free contraction R_free - 1 in \(-1, 0\]")


def test_angle_from_ratio_checks_the_ratio():
    with pytest.raises(ValueError, match=r"R: expected a contraction ratio in \[0\.01, 1\], got 1\.5"):
        gdfe.angle_from_ratio(1.5, 1.0)
    with pytest.raises(ValueError, match=r"alpha: expected a fold angle in \[0, L/h\)"):
        gdfe.ratio_from_angle(10.0, 1.0)


# -- tracebacks -----------------------------------------------------------------------------------
def test_not_a_png_mask(tmp_path):
    (tmp_path / "top.png").write_bytes(b"this is not an image")
    with pytest.raises(gdfe.GdfeError, match=r"top: top\.png: not a readable image \(UnidentifiedImageError"):
        gdfe.from_masks(tmp_path / "top.png", np.zeros((2, 2), bool), 0.1, R=0.7)


def test_out_naming_an_existing_file(tmp_path, capsys):
    (tmp_path / "f").write_text("mine")
    _error(capsys, ["hinge", "--length", "1", "--d", "0.33", "--out", str(tmp_path / "f")],
           r"--out: expected a folder, got the file .*f$")
    assert (tmp_path / "f").read_text() == "mine"


def test_identical_angles_in_calibrate(tmp_path, capsys):
    path = tmp_path / "same.csv"
    path.write_text("L_mm,d_mm,h_mm,alpha_rad\n1,0.3,0.29,1\n2,0.3,0.29,1\n3,0.3,0.29,1\n")
    rc, out, _ = _run(capsys, ["calibrate", str(path)])
    assert rc == 0 and "r2     undefined  (about the mean" in out and "every angle is the same" in out
    rc, out, _ = _run(capsys, ["calibrate", str(path), "--json"])
    assert rc == 0 and json.loads(out)["r2"] is None  # JSON has no NaN
    path.write_text("L_mm,d_mm,h_mm,alpha_rad\n1,0.3,0.29,1\n2,0.3,0.29,1\n")
    _error(capsys, ["calibrate", str(path)], r"tests: expected at least 3 folding tests to hold one out for eq1, got 2")


def test_huge_h_is_refused(tmp_path):
    with pytest.raises(gdfe.GdfeError, match=r"d\.toml: \[film\] h: expected a length between 1e-06 and 1e\+06 mm, "
                                             r"got 1e\+308"):
        gdfe.load_design(_toml(tmp_path, "[film]\nh = 1e308\nR = 0.7\n[hinge]\nlength = 1\n"))
    with pytest.raises(gdfe.GdfeError, match="h: expected a length between"):
        gdfe.hinge(1.0, R=0.7, h=1e308)


def test_a_million_cells_across_a_hinge_is_refused_with_an_estimate(capsys):
    _error(capsys, ["hinge", "--length", "1", "--d", "0.33", "--cells", "1000000"],
           r"hinge: expected a design that fits in memory, got 1\.5e\+12 cells, whose mesh alone needs about "
           r"[0-9.]+ [TP]iB \(this machine has")


def test_corrupt_vtu_scan_is_one_error(tmp_path):
    from gdfe.diagnosis.scan import load_measured

    (tmp_path / "scan.vtu").write_text('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid">\n<Piece')
    with pytest.raises(gdfe.GdfeError, match=r"scan\.vtu: expected a readable VTU file, got one meshio cannot read"):
        load_measured(tmp_path / "scan.vtu")


# -- obscure messages -----------------------------------------------------------------------------
def test_a_utf8_byte_order_mark_is_read(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes("\ufeffL_mm,d_mm,h_mm,alpha_rad\n1.5,0.11,0.29,1.75\n3.27,0.15,0.29,2.27\n".encode())
    tests = gdfe.load_folding_tests(path)
    assert len(tests) == 2 and tests.L[0] == 1.5


@pytest.mark.parametrize("loader, suffix", [
    (gdfe.load_folding_tests, ".csv"), (gdfe.load_design, ".toml"), (gdfe.load_model, ".toml")])
def test_binary_files_name_the_file(tmp_path, loader, suffix):
    path = tmp_path / f"data{suffix}"
    path.write_bytes(b"\xb4\x62\xd5\x00\x8f" * 40)
    with pytest.raises(gdfe.GdfeError, match=rf"data\{suffix}: not a text file: expected a .*, got binary data"):
        loader(path)
    path.write_bytes("L_mm,d_mm\n1,2\n".encode("utf-16"))  # no NUL-free UTF-8: another encoding
    with pytest.raises(gdfe.GdfeError, match=rf"data\{suffix}: not"):
        loader(path)
    path.write_bytes(b"L_mm,d_mm,h_mm,alpha_rad\n1,0.3,0.29,caf\xe9\n")
    with pytest.raises(gdfe.GdfeError, match=rf"data\{suffix}: not a UTF-8 text file: .* got byte 0xe9 at line 2"):
        loader(path)


def test_zero_pixel_is_named_pixel(tmp_path):
    with pytest.raises(gdfe.GdfeError, match=r"d\.toml: \[layout\] pixel: expected a positive finite number, got 0"):
        gdfe.load_design(_toml(tmp_path, "[film]\nR = 0.7\n[layout]\npixel = 0\nrows = [\"RRTT\"]\n"))
    with pytest.raises(gdfe.GdfeError, match=r"^pixel: expected a positive finite number, got 0"):
        gdfe.from_rows(["RT"], R=0.7, pixel=0)


def test_nan_thickness_in_folding_tests_is_named():
    t = gdfe.load_folding_tests(gdfe.TABLE1)
    d = t.d.copy()
    d[3] = np.nan
    with pytest.raises(gdfe.GdfeError, match=r"^d: expected finite numbers, got nan at \[3\]"):
        gdfe.Calibration.fit(gdfe.FoldingTests(L=t.L, d=d, h=t.h, alpha=t.alpha), n_boot=0)


# -- silent and slow ------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, match", [
    (["--nz", "2000"], r"this run is large: 768,000 cells: about .* of memory \(this machine has .*\); pass --large"),
    (["--steps", "100000"], r"this run is large: 384 cells x 100000 frames: about .*; pass --large"),
])
def test_large_runs_get_an_estimate_and_need_large(capsys, argv, match):
    _error(capsys, ["hinge", "--length", "1", "--d", "0.33", *argv], match)


def test_a_million_cell_layout_gets_an_estimate(tmp_path, capsys):
    rows = ", ".join(['"' + "RT" * 500 + '"'] * 1000)
    path = _toml(tmp_path, f"[film]\nR = 0.7\n[layout]\npixel = 0.1\nrows = [{rows}]\n")
    _error(capsys, ["simulate", str(path), "--out", str(tmp_path / "o")],
           r"this run is large: 1,000,000 cells: about [0-9.]+ min and [0-9.]+ GiB of memory")
    assert not (tmp_path / "o").exists()


def test_the_library_refuses_a_run_beyond_the_machine(monkeypatch):
    import gdfe.resources

    monkeypatch.setattr(gdfe.resources, "machine_memory", lambda: 50 * 2**20)
    with pytest.raises(gdfe.GdfeError, match=r"design, steps: expected a simulation that fits in memory, got 384 "
                                             r"cells: about .* and [0-9.]+ MiB of memory \(this machine has 50 MiB\)"):
        gdfe.simulate(gdfe.hinge(1.0, d=0.33))


# -- output you cannot trust ----------------------------------------------------------------------
def test_empty_out_is_refused(capsys):
    with pytest.raises(SystemExit):
        main(["hinge", "--length", "1", "--d", "0.33", "--out", ""])
    assert "argument --out: expected the name of a folder, got ''" in capsys.readouterr().err


def test_a_non_converged_result_is_marked(tmp_path, capsys, monkeypatch):
    import gdfe.io

    titles = []
    monkeypatch.setattr(gdfe.io, "render_png", lambda res, path, title=None, **kw: titles.append(title) or path)
    rc, out, err = _run(capsys, ["hinge", "--length", "1", "--d", "0.33", "--method", "plain", "--max-iter", "3",
                                 "--out", str(tmp_path / "o"), "--json"])
    assert rc == 3 and "did not converge" in err
    summary = json.loads(out)
    assert summary["converged"] is False and summary["status"] == "NOT CONVERGED"
    assert titles[0].startswith("NOT CONVERGED (residual ")
    manifest = json.loads((tmp_path / "o" / "gdfe-manifest.json").read_text())
    assert manifest["converged"] is False and manifest["complete"] is True


# -- papercuts ------------------------------------------------------------------------------------
def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"gdfe {gdfe.__version__}"


def test_verbose_after_the_subcommand(capsys):
    rc, _, err = _run(capsys, ["hinge", "-L", "1", "--d", "0.33", "-v"])
    assert rc == 0 and "INFO gdfe.solver.simulation: GDFE newton-cg: 384 cells" in err


def test_json_means_the_same_on_every_subcommand(tmp_path, capsys):
    rc, out, _ = _run(capsys, ["calibrate", str(gdfe.TABLE1), "--boot", "0", "--json"])
    assert rc == 0 and json.loads(out)["model"] == "eq1"
    rc, out, _ = _run(capsys, ["calibrate", str(gdfe.TABLE1), "--boot", "0", "--json", "-"])
    assert rc == 0 and json.loads(out)["model"] == "eq1"
    rc, out, _ = _run(capsys, ["calibrate", str(gdfe.TABLE1), "--boot", "0", "--json", str(tmp_path / "c.json")])
    assert rc == 0 and out.startswith("model  eq1") and f"wrote {tmp_path / 'c.json'}" in out
    assert json.loads((tmp_path / "c.json").read_text())["model"] == "eq1"
    rc, out, _ = _run(capsys, ["hinge", "-L", "1", "--d", "0.33", "--json", str(tmp_path / "h.json")])
    assert rc == 0 and "GDFE fold angle" in out and json.loads((tmp_path / "h.json").read_text())["converged"]
    rc, out, _ = _run(capsys, ["diagnose", str(gdfe.TABLE1), "--check", "none", "--no-pairs", "--json"])
    assert rc == 0 and "verdict" in json.loads(out)
    # a file that is not .json is refused: it is most likely the input, misplaced
    with pytest.raises(SystemExit):
        main(["calibrate", "--json", str(gdfe.TABLE1)])
    assert "--json: expected FILE.json, or nothing (or '-') for standard output" in capsys.readouterr().err


def test_the_iteration_count_says_it_sums_frames(capsys):
    rc, out, _ = _run(capsys, ["hinge", "-L", "1", "--d", "0.33", "--steps", "3"])
    assert rc == 0
    line = next(x for x in out.splitlines() if "iterations" in x)
    assert pytest.importorskip("re").search(r"converged in \d+ iterations over 3 frames \(\d+-\d+ per frame\)", line)


def test_simulate_prints_the_fold_angles_it_measured(tmp_path, capsys):
    path = _toml(tmp_path, '[film]\nd = 0.33\n[layout]\npixel = 0.25\nrows = ["RRRTTTRRRBBBRRR", '
                           '"RRRTTTRRRBBBRRR"]\n', "zig.toml")
    rc, out, _ = _run(capsys, ["simulate", str(path), "--out", str(tmp_path / "o")])
    assert rc == 0
    # the T hinge folds the top face inside (positive, as fold_angle signs a strip's), the B hinge the other way
    assert pytest.importorskip("re").search(r"fold angles \(2\) panels 1-2: [0-9.]+ rad, panels 2-3: -[0-9.]+ rad", out)
    summary = json.loads((tmp_path / "o" / "result.json").read_text())
    assert [r["panels"] for r in summary["panel_angles"]] == [[1, 2], [2, 3]]
    assert all(0.3 < s * r["angle_rad"] < 1.5 for s, r in zip((1, -1), summary["panel_angles"]))


def test_a_designs_d_reaches_its_result(tmp_path, capsys):
    path = _toml(tmp_path, '[film]\nd = 0.4\n[layout]\npixel = 0.25\nrows = ["RRTTRR", "RRTTRR"]\n', "s.toml")
    rc, out, _ = _run(capsys, ["simulate", str(path), "--out", str(tmp_path / "o"), "--json"])
    summary = json.loads(out)
    assert rc == 0 and summary["d_mm"] == 0.4 and summary["nz"] == 1
    rc, out, _ = _run(capsys, ["simulate", str(path), "--out", str(tmp_path / "o")])
    assert "film h = 0.29 mm, d = 0.4 mm, nz = 1" in out


def test_vtu_material_codes_are_named(tmp_path):
    import meshio

    from gdfe.io import MATERIAL_CODES, write_series

    res = gdfe.simulate(gdfe.hinge(1.0, d=0.33))
    pvd = write_series(res, tmp_path, "h")
    m = meshio.read(tmp_path / "h_001.vtu")
    assert {k: int(v[0]) for k, v in m.field_data.items()} == {
        "material_rigid": 0, "material_contract_top": 1, "material_contract_bottom": 2, "material_free_shrink": 3}
    assert "0 = rigid (both faces coated)" in pvd.read_text()
    assert set(MATERIAL_CODES) == {int(c) for c in gdfe.Material}


def test_one_default_for_nz(tmp_path):
    from gdfe.mesh import DEFAULT_NZ

    layers = lambda des: int(des.mesh.cell_k.max()) + 1  # noqa: E731
    assert DEFAULT_NZ == 1
    assert layers(gdfe.hinge(1.0, R=0.7)) == DEFAULT_NZ
    assert layers(gdfe.from_rows(["RT"], R=0.7)) == DEFAULT_NZ
    assert layers(gdfe.from_masks(np.ones((2, 2), bool), np.zeros((2, 2), bool), 0.1, R=0.7)) == DEFAULT_NZ
    assert layers(gdfe.load_design(_toml(tmp_path, HINGE))[0]) == DEFAULT_NZ
    assert layers(gdfe.load_design(_toml(tmp_path, '[film]\nR = 0.7\n[layout]\npixel = 0.2\nrows = ["RT"]\n'))[0]) == 1


def test_repeated_warnings_are_said_once(tmp_path, capsys):
    # a layout of elongated cells warns at every design it makes (here: the design and its probe)
    path = _toml(tmp_path, '[film]\nR = 0.7\n[layout]\npixel = [0.4, 0.1]\nrows = ["RTR"]\n', "long.toml")
    for _ in range(2):
        gdfe.load_design(path)
    logging.getLogger("gdfe.design").warning("a repeated warning")
    rc, _, err = _run(capsys, ["simulate", str(path), "--out", str(tmp_path / "o")])
    rc, _, err2 = _run(capsys, ["simulate", str(path), "--out", str(tmp_path / "o")])
    assert err.count("elongated cells stiffen the fold") == 1 and err2.count("elongated cells") == 1
    from gdfe.cli._main import _Once

    once = _Once()
    rec = logging.LogRecord("gdfe.x", logging.WARNING, __file__, 1, "same %s", ("thing",), None)
    assert once.filter(rec) and not once.filter(rec)


def test_panel_angles_agree_with_the_hinge_fold_angle():
    from gdfe.measure import panel_angles

    res = gdfe.simulate(gdfe.hinge(1.0, d=0.33))
    (row,) = panel_angles(res)
    # whole panels against fold_angle's outer parts of them: the columns next to the hinge warp
    # with it (isotropic shrink), a difference of 2.5e-4 rad here
    assert row["panels"] == [1, 2] and row["hinge_cells"] == 16 * 8
    assert math.isclose(row["angle_rad"], gdfe.fold_angle(res), abs_tol=1e-3)


# -- found by the property tests (tests/test_properties.py) and the catalogue -----------------------
def test_argument_mistakes_are_one_line(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["hinge", "-L", "abc"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err == ("gdfe hinge: error: argument --length/-L: invalid float value: 'abc' "
                                           "(options: gdfe hinge --help)\n")


def test_cells_too_long_for_their_fold_are_refused(capsys):
    # a cell longer than half the circumference pi h/(1 - R) of the circle the film rolls into: the
    # solver spent minutes in its contact steps (h = 0.05, R = 0.05) or 11 minutes silently (-L 1e5)
    with pytest.raises(gdfe.GdfeError, match=r"^cell_size: expected cells of at most half the circumference of the "
                                             r"circle the film rolls into \(pi h/\(1 - R\) = 0\.165 mm for h = 0\.05 mm, "
                                             r"R = 0\.05\), got 0\.167 mm: each cell would turn by 3\.17 rad, more than "
                                             r"half a turn"):
        gdfe.hinge(2.6, R=0.05, h=0.05)
    with pytest.raises(gdfe.GdfeError, match=r"^pixel: expected cells of at most half .* \(pi h/\(1 - R\) = 0\.349 mm "
                                             r"for h = 0\.1 mm, R = 0\.1\), got 0\.5 mm: each cell would turn by 4\.5 rad"):
        gdfe.from_rows(["RTTR"], R=0.1, h=0.1, pixel=0.5)
    _error(capsys, ["hinge", "-L", "1e5", "--d", "0.33", "--cells", "16"],
           r"--cells 16: expected cells of at most half the circumference .* got 6\.25e\+03 mm")
    _error(capsys, ["hinge", "-L", "1e5", "--d", "0.33"], r"this run is large: 800,016 cells")
    assert gdfe.hinge(2.6, d=0.33, cell_size=2.6).n_cells  # one cell turning by 2.74 rad: coarse, allowed


def test_the_hinge_command_makes_square_cells(capsys):
    rc, out, _ = _run(capsys, ["hinge", "-L", "8", "--d", "0.33", "--json"])
    # 16 cells of 0.5 mm would be twice as long as the strip's 0.25 mm rows: 32 cells of 0.25 mm
    assert json.loads(out)["n_elements"] == gdfe.hinge(8.0, d=0.33).n_cells == (32 + 2 * 4) * 2
    with pytest.raises(gdfe.GdfeError, match=r"^cell_size: expected at most the hinge's length 1 mm"):
        gdfe.hinge(1.0, d=0.33, cell_size=5.0)


def test_library_arguments_found_by_the_catalogue():
    with pytest.raises(gdfe.GdfeError, match=r"^process: expected a mapping of process variables"):
        gdfe.hinge(1.0, d=0.33, process="x")
    with pytest.raises(gdfe.GdfeError, match=r"^process: T_C: expected a finite number or a text label, got nan"):
        gdfe.hinge(1.0, d=0.33, process={"T_C": math.nan})
    with pytest.raises(TypeError, match=r"^length: expected a positive finite number, got \[1\.0\]"):
        gdfe.hinge([1.0], d=0.33)
    with pytest.raises(TypeError, match=r"^R: expected a contraction ratio in \[0\.01, 1\], got True"):
        gdfe.from_masks(np.zeros((2, 2), bool), np.ones((2, 2), bool), 0.1, R=True)
    with pytest.raises(gdfe.GdfeError, match=r"^a: expected finite numbers, got nan at \[0, 0\]"):
        gdfe.shape_distance(np.full((4, 3), np.nan), np.zeros((4, 3)))
    with pytest.raises(gdfe.GdfeError, match=r"^rows: expected at least one cell of film \(R T B S\), got only '\.'"):
        gdfe.from_rows(["...."], R=0.7)


def test_a_design_files_layout_errors_name_their_section(tmp_path):
    with pytest.raises(gdfe.GdfeError, match=r"^d\.toml: \[layout\] pixel: expected cells of at most half"):
        gdfe.load_design(_toml(tmp_path, '[film]\nR = 0.7\n[layout]\npixel = [1, 4]\nrows = ["RT"]\n'))
    with pytest.raises(gdfe.GdfeError, match=r"^d\.toml: \[film\] d=0\.1 mm gives R="):
        gdfe.load_design(_toml(tmp_path, "[film]\nd = 0.1\n[hinge]\nlength = 1\n"))
    design, options = gdfe.load_design(_toml(tmp_path, HINGE + '[simulate]\nmethod = "bogus"\n'))
    with pytest.raises(gdfe.GdfeError, match=r"^method: expected one of .*'auto'.*, got 'bogus'"):
        gdfe.simulate(design, **options)


def test_a_loose_tol_is_said_by_the_library(caplog):
    res = gdfe.simulate(gdfe.hinge(1.0, d=0.33), tol=0.01)
    assert res.converged  # its test passed, and the log says what that means
    assert "tol = 0.01 is looser than 0.0001 (units of h): such a solve can stop far from the shape" in caplog.text


def test_calibrate_says_when_there_is_no_interval(capsys):
    rc, out, _ = _run(capsys, ["calibrate", str(gdfe.TABLE1), "--boot", "0"])
    assert rc == 0 and "K      0.0608  (no interval: no bootstrap was run)" in out and "CI" not in out
    rc, out, _ = _run(capsys, ["calibrate", str(gdfe.TABLE1), "--boot", "0", "--json"])
    assert json.loads(out)["K_ci95"] == [None, None]
    _error(capsys, ["calibrate", str(gdfe.TABLE1), "--boot", "0", "--d", "0.01"],
           r"--d: expected a passive thickness above 0\.04486 mm, where Eq\. 3 of the eq1 reading gives R > 0 "
           r"\(h = 0\.29 mm\), got 0\.01 mm \(R = -8\.501\)")


def test_paths_that_cannot_be_written(tmp_path, capsys):
    _error(capsys, ["hinge", "-L", "1", "--d", "0.33", "--out", "/proc/gdfe-out"],
           r"--out: cannot create the folder /proc/gdfe-out")
    (tmp_path / "f").write_text("x")
    _error(capsys, ["hinge", "-L", "1", "--d", "0.33", "--out", str(tmp_path / "f" / "sub")],
           r"--out: cannot create the folder .*sub: .*f is a file")
    import shutil

    data = tmp_path / "t.csv"
    shutil.copy(gdfe.TABLE1, data)
    for argv in (["view", str(tmp_path), "--html", ""], ["calibrate", str(data), "--model-out", str(tmp_path)],
                 ["calibrate", ""], ["calibrate", str(data), "--model-out", str(data)]):
        with pytest.raises(SystemExit):
            main(argv)
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "expected " in err, err
    assert data.read_bytes() == gdfe.TABLE1.read_bytes()  # --model-out t.csv wrote a model over the data
    from gdfe.io import write_text

    with pytest.raises(gdfe.GdfeError, match="expected the name of a file to write, got a folder"):
        write_text(tmp_path, "x")


def test_the_corrupt_vtu_through_diagnose_shape_and_its_command(tmp_path, capsys):
    from gdfe.diagnosis.shape import diagnose_shape

    vtu = tmp_path / "scan.vtu"
    vtu.write_text('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid">\n<Piece')
    design = _toml(tmp_path, "[film]\nd = 0.33\n[hinge]\nlength = 1\n")
    with pytest.raises(gdfe.GdfeError, match=r"scan\.vtu: expected a readable VTU file, got one meshio cannot read"):
        diagnose_shape(design, vtu, correct=False)
    _error(capsys, ["diagnose-shape", str(design), str(vtu)], r"scan\.vtu: expected a readable VTU file")
    with pytest.raises(gdfe.GdfeError, match=r"^measured: expected coordinates within \+-1e\+06 mm, got 1e\+300"):
        diagnose_shape(design, np.full((5, 3), 1e300), correct=False)


def test_not_a_png_mask_through_simulate(tmp_path, capsys):
    (tmp_path / "top.png").write_bytes(b"this is not an image")
    (tmp_path / "bottom.png").write_bytes(b"this is not an image")
    path = _toml(tmp_path, '[film]\nR = 0.7\n[masks]\npixel = 0.1\ntop = "top.png"\nbottom = "bottom.png"\n')
    _error(capsys, ["simulate", str(path), "--out", str(tmp_path / "o")],
           r"d\.toml: \[masks\] top: top\.png: not a readable image \(UnidentifiedImageError")


def test_every_subcommand_takes_json_the_same_way():
    from gdfe.cli._common import _JsonAction
    from gdfe.cli._main import _subparsers, build_parser

    leaves = [p for p in _subparsers(build_parser()) if not any(
        a.__class__.__name__ == "_SubParsersAction" for a in p._actions)]
    assert len(leaves) >= 12
    for p in leaves:
        (action,) = [a for a in p._actions if "--json" in a.option_strings]
        assert isinstance(action, _JsonAction) and action.nargs == "?" and action.const == "-", p.prog


def test_progress_bars_show_frames_and_residuals_and_can_be_silenced(capsys):
    rc, _, err = _run(capsys, ["hinge", "-L", "1", "--d", "0.33", "--steps", "2", "--method", "newton", "--progress"])
    assert rc == 0 and "solving" in err and "frame 2/2, residual" in err and " h, estimate " in err
    rc, _, err = _run(capsys, ["hinge", "-L", "1", "--d", "0.33", "--steps", "2", "--progress", "-q"])
    assert rc == 0 and err == ""
