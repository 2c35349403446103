"""Inputs that used to give a silent wrong answer or a traceback on the data and design surfaces:
each is now refused with its file, row, column or key named, or warned of."""
from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import gdfe
from gdfe.cli import main
from gdfe._validation import data_float
from gdfe.diagnosis import diagnose


def _run(capsys, argv):
    """``main(argv)``: (exit status, stderr); a traceback anywhere fails the test."""
    rc = main([str(a) for a in argv])
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err
    return rc, cap.err


def _refused(capsys, argv, match):
    rc, err = _run(capsys, argv)
    assert rc == 1, err
    assert err.count("\n") == 1, err  # one line
    assert re.search(match, err), err


def _table1(tmp_path, edit=None):
    lines = Path(gdfe.TABLE1).read_text().splitlines()
    if edit is not None:
        lines = edit(lines)
    path = tmp_path / "tests.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


# --- design files: R beside d --------------------------------------------------------------------------


def test_a_design_file_giving_R_and_d_is_refused_as_the_hinge_command_refuses_them(tmp_path):
    f = tmp_path / "both.toml"
    f.write_text("[film]\nR = 0.9\nd = 0.33\n[hinge]\nlength = 1.0\n")
    with pytest.raises(gdfe.GdfeError, match=r"both\.toml: \[film\] gives R = 0\.9 and d = 0\.33 mm; expected one"):
        gdfe.load_design(f)
    f.write_text("[film]\nd = 0.33\n[hinge]\nlength = 1.0\n")  # d alone: R from Eq. 3
    assert gdfe.load_design(f)[0].meta["R"] == pytest.approx(gdfe.Calibration().ratio(0.33))


def test_mask_coat_thicknesses_beside_R_are_refused(tmp_path):
    Image.fromarray(np.full((4, 6), 255, np.uint8)).save(tmp_path / "white.png")
    Image.fromarray(np.zeros((4, 6), np.uint8)).save(tmp_path / "black.png")
    f = tmp_path / "masks.toml"
    f.write_text('[film]\nR = 0.9\n[masks]\npixel = 0.1\ntop = "white.png"\nbottom = "black.png"\n'
                 'd_top = 0.2\nd_bottom = 0.5\n')
    with pytest.raises(gdfe.GdfeError, match=r"masks\.toml: \[masks\] d_top, d_bottom: expected no coat thickness "
                                             r"beside \[film\] R = 0\.9"):
        gdfe.load_design(f)
    f.write_text('[film]\nh = 0.29\n[masks]\npixel = 0.1\ntop = "white.png"\nbottom = "black.png"\n'
                 'd_top = 0.2\nd_bottom = 0.5\n')
    assert gdfe.load_design(f)[0].n_cells == 24  # the thicknesses alone: R from Eq. 3 per face


# --- the command line's --json FILE --------------------------------------------------------------------


def test_an_unwritable_json_file_is_one_line_before_any_output_is_written(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    out = tmp_path / "model" / "m.toml"
    _refused(capsys, ["calibrate", gdfe.TABLE1, "--boot", "0", "--json", blocker / "x.json", "--model-out", out],
             r"--json: cannot create the file .*a_file is a file")
    assert not out.exists() and not out.parent.exists()


def test_a_negative_plan_seed_is_refused_naming_the_option(capsys):
    _refused(capsys, ["plan", gdfe.TABLE1, "--seed", "-1"], r"--seed: expected an integer >= 0, got -1")


# --- numbers in data files -----------------------------------------------------------------------------


@pytest.mark.parametrize("text", ["1_50", "1_000.5", "\u0661\u0665", "\uff11.5"])
def test_data_float_refuses_what_only_python_reads_as_a_number(text):
    assert float(text) > 0  # Python reads each of them
    with pytest.raises(ValueError):
        data_float(text)


def test_data_float_reads_plain_numbers():
    assert [data_float(t) for t in (" 1.5 ", "-2", "1e-3", ".5", "3.")] == [1.5, -2.0, 1e-3, 0.5, 3.0]
    assert np.isnan(data_float("nan")) and data_float("inf") == np.inf  # refused as not finite by the readers


def test_a_digit_separator_in_the_folding_tests_is_refused_with_its_row_and_column(tmp_path):
    path = _table1(tmp_path, lambda lines: [lines[0], "1_50" + lines[1][4:]] + lines[2:])
    with pytest.raises(gdfe.GdfeError, match=r"tests\.csv: row 2, column L_mm: expected a number, got '1_50'"):
        gdfe.load_folding_tests(path)


def test_a_row_pasted_twice_is_warned_of(tmp_path, caplog):
    path = _table1(tmp_path, lambda lines: lines + [lines[1], lines[3]])
    n = len(Path(gdfe.TABLE1).read_text().splitlines())
    with caplog.at_level(logging.WARNING, logger="gdfe.calibration"):
        tests = gdfe.load_folding_tests(path)
    assert len(tests) == n + 1
    assert f"row(s) {n + 1} (= 2), {n + 2} (= 4) repeat an earlier row" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="gdfe.calibration"):
        gdfe.load_folding_tests(gdfe.TABLE1)
    assert "repeat" not in caplog.text  # Table 1 has no such row


