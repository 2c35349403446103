"""Figure 8: freeform surfaces from two 2-D passive patterns given as PNG masks.

The paper shows two freeform surfaces obtained from 2-D passive patterns; the patterns
are not published. Three are designed here, each as a pair of PNG masks of the passive
material on the top and on the bottom face (dark = passive), written to the output
directory and read back with :func:`gdfe.from_masks`. The plate is 8 mm square (the dome
a disc of 8 mm diameter), h = 0.29 mm, R = 0.6947 (Eq. 3, d = 0.33 mm), one cell per
printer pixel, one cell through the film, in-plane isotropic shrink. The patterns are
drawn in millimetres, so every resolution prints the same design (coarse: 0.5 mm pixels,
default 0.25, fine 0.125); each leaves a quarter of a face free (f = 1/4):

- *twist*: free stripes at +45 degrees on the top face and at -45 degrees on the bottom,
  1 mm wide along x every 4 mm (at coarse resolution two pixels: one-pixel diagonal
  stripes would be isolated pixels touching at corners, which contract like isotropic
  patches and do not twist);
- *dome*: free concentric rings 0.5 mm wide every 2 mm on the top face, the first 1 mm
  from the centre, bottom fully coated;
- *saddle*: free lines 0.5 mm wide every 2 mm, along y on the top face and along x on the
  bottom.

A stripe pattern bends the plate across its stripes; the homogenised estimate of the
curvature is ``f (1 - R) / h``. The shape is measured at the centre: a quadratic fit of
the deformed mid-surface against the flat coordinates within ``RHO`` of the centre
gives the second fundamental form, hence the curvatures ``k_xx``, ``k_xy``, ``k_yy``
along the print's axes (positive: towards the top face), the Gaussian curvature and the
mean curvature.

Run ``python -m studies.fig08_freeform [--out DIR] [--resolution R] [--json]`` or
``gdfe study fig08``; writes ``fig08.png``, ``fig08.json`` and the masks
``fig08_<pattern>_{top,bottom}.png``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from gdfe import paper
from gdfe._validation import GdfeError
from studies._common import check_resolution, finish, headline, n_jobs, main_of, pyplot

NAME = "fig08"
H = paper.H
D = paper.FIG6_D
SIZE = 8.0
PIXEL = {"coarse": 0.5, "default": 0.25, "fine": 0.125}
PERIOD = 2.0  # mm, period of the stripes and rings
FREE = 0.5  # mm, free width in each period: free fraction f = 1/4
RHO = 2.0  # mm, radius of the central patch the curvature is fitted on
PATTERNS = ("twist", "dome", "saddle")


def masks(pattern, n, pixel):
    """Top, bottom (passive = True) and film masks, (n, n) bool arrays indexed [i (x), j (y)].

    The patterns are defined in millimetres on the pixel centres, so every resolution
    prints the same design: stripes free over ``FREE`` of every ``PERIOD`` mm (f = 1/4).
    """
    x = (np.arange(n) + 0.5) * pixel
    X, Y = np.meshgrid(x, x, indexing="ij")
    full = np.ones((n, n), bool)
    film = full
    if pattern == "twist":
        # measured along x, the diagonal stripes repeat every 2 PERIOD and are 2 FREE wide (f = 1/4);
        # narrower diagonal stripes would be pixels touching only at corners
        top = np.mod(X - Y, 2 * PERIOD) >= 2 * FREE  # free along +45 degrees
        bottom = np.mod(X + Y, 2 * PERIOD) >= 2 * FREE  # free along -45 degrees
    elif pattern == "dome":
        r = np.hypot(X - SIZE / 2, Y - SIZE / 2)
        film = r <= SIZE / 2
        top = np.mod(r - PERIOD / 2, PERIOD) >= FREE  # free rings starting 1 mm from the centre
        bottom = full
    elif pattern == "saddle":
        top = np.mod(X, PERIOD) >= FREE  # free lines along y: bend about y, towards +z
        bottom = np.mod(Y, PERIOD) >= FREE  # free lines along x: bend about x, towards -z
    else:
        raise GdfeError(f"pattern: expected one of {', '.join(PATTERNS)}, got {pattern!r}")
    return top, bottom, film


def write_mask(path, mask):
    """Save a (nx, ny) mask as a PNG: dark where True, row 0 at the largest y (as gdfe.from_masks reads)."""
    from PIL import Image

    img = np.where(np.asarray(mask, bool).T[::-1], 0, 255).astype(np.uint8)
    Image.fromarray(img, mode="L").save(path)
    return Path(path)


def midsurface(points, design):
    """Flat (x, y) and deformed mid-surface point of every in-plane vertex of a one-layer film."""
    flat = design.mesh.points
    key = np.round(flat[:, :2] / design.mesh.spacing[:2]).astype(np.int64)
    order = np.lexsort((flat[:, 2], key[:, 1], key[:, 0]))
    k = key[order]
    start = np.r_[0, np.nonzero(np.any(np.diff(k, axis=0) != 0, axis=1))[0] + 1, len(k)]
    XY = np.array([flat[order[a], :2] for a in start[:-1]])
    M = np.array([points[order[a:b]].mean(axis=0) for a, b in zip(start[:-1], start[1:])])
    return XY, M


def curvatures(XY, M, centre, rho):
    """Second fundamental form at ``centre`` from a quadratic fit of M(X, Y) on the patch |XY - centre| < rho."""
    d = XY - centre
    sel = np.hypot(d[:, 0], d[:, 1]) <= rho
    x, y = d[sel, 0], d[sel, 1]
    A = np.column_stack([np.ones_like(x), x, y, 0.5 * x * x, x * y, 0.5 * y * y])
    coef, *_ = np.linalg.lstsq(A, M[sel], rcond=None)
    pX, pY, pXX, pXY, pYY = coef[1], coef[2], coef[3], coef[4], coef[5]
    n = np.cross(pX, pY)
    n /= np.linalg.norm(n)
    E, F, G = pX @ pX, pX @ pY, pY @ pY
    e, f, g = n @ pXX, n @ pXY, n @ pYY
    det = E * G - F * F
    K = (e * g - f * f) / det
    Hm = (e * G - 2 * f * F + g * E) / (2 * det)
    return {"k_xx": float(e / E), "k_xy": float(f / np.sqrt(E * G)), "k_yy": float(g / G),
            "gaussian": float(K), "mean": float(Hm), "n_points": int(sel.sum())}


def _simulate(case):
    import gdfe

    des = gdfe.from_masks(case["top"], case["bottom"], case["pixel"], case["R"], h=H, nz=1, film=case["film"])
    # from the flat print (seeded perturbation): the linearised start costs the dome 20 times more iterations
    res = gdfe.simulate(des, init="flat", max_iter=400)
    XY, M = midsurface(res.points, des)
    centre = np.array([SIZE / 2, SIZE / 2])
    kap = curvatures(XY, M, centre, RHO)
    counts = {m.name.lower(): int((des.material == m).sum()) for m in gdfe.Material}
    return {"pattern": case["pattern"], **kap, "converged": bool(res.converged), "iterations": int(res.iterations),
            "residual": float(res.residual), "seconds": float(res.seconds), "n_cells": int(des.n_cells),
            "cells_by_material": counts, "_points": res.points, "_design": des}


def run(resolution="default", out=None):
    """Write the masks, simulate the three patterns, measure their curvature at the centre."""
    import gdfe
    from gdfe.parallel import parallel_map

    check_resolution(resolution)
    R = float(gdfe.Calibration().ratio(D))
    pixel = PIXEL[resolution]
    n = int(round(SIZE / pixel))
    tmp = None
    if out is None:
        tmp = tempfile.TemporaryDirectory()
        mdir = Path(tmp.name)
    else:
        mdir = Path(out)
        mdir.mkdir(parents=True, exist_ok=True)
    cases = []
    for p in PATTERNS:
        top, bottom, film = masks(p, n, pixel)
        paths = {k: write_mask(mdir / f"{NAME}_{p}_{k}.png", m) for k, m in (("top", top), ("bottom", bottom))}
        fpath = write_mask(mdir / f"{NAME}_{p}_film.png", film) if not film.all() else None
        cases.append({"pattern": p, "top": str(paths["top"]), "bottom": str(paths["bottom"]),
                      "film": None if fpath is None else str(fpath), "pixel": pixel, "R": R})
    try:
        done = parallel_map(_simulate, cases, n_jobs=n_jobs(resolution), desc="fig08 surfaces")
    finally:
        if tmp is not None:
            tmp.cleanup()
    by = {d["pattern"]: d for d in done}
    k0 = 0.25 * (1 - R) / H  # homogenised curvature of a stripe pattern with f = 1/4
    tw, dome, sad = by["twist"], by["dome"], by["saddle"]
    hl = [
        headline("dome: Gaussian curvature at the centre (> 0)", dome["gaussian"], None, 0.0, "ge", unit="1/mm^2",
                 paper_text="a curved freeform surface (photo)"),
        headline("saddle: Gaussian curvature at the centre (< 0)", -sad["gaussian"], None, 0.0, "ge", unit="1/mm^2",
                 note="sign flipped: -K >= 0"),
        headline("twist: k_xy / estimate -f(1-R)/h", tw["k_xy"] / -k0, None, 0.3, "ge",
                 note="twist of the sign the stripes set; its size relative to the homogenised estimate"),
        headline("dome: mean curvature / estimate f(1-R)/h", dome["mean"] / k0, None, 0.2, "ge",
                 note="a doubly curved shape must stretch the film: the 8 mm disc stays much flatter"),
        headline("saddle: k_xx / estimate f(1-R)/h", sad["k_xx"] / k0, None, 0.1, "ge",
                 note="frustrated like the dome"),
    ]
    converged = all(d["converged"] for d in done)
    summary = {
        "paper": "two freeform surfaces from 2-D passive patterns, compared with photographs (no numbers)",
        "ours": (f"twist k_xy = {tw['k_xy']:.3f} /mm; dome K = {dome['gaussian']:.4f} /mm^2 "
                 f"(H = {dome['mean']:.3f} /mm); saddle K = {sad['gaussian']:.4f} /mm^2 "
                 f"(k_xx = {sad['k_xx']:.3f}, k_yy = {sad['k_yy']:.3f} /mm); estimate f(1-R)/h = {k0:.3f} /mm"),
        "verdict": "reproduced qualitatively (twist, dome and saddle from mask pairs; the paper's patterns are not published)",
        "discrepancy": (
            "No numbers to compare: the paper's patterns and shapes are only shown as pictures. Relative to the "
            f"homogenised estimate f(1-R)/h the twist reaches {tw['k_xy'] / -k0:.2f}, the dome {dome['mean'] / k0:.2f} "
            f"and the saddle {sad['k_xx'] / k0:.2f}: a doubly curved shape has to stretch the film, and an 8 mm "
            "plate 0.29 mm thick stays flatter than its patterns ask (the same minima are found from the flat "
            "print and from the linearised start)."),
    }
    result = {"study": NAME, "figure": "Fig. 8", "title": "freeform surfaces from PNG masks",
              "resolution": resolution, "R": R, "h_mm": H, "pixel_mm": pixel, "size_mm": SIZE,
              "free_fraction": FREE / PERIOD, "period_mm": PERIOD, "estimate_curvature": k0, "rho_mm": RHO,
              "masks": {c["pattern"]: {k: (Path(c[k]).name if c[k] else None) for k in ("top", "bottom", "film")}
                        for c in cases} if out is not None else None,
              "headlines": hl, "converged": converged, "summary": summary,
              "surfaces": [{k: v for k, v in d.items() if not k.startswith("_")} for d in done],
              "_shapes": {d["pattern"]: (d["_points"], d["_design"]) for d in done}}
    return finish(result, out, plot)


def plot(result, out):
    from studies._draw import COLOURS, save_figure, surface

    plt = pyplot()
    fig = plt.figure(figsize=(13, 8.5))
    n = len(PATTERNS)
    for k, p in enumerate(PATTERNS):
        pts, des = result["_shapes"][p]
        ax = fig.add_subplot(2, n, k + 1)
        nx = int(des.mesh.cell_ij[:, 0].max()) + 1
        ny = int(des.mesh.cell_ij[:, 1].max()) + 1
        img = np.ones((ny, nx, 3))
        top = des.mesh.cell_k == 0
        ij = des.mesh.cell_ij[top]
        img[ij[:, 1], ij[:, 0]] = np.array(COLOURS)[des.material[top]]
        ax.imshow(img, origin="lower", extent=(0, nx * result["pixel_mm"], 0, ny * result["pixel_mm"]))
        ax.set(title=f"{p}: pattern (orange: top free, blue: bottom free,\ngreen: both free, grey: both coated)",
               xlabel="x [mm]", ylabel="y [mm]")
        ax.title.set_fontsize(8)
        ax3 = fig.add_subplot(2, n, n + k + 1, projection="3d")
        surface(ax3, pts, des, edges=False)
        s = next(d for d in result["surfaces"] if d["pattern"] == p)
        ax3.set_title(f"{p}: K = {s['gaussian']:.3f} /mm², k_xy = {s['k_xy']:.3f} /mm\n"
                      f"k_xx = {s['k_xx']:.3f}, k_yy = {s['k_yy']:.3f} /mm", fontsize=8)
    title = (f"Fig. 8: freeform surfaces from mask pairs (R = {result['R']:.4f}, pixel {result['pixel_mm']} mm; "
             f"homogenised estimate f(1-R)/h = {result['estimate_curvature']:.3f} /mm)")
    save_figure(fig, out, NAME, title=title)


main = main_of(__name__)


if __name__ == "__main__":
    raise SystemExit(main())
