"""The command line's JSON: one vocabulary (gdfe/cli/_vocabulary.py), errors as JSON, and the
commands' files (the page of ``gdfe view``, ``gdfe design --text``'s parts, design files in TOML)."""

import json
import time
import tomllib
import zipfile

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.cli._vocabulary import ALIASES, COMMAND_ALIASES, VOCABULARY, known_keys, with_aliases

HINGE = ["--length", "1.6", "--d", "0.33"]


def _json(capsys, argv, status=0):
    assert main(argv) == status
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def hinge_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("hinge") / "hinge.toml"
    path.write_text("[film]\nd = 0.33\n[hinge]\nlength = 1.6\n")
    return path


# -- one vocabulary -----------------------------------------------------------------------------------------
def test_hinge_and_simulate_of_one_hinge_say_the_same_in_the_same_words(hinge_file, tmp_path, capsys):
    hinge = _json(capsys, ["hinge", *HINGE, "--json"])
    sim = _json(capsys, ["simulate", str(hinge_file), "--out", str(tmp_path / "o"), "--json"])
    shared = ("fold_angle_rad", "length_mm", "d_mm", "h_mm", "width_mm", "panel_length_mm", "R", "K", "isotropy",
              "nz", "n_cells", "converged", "status", "iterations", "frame_iterations", "residual", "method",
              "penetration_mm", "contact")
    for key in shared:
        assert key in hinge and key in sim, key
        if isinstance(hinge[key], (int, float)) and not isinstance(hinge[key], bool):
            assert hinge[key] == pytest.approx(sim[key], rel=1e-9), (key, hinge[key], sim[key])
        else:
            assert hinge[key] == sim[key], (key, hinge[key], sim[key])
    assert "seconds" in hinge and "seconds" in sim
    # the last frame's Newton steps, one per iteration but the last, which finds the test met
    for out in (hinge, sim):
        assert len(out["newton_steps"]) == out["frame_iterations"][-1] - 1
        assert [s["iteration"] for s in out["newton_steps"]] == list(range(1, out["frame_iterations"][-1]))
    assert sim["start_levels"] == []  # a hinge starts from the linearised start
    # the old keys of gdfe hinge stay for a release, beside the new ones, and say what replaces them
    assert hinge["alpha_rad"] == hinge["fold_angle_rad"] and hinge["L_mm"] == hinge["length_mm"] == 1.6
    assert hinge["deprecated_keys"]["alpha_rad"] == "fold_angle_rad"
    assert hinge["deprecated_keys"]["L_mm"] == "length_mm"
    assert hinge["alpha_eq1_rad"] == hinge["fold_angle_eq1_rad"] == pytest.approx(1.684, abs=1e-3)
    # result.json of an output folder speaks the same vocabulary
    written = json.loads((tmp_path / "o" / "result.json").read_text())
    assert written["fold_angle_rad"] == sim["fold_angle_rad"] and written["n_cells"] == sim["n_cells"]


def test_the_vocabulary_table_is_consistent():
    for new, (unit, what, olds) in VOCABULARY.items():
        suffix = {"mm": "_mm", "rad": "_rad", "s": ("seconds", "_s"), "mib": "_mib"}.get(unit)
        assert suffix is None or new.endswith(suffix), f"{new}: its unit {unit} is not in its name"
        assert what, new
        for old in olds:
            assert old not in VOCABULARY, f"{old}: both a key and an alias"
    for renames in [ALIASES, *COMMAND_ALIASES.values()]:
        assert set(renames.values()) <= set(VOCABULARY) | {"n_tests"}, renames


def test_aliases_are_added_beside_and_listed():
    out = with_aliases({"rmse": 0.1, "rows": [{"L_mm": 2.0}], "bins": [{"n": 3}]}, "calibrate")
    assert out["rmse_rad"] == out["rmse"] == 0.1 and out["rows"][0] == {"length_mm": 2.0, "L_mm": 2.0}
    assert out["bins"] == [{"n": 3}]  # generic names are renamed at the top of their command only
    assert out["deprecated_keys"] == {"L_mm": "length_mm", "rmse": "rmse_rad"}
    assert with_aliases({"fold_angle_rad": 1.0}, "simulate") == {"fold_angle_rad": 1.0}  # nothing old: no alias


