"""How errors reach the user of the command line (docs/ARCHITECTURE.md, "Errors").

A user error (:class:`gdfe.GdfeError`) is one line and exit status 1; any other exception is
a bug and keeps its traceback after a line saying how to report it; ``--debug`` shows the
traceback of user errors too. A bug in the progress display is printed, not hidden.
"""

import logging

import pytest

import gdfe
from gdfe.cli import main


def test_a_user_error_is_one_line_and_status_1(capsys):
    assert main(["calibrate", str(gdfe.TABLE1), "--boot", "1"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("gdfe calibrate: error: --boot: expected") and err.count("\n") == 1
    assert "Traceback" not in err


def test_debug_prints_the_traceback_of_a_user_error(capsys):
    assert main(["calibrate", str(gdfe.TABLE1), "--boot", "1", "--debug"]) == 1
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and "GdfeError" in err
    assert "gdfe calibrate: error: --boot: expected" in err


def test_any_other_exception_is_a_bug_and_keeps_its_traceback(capsys, monkeypatch):
    def broken(path):
        raise KeyError("a key the code forgot")

    monkeypatch.setattr(gdfe, "load_folding_tests", broken)
    with pytest.raises(KeyError, match="a key the code forgot"):
        main(["calibrate", str(gdfe.TABLE1), "--boot", "0"])
    err = capsys.readouterr().err
    assert "gdfe calibrate: internal error: this is a bug in gdfe" in err and "Please report it" in err


def test_a_bug_in_the_progress_display_is_printed_not_hidden(capsys, monkeypatch):
    pytest.importorskip("tqdm")
    from gdfe.cli._progress import SolveProgress

    def broken(self, record):
        raise ZeroDivisionError("a bug in the display")

    monkeypatch.setattr(SolveProgress, "_progress", broken)
    with SolveProgress(True, frames=1):
        logging.getLogger("gdfe.solver.newton").debug("newton %d: residual %.3e, error estimate %.3e", 1, 0.1, 0.1)
    err = capsys.readouterr().err
    assert "ZeroDivisionError: a bug in the display" in err


def test_a_fold_of_round_off_size_is_printed_as_zero():
    """gdfe.cli._common.shown: a printed value rounded to its digits, a negative zero made 0 (R = 1: nothing folds)."""
    from gdfe.cli._common import shown

    assert f"{shown(-1e-14, 4):.4f}" == "0.0000" and f"{shown(-1e-14, 4):+.4f}" == "+0.0000"
    assert f"{shown(-0.00006, 4):.4f}" == "-0.0001" and shown(1.23456, 2) == 1.23
