"""Figure 7: reconstructions of two crease-fold test cases of Deng and Chen.

(a)-(b) *Rolled tube.* A strip with eight hinges across it, each designed by Eq. 2 to
fold by 2 pi / 8 (hinge width ``L = (pi/4) h / (1 - R)``), rigid panels of 2.5 mm
between them and half panels at the ends, so that the folded strip closes into an
octagonal tube 2 mm long (the strip's width). It is simulated with uniaxial shrink
(the film shrinks along the strip only) and with in-plane isotropic shrink, the
paper's generalisation to 2-D; for isotropic shrink with one cell across the width, with
square cells, and (``default``/``fine``) with cells elongated across the strip.
Measured: the total turn of the strip (2 pi closes it), the turn of each hinge and the
gap between the strip's ends.

(c)-(d) *A crease-pattern figure in the spirit of the paper's crane.* The paper's crane
pattern is not published, and a folded origami crane needs layered, collapsing folds that
a one-sided hinge cannot make. Designed here instead, and assumed to stand for it: a
cross-shaped flat blank (5 mm square body; neck and tail 1.5 mm wide reaching 11 mm
from the centre along +x and -x; wings 4 mm wide reaching 8 mm along +y and -y) with
five hinges across the arms: the neck and the tail fold up from the body (1.2 and 0.9
rad), the head folds down at 5.5 mm along the neck (1.8 rad), and the two wings fold up
(0.5 rad). Hinge widths come from Eq. 2 rounded to whole pixels; the angle the rounded
width folds by (Eq. 2) is the design angle each simulated fold is compared with.

Both use h = 0.29 mm and R = 0.6947 (Eq. 3, d = 0.33 mm), one cell through the film.

Run ``python -m studies.fig07_crease_fold [--out DIR] [--resolution R] [--json]`` or
``gdfe study fig07``; writes ``fig07.png`` and ``fig07.json``.
"""

from __future__ import annotations

import math

import numpy as np

from gdfe import paper
from studies._common import check_resolution, finish, headline, n_jobs, main_of, pyplot

NAME = "fig07"
H = paper.H
D = paper.FIG6_D
N_HINGES = 8
PANEL = 2.5
TUBE_WIDTH = 2.0
# isotropic tube meshes: (cells across a hinge, cells across the 2 mm width); (2, 5) and (4, 11) have
# square cells, (4, 4) and (4, 2) cells 2.7 and 5.4 times longer across the strip than along it
TUBE = {"coarse": {"div": 4, "iso": ((4, 1), (2, 5))}, "default": {"div": 4, "iso": ((4, 1), (2, 5), (4, 4))},
        "fine": {"div": 4, "iso": ((4, 1), (2, 5), (4, 11), (4, 4), (4, 2))}}
CRANE_PIXEL = {"coarse": 0.5, "default": 0.25, "fine": 0.25}
# crane hinges: name, panels (a, b), direction from a to b, design angle [rad] (> 0 folds up, towards +z)
CRANE_FOLDS = (("neck", "body", "neck", (1, 0), 1.2), ("head", "neck", "head", (1, 0), -1.8),
               ("tail", "body", "tail", (-1, 0), 0.9), ("wing_left", "body", "wing_left", (0, 1), 0.5),
               ("wing_right", "body", "wing_right", (0, -1), 0.5))


# -- rolled tube -----------------------------------------------------------------------------

def tube_design(R, div=4, ny=1, isotropy=1.0):
    """The strip of the rolled tube: half panel, (hinge, panel) x 7, hinge, half panel."""
    import gdfe

    L_h = (2 * math.pi / N_HINGES) * H / (1 - R)
    dx = L_h / div
    npan = int(round(PANEL / dx))
    half = npan // 2
    cols = [0] * half
    for k in range(N_HINGES):
        cols += [int(gdfe.Material.CONTRACT_TOP)] * div + [0] * (npan if k < N_HINGES - 1 else half)
    mat = np.repeat(np.array(cols)[:, None], ny, axis=1)
    return gdfe.grid_design(mat, R, h=H, pixel=(dx, TUBE_WIDTH / ny), nz=1, isotropy=isotropy,
                            meta={"kind": "tube", "hinge_mm": L_h, "panel_mm": npan * dx})


