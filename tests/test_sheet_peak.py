"""``studies.sheet_peak``: one benchmark sheet's whole simulation with its peak memory."""

import json
from pathlib import Path

import pytest

from studies import sheet_peak


def test_a_small_sheet_is_measured_with_its_peak_and_where_it_was(tmp_path):
    out = tmp_path / "row.json"
    assert sheet_peak.main(["corrugation", "1e3", "--out", str(out)]) == 0
    row = json.loads(out.read_text())
    assert row["design"] == "corrugation" and row["cells"] == 1024 and row["converged"]
    assert row["peak_sampled_mib"] > 0 and row["peak_rss_mib"] == max(row["ru_maxrss_mib"], row["peak_sampled_mib"])
    assert row["peak_rss_mib"] >= row["rss_before_mib"] > 0
    assert 0.0 <= row["peak_at_s"] <= row["seconds"] + 1.0
    assert set(row["timings"]) >= {"setup"}


def test_an_unknown_design_is_refused_by_name(capsys):
    with pytest.raises(SystemExit):
        sheet_peak.main(["mystery", "1e3"])
    assert "kind: expected one of 'corrugation', 'fig08-twist', 'fig08-dome', 'fig08-saddle', got 'mystery'" in \
        capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["corrugation", "inf"], "cells: expected a finite number >= 4, got inf"),
    (["corrugation", "2"], "cells: expected a finite number >= 4, got 2"),
    (["corrugation", "1e12"], "cells: expected a sheet that fits in memory, got 1,000,000,000,000 cells"),
    (["corrugation", "1e3", "--stop-above", "nan"], "stop_above_gib: expected a positive finite number, got nan"),
    (["corrugation", "1e3", "--stop-above", "0"], "stop_above_gib: expected a positive finite number, got 0"),
])
def test_a_bad_size_or_limit_is_refused_before_anything_is_made(capsys, argv, message):
    with pytest.raises(SystemExit) as exc:
        sheet_peak.main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err


def test_an_out_that_cannot_be_written_is_refused_before_the_run(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sheet_peak, "measure", lambda *a: pytest.fail("the run began"))
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for out, message in [(tmp_path, "--out: expected the name of a file to write, got a folder"),
                         (f"{tmp_path}/new/", "--out: expected the name of a file to write, got a folder"),
                         ("", "--out: expected the name of a file to write, got an empty name"),
                         (blocker / "row.json",
                          f"--out: cannot create the file {blocker / 'row.json'}: {blocker} is a file")]:
        with pytest.raises(SystemExit) as exc:
            sheet_peak.main(["corrugation", "1e3", "--out", str(out)])
        assert exc.value.code == 2 and message in capsys.readouterr().err


def test_a_record_that_cannot_be_written_goes_to_stdout(tmp_path, capsys, monkeypatch):
    def refuse(path, text):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(sheet_peak, "write_text", refuse)
    out = tmp_path / "row.json"
    assert sheet_peak.main(["corrugation", "1e3", "--out", str(out)]) == 1
    captured = capsys.readouterr()
    assert json.loads(captured.out)["cells"] == 1024 and not out.exists()
    assert f"sheet_peak: --out: cannot write {out}" in captured.err and "No space left on device" in captured.err


def test_a_run_that_does_not_converge_says_so_and_fails(tmp_path, monkeypatch, capsys):
    import gdfe

    simulate = gdfe.simulate
    monkeypatch.setattr(gdfe, "simulate", lambda design, **kw: simulate(design, max_iter=1, **kw))
    out = tmp_path / "row.json"
    assert sheet_peak.main(["corrugation", "1e3", "--out", str(out)]) == 1
    row = json.loads(out.read_text())
    assert not row["converged"] and row["iterations"] == 1
    assert "sheet_peak: the 1,024-cell corrugation did not converge in 1 iterations" in capsys.readouterr().err
    # a record that cannot be written does not hide that the run did not converge
    monkeypatch.setattr(sheet_peak, "write_text", lambda path, text: (_ for _ in ()).throw(OSError(28, "full")))
    assert sheet_peak.main(["corrugation", "1e3", "--out", str(tmp_path / "other.json")]) == 1
    captured = capsys.readouterr()
    assert not json.loads(captured.out)["converged"]
    assert "cannot write" in captured.err and "did not converge in 1 iterations" in captured.err


def test_a_run_past_its_limit_is_stopped_and_says_so():
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    proc = subprocess.run([sys.executable, "-m", "studies.sheet_peak", "corrugation", "1e3", "--stop-above", "0.001"],
                          capture_output=True, text=True, timeout=300, cwd=root)
    assert proc.returncode == 3
    assert "passed --stop-above 0.001 GiB" in proc.stderr and "stopped" in proc.stderr
