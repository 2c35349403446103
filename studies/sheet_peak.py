"""One whole simulation of a benchmark sheet, with its peak memory and where the peak was.

``gdfe bench`` measures each sheet's peak as its child process's maximum resident set. This
module does the same for one sheet in this process, and also samples the resident set from a
thread (every :data:`SAMPLE_SECONDS`), so that it can say which code the main thread was in at the
peak and stop the run when the resident set passes a limit (a run that would take the machine's
last memory is stopped, and says so, instead of being killed by the system). The 4*10^6-cell
corrugation and the 785 456-cell Figure 8 dome in ``docs/bench/sheet4e6`` were measured with it::

    python -m studies.sheet_peak corrugation 4e6 --stop-above 22 --out corrugation_4e6.json

It sits beside the benchmark (:mod:`studies.bench`, whose designs it solves) and is not one of
the report's studies. It reads the resident set from ``/proc`` (Linux, like the benchmark's machines).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import threading
import time
import traceback

from gdfe._validation import GdfeError, check_choice, check_number, check_positive
from gdfe.io import check_creatable, write_text

__all__ = ["SAMPLE_SECONDS", "MIN_CELLS", "measure", "main"]

#: How often the sampling thread reads the resident set.
SAMPLE_SECONDS = 0.02
#: The smallest sheet (cells) it measures, as ``gdfe bench``.
MIN_CELLS = 4


def _rss_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def _where(main_id, own_id):
    """The last few gdfe frames of every other thread (the main thread named ``main``)."""
    out = {}
    for tid, frame in sys._current_frames().items():
        if tid == own_id:
            continue
        stack = [f"{f.filename.rsplit('/', 1)[-1]}:{f.lineno}:{f.name}" for f in traceback.extract_stack(frame)
                 if "gdfe" in f.filename][-5:]
        if stack:
            out["main" if tid == main_id else str(tid)] = stack
    return out


class _Sampler(threading.Thread):
    """The resident set's maximum, where it was reached, and a stop above ``limit`` bytes."""

    def __init__(self, limit):
        super().__init__(daemon=True)
        self.limit, self.peak, self.where, self.at = limit, 0, {}, 0.0
        self.t0, self.done = time.perf_counter(), threading.Event()
        self.main_id = threading.main_thread().ident

    def run(self):
        while not self.done.is_set():
            rss = _rss_bytes()
            if rss > self.peak:
                self.peak, self.at = rss, time.perf_counter() - self.t0
                self.where = _where(self.main_id, threading.get_ident())
            if self.limit is not None and rss > self.limit:
                print(f"sheet_peak: resident set {rss / 2**30:.2f} GiB passed --stop-above "
                      f"{self.limit / 2**30:g} GiB after {self.at:.0f} s, in {self.where.get('main')}; stopped",
                      file=sys.stderr, flush=True)
                os._exit(3)
            self.done.wait(SAMPLE_SECONDS)


def measure(kind, n_cells, stop_above_gib=None):
    """Simulate the benchmark's sheet ``kind`` of about ``n_cells`` cells (:func:`studies.bench._design`, defaults).

    Returns a dict: the run's cells, steps, seconds, timings, energy and convergence; ``peak_rss_mib``
    (the process's maximum resident set: the larger of the kernel's high-water mark, ``ru_maxrss_mib``,
    and the sampled one, ``peak_sampled_mib``), ``peak_at_s`` and ``peak_where`` (the sampled peak's time,
    in seconds after the simulation began, and the main thread's last gdfe frames there), ``rss_before_mib``
    (with the design made).
    ``stop_above_gib`` ends the process (exit status 3) once its resident set passes it. A sheet whose
    estimate (:func:`gdfe.resources.estimate_run`) does not fit the machine is refused before it is made.
    """
    import gdfe
    from gdfe.resources import estimate_run
    from studies.bench import DESIGNS, _design

    check_choice("kind", kind, DESIGNS)
    n_cells = int(check_number("cells", n_cells, minimum=MIN_CELLS))
    limit = None if stop_above_gib is None else float(check_positive("stop_above_gib", stop_above_gib)) * 2**30
    est = estimate_run(n_cells)  # refused before its masks and mesh are made, not by the system while they are
    if not est.fits:
        raise GdfeError(f"cells: expected a sheet that fits in memory, got {est.text()}")
    with tempfile.TemporaryDirectory() as masks:  # the design is read from its masks, which go with the folder
        des, pixels = _design(kind, n_cells, masks)
    sampler = _Sampler(limit)
    before = _rss_bytes()
    sampler.start()
    try:
        res = gdfe.simulate(des, method="auto")
    finally:
        sampler.done.set()
        sampler.join()
    # the kernel updates its high-water mark lazily: it can lag the resident set last read from /proc
    # (by 0.2 MiB at the 4*10^6-cell sheet's peak), so the peak is the larger of the two
    ru_maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    sampled = sampler.peak / 2**20
    return {"design": kind, "cells": des.n_cells, "points": des.mesh.n_points, "pixels": list(pixels),
            "seconds": res.seconds, "iterations": res.iterations, "converged": bool(res.converged),
            "energy": float(res.energy), "timings": {k: float(v) for k, v in res.timings.items()},
            "peak_rss_mib": max(ru_maxrss, sampled), "ru_maxrss_mib": ru_maxrss, "peak_sampled_mib": sampled, "peak_at_s": sampler.at, "peak_where": sampler.where,
            "rss_before_mib": before / 2**20, "load_average": list(os.getloadavg())}


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m studies.sheet_peak", description=__doc__.splitlines()[0])
    p.add_argument("kind", help="the benchmark's design (corrugation, fig08-twist, fig08-dome, fig08-saddle)")
    p.add_argument("cells", type=float, help="about this many cells (e.g. 4e6)")
    p.add_argument("--stop-above", type=float, metavar="GIB", help="stop once the resident set passes this")
    p.add_argument("--out", help="write the record as JSON here (else print it)")
    args = p.parse_args(argv)
    try:
        if args.out is not None:  # refused before a run of an hour, not after it
            check_creatable(args.out, "--out", what="file")
        row = measure(args.kind, args.cells, args.stop_above)
    except GdfeError as exc:
        p.error(str(exc))
    text = json.dumps(row, indent=1)
    status = 0
    if args.out is None:
        print(text)
    else:
        try:
            write_text(args.out, text + "\n")
        except (GdfeError, OSError) as exc:  # the record is not lost with the file: it goes to stdout
            print(text)
            print(f"sheet_peak: --out: cannot write {args.out} ({exc}); the record is above", file=sys.stderr)
            status = 1
    if not row["converged"]:  # its seconds are not a solve's: the record says so, and so does the exit status
        print(f"sheet_peak: the {row['cells']:,}-cell {row['design']} did not converge in {row['iterations']} "
              f"iterations", file=sys.stderr)
        status = 1
    return status


if __name__ == "__main__":
    raise SystemExit(main())
