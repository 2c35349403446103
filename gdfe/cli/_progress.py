"""Progress of the command line's long work: tqdm bars on standard error, silenced by ``--quiet``.

:class:`SolveProgress` shows a simulation's Newton iterations with their residual and the
frame being solved. The solver reports each iteration in its log (``gdfe.solver.newton``, at
debug level) and each coarse level of a multilevel start (``gdfe.solver.starts``); while the
bar is shown those records feed it instead of the log, and every record at the level the user
asked for (warnings by default, ``-v`` for more) still reaches the log, written above the bar.

Bars appear when standard error is a terminal (``--progress``: always, ``--quiet``: never).
"""

from __future__ import annotations

import contextlib
import logging
import math
import sys

__all__ = ["progress_mode", "SolveProgress", "bar"]


def progress_mode(args):
    """The ``--quiet``/``--progress`` choice of a command: False, True, or None (on a terminal)."""
    if getattr(args, "quiet", False):
        return False
    return True if getattr(args, "progress", False) else None


def _enabled(mode):
    return mode is True or (mode is None and sys.stderr.isatty())


def bar(iterable, mode, **kwargs):
    """``tqdm(iterable)`` on standard error when progress is on (``mode``), else ``iterable`` itself."""
    if not _enabled(mode):
        return iterable
    from tqdm.auto import tqdm

    return tqdm(iterable, file=sys.stderr, dynamic_ncols=True, **kwargs)


def _coarse_levels(cells):
    """Coarse levels a multilevel start solves for ``cells`` cells (2 x 2 coarsening, see gdfe.solver.starts)."""
    from gdfe.solver import MULTILEVEL_COARSEST

    levels, n = 0, float(cells)
    while True:
        n /= 4.0
        levels += 1
        if n <= MULTILEVEL_COARSEST:
            return levels


class SolveProgress(logging.Handler):
    """A tqdm bar of a :func:`gdfe.simulate` call, fed by the solver's log records.

    Parameters
    ----------
    mode : bool or None
        :func:`progress_mode`.
    frames : int
        The ramp's steps.
    cells : int
        The design's cells (a multilevel start solves coarse levels first).
    multilevel : bool
        Whether the first frame starts from coarse levels.
    contact : str
        ``"auto"``, ``"on"`` or ``"off"``: with contact the frames are solved in levels, so
        the bar counts solves rather than frames.
    """

    def __init__(self, mode, *, frames=1, cells=0, multilevel=False, contact="auto"):
        super().__init__(level=logging.DEBUG)
        self.enabled = _enabled(mode)
        self.frames = int(frames)
        self.coarse_expected = _coarse_levels(cells) if multilevel else 0
        self.coarse_done = 0
        self.contact = contact == "on"
        self.solves = 0
        self.last_it = math.inf
        self.bar = None
        self._stack = None

    # -- context -------------------------------------------------------------------------------
    def __enter__(self):
        if not self.enabled:
            return self
        from tqdm.auto import tqdm
        from tqdm.contrib.logging import logging_redirect_tqdm

        self._stack = contextlib.ExitStack()
        self._stack.enter_context(logging_redirect_tqdm())
        self.bar = tqdm(desc="solving", unit=" it", file=sys.stderr, dynamic_ncols=True, leave=False)
        logger = logging.getLogger("gdfe.solver")
        self._saved = (logger.level, logger.propagate)
        self._threshold = logger.getEffectiveLevel()  # what the user asked to see
        logger.setLevel(logging.DEBUG)
        logger.propagate = False
        logger.addHandler(self)
        return self

    def __exit__(self, *exc):
        if not self.enabled:
            return False
        logger = logging.getLogger("gdfe.solver")
        logger.removeHandler(self)
        logger.setLevel(self._saved[0])
        logger.propagate = self._saved[1]
        self.bar.close()
        self._stack.close()
        return False

    # -- records -------------------------------------------------------------------------------
    def emit(self, record):
        try:
            self._progress(record)
        except Exception:  # a bug in the display: logging prints its traceback, the solve goes on
            self.handleError(record)
        if record.levelno >= self._threshold:
            logging.getLogger().handle(record)

    def _label(self):
        if self.coarse_done < self.coarse_expected:
            return f"start: coarse level {self.coarse_done + 1}/{self.coarse_expected}"
        if self.contact:
            return f"solve {self.solves} with contact"
        k = self.solves - self.coarse_expected
        return f"frame {k}/{self.frames}" if 1 <= k <= self.frames else f"solve {self.solves}"

    def _progress(self, record):
        msg = record.msg if isinstance(record.msg, str) else ""
        if record.name == "gdfe.solver.newton" and msg.startswith("newton %d"):
            it, residual, estimate = record.args[:3]
            if it <= self.last_it:
                self.solves += 1
            self.last_it = it
            self.bar.update(1)
            self.bar.set_postfix_str(f"{self._label()}, residual {residual:.1e} h, estimate {estimate:.1e} h",
                                     refresh=False)
        elif record.name == "gdfe.solver.starts" and msg.startswith("multilevel"):
            self.coarse_done += 1
            self.last_it = math.inf
        elif record.name == "gdfe.solver.simulation" and msg.startswith("the contact-free solve passes"):
            self.contact = True
            self.solves = 0
            self.last_it = math.inf