# --- gdfe predict's specimens ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("model") / "m.toml"
    assert main(["calibrate", str(gdfe.TABLE1), "--boot", "0", "--model-out", str(path)]) == 0
    return path


@pytest.mark.parametrize("csv, match", [
    ("L_mm,d_mm,h_mn\n2.6,0.33,0.5\n", r"column 'h_mn': did you mean 'h_mm'\?"),
    ("L_mm,d_mm,alpha_deg\n2.6,0.33,52\n", r"column 'alpha_deg': did you mean 'alpha_rad'\?"),
    ("L_mm,d_mm,alpha_rad\n2.6,0.33,52\n", r"row 2, column alpha_rad: expected a fold angle in radians .*\(degrees\?\)"),
    ("L_mm,d_mm\n2_6,0.33\n", r"row 2, column L_mm: expected a number, got '2_6'"),
])
def test_specimens_that_would_be_misread_are_refused(tmp_path, capsys, model_file, csv, match):
    (tmp_path / "s.csv").write_text(csv)
    _refused(capsys, ["predict", model_file, tmp_path / "s.csv"], r"s\.csv: " + match)


def test_process_and_label_columns_still_pass(tmp_path, capsys, model_file):
    (tmp_path / "s.csv").write_text("L_mm,d_mm,specimen,alpha_rad\n2.6,0.33,a1,2.5\n")
    rc, err = _run(capsys, ["predict", model_file, tmp_path / "s.csv"])
    assert rc == 0, err


def test_specimen_lengths_outside_the_design_range_are_refused(tmp_path, capsys, model_file):
    (tmp_path / "s.csv").write_text("L_mm,d_mm\n1e300,0.33\n")
    _refused(capsys, ["predict", model_file, tmp_path / "s.csv"],
             r"s\.csv: row 2, column L_mm: expected a length between 1e-06 and 1e\+06 mm, got '1e300'")


# --- gdfe plan and gdfe data ----------------------------------------------------------------------------


@pytest.mark.parametrize("argv, match", [
    (["--L", "1:1e9"], r"--L: expected lengths between 1e-06 and 1e\+06 mm, got '1:1e9'"),
    (["--d", "1e-300:1e-299"], r"--d: expected lengths between"),
    (["--h", "30:40"], r"no candidate in the ranges \(--L 1-6 mm, --d 0\.11-0\.5 mm, --h 30-40 mm\).*change --h"),
])
def test_plan_ranges_out_of_reach_are_refused_naming_them(capsys, argv, match):
    _refused(capsys, ["plan", gdfe.TABLE1, "--L", "1:6", "--d", "0.11:0.5", *argv], match)


def test_data_refuses_one_file_for_the_copy_and_the_json(tmp_path, capsys):
    same = tmp_path / "same.json"
    _refused(capsys, ["data", "table1", "--out", same, "--json", same], r"--out, --json: expected two files")


def test_calibrate_warns_where_the_fit_is_worse_than_the_mean(tmp_path, capsys):
    path = _table1(tmp_path, lambda lines: [lines[0], "1e5" + lines[1][4:]] + lines[2:])  # L = 1e5 mm in row 2
    rc, err = _run(capsys, ["calibrate", path, "--boot", "0", "--json", tmp_path / "fit.json"])
    assert rc == 0, err
    warnings = __import__("json").loads((tmp_path / "fit.json").read_text())["warnings"]
    assert len(warnings) == 1 and re.match(r"r2 = -4\.\d+: the eq1 fit predicts the angles worse than their mean", warnings[0])
    rc, err = _run(capsys, ["calibrate", gdfe.TABLE1, "--boot", "0", "--json", tmp_path / "t1.json"])
    assert "warnings" not in __import__("json").loads((tmp_path / "t1.json").read_text())  # Table 1: r2 0.58