def _tube(case):
    import gdfe
    from gdfe import inverse as inv

    des = tube_design(case["R"], case["div"], case["ny"], case["isotropy"])
    res = inv.simulate_strip(des, max_iter=3000)
    _, uv, _ = inv.strip_midline(res)
    prof = gdfe.curvature_profile(res)
    turn = prof["turn"]
    # turn of each hinge: the turn between the middles of the panels on either side of it
    dth = prof["kappa"] * np.linalg.norm(np.diff(uv[1:-1], axis=0), axis=1)
    pitch = des.meta["panel_mm"] + des.meta["hinge_mm"]
    start = 0.5 * des.meta["panel_mm"]  # first hinge begins after the half panel
    k = np.clip(np.floor((prof["s"] - start + 0.5 * des.meta["panel_mm"]) / pitch), 0, N_HINGES - 1).astype(int)
    hinge_turns = np.bincount(k, dth, N_HINGES)
    return {**case, "turn_rad": float(turn), "closure_gap_mm": float(np.linalg.norm(uv[-1] - uv[0])),
            "hinge_turns_rad": hinge_turns.tolist(),
            "hinge_mm": des.meta["hinge_mm"], "converged": bool(res.converged), "iterations": int(res.iterations),
            "seconds": float(res.seconds), "n_cells": int(des.n_cells), "_points": res.points, "_design": des}


# -- crane -----------------------------------------------------------------------------------

def crane_design(R, pixel):
    """The cross-shaped crane blank with its five hinges; regions name its panels and hinges."""
    import gdfe

    nx = int(round(22.0 / pixel))
    ny = int(round(16.0 / pixel))
    x = (np.arange(nx) + 0.5) * pixel - 11.0
    y = (np.arange(ny) + 0.5) * pixel - 8.0
    X, Y = np.meshgrid(x, y, indexing="ij")
    body = (np.abs(X) <= 2.5) & (np.abs(Y) <= 2.5)
    neck_arm = (X > 2.5) & (np.abs(Y) <= 0.75)
    tail_arm = (X < -2.5) & (np.abs(Y) <= 0.75)
    wing_l = (Y > 2.5) & (np.abs(X) <= 2.0)
    wing_r = (Y < -2.5) & (np.abs(X) <= 2.0)
    film = body | neck_arm | tail_arm | wing_l | wing_r
    mat = np.zeros((nx, ny), int)
    design_angle = {}
    hinges = {}

    def width(alpha):
        n = max(1, int(round(abs(alpha) * H / (1 - R) / pixel)))
        return n, math.copysign(n * pixel * (1 - R) / H, alpha)

    n, design_angle["neck"] = width(1.2)
    hinges["neck"] = neck_arm & (X < 2.5 + n * pixel)
    n, design_angle["head"] = width(-1.8)
    hinges["head"] = neck_arm & (X > 8.0) & (X < 8.0 + n * pixel)
    n, design_angle["tail"] = width(0.9)
    hinges["tail"] = tail_arm & (X > -2.5 - n * pixel)
    n, a = width(0.5)
    design_angle["wing_left"] = design_angle["wing_right"] = a
    hinges["wing_left"] = wing_l & (Y < 2.5 + n * pixel)
    hinges["wing_right"] = wing_r & (Y > -2.5 - n * pixel)
    for k, m in hinges.items():
        mat[m] = int(gdfe.Material.CONTRACT_TOP if design_angle[k] > 0 else gdfe.Material.CONTRACT_BOTTOM)
    any_hinge = np.any(list(hinges.values()), axis=0)
    regions = {"body": body, "neck": neck_arm & ~any_hinge & (X < 8.0), "head": neck_arm & ~any_hinge & (X > 8.0),
               "tail": tail_arm & ~any_hinge, "wing_left": wing_l & ~any_hinge, "wing_right": wing_r & ~any_hinge}
    regions.update({f"hinge_{k}": m for k, m in hinges.items()})
    des = gdfe.grid_design(mat, R, h=H, pixel=pixel, nz=1, isotropy=1.0, film=film, regions2d=regions,
                           meta={"kind": "crane", "pixel_mm": pixel})
    return des, design_angle


