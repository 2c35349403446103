"""What a design or a simulation will cost before it starts: cells, memory and time, against the machine.

A design's mesh takes about :data:`MESH_BYTES_PER_CELL` per cell; a simulation's peak memory
grows by about :data:`SOLVE_BYTES_PER_CELL` per cell over a base of :data:`BASE_BYTES`, plus
the frames it keeps; its time per frame follows a power law in the cell count
(:data:`SECONDS_AT`, :data:`TIME_EXPONENTS`). The constants are fitted to the benchmark's
measurements on 2 cores (``gdfe bench``, 10^3 to 10^6 cells, and the 4*10^6-cell sheet of
``docs/bench/sheet4e6`` and ``sheet4e6_heap``): they are estimates, meant to decide before a run
whether it fits the machine and whether it is long enough to ask first. The memory is an upper envelope of the
measured peaks (1.05-1.29 times each from 7.8*10^4 cells up); the time is within a factor of 2
of the benchmark's sheets, and longer than a design that converges in a few steps takes (the
785 456-cell Figure 8 dome, 4 steps: a fifth of its estimate). Thin cells (``nz`` large)
converge more slowly (:func:`thin_factor`).

Calibration. The time of a frame is fitted to the benchmark's corrugated sheets
(``docs/bench/corrugation``; ``docs/bench/bench.json`` ``sheets``), whose measured seconds
are those of a whole :func:`gdfe.simulate` call: the multilevel start of the large sheets and
the penetration check after the solve are inside them, and so inside the estimate. The Figure 8
plates of the same benchmark take up to about 1.4 times as long at 10^5 cells (they bend more
and converge in more iterations); a command adds reading its input and writing its outputs,
a few seconds at 10^5 cells. A 2-D design (:func:`estimate_design`) is several simulations of
one film: its optimisation's folds, each with an adjoint solve, and the folds that check the
result; their cost in simulations is measured by ``gdfe study inverse2d``
(``docs/bench/inverse2d``, its ``timing``), against the simulations of the same run so that
the machine's load cancels.

:func:`check_design_cells` refuses a design whose mesh alone would not fit in memory;
:func:`check_run` refuses a simulation whose estimate does not (both raise
:class:`gdfe.GdfeError` with the estimate); :attr:`Estimate.large` says when a run is long
or takes most of the memory, which the command line runs only when asked (``--large``).
"""

from __future__ import annotations

import dataclasses
import os

from gdfe import _memory
from gdfe._validation import GdfeError

__all__ = ["Estimate", "estimate_run", "estimate_design", "machine_memory", "check_design_cells", "check_run",
           "check_grid", "check_work", "thin_factor", "format_bytes", "format_seconds", "LARGE_SECONDS",
           "LARGE_MEMORY_FRACTION",
           "PROGRESS_SECONDS", "CALIBRATION", "solve_heap"]

