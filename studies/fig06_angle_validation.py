"""Figure 6: fold angles of the hinge specimen simulated with GDFE against Eq. 1.

Three hinges, L = 1, 1.6 and 2.6 mm, h = 0.29 mm, d = 0.33 mm. The paper reports
simulated angles 1.04, 1.66, 2.70 rad against Eq. 1's 1.05, 1.68, 2.73 rad (maximum
error 0.03 rad) with "R = 0.7". Here the hinges are simulated with R from Eq. 3
unrounded (0.6947, which is what Eq. 1 with K = 0.3706 implies) and with R = 0.7, at the
default specimen of :func:`gdfe.hinge` (strip 0.5 mm wide, in-plane isotropic shrink,
16 cells across the hinge, one cell through the film). At ``default`` and ``fine``
resolution the L = 2.6 mm hinge is also simulated for other strip widths, for uniaxial
shrink and with two cells through the film: the angle depends on the specimen.

Run ``python -m studies.fig06_angle_validation [--out DIR] [--resolution R] [--json]``
or ``gdfe study fig06``; writes ``fig06.png`` and ``fig06.json``.
"""

from __future__ import annotations

import numpy as np

from gdfe import paper
from studies._common import check_resolution, finish, headline, n_jobs, main_of, pyplot

NAME = "fig06"
LENGTHS = paper.FIG6_LENGTHS
D = paper.FIG6_D
H = paper.H
PAPER_SIM = paper.FIG6_SIMULATED
PAPER_EQ1 = paper.FIG6_EQ1
PAPER_MAX_ERROR = paper.FIG6_MAX_ERROR
CELLS = {"coarse": 16, "default": 16, "fine": 32}
WIDTHS = (0.25, 0.5, 1.0, 2.0)


def _hinge_angle(case):
    """Simulate one hinge; a module-level function so that it runs in worker processes."""
    import gdfe

    des = gdfe.hinge(case["L"], R=case["R"], h=H, width=case.get("width", 0.5),
                     cell_size=case["L"] / case["cells"], nz=case.get("nz", 1), isotropy=case.get("isotropy", 1.0))
    res = gdfe.simulate(des)
    return {**case, "alpha": float(gdfe.fold_angle(res)), "converged": bool(res.converged),
            "iterations": int(res.iterations), "residual": float(res.residual), "seconds": float(res.seconds),
            "n_cells": int(des.n_cells), "points": res.points if case.get("keep") else None}


