"""Mesh refinement of the fold angle of the paper's Figure 6 hinges (issue: GDFE core).

For L = 1, 1.6, 2.6 mm (h = 0.29, d = 0.33, R from Eq. 3) the hinge is simulated with
8, 16, 32 (and 64 at ``fine``) cells across the hinge, for in-plane isotropic shrink
(the default specimen, width 0.5 mm) and for uniaxial shrink. The observed order of
convergence of the angle is fitted from the successive differences; for uniaxial shrink
the exact discrete answer ``2 n atan((1 - R) L / (2 n h))`` converges to Eq. 2 at
second order.

Run ``python -m studies.hinge_refinement [--out DIR]``; writes ``hinge_refinement.png``
and ``hinge_refinement.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import gdfe
from gdfe import paper
from gdfe._validation import check_choice

LENGTHS = paper.FIG6_LENGTHS
D = paper.FIG6_D
CELLS = {"coarse": (4, 8, 16), "default": (8, 16, 32), "fine": (8, 16, 32, 64)}


def run(resolution="default", out=None):
    """Simulate every hinge at every resolution; return the angles, errors and rates."""
    check_choice("resolution", resolution, CELLS)
    cal = gdfe.Calibration()
    rows = []
    for iso in (1.0, 0.0):
        for L in LENGTHS:
            eq1 = float(cal.alpha(L, D))
            angles, iters = [], []
            for n in CELLS[resolution]:
                res = gdfe.simulate(gdfe.hinge(L, d=D, isotropy=iso, cell_size=L / n)).check()
                angles.append(gdfe.fold_angle(res))
                iters.append(res.iterations)
            a = np.array(angles)
            diffs = np.abs(np.diff(a))
            # successive differences shrink like h^p (refinement ratio 2)
            rate = float(np.log2(diffs[:-1] / diffs[1:]).mean()) if len(a) >= 3 else float("nan")
            rows.append({"isotropy": iso, "L_mm": L, "cells": list(CELLS[resolution]), "alpha_rad": angles,
                         "iterations": iters, "alpha_eq1_rad": eq1, "error_finest_rad": float(a[-1] - eq1),
                         "observed_order": rate})
    result = {"study": "hinge_refinement", "resolution": resolution, "d_mm": D, "h_mm": paper.H,
              "R": float(cal.ratio(D)), "rows": rows}
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        from gdfe.io import write_json

        write_json(out / "hinge_refinement.json", result)
        plot(result, out)
    return result


def plot(result, out):
    from studies._common import pyplot

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, iso in zip(axes, (1.0, 0.0)):
        for row in (r for r in result["rows"] if r["isotropy"] == iso):
            h = row["L_mm"] / np.array(row["cells"])
            err = np.abs(np.array(row["alpha_rad"]) - row["alpha_eq1_rad"])
            ax.loglog(h, np.maximum(err, 1e-8), "o-", label=f"L = {row['L_mm']:g} mm "
                      f"(order {row['observed_order']:.2f})")
        ax.set(xlabel="cell size along the hinge [mm]", ylabel="|alpha - Eq. 1| [rad]",
               title="isotropic in-plane shrink" if iso else "uniaxial shrink")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(Path(out) / "hinge_refinement.png", dpi=120)
    plt.close(fig)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("out/hinge_refinement"))
    p.add_argument("--resolution", choices=sorted(CELLS), default="default")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    res = run(args.resolution, args.out)
    if args.json:
        print(json.dumps(res, indent=2))
    else:
        for r in res["rows"]:
            print(f"isotropy {r['isotropy']:g}  L={r['L_mm']:<4g} cells {r['cells']}  alpha "
                  + " ".join(f"{a:.4f}" for a in r["alpha_rad"])
                  + f"  Eq.1 {r['alpha_eq1_rad']:.4f}  order {r['observed_order']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