#: Bytes per cell of a design's mesh and cell data (points, hexahedra, indices, materials).
MESH_BYTES_PER_CELL = 600
#: Peak memory of a solve: a base and bytes per cell (the design, the solver's systems and
#: multigrid, the Newton-CG Hessian and vectors, the penetration check's triangles), an upper
#: envelope of the peaks measured on 2 cores (ru_maxrss of one process, the design inside):
#: the 10^5 sheets 651-809 MiB and the 10^6 corrugation 5 556-5 744 MiB (``docs/bench/watch``,
#: ``watch2`` and ``heap``, the last with the C heap's setting of :func:`solve_heap`), the 785 456-cell
#: Figure 8 dome 4 570 MiB and the 4*10^6 corrugation 20 274 MiB (``docs/bench/sheet4e6``, before
#: that setting) and 20 390 MiB (``sheet4e6_heap``, with it). The estimate is 1.05-1.29 times each
#: (the 10^6 sheet with the setting nearest). The
#: fit before, 600 MiB and 5 600 B, was 1.41-1.56 times the 10^5 sheets once ``contact="auto"`` no
#: longer held the IPC Toolkit's collision mesh through their solve; the one before that, 100 MiB
#: and 7 000 B, said 26.5 GiB at 4*10^6 cells and kept that run off this 23.5 GiB machine.
#: (The base is the envelope's intercept, not the interpreter's own: a 1 024-cell run peaks at 115 MiB.)
BASE_BYTES = 400 * 2**20
SOLVE_BYTES_PER_CELL = 5_800
#: Seconds of one frame at 10^4 cells, and the exponent of the time against the cell count below
#: and above 10^5 cells, fitted to the benchmark's corrugated sheets with the default solver
#: (docs/bench/turn, recycle3 and windows: 1.16-1.47 s at 10^4 cells, 12.7-16.8 s at 10^5,
#: 508-634 s at 10^6; the fit gives 13.9 s and 593 s). The Figure 8 plates took 0.5-1.1 times the
#: corrugation's time at 10^5 cells. (The fit before, (1.60 s, 1.21, 1.86), was of a slower solver:
#: it said 31 min for the 10^6 sheet's 8-10.) The 4*10^6-cell corrugation (docs/bench/sheet4e6 and
#: sheet4e6_heap) took 74 and 75 min against the 1.6 h it gives. The 10^6 sheet has since got faster:
#: 331-362 s in the latest four benchmarks (docs/bench/heap, quads, records, chebyshev/after_1e6), 0.56-0.61
#: of its estimate, still within the stated factor. A fit to them (exponent 1.40 from 10^5 to 10^6) was
#: tried and not kept: it estimated the 800 016-cell hinge of 100 m (``gdfe hinge -L 1e5``), a strip that
#: rolls up on itself in contact, at 4.3 min, under :data:`LARGE_SECONDS`, so that the command line started it
#: without ``--large`` where tests/test_bad_inputs.py asks for it to be refused. The estimate is fitted to
#: sheets; the larger exponent keeps such runs behind ``--large``.
SECONDS_AT = (1e4, 1.30)
TIME_EXPONENTS = ((1e5, 1.03), (float("inf"), 1.63))
#: Seconds every frame costs whatever its size (set-up, the penetration check, Python).
FRAME_OVERHEAD_SECONDS = 0.02
#: One evaluation of the 2-D design's optimisation (a fold continued from the last one, its adjoint
#: solve and the gradient), in simulations of the same film from the flat print: the evaluations'
#: mean time over the mean of the two simulations of the relaxed design's check in the same run of
#: ``gdfe study inverse2d`` (docs/bench/inverse2d/inverse2d.json, ``timing``: ``per_evaluation_s``
#: and ``seconds_by_step.relaxed_check``; 10^4 cells, 40 iterations, 46 evaluations: 4.39 s against
#: 1.29 s). It was 1.34 when the solver took 2.73 s for that simulation; the solver got faster for a fold
#: from the flat print than for the design's continued folds, and 1.34 estimated that design at 78 s
#: where it took 209 s (3.41: 190 s).
DESIGN_EVALUATION_SIMULATIONS = 3.41
#: Simulations of a 2-D design besides its optimisation's evaluations: the start's fold, the
#: relaxed design's and the printed design's checks (and the fold from the flat print that
#: follows an optimisation).
DESIGN_CHECK_SIMULATIONS = 3
#: Where the time estimates come from, for the line printed with them.
CALIBRATION = ("fitted to gdfe bench on 2 cores (docs/bench): its sheets took half to twice their estimated "
               "time, a design that converges in a few steps less")
#: A run estimated to take longer than this, or more than this fraction of the machine's memory,
#: is *large*: the command line asks for ``--large`` before it starts one (the 10^6-cell sheet, ~10 min).
LARGE_SECONDS = 300.0
LARGE_MEMORY_FRACTION = 0.5
#: Work estimated to take longer than this says so before it starts, and shows its progress.
PROGRESS_SECONDS = 10.0


