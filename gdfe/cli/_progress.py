"""Progress of the command line's long work, shown wherever it runs, silenced by ``--quiet``.

What a long command shows on standard error (:func:`progress_mode`):

- on a terminal, or anywhere with ``--progress``: a tqdm bar with a total and a time
  estimate. :class:`SolveProgress` counts a simulation's solves (the coarse levels of a
  multilevel start, then the ramp's frames; the frames again where the solve is redone with
  contact) and shows the Newton iteration and its residual beside the count; ``gdfe design``
  counts its folds, ``gdfe report`` its studies;
- elsewhere (a log file, CI, ``nohup``, a notebook's subprocess): a plain line at most every
  :data:`INTERVAL` seconds with the stage, the iteration, the residual and the time so far,
  ``gdfe: solving frame 3/10, Newton 14, residual 2.1e-07 h, 42 s`` (also where tqdm is not
  installed). The line comes when a record arrives, or, where a step says nothing for that
  long (a factorisation, writing files), from a timer thread, saying for how long it has
  been busy since the last news (``..., 1 min 2 s (busy 50 s since)``);
- with ``--quiet``: neither.

Both are fed by the library's log: the library never imports the command line and reports
what it does through ``logging.getLogger(__name__)``. A record with a ``progress``
attribute (``log.debug(..., extra={"progress": {...}})``) is a progress report, its
``event`` one of

- ``"newton"``: an iteration (``iteration``, ``residual_h``, ``estimate_h``: units of h);
- ``"level"``: a coarse level of the multilevel start is solved (``cells``);
- ``"frame"``, ``"frame solved"``: a frame of the ramp begins, ends (``frame``, ``frames``);
- ``"contact"``: the frames are solved again, with self-contact;
- ``"check"``: the penetration check after the solve sets up (``frame`` None) or checks a
  frame (``frame``, ``frames``);
- ``"stage"``: a long step outside the Newton loop (``stage``; ``step``/``total`` where it
  counts, as the penetration check's chunks do: step ``step`` of ``total`` under way);
- ``"steps"``: a step of a study's sweep (``stage``, ``step``, ``total``;
  :func:`studies._common.progress`), or an item of :func:`gdfe.parallel.parallel_map`: the bar of
  ``gdfe study`` counts them, and its lines name the step under way (``study fig09 letters 3/16``);
- ``"study"``: a study of the report begins (``status`` None) or ends (``status``, ``seconds``),
  ``name``, ``step`` of ``total``.

While progress is shown, the loggers ``gdfe`` and ``studies`` send their records here, and
every record at the level the user asked for (warnings by default, ``-v`` for more) still
reaches the log, written above the bar. Lines that must not be missed (each study of the
report as it ends) are written whatever the interval.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import threading
import time

__all__ = ["progress_mode", "shows_bar", "Progress", "SolveProgress", "StudyProgress", "announce_estimate",
           "elapsed_text", "study_line", "INTERVAL", "ESTIMATE_SECONDS"]

#: Seconds between two plain progress lines (off a terminal).
INTERVAL = 10.0
#: A run whose estimate (:mod:`gdfe.resources`) exceeds this many seconds has it printed before it starts.
ESTIMATE_SECONDS = 10.0
#: Whether lines also come from a timer thread when the work says nothing for :data:`INTERVAL` seconds.
HEARTBEAT = True
#: Seconds between two redraws of a bar for Newton iterations (a count or a stage redraws it at once).
_REDRAW = 0.1

_shown = []  # the progress on screen: one at a time, a progress inside it stays silent
_clock = time.monotonic  # the clock of the intervals (a test sets its own)


def progress_mode(args):
    """The ``--quiet``/``--progress`` choice of a command: False (nothing), True (a bar even off a
    terminal) or None (a bar on a terminal, plain lines elsewhere)."""
    if getattr(args, "quiet", False):
        return False
    return True if getattr(args, "progress", False) else None


def _tqdm():
    try:
        from tqdm.auto import tqdm
    except ModuleNotFoundError:  # tqdm comes with the `parallel` extra: plain lines without it
        return None
    return tqdm


def shows_bar(mode) -> bool:
    """Whether progress in ``mode`` is a tqdm bar (else plain lines, or nothing when ``mode`` is False)."""
    wanted = mode is True or (mode is None and sys.stderr.isatty())
    return wanted and _tqdm() is not None


def elapsed_text(seconds) -> str:
    """``42 s``, ``1 min 52 s``, ``2 h 05 min``."""
    s = int(round(float(seconds)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def announce_estimate(est, mode, what=""):
    """Print the estimate ``est`` (:class:`gdfe.resources.Estimate`) of a run on standard error
    when it exceeds :data:`ESTIMATE_SECONDS`, unless ``mode`` is quiet."""
    from gdfe.resources import CALIBRATION

    if mode is False or est.seconds <= ESTIMATE_SECONDS:
        return
    line = f"gdfe: estimated {what}{est.text()}; {CALIBRATION}"
    if _shown:  # above the bar being shown
        _shown[-1].write(line)
    else:
        print(line, file=sys.stderr, flush=True)


class Progress(logging.Handler):
    """A long task's progress: a bar, or plain lines every :data:`INTERVAL` seconds, or nothing.

    Used as a context manager. The caller counts steps (:meth:`advance`) and names them
    (:meth:`step`); the library's progress records (see the module) say what happens inside
    a step.

    Parameters
    ----------
    mode : bool or None
        :func:`progress_mode`.
    desc : str
        What the task is (``solving``, ``designing``, ``report``).
    total : int, optional
        Steps expected; None where unknown (then :meth:`advance` may set it).
    unit : str
        What a step is, for the bar (`` fold``).
    """

    #: Loggers whose records feed the progress.
    LOGGERS = ("gdfe", "studies")

    def __init__(self, mode, desc, *, total=None, unit=" step"):
        super().__init__(level=logging.DEBUG)
        self.mode = mode
        self.enabled = mode is not False
        self.desc, self.total, self.unit = desc, total, unit
        self.done = 0
        self.label = ""  # the current step, e.g. "frame 3/10"
        self.stage = ""  # what happens inside it, e.g. "checking self-penetration: gap search 3/13"
        self.newton = None  # (iteration, residual, estimate) of the last Newton iteration
        self.bar = None
        self._t0 = self._last_line = self._last_draw = self._last_news = 0.0
        self._stack = None
        self._saved = []
        self._lock = threading.Lock()  # one line at a time, from the work or the timer
        self._stop = threading.Event()
        self._timer = None

    # -- context -------------------------------------------------------------------------------
    def __enter__(self):
        if not self.enabled or _shown:
            self.enabled = False
            return self
        _shown.append(self)
        self._t0 = self._last_line = self._last_news = _clock()
        self._stack = contextlib.ExitStack()
        if shows_bar(self.mode):
            from tqdm.contrib.logging import logging_redirect_tqdm

            self._stack.enter_context(logging_redirect_tqdm())
            self.bar = _tqdm()(total=self.total, desc=self.desc, unit=self.unit, file=sys.stderr,
                               dynamic_ncols=True, leave=False)
        elif HEARTBEAT:
            self._stop.clear()
            self._timer = threading.Thread(target=self._heartbeat, name="gdfe-progress", daemon=True)
            self._timer.start()
        for name in self.LOGGERS:
            logger = logging.getLogger(name)
            self._saved.append((logger, logger.level, logger.propagate, logger.getEffectiveLevel()))
            logger.setLevel(logging.DEBUG)
            logger.propagate = False
            logger.addHandler(self)
        return self

    def __exit__(self, *exc):
        if not self.enabled:
            return False
        for logger, level, propagate, _ in self._saved:
            logger.removeHandler(self)
            logger.setLevel(level)
            logger.propagate = propagate
        self._saved = []
        if self._timer is not None:
            self._stop.set()
            self._timer.join()
            self._timer = None
        if self.bar is not None:
            self.bar.close()
        self._stack.close()
        _shown.remove(self)
        self.enabled = False
        return False

    # -- what the caller says ------------------------------------------------------------------
    def advance(self, n=1):
        """``n`` more steps done (the total grows where they pass it)."""
        if not self.enabled:
            return
        self.done += n
        if self.total is not None and self.done > self.total:
            self.total = self.done
            if self.bar is not None:
                self.bar.total = self.total
        if self.bar is not None:
            self.bar.update(n)
        self._show(now=True)

    def step(self, label, stage=""):
        """The step now under way is ``label`` (``stage``: what happens in it, if known)."""
        if not self.enabled:
            return
        self.label, self.stage, self.newton = label, stage, None
        self._show(now=True)

    def write(self, text):
        """A line on standard error whatever the interval (above the bar where there is one)."""
        if not self.enabled:
            return
        with self._lock:
            if self.bar is not None:
                self.bar.write(text, file=sys.stderr)
            else:
                print(text, file=sys.stderr, flush=True)
            self._last_line = _clock()

    # -- what the library says -----------------------------------------------------------------
    def emit(self, record):
        try:
            self._progress(record)
        except Exception:  # a bug in the display: logging prints its traceback, the work goes on
            self.handleError(record)
        if record.levelno >= self._threshold(record):
            logging.getLogger().handle(record)

    def _threshold(self, record):
        """The level the user asked to see for ``record``'s logger (what it was before the progress)."""
        for logger, _, _, effective in self._saved:
            if record.name == logger.name or record.name.startswith(logger.name + "."):
                return effective
        return logging.WARNING

    def _progress(self, record):
        info = getattr(record, "progress", None)
        if isinstance(info, dict):
            self.on(info)

    def on(self, info):
        """Take in a progress record's ``info`` (the module lists them); subclasses count their own."""
        event = info.get("event")
        if event == "newton":
            self.newton = (info["iteration"], info["residual_h"], info.get("estimate_h"))
            self.stage = ""
            self._show()
        elif event == "check":
            frame, frames = info.get("frame"), info.get("frames")
            self.on({"event": "stage", "stage": "checking self-penetration: " + (
                "set-up" if frame is None else f"frame {frame}/{frames}")})
        elif event in ("stage", "steps"):
            step, total = info.get("step"), info.get("total")
            self.stage = info["stage"] + (f" {step}/{total}" if total else f" {step}" if step else "")
            self.newton = None
            self._show()
        elif event == "study" and info.get("status") is not None:
            self.write(study_line(info))

    # -- what is shown -------------------------------------------------------------------------
    def _inside(self, bar):
        if self.newton is None:
            return self.stage
        it, res, est = self.newton
        if bar:  # beside the count: the residual first
            return f"residual {res:.1e} h" + (f", estimate {est:.1e} h" if est is not None else "") + f", Newton {it}"
        return f"Newton {it}, residual {res:.1e} h"

    def text(self, bar=False) -> str:
        """What the task is doing now: the bar's postfix, or a plain line without the ``gdfe:`` and the time."""
        parts = [p for p in (self.label, self._inside(bar)) if p]
        if bar:
            return ", ".join(parts)
        if not self.label:
            return ", ".join([self.desc, *parts])
        return ", ".join([f"{self.desc} {parts[0]}", *parts[1:]])

    def _show(self, now=False):
        t = self._last_news = _clock()
        if self.bar is not None:
            if now or t - self._last_draw >= _REDRAW:
                self.bar.set_postfix_str(self.text(bar=True), refresh=True)
                self._last_draw = t
            else:
                self.bar.set_postfix_str(self.text(bar=True), refresh=False)
            return
        self._line()

    def _line(self):
        """A plain line if the last one is :data:`INTERVAL` seconds old."""
        with self._lock:
            t = _clock()
            if t - self._last_line < INTERVAL:
                return
            quiet = t - self._last_news
            busy = f" (busy {elapsed_text(quiet)} since)" if quiet >= max(INTERVAL, 1.0) else ""
            print(f"gdfe: {self.text()}, {elapsed_text(t - self._t0)}{busy}", file=sys.stderr, flush=True)
            self._last_line = t

    def _heartbeat(self):
        while not self._stop.wait(min(1.0, max(INTERVAL / 4, 0.01))):
            try:
                self._line()
            except Exception:  # a bug in the display must not stop the work: say it once, stop the timer
                import traceback

                traceback.print_exc()
                return