def panel_angle(points, design, a, b, direction):
    """Signed fold angle [rad] from panel ``a`` to panel ``b`` (> 0: ``b`` folds up, towards +z).

    ``direction`` is the in-plane direction from ``a`` to ``b`` in the flat print; the fold
    axis is ``direction x z``. The rotation of each panel is its best rigid fit (Kabsch).
    """
    from gdfe.measure import rigid_align

    def rot(name):
        vid = np.unique(design.mesh.cells[design.region_cells(name)])
        return rigid_align(design.mesh.points[vid], points[vid])[0]

    Qa, Qb = rot(a), rot(b)
    rel = Qa.T @ Qb
    c = np.clip((np.trace(rel) - 1) / 2, -1, 1)
    th = math.acos(c)
    v = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
    axis = np.cross(np.r_[direction, 0.0], [0.0, 0.0, 1.0])
    return float(th * np.sign(v @ axis)) if np.linalg.norm(v) > 1e-12 else 0.0


def _crane(case):
    import gdfe

    des, design_angle = crane_design(case["R"], case["pixel"])
    res = gdfe.simulate(des, max_iter=400)
    folds = []
    for name, a, b, direction, target in CRANE_FOLDS:
        ang = panel_angle(res.points, des, a, b, direction)
        folds.append({"fold": name, "asked_rad": target, "design_rad": design_angle[name], "gdfe_rad": ang,
                      "error_rad": ang - design_angle[name]})
    return {"folds": folds, "converged": bool(res.converged), "iterations": int(res.iterations),
            "residual": float(res.residual), "seconds": float(res.seconds), "n_cells": int(des.n_cells),
            "_points": res.points, "_design": des}


