"""Printable strips of the 1-D design: a plan's masks and design file, read back, checked, reported.

:func:`write_strip` prints a :class:`gdfe.inverse.StripPlan` at the printer's pixel (the
pattern's cell): the strip's two masks and a design file that reads them
(``[masks]``), then reads that file back with :func:`gdfe.load_design`, so that the design
that is checked is the one the files describe. :func:`write_check` writes the simulated
check's deviation report: a PNG overlay (:func:`gdfe.inverse.plot_deviation`) and a JSON of
the RMS and largest deviation, overall and per printed segment.

All lengths in millimetres.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_positive

__all__ = ["PrintedStrip", "write_strip", "write_check"]


@dataclasses.dataclass
class PrintedStrip:
    """A strip written for the printer.

    Attributes
    ----------
    name : str
    files : dict
        ``top``, ``bottom`` (masks) and ``design`` (the TOML) -> Path.
    design : Design
        The design read back from ``files["design"]``.
    ny : int
        Pixels across the strip.
    width : float [mm]
        Printed strip width (``ny`` pixels).
    """

    name: str
    files: dict
    design: object
    ny: int
    width: float


def write_strip(plan, out_dir, name, width, film, comment=None):
    """Write a plan's strip as printer masks and a design file, and read the design back.

    Parameters
    ----------
    plan : gdfe.inverse.StripPlan
        Its pattern's cell is the printer pixel.
    out_dir : str or Path
    name : str
        File stem: ``NAME_top.png``, ``NAME_bottom.png``, ``NAME.toml``.
    width : float [mm]
        Strip width: a whole number of pixels.
    film : dict
        The design file's ``[film]`` table (``h``, ``d`` and ``K``, or ``R``; ``nz``).
    comment : str, optional
        Lines at the top of the design file (the source, the couples).

    Returns
    -------
    PrintedStrip
    """
    from gdfe.design import load_design
    from gdfe.fabrication.masks import face_masks, write_design_toml, write_masks

    pixel = plan.pattern.cell
    width = check_positive("width", width)
    ny = int(round(width / pixel))
    if ny < 1 or not math.isclose(ny * pixel, width, rel_tol=1e-6):
        raise GdfeError(f"width: expected a whole number of pixels ({pixel:g} mm), got {width:g} mm")
    out_dir = Path(out_dir)
    masks = face_masks(plan.design(width=width, ny=ny, nz=int(film.get("nz", 1))))
    files = write_masks(masks, out_dir, name)
    files["design"] = write_design_toml(out_dir / f"{name}.toml", files, pixel, film, comment=comment,
                                        simulate={"method": "newton"})
    design, _ = load_design(files["design"])
    back = face_masks(design)
    if not (np.array_equal(back.top, masks.top) and np.array_equal(back.bottom, masks.bottom)):
        raise RuntimeError(f"{files['design']}: the masks read back differ from those written")
    return PrintedStrip(name=name, files=files, design=design, ny=ny, width=ny * pixel)


def write_check(check, out_dir, name, extra=None):
    """Write a simulated check's deviation report: ``NAME_deviation.png`` and ``NAME_deviation.json``.

    A check that did not converge gets a JSON that says so and no deviation (nor picture).

    Returns
    -------
    dict
        The JSON's content, with ``files``.
    """
    from gdfe.inverse.deviation import plot_deviation
    from gdfe.io import write_json

    out_dir = Path(out_dir)
    res = check.result
    rec = {"name": name, "converged": bool(res.converged), "iterations": int(res.iterations),
           "residual": float(res.residual), "seconds": float(res.seconds), "n_cells": int(check.design.n_cells),
           "target": check.plan.target.summary(), "plan": check.plan.summary(), **(extra or {})}
    files = {"json": out_dir / f"{name}_deviation.json"}
    if check.deviation is None:
        rec["deviation"] = None
        rec["note"] = "the solver did not converge: the shape is not an equilibrium and is not measured"
    else:
        rec["deviation"] = check.deviation.summary()
        files["png"] = plot_deviation(check.deviation, out_dir / f"{name}_deviation.png",
                                      title=f"{name}: target (grey) vs GDFE mid-line, max "
                                            f"{check.deviation.max:.3f} mm, RMS {check.deviation.rms:.3f} mm")
    rec["files"] = {k: str(v) for k, v in files.items()}
    write_json(files["json"], rec)
    return rec