def study_line(info):
    """``gdfe: fig06 ok, 12.3 s (3/17)``: a study that ended (a ``"study"`` record's info)."""
    count = f" ({info['step']}/{info['total']})" if info.get("total") else ""
    return f"gdfe: {info['name']} {info['status']}, {info['seconds']:.1f} s{count}"


class StudyProgress(Progress):
    """The progress of ``gdfe report`` (counts its studies, a line as each ends) or of ``gdfe study``
    (counts the study's sweep, where it reports one through :func:`studies._common.progress`).

    Parameters
    ----------
    mode : bool or None
        :func:`progress_mode`.
    desc : str
        ``report`` or ``study NAME``.
    total : int, optional
        The report's studies; None for one study (the sweep's steps set it).
    """

    def __init__(self, mode, desc, total=None):
        super().__init__(mode, desc, total=total, unit=" study" if total is not None else " step")
        self.report = total is not None

    def on(self, info):
        event = info.get("event")
        if self.report and event == "study":
            if info.get("status") is None:
                self.step(f"{info['name']} ({info['step']}/{info['total']})")
            else:
                self.advance()
                self.write(study_line(info))
                self.step("")
            return
        if not self.report and event == "steps":
            step, total = info.get("step"), info.get("total")
            if total:
                self.total = max(int(total), self.done)
                self.done = int(step) - 1
                if self.bar is not None:
                    self.bar.total, self.bar.n = self.total, self.done
            # the sweep's step labels the line until the next one: a stage would give way to the first
            # Newton record ("study inverse2d, Newton 12, ..." for half an hour, no word of which design)
            stage = info["stage"]
            name = self.desc.split(" ", 1)[-1] + " "  # "fig06 hinges" in study fig06: "study fig06 hinges 3/12"
            stage = stage[len(name):] if stage.startswith(name) else stage
            self.step(stage + (f" {step}/{total}" if total else f" {step}" if step else ""))
            return
        super().on(info)