def machine_memory():
    """The machine's physical memory in bytes (None where it cannot be read)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def format_bytes(n) -> str:
    """``n`` bytes as ``12 MiB``, ``3.4 GiB``, ..."""
    n = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit in ("B", "KiB", "MiB") else f"{n:.3g} {unit}"
        n /= 1024


def format_seconds(s) -> str:
    """Seconds as ``0.4 s``, ``12 min``, ``3.1 h``, ``5 days``."""
    s = float(s)
    if s < 60:
        return f"{s:.2g} s"
    if s < 3600:
        return f"{s / 60:.2g} min"
    if s < 86400 * 2:
        return f"{s / 3600:.2g} h"
    return f"{s / 86400:.3g} days"


def _frame_seconds(cells):
    n0, t0 = SECONDS_AT
    t, n_from = t0, n0
    for n_to, exponent in TIME_EXPONENTS:
        if cells <= n_to:
            try:
                return t * (float(cells) / n_from) ** exponent + FRAME_OVERHEAD_SECONDS
            except OverflowError:  # more cells than any machine holds: refused on its memory
                return float("inf")
        t *= (n_to / n_from) ** exponent
        n_from = n_to
    return t  # pragma: no cover


@dataclasses.dataclass(frozen=True)
class Estimate:
    """The estimated cost of simulating a design.

    Attributes
    ----------
    cells : int
    frames : int
        Frames solved (the contraction ramp's ``steps``).
    memory_bytes : float
        Peak memory.
    seconds : float
        Wall-clock time on 2 cores like the benchmark's.
    machine_bytes : int or None
        The machine's physical memory.
    unit : str
        What ``frames`` counts (``frames``; a 2-D design's ``simulations``).
    """

    cells: int
    frames: int
    memory_bytes: float
    seconds: float
    machine_bytes: int | None
    unit: str = "frames"

    @property
    def fits(self) -> bool:
        """Whether the estimated memory is within the machine's."""
        return self.machine_bytes is None or self.memory_bytes <= self.machine_bytes

    @property
    def large(self) -> bool:
        """Long (over :data:`LARGE_SECONDS`) or using more than :data:`LARGE_MEMORY_FRACTION` of the memory."""
        return self.seconds > LARGE_SECONDS or (self.machine_bytes is not None and
                                                self.memory_bytes > LARGE_MEMORY_FRACTION * self.machine_bytes)

    def text(self) -> str:
        machine = "" if self.machine_bytes is None else f" (this machine has {format_bytes(self.machine_bytes)})"
        frames = f" x {self.frames} {self.unit}" if self.frames > 1 else ""
        return (f"{self.cells:,} cells{frames}: about {format_seconds(self.seconds)} and "
                f"{format_bytes(self.memory_bytes)} of memory{machine}")

    def as_dict(self) -> dict:
        return {"cells": self.cells, "frames": self.frames, "memory_bytes": float(self.memory_bytes),
                "seconds": float(self.seconds), "machine_bytes": self.machine_bytes}


#: Thin cells converge slowly: the time of a frame grows as ``(aspect / THIN_ASPECT) ** THIN_EXPONENT``
#: for cells more than :data:`THIN_ASPECT` times as wide as they are thick, measured on the paper's
#: 1 mm hinge (``gdfe hinge -L 1 --d 0.33 --nz N``, 2 cores): nz = 16 (aspect 3.4) 1.4 s, nz = 64
#: (aspect 13.8) 32 s, 6.6 times the estimate without it; nz = 200 (aspect 43) had not converged after
#: 400 s. The benchmark's sheets, one layer of cells thicker than wide, set the base time.
THIN_ASPECT, THIN_EXPONENT = 2.3, 1.06


def thin_factor(spacing) -> float:
    """How many times longer a frame takes for cells of ``spacing`` ``(dx, dy, dz)`` [mm] (1 for cells no
    flatter than :data:`THIN_ASPECT`)."""
    dx, dy, dz = (float(v) for v in spacing)
    aspect = max(dx, dy) / dz if dz > 0 else 1.0
    return max(1.0, aspect / THIN_ASPECT) ** THIN_EXPONENT


def estimate_run(cells, frames=1, points=None, spacing=None) -> Estimate:
    """The estimated memory and time of simulating ``cells`` cells over ``frames`` frames.

    Parameters
    ----------
    cells : int
    frames : int
        The ramp's ``steps``; every frame is kept (``points`` x 3 floats each).
    points : int, optional
        Vertices of the design (default: about 2 per cell, a one-layer sheet).
    spacing : (3,) float [mm], optional
        The cells' size (dx, dy, dz): thin cells (many layers, ``nz``) converge slowly
        (:func:`thin_factor`).
    """
    import math

    if not (isinstance(cells, (int, float)) or hasattr(cells, "__index__")) or not math.isfinite(float(cells)) \
            or float(cells) < 1 or float(frames) < 1:
        raise GdfeError(f"cells, frames: expected at least one cell and one frame, got {cells!r} cells and "
                        f"{frames!r} frames")
    cells, frames = int(cells), int(frames)
    points = 2 * cells if points is None else int(points)
    memory = BASE_BYTES + SOLVE_BYTES_PER_CELL * float(cells) + (frames + 1) * float(points) * 3 * 8
    return Estimate(cells=cells, frames=frames, memory_bytes=float(memory),
                    seconds=frames * _frame_seconds(cells) * (1.0 if spacing is None else thin_factor(spacing)),
                    machine_bytes=machine_memory())


def estimate_design(cells, iterations, points=None) -> Estimate:
    """The estimated memory and time of a 2-D design (:func:`gdfe.inverse2d.design_surface`) of ``cells`` cells.

    Parameters
    ----------
    cells : int
        The film's cells (pixels).
    iterations : int
        L-BFGS-B iterations: about one evaluation each, plus the start's (a second phase, where
        the flat print folds onto another branch, doubles them and is not counted).
    points : int, optional
        Vertices of the film (default: about 2 per cell).

    Returns
    -------
    Estimate
        Its ``frames`` are the simulations' equivalent: :data:`DESIGN_EVALUATION_SIMULATIONS` per
        evaluation and :data:`DESIGN_CHECK_SIMULATIONS` (one more after an optimisation), each
        costed as one frame of :func:`estimate_run`.
    """
    iterations = int(iterations)
    evaluations = 1 + iterations
    simulations = DESIGN_EVALUATION_SIMULATIONS * evaluations + DESIGN_CHECK_SIMULATIONS + (iterations > 0)
    one = estimate_run(cells, 1, points)
    return dataclasses.replace(one, frames=max(1, int(round(simulations))), seconds=simulations * one.seconds,
                               unit="simulations")


def check_design_cells(name, cells):
    """Refuse a design of ``cells`` cells whose mesh alone would not fit in the machine's memory."""
    machine = machine_memory()
    need = float(cells) * MESH_BYTES_PER_CELL
    if machine is not None and need > machine:
        raise GdfeError(f"{name}: expected a design that fits in memory, got {float(cells):.3g} cells, whose mesh "
                        f"alone needs about {format_bytes(need)} (this machine has {format_bytes(machine)}); "
                        f"use larger cells (pixel, cell_size) or fewer layers (nz)")
    return int(cells)


def check_run(design, steps):
    """Refuse a simulation of ``design`` over ``steps`` frames whose memory estimate exceeds the machine's.

    Returns
    -------
    Estimate
    """
    est = estimate_run(design.n_cells, steps, design.mesh.n_points, design.mesh.spacing)
    if not est.fits:
        raise GdfeError(f"design, steps: expected a simulation that fits in memory, got {est.text()}; "
                        f"use a coarser design or fewer steps")
    return est


def solve_heap(design):
    """The C heap's setting for a simulation of ``design``, a context manager (:func:`gdfe._memory.heap_blocks`).

    Blocks up to a 3 x 3 matrix of doubles per vertex or per cell, whichever are more (the
    cells' rotations; three ``(n, 3)`` arrays), are served from the heap and reused. Of a
    10^6-cell sheet's arrays that covers the vertices' (46 MiB) and the cells' rotations (69 MiB)
    every Newton step makes, not its Jacobian's values (549 MiB). :func:`gdfe.simulate` runs
    inside it; a measurement of a simulation's parts (``gdfe bench``'s lower bound) runs inside
    it to be measured alike.
    """
    return _memory.heap_blocks(72 * max(design.mesh.n_points, design.n_cells))


def check_work(name, memory_bytes, what, remedy, seconds=None, logger=None):
    """The one guard in front of work whose size the input decides (a grid, a file, a sweep).

    Refuses work whose memory estimate exceeds the machine's, before any of it is allocated, with the
    estimate and what to change; says the estimate (a log line) of work that will take longer than
    :data:`PROGRESS_SECONDS`.

    Parameters
    ----------
    name : str
        The argument, option, key or file whose value set the size: the message's first word.
    memory_bytes : float
        The estimated peak memory.
    what : str
        The work in words, with its size (``"a grid of 2e+10 pixels"``).
    remedy : str
        What the user can change (``"use a larger pixel"``, ``"pass --large"``).
    seconds : float, optional
        The estimated time.
    logger : logging.Logger, optional
        Where the estimate of long work is said (default this module's).

    Returns
    -------
    float
        ``memory_bytes``.
    """
    import logging
    import math

    machine = machine_memory()
    need = float(memory_bytes)
    if not math.isfinite(need) or (machine is not None and need > machine):
        have = "" if machine is None else f" (this machine has {format_bytes(machine)})"
        size = format_bytes(need) if math.isfinite(need) else "more memory than any machine has"
        raise GdfeError(f"{name}: expected work that fits in memory, got {what}, which needs about {size}{have}; "
                        f"{remedy}")
    if seconds is not None and seconds > PROGRESS_SECONDS:
        memory = f" and {format_bytes(need)} of memory" if need > 0 else ""
        (logger or logging.getLogger(__name__)).warning("%s: %s: about %s%s", name, what, format_seconds(seconds),
                                                        memory)
    return need


def check_grid(name, cells, size_mm, pixel, bytes_per_cell=0):
    """Refuse a drawing's grid of ``cells`` pixels whose design (and the arrays that make it) would not fit.

    Parameters
    ----------
    name : str
        What set the pixel (``"pixel"``, ``"crane.fold: pixel"``).
    cells : float
        Pixels of the grid (a float: it may be far beyond any integer array).
    size_mm : (2,) float
        The drawing's extent [mm], for the message.
    pixel : float [mm]
    bytes_per_cell : float
        Bytes per pixel of making the grid, beside the design's mesh (:data:`MESH_BYTES_PER_CELL`).
    """
    w, h = (float(v) for v in size_mm)
    check_work(name, float(cells) * (MESH_BYTES_PER_CELL + bytes_per_cell),
               f"a drawing of {w:.4g} x {h:.4g} mm at {pixel:g} mm pixels ({float(cells):.3g} cells)",
               "use a larger pixel, or check the drawing's unit (a drawing in metres read as millimetres is "
               "10^6 times as many pixels)")
    return float(cells)
