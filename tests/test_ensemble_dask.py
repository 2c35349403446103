"""``gdfe hinge --uncertainty N --scheduler ADDRESS``: the draws on a loopback Dask cluster give the local numbers."""

import json

import pytest

import gdfe
from gdfe.cli import main

distributed = pytest.importorskip("distributed")


def test_hinge_ensemble_on_a_cluster_equals_the_local_one(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("GDFE_JOBS", "1")
    model = tmp_path / "eq1.toml"
    assert main(["-q", "calibrate", str(gdfe.TABLE1), "--model", "eq1", "--model-out", str(model)]) == 0
    capsys.readouterr()
    argv = ["hinge", "--length", "1.6", "--d", "0.33", "--model", str(model), "--uncertainty", "3", "--json"]
    assert main(argv) == 0
    local = json.loads(capsys.readouterr().out)["uncertainty"]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        assert main([*argv, "--scheduler", cluster.scheduler_address]) == 0
    remote = json.loads(capsys.readouterr().out)["uncertainty"]
    assert remote["fold_angles"] == local["fold_angles"] and remote["spread_mm"] == local["spread_mm"]
