"""The study, report and calibrate commands, and the HTML report."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

import gdfe
from gdfe.cli import main
from studies import STUDIES

FIGURES = ("fig02", "fig06", "fig07", "fig08", "fig09", "fig10", "fig11")


def test_registry_lists_every_figure_and_the_other_studies():
    for name in FIGURES:
        assert name in STUDIES
    assert STUDIES["compare"] == "studies.compare_models"
    assert STUDIES["blind-diagnosis"] == "studies.blind_diagnosis"
    assert STUDIES["bench-scaling"] == "studies.bench_scaling"


@pytest.mark.parametrize("model, K, r2", [("eq1", 0.0608, 0.576), ("eq1-d1", 0.3708, 0.796)])
def test_calibrate_prints_the_fit(capsys, model, K, r2):
    assert main(["calibrate", str(gdfe.TABLE1), "--model", model, "--json", "--boot", "200"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"] == model and out["n"] == 18
    assert out["K"] == pytest.approx(K, abs=5e-4) and out["r2"] == pytest.approx(r2, abs=2e-3)
    assert {"K", "r2", "rmse", "n", "model"} <= set(out)


def test_calibrate_power_and_text(capsys):
    assert main(["calibrate", str(gdfe.TABLE1), "--model", "power", "--boot", "100", "--d", "0.33"]) == 0
    text = capsys.readouterr().out
    for word in ("model", "K", "p ", "r2", "rmse", "n ", "R "):
        assert word in text
    assert main(["calibrate", str(gdfe.TABLE1), "--model", "all", "--json", "--boot", "0"]) == 0
    assert [f["model"] for f in json.loads(capsys.readouterr().out)] == ["eq1", "eq1-d1", "power"]


def test_calibrate_errors(tmp_path, capsys):
    assert main(["calibrate", str(tmp_path / "none.csv")]) == 1
    assert "not found" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("L_mm,d_mm,h_mm,alpha_rad\n1.0,-0.2,0.29,1.0\n")
    assert main(["calibrate", str(bad)]) == 1
    assert "d_mm" in capsys.readouterr().err


def test_study_command_writes_png_and_json(tmp_path, capsys):
    assert main(["study", "fig02", "--out", str(tmp_path), "--resolution", "coarse", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["study"] == "fig02" and all(h["passed"] for h in out["headlines"])
    assert (tmp_path / "fig02.png").is_file() and (tmp_path / "fig02.json").is_file()


def test_study_runs_as_a_module(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "studies.fig02_calibration", "--out", str(tmp_path),
                           "--resolution", "coarse"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "K, regressor sqrt(h/d)*L" in proc.stdout
    assert (tmp_path / "fig02.png").is_file()


def test_study_command_runs_the_bench_study_as_a_plain_study(tmp_path, capsys, monkeypatch):
    import studies.bench_scaling

    seen = {}

    def run(resolution, out):
        seen.update(resolution=resolution, out=out)
        return {"mode": "quick"}

    monkeypatch.setattr(studies.bench_scaling, "run", run)
    assert main(["study", "bench-scaling", "--out", str(tmp_path), "--resolution", "coarse", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == {"mode": "quick"}
    assert seen == {"resolution": "coarse", "out": tmp_path}


@pytest.mark.slow
def test_study_command_runs_the_bench(tmp_path, capsys):
    assert main(["study", "bench-scaling", "--out", str(tmp_path), "--resolution", "coarse"]) == 0
    assert f"bench-scaling: wrote {tmp_path}" in capsys.readouterr().out
    for name in ("bench.json", "bench_scaling.png", "bench.txt"):
        assert (tmp_path / name).is_file(), name


def test_report_links_figures_and_skips_missing_studies(tmp_path, monkeypatch):
    from studies.validation_report import build_report
    import studies

    monkeypatch.setitem(studies.STUDIES, "missing", "studies.no_such_study")
    summary = build_report(tmp_path, resolution="coarse", names=["fig02", "missing"], progress=False)
    html = (tmp_path / "index.html").read_text()
    assert '<img src="fig02/fig02.png"' in html
    assert "Closing note" in html and "numpy" in html and "scipy" in html and "gdfe" in html
    assert "0.3706" in html  # the paper's number beside ours
    rec = {r["name"]: r for r in summary["studies"]}
    assert rec["fig02"]["status"] == "ok" and rec["missing"]["status"] == "skipped"
    assert "skipped" in html
    assert summary["ok"]
    assert json.loads((tmp_path / "report.json").read_text())["results"]["fig02"]["study"] == "fig02"


def test_report_records_a_failing_study(tmp_path, monkeypatch):
    from studies.validation_report import build_report
    import studies

    monkeypatch.setitem(studies.STUDIES, "broken", "studies._broken_for_test")
    module = type(sys)("studies._broken_for_test")

    def run(resolution, out):
        raise RuntimeError("boom")

    module.run = run
    monkeypatch.setitem(sys.modules, "studies._broken_for_test", module)
    summary = build_report(tmp_path, resolution="coarse", names=["broken"], progress=False)
    assert summary["studies"][0]["status"] == "error" and not summary["ok"]
    assert "boom" in (tmp_path / "index.html").read_text()


def test_report_rejects_unknown_names(tmp_path):
    from studies.validation_report import build_report

    with pytest.raises(ValueError, match="unknown studies"):
        build_report(tmp_path, names=["fig99"])
    with pytest.raises(ValueError, match="resolution"):
        build_report(tmp_path, resolution="huge")


@pytest.mark.slow
@pytest.mark.parametrize("name", list(STUDIES))
def test_every_registered_study_runs_at_its_coarsest_resolution(name, coarse_study):
    """Each study of the registry, at its coarsest resolution: it runs, converges, every headline
    passes (a known discrepancy is recorded as expected not to hold), and its PNG and JSON are
    written; so no study can break unseen (CI runs the slow tests)."""
    result, out = coarse_study(name)
    failing = [h for h in result.get("headlines", []) if not h["passed"]]
    assert not failing, failing
    assert result.get("converged", True), name
    pngs, jsons = sorted(out.glob("*.png")), sorted(out.glob("*.json"))
    assert pngs and jsons, (name, sorted(p.name for p in out.iterdir()))
    for path in jsons:
        json.loads(path.read_text())  # complete JSON
    if "files" in result:
        assert (out / result["files"]["png"]).is_file() and (out / result["files"]["json"]).is_file()


def test_a_speed_goal_is_reported_with_its_verdict_but_is_no_regression():
    """A headline marked ``goal`` (seconds on the machine at hand) says whether the goal is met and
    never fails a study: on a loaded machine the same code takes twice as long."""
    from studies._common import format_headlines, headline

    slow = headline("diagnosis of 2000 rows, processor time [s]", 75.0, tol=60.0, kind="le", unit="s",
                    goal=True, paper_text="10,000 rows in <= 60 s")
    fast = headline("the same, fast", 20.0, tol=60.0, kind="le", unit="s", goal=True)
    check = headline("an angle", 1.2, paper=1.0, tol=0.1)
    assert (slow["holds"], slow["passed"], slow["goal"]) == (False, True, True)
    assert (fast["holds"], fast["passed"]) == (True, True)
    assert (check["holds"], check["passed"], check["goal"]) == (False, False, False)
    text = format_headlines({"figure": "f", "title": "t", "resolution": "coarse", "headlines": [slow, fast, check]})
    lines = text.splitlines()
    assert "NOT MET" in lines[1] and "REGRESSION" not in lines[1]
    assert "met" in lines[2] and "NOT MET" not in lines[2]
    assert "REGRESSION" in lines[3]