def _commands(tmp, hinge_file):
    sim = tmp / "sim"
    return [
        ("hinge", ["hinge", *HINGE, "--json"]),
        ("simulate", ["simulate", str(hinge_file), "--out", str(sim), "--json"]),
        ("view", ["view", str(sim), "--json"]),
        ("data", ["data", "--json"]),
        ("data", ["data", "table1", "--json"]),
        ("calibrate", ["calibrate", str(gdfe.TABLE1), "--boot", "0", "--d", "0.3", "--json"]),
        ("calibrate", ["calibrate", str(gdfe.TABLE1), "--boot", "0", "--model", "all", "--json"]),
        ("fem hinge", ["fem", "hinge", *HINGE, "--resolution", "coarse", "--json"]),
        ("diagnose", ["diagnose", str(gdfe.TABLE1), "--check", "none", "--no-pairs", "--json"]),
        ("design", ["design", "--text", "i", "--no-check", "--out", str(tmp / "design"), "--json"]),
        ("study fig06", ["study", "fig06", "--resolution", "coarse", "--out", str(tmp / "study"), "--json"]),
    ]


def test_every_command_speaks_the_vocabulary(hinge_file, tmp_path, capsys):
    for command, argv in _commands(tmp_path, hinge_file):
        out = _json(capsys, argv)
        for obj in out if isinstance(out, list) else [out]:
            unknown = set(obj) - known_keys(command)
            assert not unknown, f"gdfe {command}: keys neither in the vocabulary nor its own: {sorted(unknown)}"
            old = set(obj) & (set(ALIASES) | set(COMMAND_ALIASES.get(command, {})))
            assert isinstance(out, list) or old <= set(obj.get("deprecated_keys", {})), command


@pytest.mark.slow
def test_bench_and_report_speak_the_vocabulary(tmp_path, capsys):
    for command, argv in [("bench", ["bench", "--quick", "--json"]),
                          ("report", ["report", "--only", "fig06", "--resolution", "coarse", "--out",
                                      str(tmp_path / "r"), "--json"])]:
        out = _json(capsys, argv)
        assert not set(out) - known_keys(command), f"gdfe {command}: {sorted(set(out) - known_keys(command))}"