def _coarse_levels(cells):
    """Coarse levels a multilevel start solves for ``cells`` cells (2 x 2 coarsening, see gdfe.solver.starts)."""
    from gdfe.solver import MULTILEVEL_COARSEST

    levels, n = 0, float(cells)
    while True:
        n /= 4.0
        levels += 1
        if n <= MULTILEVEL_COARSEST:
            return levels


class SolveProgress(Progress):
    """The progress of a :func:`gdfe.simulate` call: its solves counted, fed by the solver's log records.

    The bar counts solves: the coarse levels of a multilevel start, then the ramp's frames
    (and the frames again where the contact-free solve passes through itself and is redone
    with contact); beside the count, the Newton iteration with its residual and error
    estimate (units of h), or the stage after the Newton loop (the penetration check).

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
        ``"auto"``, ``"on"`` or ``"off"``.
    """

    def __init__(self, mode, *, frames=1, cells=0, multilevel=False, contact="auto"):
        self.frames = int(frames)
        self.coarse_expected = _coarse_levels(cells) if multilevel else 0
        super().__init__(mode, "solving", total=self.coarse_expected + self.frames, unit=" solve")
        self.coarsened = self.coarse_done = 0
        self.contact = contact == "on"
        self.frame_label = ""

    def _retotal(self, change):
        self.total = max(self.done, (self.total or 0) + change)
        if self.bar is not None:
            self.bar.total = self.total

    def _solve_label(self):
        if self.coarse_done < self.coarse_expected:
            return f"multilevel start, level {self.coarse_done + 1}/{self.coarse_expected}"
        return self.frame_label

    def on(self, info):
        event = info.get("event")
        if event == "coarsened":  # the start coarsens all its levels before it solves the coarsest
            self.coarsened += 1
        elif event == "level":
            if self.coarse_done == 0 and self.coarsened and self.coarsened != self.coarse_expected:
                self._retotal(self.coarsened - self.coarse_expected)  # the count was a guess: now it is known
                self.coarse_expected = self.coarsened
            self.coarse_done += 1
            self.advance()
            self.step(self._solve_label())
        elif event == "frame":
            self.frames = int(info.get("frames", self.frames))
            self.frame_label = f"frame {info['frame']}/{self.frames}" + (" with contact" if self.contact else "")
            self.step(self._solve_label())
        elif event == "frame solved":
            self.advance()
        elif event == "contact":
            self.contact = True
            self.desc = "solving"
            if self.bar is not None:
                self.bar.set_description(self.desc, refresh=False)
            self._retotal(self.frames)
            self.frame_label = "solving again with contact"
            self.step(self.frame_label)
        elif event == "check":  # every solve done: the check after them
            self.desc = "checking self-penetration"
            if self.bar is not None:
                self.bar.set_description(self.desc, refresh=False)
            frame, frames = info.get("frame"), info.get("frames") or 1
            self.step("set-up" if frame is None else f"frame {frame}/{frames}" if frames > 1 else "")
        elif event == "stage" and self.desc == "checking self-penetration":
            prefix = "checking self-penetration: "
            super().on({**info, "stage": info["stage"][len(prefix):] if info["stage"].startswith(prefix)
                        else info["stage"]})
        else:
            super().on(info)
