"""The hinge specimen's panels are a detail of the test: where a model's contraction reaches through
them, :func:`gdfe.hinge` lengthens them, says so, and measures the fold on outer parts as long as the
panels asked for."""

import csv
import json
import logging

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.model import DeformationModel


def spreading(lam):
    return DeformationModel(principle="eq1", params={"K": 0.0608, "lambda": lam}, mechanisms=("hinge_length",))


def test_panels_lengthen_past_the_reach_and_keep_the_requested_outer_length(caplog):
    m = spreading(2.0)  # reaches 1 mm past each coat edge, through a 0.5 mm panel
    with caplog.at_level(logging.WARNING, logger="gdfe.design"):
        des = gdfe.hinge(1.6, d=0.33, model=m, panel_length=0.5, cell_size=0.1)
    assert "panels lengthened" in caplog.text
    dx = des.mesh.spacing[0]
    assert des.meta["panel_lengthened_from_mm"] == pytest.approx(0.5)
    assert des.meta["panel_reach_mm"] == pytest.approx(1.0, abs=dx)
    assert des.meta["panel_length_mm"] == pytest.approx(1.5, abs=dx)
    # the measured outer parts: unreached, and as long as the panels asked for
    reached = (des.contraction > 0).any(axis=1)
    for name in ("panel_a", "panel_b"):
        cells = des.regions[name]
        assert not reached[cells].any()
        columns = np.unique(des.mesh.cell_ij[cells, 0])
        assert columns.size * dx == pytest.approx(0.5)
    # and the fold is the model's closed form, as with panels chosen long enough by hand
    by_hand = gdfe.hinge(1.6, d=0.33, model=m, panel_length=1.5, cell_size=0.1)
    a, b = (gdfe.fold_angle(gdfe.simulate(x).check()) for x in (des, by_hand))
    assert a == pytest.approx(b, abs=1e-9)
    assert a == pytest.approx(float(m.hinge_angle(1.6, 0.33)), abs=0.01)


def test_panels_stay_as_asked_when_nothing_reaches_through(caplog):
    with caplog.at_level(logging.WARNING, logger="gdfe.design"):
        des = gdfe.hinge(1.6, d=0.33, model=spreading(0.4), panel_length=0.5, cell_size=0.1)
        plain = gdfe.hinge(1.6, d=0.33, panel_length=0.5, cell_size=0.1)
    assert "lengthened" not in caplog.text
    for d in (des, plain):
        assert d.meta["panel_length_mm"] == pytest.approx(0.5)
        assert "panel_lengthened_from_mm" not in d.meta


def test_a_reach_without_end_is_a_clear_error():
    with pytest.raises(gdfe.GdfeError, match=r"panel_length: the model's contraction reaches more than"):
        gdfe.hinge(1.0, d=0.33, model=spreading(400.0), panel_length=0.5, cell_size=0.25)


@pytest.mark.slow
def test_held_out_loop_diagnose_model_out_hinge_works_for_every_table1_specimen(tmp_path, capsys):
    """Each Table 1 test held out: ``gdfe diagnose`` the other 17 with ``--model-out``, then
    ``gdfe hinge --model`` on the held-out specimen converges, lengthening its panels where the
    model reaches past them, and folds as the model's closed form says."""
    rows = list(csv.DictReader(gdfe.TABLE1.open()))
    for k, held in enumerate(rows):
        data = tmp_path / f"without{k}.csv"
        with data.open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(r for i, r in enumerate(rows) if i != k)
        model = tmp_path / f"M{k}.toml"
        assert main(["diagnose", str(data), "--model-out", str(model), "-q"]) == 0
        capsys.readouterr()
        status = main(["hinge", "-L", held["L_mm"], "--d", held["d_mm"], "--h", held["h_mm"],
                       "--model", str(model), "--json", "-q"])
        out = json.loads(capsys.readouterr().out)
        assert status == 0, (k, held, out)
        assert out["converged"]
        assert abs(out["error_rad"]) < 0.02, (k, held, out["error_rad"])


def test_cli_says_the_panels_were_lengthened(tmp_path, capsys):
    """``gdfe hinge --model`` says in its text, its JSON and result.json how far the panels were lengthened."""
    path = spreading(2.0).save(tmp_path / "M.toml")
    assert main(["hinge", "-L", "1.6", "--d", "0.33", "--panel-length", "0.5", "--model", str(path), "-q"]) == 0
    assert "panels lengthened to" in capsys.readouterr().out
    assert main(["hinge", "-L", "1.6", "--d", "0.33", "--panel-length", "0.5", "--model", str(path), "--json",
                 "-q", "--out", str(tmp_path / "run")]) == 0
    out = json.loads(capsys.readouterr().out)
    saved = json.loads((tmp_path / "run" / "result.json").read_text())  # the file says it as the output does
    assert saved["panel_lengthened_from_mm"] == out["panel_lengthened_from_mm"]
    assert saved["panel_reach_mm"] == out["panel_reach_mm"]
    assert out["panel_lengthened_from_mm"] == pytest.approx(0.5, abs=0.06)
    assert out["panel_reach_mm"] == pytest.approx(1.0, abs=0.11)  # lambda / 2, within a cell
    assert out["panel_length_mm"] == pytest.approx(out["panel_lengthened_from_mm"] + out["panel_reach_mm"])