def run(resolution="default", out=None):
    """Simulate the rolled tube (several specimens) and the crane; measure turns and fold angles."""
    import gdfe
    from gdfe.parallel import parallel_map

    check_resolution(resolution)
    R = float(gdfe.Calibration().ratio(D))
    t = TUBE[resolution]
    cases = [{"kind": "tube", "R": R, "div": t["div"], "ny": 1, "isotropy": 0.0}]
    cases += [{"kind": "tube", "R": R, "div": div, "ny": ny, "isotropy": 1.0} for div, ny in t["iso"]]
    cases.append({"kind": "crane", "R": R, "pixel": CRANE_PIXEL[resolution]})

    done = parallel_map(_work, cases, n_jobs=n_jobs(resolution), desc="fig07 tube and crane")
    tubes = [d for d in done if d.get("kind") == "tube"]
    for d in tubes:
        dx = d["hinge_mm"] / d["div"]
        d["cell_aspect"] = (TUBE_WIDTH / d["ny"]) / dx  # cell size across the strip / along it
    crane = next(d for d in done if d.get("kind") == "crane")
    uni = tubes[0]
    iso1 = next(d for d in tubes if d["isotropy"] == 1.0 and d["ny"] == 1)
    square = [d for d in tubes if d["isotropy"] == 1.0 and d["ny"] > 1 and d["cell_aspect"] < 1.5]
    long_cells = [d for d in tubes if d["isotropy"] == 1.0 and d["ny"] > 1 and d["cell_aspect"] >= 1.5]
    crane_err = max(abs(f["error_rad"]) for f in crane["folds"])
    hl = [
        headline("tube, uniaxial shrink: total turn", uni["turn_rad"], 2 * math.pi, 0.1, "abs", unit="rad",
                 paper_text="the rolled tube closes (photo)"),
        headline("tube, uniaxial shrink: gap between the ends", uni["closure_gap_mm"], None, 0.5, "le", unit="mm"),
        headline("tube, isotropic shrink, one cell across: total turn", iso1["turn_rad"], 2 * math.pi, 0.1, "abs",
                 unit="rad"),
        headline("crane: largest |GDFE - design| fold angle", crane_err, None, 0.25, "le", unit="rad",
                 paper_text="the crane reconstruction matches the photo"),
    ]
    for d in square:
        hl.append(headline(f"tube, isotropic shrink, square cells ({d['ny']} across): total turn", d["turn_rad"],
                           2 * math.pi, 0.1, "abs", unit="rad", expect=False,
                           note="each hinge folds 4-6 % less than Eq. 2: the free face also shrinks along the "
                                "hinge line"))
    for d in long_cells:
        hl.append(headline(f"tube, isotropic shrink, cells {d['cell_aspect']:.1f}x longer across: total turn",
                           d["turn_rad"], 2 * math.pi, 0.1, "abs", unit="rad", expect=False,
                           note="mesh artefact: elongated cells across the strip fold much less"))
    converged = all(d["converged"] for d in done)
    summary = {
        "paper": "a rolled tube and a crane reconstructed; 'the simulated shapes match well with the physical test "
                 "cases' (photos, no numbers)",
        "ours": (f"tube: total turn {uni['turn_rad']:.3f} rad (2 pi = 6.283), gap {uni['closure_gap_mm']:.2f} mm "
                 f"with uniaxial shrink; isotropic shrink "
                 + ", ".join(f"{d['turn_rad']:.2f} rad ({d['ny']} cells across, aspect {d['cell_aspect']:.1f})"
                             for d in tubes if d["isotropy"] == 1.0)
                 + f"; crane folds within {crane_err:.3f} rad of their Eq. 2 design ("
                 + ", ".join(f"{f['fold']} {f['gdfe_rad']:.2f}/{f['design_rad']:.2f}" for f in crane["folds"]) + ")"),
        "verdict": ("reproduced for the crane-like figure and for the tube with uniaxial shrink; with the paper's "
                    "in-plane isotropic shrink and square cells the tube turns "
                    + ", ".join(f"{d['turn_rad'] / (2 * math.pi):.0%}" for d in square) + " of a full turn"),
        "discrepancy": (
            "With isotropic shrink the free face of each hinge also shrinks along the hinge line (across the "
            "strip), which the panels on either side resist: with square cells each hinge folds "
            + ", ".join(f"{np.mean(d['hinge_turns_rad']):.3f}" for d in square)
            + f" rad instead of {np.mean(uni['hinge_turns_rad']):.3f} (uniaxial), so the tube stays open by "
            + ", ".join(f"{d['closure_gap_mm']:.2f}" for d in square) + " mm (compare fig06's width dependence). "
            + ("The result also depends on the cells' shape, which it should not: cells longer across the strip than "
               "along it fold much less (" + ", ".join(f"{d['turn_rad']:.2f} rad at aspect {d['cell_aspect']:.1f}"
                                                          for d in long_cells)
               + "); one cell across the width cannot curl across it and folds like uniaxial shrink. "
               if long_cells else "")
            + "Whether the paper's tube used a one-cell-wide mesh or a uniaxially shrinking film is not stated: "
            "open question. The crane is our own design (pattern not published); its folds differ from their "
            f"Eq. 2 design angles by up to {crane_err:.2f} rad (hinges a few pixels wide, isotropic shrink along "
            "the hinge lines)."),
    }
    result = {"study": NAME, "figure": "Fig. 7", "title": "crease-fold reconstructions: rolled tube and crane",
              "resolution": resolution, "R": R, "h_mm": H,
              "tube": {"hinges": N_HINGES, "panel_mm": PANEL, "width_mm": TUBE_WIDTH,
                       "hinge_mm": uni["hinge_mm"],
                       "cases": [{k: v for k, v in d.items() if not k.startswith("_")} for d in tubes]},
              "crane": {"pixel_mm": CRANE_PIXEL[resolution],
                        **{k: v for k, v in crane.items() if not k.startswith("_")}},
              "headlines": hl, "converged": converged, "summary": summary,
              "_shapes": {"tube_uniaxial": (uni["_points"], uni["_design"]),
                          "tube_isotropic": [(d["ny"], d["_points"], d["_design"]) for d in tubes
                                             if d["isotropy"] == 1.0],
                          "crane": (crane["_points"], crane["_design"])}}
    return finish(result, out, plot)


