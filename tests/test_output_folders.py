"""Output folders are complete or marked incomplete; a rerun replaces them; Ctrl-C says what it left.

The command-line tests run ``gdfe`` in a child process whose writer is slowed down (each VTU
frame takes 0.2 s more), so that the test can kill it or press Ctrl-C while it writes.
"""

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import gdfe
from gdfe.cli import main
from gdfe.io import MANIFEST, MARKER, OutputFolder, folder_state

CHILD = textwrap.dedent("""
    import sys, time
    import gdfe, gdfe.io

    write_vtu, simulate = gdfe.io.write_vtu, gdfe.simulate

    def slow_write(*args, **kwargs):
        out = write_vtu(*args, **kwargs)
        print("frame", flush=True)
        time.sleep(0.2)
        return out

    def slow_simulate(*args, **kwargs):
        print("solving", flush=True)
        time.sleep(0.5 if "--slow-solve" not in sys.argv else 30)
        return simulate(*args, **kwargs)

    gdfe.io.write_vtu, gdfe.simulate = slow_write, slow_simulate
    from gdfe.cli import main
    sys.exit(main([a for a in sys.argv[1:] if a != "--slow-solve"]))
""")


def _child(argv, signum, after, word):
    """Run gdfe in a child process; send ``signum`` once it printed ``word`` ``after`` times."""
    proc = subprocess.Popen([sys.executable, "-c", CHILD, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=Path(__file__).resolve().parents[1],
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    seen = 0
    for line in proc.stdout:
        seen += line.strip() == word
        if seen >= after:
            proc.send_signal(signum)
            break
    out, err = proc.communicate(timeout=60)
    return proc.returncode, err


def _hinge(out, steps):
    return ["hinge", "-L", "2.6", "--d", "0.33", "--cells", "8", "--steps", str(steps), "--out", str(out), "-q"]


def _files(folder):
    return sorted(p.name for p in Path(folder).iterdir())


def test_a_killed_run_is_marked_and_a_rerun_replaces_it(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(_hinge(out, 6)) == 0
    assert folder_state(out) == "complete"
    rc, _ = _child(_hinge(out, 12), signal.SIGKILL, 3, "frame")  # killed while writing the series
    assert rc == -signal.SIGKILL
    assert folder_state(out) == "incomplete" and not (out / MANIFEST).exists()
    marker = (out / MARKER).read_text()
    assert marker.startswith("This folder is incomplete: running.") and "--steps 12" in marker
    assert not (out / "hinge_006.vtu").exists()  # the old, longer series is gone, not mixed in
    capsys.readouterr()
    assert main(["view", str(out)]) == 1
    assert f"{out} is incomplete (INCOMPLETE.txt: the run that wrote it did not finish)" in capsys.readouterr().err
    # a shorter rerun replaces the whole folder: no frame of the killed run is left beside it
    assert main(_hinge(out, 2)) == 0
    assert folder_state(out) == "complete"
    assert _files(out) == [MANIFEST, "hinge.png", "hinge.pvd", "hinge_000.vtu", "hinge_001.vtu", "hinge_002.vtu",
                           "result.json"]
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["complete"] and manifest["converged"] and set(manifest["files"]) == set(_files(out)) - {MANIFEST}
    assert "--steps 2" in manifest["command"]
    assert json.loads((out / "result.json").read_text())["files"]["pvd"] == str(out / "hinge.pvd")


def test_ctrl_c_while_writing_says_what_it_left(tmp_path, capsys):
    out = tmp_path / "run"
    rc, err = _child(_hinge(out, 12), signal.SIGINT, 3, "frame")
    assert rc == 130 and "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"gdfe hinge: interrupted: {out} holds the ") and last.endswith(
        "files written so far and is marked incomplete (INCOMPLETE.txt); rerun to replace it")
    assert folder_state(out) == "incomplete"
    assert (out / MARKER).read_text().startswith("This folder is incomplete: stopped by Ctrl-C.")
    assert main(_hinge(out, 1)) == 0  # the rerun replaces it: complete, none of the stopped run's frames
    assert folder_state(out) == "complete" and _files(out) == [MANIFEST, "hinge.png", "hinge.pvd", "hinge_000.vtu",
                                                               "hinge_001.vtu", "result.json"]


def test_ctrl_c_while_solving_leaves_the_previous_result(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(_hinge(out, 2)) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    rc, err = _child(_hinge(out, 2) + ["--slow-solve"], signal.SIGINT, 1, "solving")
    assert rc == 130 and "Traceback" not in err
    assert err.strip().splitlines()[-1] == f"gdfe hinge: interrupted: nothing was written to {out} (it is unchanged)"
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_output_folder_refuses_what_is_not_its_own(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(gdfe.GdfeError, match=r"--out: .* is a folder with files that gdfe did not write "
                                             r"\(no gdfe-manifest\.json\); gdfe replaces only its own output folders"):
        OutputFolder(tmp_path)
    assert (tmp_path / "notes.txt").read_text() == "mine"
    with pytest.raises(gdfe.GdfeError, match=r"--out: expected a folder, got the file"):
        OutputFolder(tmp_path / "notes.txt")
    with pytest.raises(TypeError, match=r"--out: expected the name of a folder, got ''"):
        OutputFolder("")
    busy = tmp_path / "busy"
    busy.mkdir()
    import socket

    (busy / MARKER).write_text(f"This folder is incomplete: running.\n\ncommand: gdfe hinge\npid: {os.getppid()}\n"
                               f"host: {socket.gethostname()}\n")
    with pytest.raises(gdfe.GdfeError, match=r"is being written by another gdfe run \(process \d+: gdfe hinge\)"):
        OutputFolder(busy)


def test_output_folder_marks_a_failed_write_and_removes_an_empty_one(tmp_path):
    out = tmp_path / "o"
    with pytest.raises(RuntimeError):
        with OutputFolder(out, command="test") as f:
            (out / "a.txt").write_text("x")
            raise RuntimeError("disk on fire")
    assert folder_state(out) == "incomplete" and "stopped by an error (RuntimeError: disk on fire)" in (
        out / MARKER).read_text()
    assert f.left.endswith("marked incomplete (INCOMPLETE.txt); rerun to replace it")
    with OutputFolder(out, command="test") as f:  # the rerun replaces it
        (out / "b.txt").write_text("y")
    assert _files(out) == ["b.txt", MANIFEST]
    with pytest.raises(KeyboardInterrupt):
        with OutputFolder(tmp_path / "e") as f:
            raise KeyboardInterrupt
    assert not (tmp_path / "e").exists() and f.left == f"nothing was written to {tmp_path / 'e'}"
