"""Stopping a command: SIGTERM (``kill``, ``timeout``) and Ctrl-C stop its worker processes too, and
leave no half-written output folder."""

import os
import signal
import subprocess
import sys
import time

import pytest

from gdfe.parallel import _descendants, _running, stop_workers, stopping_workers, Stopped


def _alive(pids):
    return [p for p in pids if _running(p)]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_the_benchmarks_worker_and_marks_its_folder(tmp_path, sig):
    out = tmp_path / "bench"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.Popen([sys.executable, "-m", "gdfe", "bench", "--sizes", "1e5", "--freeform-sizes", "none",
                             "--no-hinges", "--no-fem", "--large", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True)  # a signal to the command alone, as timeout(1) sends it
    try:
        end = time.monotonic() + 60
        workers = []
        while time.monotonic() < end and proc.poll() is None:
            # the benchmark's sheet runs in a child process of its own (spawned: a python process)
            workers = [p for p in _descendants(proc.pid) if "spawn" in _cmdline(p)]
            if workers:
                break
            time.sleep(0.1)
        assert workers, f"the benchmark started no worker within 60 s (exit {proc.poll()})"
        kids = _descendants(proc.pid)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + int(sig), err
    end = time.monotonic() + 5
    while _alive(kids) and time.monotonic() < end:
        time.sleep(0.05)
    assert not _alive(kids), f"worker processes left running: {_alive(kids)}"
    assert "Traceback" not in err and ("stopped by signal" in err or "interrupted" in err), err
    assert not out.exists() or (out / "INCOMPLETE.txt").exists(), sorted(p.name for p in out.iterdir())


def _cmdline(pid):
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def _new_joblib_executor():
    """stop_workers stops every child of this process, the workers of the joblib executor the tests share
    too: shut it down, so that the next test's parallel run starts a new one (with it, until joblib had
    seen its workers end, a run submitted to it failed with TerminatedWorkerError)."""
    try:
        from joblib.externals.loky import get_reusable_executor
    except ModuleNotFoundError:
        return
    get_reusable_executor().shutdown(wait=True, kill_workers=True)


def test_stop_workers_ends_every_child_and_grandchild():
    grandchild = "subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'])"
    child = subprocess.Popen([sys.executable, "-c", f"import subprocess, sys, time; {grandchild}; time.sleep(60)"])
    end = time.monotonic() + 20
    while not _descendants(child.pid) and time.monotonic() < end:
        time.sleep(0.05)
    pids = [child.pid, *_descendants(child.pid)]  # (the test process may have other children of its own)
    assert len(pids) == 2 and set(pids) <= set(_descendants(os.getpid()))
    try:
        stopped = stop_workers(grace=2.0)
    finally:
        _new_joblib_executor()
    assert set(pids) <= set(stopped)
    child.wait(timeout=10)
    end = time.monotonic() + 5
    while _alive(pids) and time.monotonic() < end:
        time.sleep(0.05)
    assert not _alive(pids)


_SPARE = """
import json, os, time
from gdfe.parallel import _descendants, _resource_trackers, _running, parallel_map, stop_workers
assert parallel_map(abs, [-1, 2, -3, 4], n_jobs=2, progress=False) == [1, 2, 3, 4]
trackers = _resource_trackers()
below = set(_descendants(os.getpid()))
# the trackers as the system names them, apart from the library: their command lines
named = [p for p in below if b"resource_tracker import main" in open(f"/proc/{p}/cmdline", "rb").read()]
loky = [p for p in named if b"loky" in open(f"/proc/{p}/cmdline", "rb").read()]
stopped = stop_workers(grace=2.0)
end = time.monotonic() + 5
while any(_running(p) for p in stopped) and time.monotonic() < end:
    time.sleep(0.05)
print(json.dumps({"trackers": sorted(trackers), "named": sorted(named), "loky": loky, "stopped": stopped,
                  "alive": [p for p in stopped if _running(p)], "trackers_alive": sorted(p for p in trackers if _running(p))}))
"""


def test_stop_workers_spares_the_resource_trackers():
    """joblib's workers are stopped, its resource tracker is not: it frees what they leave and ends with
    the process. Stopped too, the next parallel run started it again and warned that resources might leak.
    In a process of its own: the test process's joblib executor, shared by every test, is left alone."""
    import json

    pytest.importorskip("joblib")
    out = subprocess.run([sys.executable, "-c", _SPARE], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout.splitlines()[-1])
    assert len(r["loky"]) == 1 and r["trackers"] == r["named"]  # both trackers, joblib's among them
    assert r["stopped"] and not set(r["stopped"]) & set(r["trackers"])  # the pool's workers went, the trackers stayed
    assert not r["alive"] and r["trackers_alive"] == r["trackers"]
    assert "resource_tracker" not in out.stderr, out.stderr


def test_stopping_workers_turns_sigterm_into_stopped_and_restores_the_handler():
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Stopped) as info:
        with stopping_workers():
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
    assert info.value.signum == signal.SIGTERM and isinstance(info.value, KeyboardInterrupt)
    assert signal.getsignal(signal.SIGTERM) is before