# -- errors as JSON -----------------------------------------------------------------------------------------
def test_a_user_error_with_json_is_a_json_object_too(capsys):
    assert main(["hinge", "--length", "1", "--d", "0.11", "--json"]) == 1
    cap = capsys.readouterr()
    err = json.loads(cap.out)["error"]
    assert err["type"] == "GdfeError" and err["exit_status"] == 1 and err["argument"] == "--d"
    assert "d=0.11 mm gives R=" in err["message"]
    assert cap.err.startswith("gdfe hinge: error: d=0.11 mm") and cap.err.count("\n") == 1
    # a library argument's name becomes the command's option; a message naming none has no "argument"
    assert main(["hinge", "--length", "-1", "--d", "0.33", "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["error"]["argument"] == "--length"
    assert main(["calibrate", "nope.csv", "--json"]) == 1
    assert "argument" not in json.loads(capsys.readouterr().out)["error"]
    # without --json, nothing on standard output
    assert main(["hinge", "--length", "1", "--d", "0.11"]) == 1
    assert capsys.readouterr().out == ""


def test_a_usage_error_with_json_is_a_json_object_and_status_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["hinge", "--d", "0.33", "--json"])
    assert exc.value.code == 2
    cap = capsys.readouterr()
    err = json.loads(cap.out)["error"]
    assert err == {"type": "usage", "message": err["message"], "argument": "--length", "exit_status": 2}
    assert "required: --length" in err["message"] and cap.err.count("\n") == 1
    with pytest.raises(SystemExit):
        main(["calibrate", str(gdfe.TABLE1), "--boot", "x", "--json"])
    assert json.loads(capsys.readouterr().out)["error"]["argument"] == "--boot"


def test_an_error_with_json_to_a_file_is_written_there(tmp_path, capsys):
    target = tmp_path / "result.json"
    assert main(["calibrate", str(gdfe.TABLE1), "--boot", "1", "--json", str(target)]) == 1
    assert json.loads(target.read_text())["error"]["argument"] == "--boot"
    assert capsys.readouterr().out == ""


def test_a_bug_with_json_keeps_its_traceback_and_is_a_json_object(capsys, monkeypatch):
    def broken(path):
        raise KeyError("a key the code forgot")

    monkeypatch.setattr(gdfe, "load_folding_tests", broken)
    with pytest.raises(KeyError, match="a key the code forgot"):
        main(["calibrate", str(gdfe.TABLE1), "--boot", "0", "--json"])
    cap = capsys.readouterr()
    err = json.loads(cap.out)["error"]
    assert err["type"] == "bug" and "KeyError" in err["message"] and err["exit_status"] == 1
    assert "internal error: this is a bug in gdfe" in cap.err


# -- gdfe view, gdfe design --text, design files -----------------------------------------------------------
def test_view_writes_the_page_by_default(hinge_file, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["simulate", str(hinge_file), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["view", str(out)]) == 0
    page = out / "hinge.html"
    assert page.is_file() and page.stat().st_size > 1000
    assert f"wrote {page}" in capsys.readouterr().out


def test_design_text_designs_a_repeated_letter_once(tmp_path, capsys, monkeypatch):
    from gdfe import inverse

    checked = []
    check_strip = inverse.check_strip
    monkeypatch.setattr(inverse, "check_strip", lambda plan, **kw: checked.append(plan) or check_strip(plan, **kw))
    start = time.perf_counter()
    out = _json(capsys, ["design", "--text", "iri", "--out", str(tmp_path / "d"), "--json"])
    seconds = time.perf_counter() - start
    assert len(checked) == 2, "each distinct letter is simulated once"
    parts = {p["name"]: p for p in out["parts"]}
    assert sorted(parts) == ["01_i", "02_r"]
    assert parts["01_i"]["count"] == 2 and parts["01_i"]["positions"] == [1, 3]
    assert parts["02_r"]["count"] == 1 and parts["02_r"]["positions"] == [2]
    assert out["letters"] == {"text": "iri", "count": 3, "distinct": 2}
    with zipfile.ZipFile(out["package"]) as zf:
        assert json.loads(zf.read("print.json"))["copies"] == {"01_i": 2, "02_r": 1}
    assert not list((tmp_path / "d").glob("03_*")), "no files for the repeat"
    assert seconds < 20, f"gdfe design --text iri took {seconds:.1f} s"


def test_design_files_are_toml_that_reads_back(tmp_path):
    from gdfe.fabrication import face_masks, write_design_toml, write_masks, write_print_package

    des = gdfe.from_rows(["RRTTTRR", "RRBBBRR"], R=0.7, pixel=0.25, nz=1)
    masks = face_masks(des)
    files = write_masks(masks, tmp_path, 'strip "one" é')  # a name TOML must quote and escape
    film = {"h": np.float64(0.29), "R": np.float32(0.7), "nz": np.int64(1), "K": None}
    path = write_design_toml(tmp_path / "strip.toml", files, masks.pixel, film,
                             comment="made by a test\nsecond line", simulate={"steps": 2, "method": "newton"})
    doc = tomllib.loads(path.read_text())
    assert doc["film"] == {"h": 0.29, "R": pytest.approx(0.7), "nz": 1}
    assert doc["masks"]["top"] == 'strip "one" é_top.png' and doc["simulate"] == {"steps": 2, "method": "newton"}
    back, options = gdfe.load_design(path)
    np.testing.assert_array_equal(back.material, des.material)
    np.testing.assert_allclose(back.R, des.R, rtol=1e-6)
    assert options == {"steps": 2, "method": "newton"}

    pkg = write_print_package(tmp_path / "print.zip", {"strip": des})
    with zipfile.ZipFile(pkg) as zf:
        zf.extractall(tmp_path / "pkg")
    doc = tomllib.loads((tmp_path / "pkg" / "strip.toml").read_text())
    assert doc["masks"] == {"pixel": 0.25, "top": "strip_top.png", "bottom": "strip_bottom.png"}
    back, _ = gdfe.load_design(tmp_path / "pkg" / "strip.toml")
    np.testing.assert_array_equal(back.material, des.material)
    np.testing.assert_allclose(back.R, des.R)
    assert back.h == des.h
