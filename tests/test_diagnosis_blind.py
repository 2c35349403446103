"""The blind benchmark of the fold-angle diagnoser (studies/blind_diagnosis.py)."""

import json

import numpy as np
import pytest

from studies import blind_diagnosis as bd


def _spec(effect, design="table1", rep=0, sigmas=(0.03,)):
    specs = bd._specs({"reps": rep + 1, "sigmas": sigmas, "gdfe": "coarse", "fem": "coarse"})
    return next(s for s in specs if s["effect"] == effect and s["design"] == design and s["rep"] == rep)


def test_strengths_are_drawn_in_their_ranges():
    for s in bd._specs({"reps": 3, "sigmas": (0.03,), "gdfe": "coarse", "fem": "coarse"}):
        (name, (lo, hi)), = bd.STRENGTHS[s["effect"]].items()
        v = abs(s["value"]) if name == "lambda" else s["value"]
        assert lo - 1e-12 <= v <= hi or (name == "lambda" and s["value"] < 0 and v <= 0.5 * s["L"].min())
        assert bd.MAX_FOLD[0] <= s["scale"] <= bd.MAX_FOLD[1]
        if s["design"] == "random":
            assert s["L"].size == bd.N_RANDOM and np.ptp(s["h"]) > 0  # random designs vary h


def test_forward_model_is_the_simulation_not_the_closed_form():
    """The generated angles are GDFE solves: close to, but not equal to, the closed form."""
    from gdfe.diagnosis import model

    spec = _spec("hinge_length")
    alpha, ok, params = bd.simulate(spec)
    assert ok.all()
    closed = model("hinge_length").predict(np.array([params["K"], params["lambda"]]), spec["L"], spec["d"], spec["h"])
    diff = np.abs(alpha - closed)
    assert 1e-5 < diff.max() < 0.025
    assert alpha.max() == pytest.approx(spec["scale"] * (1 + params["lambda"] / spec["L"][np.argmax(closed)]), rel=0.02)


def test_one_data_set_is_diagnosed(tmp_path):
    spec = dict(_spec("hinge_length", sigmas=(0.01, 0.03)), cache=str(tmp_path))
    recs = bd._job(spec)
    assert [r["sigma"] for r in recs] == [0.01, 0.03]
    for r in recs:
        assert r["correct"] and r["best"] == "hinge_length"
        assert r["best_loo_rmse"] < r["baseline_loo_rmse"]
        assert r["model_error"] < 0.01  # GDFE and the closed form agree to the discretisation
    assert len(list(tmp_path.glob("*.npz"))) == 1  # cached
    again = bd._job(spec)
    assert [r["best"] for r in again] == [r["best"] for r in recs]


def test_confusion_matrix_counts():
    recs = [{"effect": "cure_depth", "best": "cure_depth"},
            {"effect": "cure_depth", "best": "film_thickening"},
            {"effect": "saturation", "best": "hinge_length+saturation"},
            {"effect": bd.FEM, "best": "hinge_length+passive_stiffness"},
            {"effect": "hinge_length", "best": "baseline"}]
    M, cols = bd.confusion(recs)
    rows = list(bd.TRUTHS + (bd.FEM,))
    assert M.sum() == 5
    assert M[rows.index("cure_depth"), cols.index("cure_depth")] == 1
    assert M[rows.index("cure_depth"), cols.index("film_thickening")] == 1
    assert M[rows.index("saturation"), cols.index("pair (with truth)")] == 1
    assert M[rows.index(bd.FEM), cols.index("pair (with truth)")] == 1
    assert M[rows.index("hinge_length"), cols.index("baseline")] == 1
    assert bd._is_right(bd.FEM, "hinge_length+passive_stiffness") and not bd._is_right("saturation", "baseline")


@pytest.mark.slow
def test_blind_benchmark_coarse(tmp_path):
    """Issue 5's goal: >= 90 % of the effects named right at sigma = 0.03 rad."""
    res = bd.run(resolution="coarse", out=tmp_path)
    s = res["summary_by_design"]
    assert s["all"]["0.03"]["accuracy"] >= 0.9, s["all"]["0.03"]
    assert s["random"]["0.03"]["accuracy"] >= 0.9, s["random"]["0.03"]
    assert s["all"]["0.03"]["fem_accuracy"] >= 0.75
    # the held-out error after the chosen model follows the noise, far below the baseline's
    for sig in ("0.01", "0.03"):
        assert s["all"][sig]["best_loo_rmse_mean"] < 1.5 * float(sig)
        assert s["all"][sig]["best_loo_rmse_mean"] < 0.5 * s["all"][sig]["baseline_loo_rmse_mean"]
    t1 = res["table1"]
    assert t1["baseline"]["loo_rmse"] == pytest.approx(0.515, abs=0.005)
    assert t1["best_detail"]["loo_rmse"] < 0.5 * t1["baseline"]["loo_rmse"]
    assert res["converged"]
    for f in ("blind_diagnosis.png", "blind_diagnosis.json", "blind_diagnosis.md"):
        assert (tmp_path / f).is_file()
    json.loads((tmp_path / "blind_diagnosis.json").read_text())
