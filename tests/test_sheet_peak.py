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
    assert row["peak_rss_mib"] >= row["peak_sampled_mib"] > 0
    assert row["peak_rss_mib"] >= row["rss_before_mib"] > 0
    assert 0.0 <= row["peak_at_s"] <= row["seconds"] + 1.0
    assert set(row["timings"]) >= {"setup"}


def test_an_unknown_design_is_refused_by_name(capsys):
    with pytest.raises(SystemExit):
        sheet_peak.main(["mystery", "1e3"])
    assert "kind: expected one of corrugation, fig08-twist, fig08-dome, fig08-saddle, got 'mystery'" in \
        capsys.readouterr().err


def test_a_run_past_its_limit_is_stopped_and_says_so():
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    proc = subprocess.run([sys.executable, "-m", "studies.sheet_peak", "corrugation", "1e3", "--stop-above", "0.001"],
                          capture_output=True, text=True, timeout=300, cwd=root)
    assert proc.returncode == 3
    assert "passed --stop-above 0.0 GiB" in proc.stderr and "stopped" in proc.stderr