def run(resolution="default", out=None):
    """Simulate the three hinges (and the specimen variants); compare with Eq. 1 and the paper."""
    import gdfe
    from gdfe.parallel import parallel_map

    check_resolution(resolution)
    cal = gdfe.Calibration()
    R = float(cal.ratio(D))
    n = CELLS[resolution]
    cases = [{"set": "eq3", "L": L, "R": R, "cells": n, "keep": True} for L in LENGTHS]
    cases += [{"set": "r07", "L": L, "R": 0.7, "cells": n} for L in LENGTHS]
    if resolution != "coarse":
        for iso in (1.0, 0.0):
            cases += [{"set": "width", "L": 2.6, "R": R, "cells": n, "width": w, "isotropy": iso}
                      for w in WIDTHS]
        cases += [{"set": "nz", "L": 2.6, "R": R, "cells": n, "width": 1.0, "nz": 2, "isotropy": iso}
                  for iso in (1.0, 0.0)]
    done = parallel_map(_hinge_angle, cases, n_jobs=n_jobs(resolution), desc="fig06 hinges")
    main_set = [c for c in done if c["set"] == "eq3"]
    r07 = [c for c in done if c["set"] == "r07"]
    eq1 = np.array([float(cal.alpha(L, D)) for L in LENGTHS])
    eq2_r07 = np.array([float(gdfe.angle_from_ratio(0.7, L, H)) for L in LENGTHS])
    sim = np.array([c["alpha"] for c in main_set])
    sim07 = np.array([c["alpha"] for c in r07])
    err = sim - eq1
    converged = all(c["converged"] for c in done)
    hinges = [{"L_mm": c["L"], "alpha_gdfe": c["alpha"], "alpha_eq1": float(e), "error": float(c["alpha"] - e),
               "alpha_gdfe_R07": float(s7), "alpha_eq2_R07": float(a7), "paper_sim": ps, "paper_eq1": pe,
               "iterations": c["iterations"], "residual": c["residual"], "seconds": c["seconds"],
               "n_cells": c["n_cells"], "converged": c["converged"]}
              for c, e, s7, a7, ps, pe in zip(main_set, eq1, sim07, eq2_r07, PAPER_SIM, PAPER_EQ1)]
    specimen = [{k: c[k] for k in ("L", "R", "cells", "alpha", "converged", "iterations", "n_cells")}
                | {"width": c.get("width", 0.5), "isotropy": c.get("isotropy", 1.0), "nz": c.get("nz", 1),
                   "discrete_uniaxial": float(2 * n * np.arctan((1 - R) * 2.6 / (2 * n * H)))}
                for c in done if c["set"] in ("width", "nz")]
    max_err = float(np.abs(err).max())
    hl = [
        headline("max |GDFE - Eq. 1| (R from Eq. 3)", max_err, PAPER_MAX_ERROR, PAPER_MAX_ERROR, "le", unit="rad",
                 paper_text="max error 0.03 rad",
                 note="ours is smaller than the paper's 0.03: the paper's 0.03 comes from simulating with R rounded to 0.7"),
        headline("max |GDFE(R = 0.7) - paper's simulated angles|", float(np.abs(sim07 - PAPER_SIM).max()),
                 None, 0.02, "le", unit="rad", paper_text="1.04, 1.66, 2.70 rad",
                 note="the paper's simulated angles are (1 - 0.7) L / h = 1.034, 1.655, 2.690"),
        headline("max |Eq. 1 - paper's Eq. 1 angles|", float(np.abs(eq1 - PAPER_EQ1).max()), None, 0.01, "le",
                 unit="rad", paper_text="1.05, 1.68, 2.73 rad"),
    ]
    for c, pe in zip(main_set, PAPER_EQ1):
        hl.append(headline(f"GDFE angle, L = {c['L']:g} mm (paper: its Eq. 1 angle)", c["alpha"], pe, 0.03, "abs",
                           unit="rad"))
    wid = [s for s in specimen if s["nz"] == 1 and s["isotropy"] == 1.0]
    spread = (max(s["alpha"] for s in wid) - min(s["alpha"] for s in wid)) if wid else None
    summary = {
        "paper": "GDFE 1.04, 1.66, 2.70 rad vs Eq. 1 1.05, 1.68, 2.73 rad; max error 0.03 rad",
        "ours": ("GDFE " + ", ".join(f"{a:.4f}" for a in sim) + " rad vs Eq. 1 "
                 + ", ".join(f"{a:.4f}" for a in eq1) + f" rad; max error {max_err:.4f} rad"
                 + "; with R = 0.7: " + ", ".join(f"{a:.4f}" for a in sim07) + " rad"),
        "verdict": "reproduced (error below the paper's 0.03 rad)",
        "discrepancy": (
            "The paper's simulated angles equal (1 - R) L / h with R rounded to 0.7 (1.034, 1.655, 2.690), "
            "while its Eq. 1 angles use R = 0.6947 implicitly: its 0.03 rad error is the rounding of R. With R "
            f"from Eq. 3 unrounded the GDFE error is {max_err:.4f} rad, from discretisation and the in-plane "
            "isotropic shrink."
            + (f" The angle depends on the specimen: at L = 2.6 mm it spans {spread:.3f} rad over strip widths "
               f"{', '.join(f'{w:g}' for w in WIDTHS)} mm with isotropic shrink; uniaxial shrink gives the "
               "discrete Eq. 2 value 2n atan((1-R)L/(2nh)) for every width." if spread is not None else "")),
    }
    result = {"study": NAME, "figure": "Fig. 6", "title": "hinge fold angle: GDFE vs Eq. 1",
              "resolution": resolution, "R_eq3": R, "d_mm": D, "h_mm": H, "cells_across_hinge": n,
              "headlines": hl, "converged": converged, "summary": summary, "hinges": hinges,
              "specimen_L26": specimen,
              "_shapes": [(c["L"], c["points"]) for c in main_set]}
    return finish(result, out, plot)