def _work(case):
    return {"kind": case["kind"], **(_tube(case) if case["kind"] == "tube" else _crane(case))}


def plot(result, out):
    from gdfe import inverse as inv
    from studies._draw import COLOURS, save_figure, surface

    plt = pyplot()
    sh = result["_shapes"]
    fig = plt.figure(figsize=(13, 8.5))
    ax = fig.add_subplot(2, 3, 1, projection="3d")
    pts, des = sh["tube_uniaxial"]
    surface(ax, pts, des, elev=15, azim=-80)
    u = next(c for c in result["tube"]["cases"] if c["isotropy"] == 0.0)
    ax.set_title(f"(b) rolled tube, uniaxial shrink\nturn {u['turn_rad']:.3f} rad, gap {u['closure_gap_mm']:.2f} mm",
                 fontsize=9)
    ax = fig.add_subplot(2, 3, 2)
    for k, (ny, p, d) in enumerate(sh["tube_isotropic"]):
        _, uv, _ = inv.strip_midline(p, d)
        c = next(c for c in result["tube"]["cases"] if c["isotropy"] == 1.0 and c["ny"] == ny)
        ax.plot(uv[:, 0], uv[:, 1], "-", lw=1.3,
                label=f"isotropic, {ny} across (aspect {c['cell_aspect']:.1f}): {c['turn_rad']:.2f} rad")
    _, uvu, _ = inv.strip_midline(*sh["tube_uniaxial"])
    ax.plot(uvu[:, 0], uvu[:, 1], "k--", lw=1, label=f"uniaxial: {u['turn_rad']:.2f} rad")
    ax.set_aspect("equal")
    ax.set(xlabel="x [mm]", ylabel="z [mm]", title="tube mid-lines (side view)")
    ax.legend(fontsize=7)
    ax = fig.add_subplot(2, 3, 3)
    cr = result["crane"]
    names = [f["fold"] for f in cr["folds"]]
    xs = np.arange(len(names))
    ax.bar(xs - 0.2, [f["design_rad"] for f in cr["folds"]], 0.4, label="design (Eq. 2, whole pixels)")
    ax.bar(xs + 0.2, [f["gdfe_rad"] for f in cr["folds"]], 0.4, label="GDFE")
    ax.axhline(0, color="k", lw=0.7)
    ax.set_xticks(xs, names, rotation=20, fontsize=8)
    ax.set(ylabel="fold angle [rad] (> 0 up)", title="crane folds")
    ax.legend(fontsize=8)
    pts, des = sh["crane"]
    ax = fig.add_subplot(2, 3, 4)
    nx = int(des.mesh.cell_ij[:, 0].max()) + 1
    ny = int(des.mesh.cell_ij[:, 1].max()) + 1
    img = np.ones((ny, nx, 3))
    ij = des.mesh.cell_ij
    img[ij[:, 1], ij[:, 0]] = np.array(COLOURS)[des.material]
    p = cr["pixel_mm"]
    ax.imshow(img, origin="lower", extent=(-11, -11 + nx * p, -8, -8 + ny * p))
    ax.set(title="(c) crane blank: grey rigid, orange hinge up, blue hinge down", xlabel="x [mm]", ylabel="y [mm]")
    ax.title.set_fontsize(9)
    for k, (elev, azim) in enumerate(((25, -60), (5, -90))):
        ax = fig.add_subplot(2, 3, 5 + k, projection="3d")
        surface(ax, pts, des, elev=elev, azim=azim, edges=False)
        ax.set_title(f"(d) crane folded by GDFE (view {k + 1})", fontsize=9)
    save_figure(fig, out, NAME)


main = main_of(__name__)


if __name__ == "__main__":
    raise SystemExit(main())