def test_a_column_that_is_the_measured_angle_again_is_not_a_cause(tmp_path):
    def with_degrees(lines):
        return [lines[0] + ",alpha_deg"] + [f"{line},{float(line.split(',')[3]) * 57.29578:.2f}" for line in lines[1:]]
    diag = diagnose(_table1(tmp_path, with_degrees))
    assert diag.columns.ignored["alpha_deg"].startswith("the measured angle again (57.3 x alpha_rad)")
    assert "alpha_deg" not in diag.columns.process
    base = diagnose(gdfe.TABLE1).verdict
    assert (diag.verdict.verdict, diag.verdict.named) == (base.verdict, base.named)


def test_an_svg_line_encloses_nothing(tmp_path, caplog):
    page = ('<svg xmlns="http://www.w3.org/2000/svg" width="6mm" height="2mm" viewBox="0 0 6 2">{}'
            '<g id="both"><rect x="0" y="0" width="2" height="2"/><rect x="4" y="0" width="2" height="2"/></g>'
            '<g id="top"><rect x="2" y="0" width="2" height="2"/>{}</g></svg>')
    line = '<line x1="0" y1="1" x2="6" y2="1" stroke="red" stroke-width="0.05"/>'
    (tmp_path / "plain.svg").write_text(page.format("", ""))
    (tmp_path / "lines.svg").write_text(page.format(line, line))  # a construction line, and one in a face group
    from gdfe.fabrication.svg import svg_masks

    with caplog.at_level(logging.WARNING, logger="gdfe.fabrication.svg"):
        m = svg_masks(tmp_path / "lines.svg", 0.1)  # was refused: "a filled shape outside any group"
    plain = svg_masks(tmp_path / "plain.svg", 0.1)
    assert all((getattr(m, k) == getattr(plain, k)).all() for k in ("top", "bottom", "film"))
    assert "1 shape(s) in face groups have no fill" in caplog.text and "<line>" in caplog.text


def test_plan_members_have_distinct_names(tmp_path):
    from gdfe.plan import models_to_tell_apart, plan_tests
    from gdfe.predictive import from_diagnosis

    path = _table1(tmp_path, lambda lines: [lines[0], "1e6" + lines[1][4:]] + lines[2:])
    diag = diagnose(path)
    fits = models_to_tell_apart(diag)
    assert {"saturation", "saturation+reading_offset"} <= {f.name for f in fits}  # the case that repeated a name
    plan = plan_tests(from_diagnosis(diag, data=path, members=fits), 1, (1.0, 6.0), (0.11, 0.5), (0.29, 0.29))
    assert len(set(plan.members)) == len(plan.members) == len(fits)
    assert "saturation (fitted beside reading_offset)" in plan.members


def test_a_discrepancy_table_with_negative_angles_is_refused(tmp_path, capsys, model_file):
    path = _table1(tmp_path, lambda lines: [lines[0], lines[1].rsplit(",", 1)[0] + ",-1.75"] + lines[2:])
    (tmp_path / "s.csv").write_text("L_mm,d_mm\n2.6,0.33\n")
    _refused(capsys, ["predict", model_file, tmp_path / "s.csv", "--discrepancy", path],
             r"--discrepancy tests\.csv: tests: alpha_rad: expected fold angles as magnitudes .* 1 negative in row 2")


def test_a_process_column_reads_numbers_as_the_specimens_columns_do():
    from gdfe.predict import HingeSpecimens

    model = gdfe.DeformationModel(principle="eq1", params={"K": 0.37, "rate": 0.1, "x50": 100.0},
                                  mechanisms=("partial_activation",), columns={"partial_activation": "T_C"})
    spec = HingeSpecimens(L=np.array([2.6, 2.6]), d=np.array([0.33, 0.33]), h=np.array([0.29, 0.29]),
                          extra={"T_C": np.array(["120", "1_20"])})
    assert spec.process(0, model) == {"T_C": 120.0}
    with pytest.raises(gdfe.GdfeError, match=r"row 3, column T_C: expected a number \(partial_activation\), got '1_20'"):
        spec.process(1, model)


@pytest.mark.parametrize("argv, what", [(["data", "table1"], "file"), (["hinge", "-L", "1.0"], "folder")])
def test_out_dash_is_refused_not_written_as_a_file_named_dash(tmp_path, monkeypatch, capsys, argv, what):
    """``--json -`` is standard output; ``--out -`` wrote a file (or folder) named ``-``."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--out", "-"])
    assert exc.value.code == 2 and not (tmp_path / "-").exists()
    assert f"--out: expected the name of a {what} to write, got '-'" in capsys.readouterr().err
