"""Sweeps on a Dask cluster: the same results as local processes, in the same order."""

import json

import pytest

from gdfe.cli import main
from gdfe.parallel import SCHEDULER_ENV, parallel_map

distributed = pytest.importorskip("distributed")


def _square_after(x):
    import time

    time.sleep(0.02 * (5 - x))  # later items finish first: the order must still be the items'
    return x * x


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as c:
        yield c


def test_items_come_back_in_order(cluster):
    assert parallel_map(_square_after, range(6), scheduler=cluster.scheduler_address) == [0, 1, 4, 9, 16, 25]


def test_a_study_sweep_on_the_cluster_equals_the_local_one(cluster, tmp_path, capsys, monkeypatch):
    """Figure 6's hinges run as tasks on the loopback cluster give the numbers the local run gives."""
    assert main(["study", "fig06", "--resolution", "coarse", "--out", str(tmp_path / "a"), "--json"]) == 0
    local = json.loads(capsys.readouterr().out)
    assert main(["study", "fig06", "--resolution", "coarse", "--out", str(tmp_path / "b"), "--json",
                 "--scheduler", cluster.scheduler_address]) == 0
    remote = json.loads(capsys.readouterr().out)
    assert [h["ours"] for h in remote["headlines"]] == [h["ours"] for h in local["headlines"]]
    for key in ("alpha_gdfe", "alpha_gdfe_R07", "iterations"):
        assert [r[key] for r in remote["hinges"]] == [r[key] for r in local["hinges"]]
    # the environment is as it was after the command
    import os

    assert SCHEDULER_ENV not in os.environ


def test_a_task_error_keeps_its_traceback(cluster):
    with pytest.raises(ZeroDivisionError):
        parallel_map(_divide_by_zero, [1, 2], scheduler=cluster.scheduler_address)


def _divide_by_zero(x):
    return x / 0


def test_unreachable_scheduler_is_a_clear_error():
    import gdfe

    with pytest.raises(gdfe.GdfeError, match="cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'"):
        parallel_map(_square_after, [1], scheduler="tcp://127.0.0.1:9")


@pytest.mark.parametrize("where", ["this process", "processes", "cluster"])
def test_every_path_reports_its_items_through_the_log(where, cluster, caplog):
    """The command line's progress off a terminal reads these records (the bar is tqdm's alone): item
    k of n under way, from the first to the last."""
    import logging

    kw = {"this process": {"n_jobs": 1}, "processes": {"n_jobs": 2},
          "cluster": {"scheduler": cluster.scheduler_address}}[where]
    with caplog.at_level(logging.DEBUG, logger="gdfe.parallel"):
        assert parallel_map(_square_after, range(4), desc="squares", progress=False, **kw) == [0, 1, 4, 9]
    steps = [r.progress for r in caplog.records if hasattr(r, "progress")]
    assert steps == [{"event": "steps", "stage": "squares", "step": k, "total": 4} for k in (1, 2, 3, 4)]