def plot(result, out):
    import gdfe
    from studies._draw import save_figure, side_view

    plt = pyplot()
    fig = plt.figure(figsize=(12, 7.5))
    gs = fig.add_gridspec(2, 3)
    for k, (L, pts) in enumerate(result["_shapes"]):
        ax = fig.add_subplot(gs[0, k])
        des = gdfe.hinge(L, R=result["R_eq3"], h=H, cell_size=L / result["cells_across_hinge"])
        side_view(ax, pts, des)
        hrow = result["hinges"][k]
        ax.set_title(f"L = {L:g} mm: GDFE {hrow['alpha_gdfe']:.3f} rad\nEq. 1 {hrow['alpha_eq1']:.3f} rad "
                     f"(paper {hrow['paper_sim']:.2f} / {hrow['paper_eq1']:.2f})", fontsize=9)
        ax.set(xlabel="x [mm]", ylabel="z [mm]")
    ax = fig.add_subplot(gs[1, 0:2 if result["specimen_L26"] else 3])
    Ls = np.array([h["L_mm"] for h in result["hinges"]])
    w = 0.2
    eq1 = np.array([h["alpha_eq1"] for h in result["hinges"]])
    series = [("GDFE, R from Eq. 3 (0.6947)", "alpha_gdfe"), ("GDFE, R = 0.7", "alpha_gdfe_R07"),
              ("paper's GDFE", "paper_sim"), ("paper's Eq. 1", "paper_eq1")]
    for k, (lab, key) in enumerate(series):
        vals = np.array([h[key] for h in result["hinges"]]) - eq1
        ax.bar(np.arange(3) + (k - 1.5) * w, vals, w, label=lab)
    ax.axhline(0, color="k", lw=0.7)
    ax.axhspan(-PAPER_MAX_ERROR, PAPER_MAX_ERROR, color="0.9", zorder=0, label="paper's max error 0.03 rad")
    ax.set_xticks(np.arange(3), [f"L = {L:g} mm\nEq. 1: {a:.4f} rad" for L, a in zip(Ls, eq1)])
    ax.set(ylabel="angle − Eq. 1 (K = 0.3706, d = 0.33) [rad]",
           title=f"difference from Eq. 1 (max |GDFE − Eq. 1| = {max(abs(h['error']) for h in result['hinges']):.4f} rad)")
    ax.legend(fontsize=8, ncol=2)
    if result["specimen_L26"]:
        ax = fig.add_subplot(gs[1, 2])
        for iso, mk in ((1.0, "o-"), (0.0, "s--")):
            rows = [s for s in result["specimen_L26"] if s["isotropy"] == iso and s["nz"] == 1]
            ax.plot([s["width"] for s in rows], [s["alpha"] for s in rows], mk,
                    label="isotropic shrink" if iso else "uniaxial shrink")
            nz2 = [s for s in result["specimen_L26"] if s["isotropy"] == iso and s["nz"] == 2]
            for s in nz2:
                ax.plot([s["width"]], [s["alpha"]], "x", color="C0" if iso else "C1", ms=9,
                        label=f"nz = 2, {'isotropic' if iso else 'uniaxial'}")
        ax.axhline(result["hinges"][2]["alpha_eq1"], color="k", ls=":", label="Eq. 1")
        ax.set_xticks(WIDTHS)
        ax.set(xlabel="strip width [mm]", ylabel="fold angle [rad]", title="L = 2.6 mm: specimen dependence")
        ax.legend(fontsize=7)
    save_figure(fig, out, NAME)


main = main_of(__name__)


if __name__ == "__main__":
    raise SystemExit(main())
