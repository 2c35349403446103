"""GDFE against the reference FEM on freeform parts: curl shapes, where they differ, and time.

For each part (the Figure 8 plates: twist, dome, saddle; the Figure 7 rolled tube; the box of
the contact study) one design is simulated by GDFE (R from the paper's Eq. 3 at the part's coat
thickness, d = 0.33 mm) and by the plate FEM (:func:`reference_fem.plate_mesh`: film and coats
meshed from the same design, the Table-1 calibration of the FEM, geometrically nonlinear,
free-floating). Their film mid-surfaces are compared at the vertices of the design's cells, the
points both models have:

- after rigid alignment (Kabsch), the RMS and largest distance and the Hausdorff distance
  between the two point sets, relative to the part's size (its diagonal);
- a deviation map: the distance at every vertex (PNG, and a VTU of GDFE's film with the field
  ``deviation_mm``), and its mean over the cells of each material (where the coat is);
- GDFE with R fitted to the FEM's shape (the RMS distance minimised over one R), beside Eq. 3's;
- where the FEM is refined (every part but the coarse run's), each model's own refinement
  sequence (FEM: 1, 2 elements per cell, and 3 on the Figure 8 plates at fine; GDFE: cells split 1,
  2, 4 times, and 8 at fine), the error of each level against that model's finest, and the time
  each needs at equal shape error.

- the masks a 2-D inverse design prints (:func:`gdfe.inverse2d.design_surface` for a dome and a
  saddle on a 6 mm film at 0.5 mm pixels, designed through GDFE, printed as halftoned masks):
  how far an elastic bilayer folds the printed masks from what GDFE promised, and from the
  target itself;
- the fold angles where the part has rigid panels joined by hinges (the tube, the box):
  :func:`gdfe.measure.panel_angles` on each model's mid-surface, the same function for both.

Resolutions: coarse, the twist and the saddle on 4 mm plates (0.5 mm pixels); default, all seven
parts at their printed size (Figure 8's 8 mm plates at 0.5 mm pixels); fine, the same parts with
each model refined one level further on the Figure 8 plates (the FEM at three elements per cell,
11 520 elements on the saddle, the size this machine solves in about ten minutes; GDFE's cells
split 8 times): the finest each model reaches here. Units: mm, rad, s.

Run ``python -m studies.compare_shapes [--resolution coarse|default|fine] [--out DIR]`` (or
``gdfe study compare-shapes``); writes ``compare_shapes.png``, ``compare_shapes.json`` and
``compare_shapes_<part>.vtu``.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from gdfe import paper
from studies._common import check_resolution, finish, headline, main_of, pyplot

log = logging.getLogger(__name__)

NAME = "compare_shapes"
H = paper.H
D = paper.FIG6_D

#: Per resolution: the parts, Figure 8's plates (cells along a side, pixel), the box's pixel, the FEM's
#: in-plane refinements per part (the last is compared with GDFE; two or more give its refinement
#: sequence), GDFE's cell splits (its refinement sequence) and the tolerance of the fit of R.
#: Parts whose rigid panels are joined by hinges: their fold angles are compared.
FOLD_PARTS = ("tube", "box")
#: The 2-D inverse designs whose printed masks are compared: film size, pixel [mm], L-BFGS-B iterations.
INVERSE = {"size": 6.0, "pixel": 0.5, "iterations": 20}
SETTINGS = {
    "coarse": {"parts": ("twist", "saddle"), "fig08_cells": 8, "fig08_pixel": 0.5, "box_pixel": 0.5,
               "fem_refine": {}, "gdfe_split": (1,), "fit_tol": 0.01},
    "default": {"parts": ("twist", "dome", "saddle", "tube", "box", "inverse_dome", "inverse_saddle"),
                "fig08_cells": 16, "fig08_pixel": 0.5, "box_pixel": 0.5,
                "fem_refine": {"twist": (1, 2), "dome": (1, 2), "saddle": (1, 2), "tube": (1, 2), "box": (1, 2),
                               "inverse_dome": (1, 2), "inverse_saddle": (1, 2)},
                "gdfe_split": (1, 2, 4), "fit_tol": 0.003, "inverse": INVERSE},
    "fine": {"parts": ("twist", "dome", "saddle", "tube", "box", "inverse_dome", "inverse_saddle"),
             "fig08_cells": 16, "fig08_pixel": 0.5, "box_pixel": 0.5,
             "fem_refine": {"twist": (1, 2, 3), "dome": (1, 2, 3), "saddle": (1, 2, 3), "tube": (1, 2), "box": (1, 2),
                            "inverse_dome": (1, 2), "inverse_saddle": (1, 2)},
             "gdfe_split": (1, 2, 4, 8), "fit_tol": 0.001, "inverse": INVERSE},
}


# -- parts: (material grid, film grid, pixel) at R from Eq. 3 -----------------------------------------------


def part_grid(name, cfg):
    """The part's material codes and film, (nx, ny) arrays, and its pixel [mm]."""
    import gdfe

    if name in ("twist", "dome", "saddle"):
        from studies.fig08_freeform import masks

        n, pixel = cfg["fig08_cells"], cfg["fig08_pixel"]
        top, bottom, film = masks(name, n, pixel)
        if n * pixel < 8.0 and name == "dome":  # the disc needs the whole plate
            film = np.ones_like(film)
        mat = np.where(top & bottom, gdfe.Material.RIGID,
                       np.where(bottom, gdfe.Material.CONTRACT_TOP,
                                np.where(top, gdfe.Material.CONTRACT_BOTTOM, gdfe.Material.FREE_SHRINK))).astype(int)
        return mat, film, pixel
    if name.startswith("inverse_"):
        return inverse_masks(name[len("inverse_"):], cfg["inverse"])[:3]
    R = eq3_ratio()
    if name == "tube":
        from studies.fig07_crease_fold import tube_design

        from studies.fig07_crease_fold import N_HINGES, TUBE_WIDTH

        dx = (2 * np.pi / N_HINGES) * H / (1 - R) / 2  # two cells across each hinge: square cells
        des = tube_design(R, div=2, ny=max(1, int(round(TUBE_WIDTH / dx))))
    elif name == "box":
        from studies.contact import box_design

        des = box_design(cfg["box_pixel"])
    else:
        raise ValueError(name)
    from reference_fem.plate import design_grid

    grid = design_grid(des, d=D)
    return grid.material.copy(), grid.film.copy(), tuple(grid.pixel)


_INVERSE_CACHE = {}


def inverse_masks(kind, inv):
    """The masks a 2-D inverse design prints for ``kind`` (``"dome"``, ``"saddle"``): material codes,
    film, pixel, and the design (its target and GDFE's fold of the printed masks)."""
    key = (kind, inv["size"], inv["pixel"], inv["iterations"])
    if key not in _INVERSE_CACHE:
        import gdfe
        from gdfe.inverse2d import design_surface, make_target

        dsg = design_surface(make_target(kind, inv["size"]), pixel=inv["pixel"], d=D, iterations=inv["iterations"])
        top, bottom = np.asarray(dsg.top, bool), np.asarray(dsg.bottom, bool)
        mat = np.where(top & bottom, gdfe.Material.RIGID,
                       np.where(bottom, gdfe.Material.CONTRACT_TOP,
                                np.where(top, gdfe.Material.CONTRACT_BOTTOM, gdfe.Material.FREE_SHRINK))).astype(int)
        _INVERSE_CACHE[key] = (mat, np.ones_like(top), inv["pixel"], dsg)
    return _INVERSE_CACHE[key]


def target_distance(dsg, shape):
    """RMS distance [mm] of a vertex shape (``{(i, j): point}``) from the inverse design's target
    surface after the best rigid motion (:func:`gdfe.inverse2d.distance.surface_distance`, the
    measure the design reports), on two triangles per cell of the grid."""
    from gdfe.inverse2d.distance import surface_distance

    keys = sorted(shape)
    index = {k: n for n, k in enumerate(keys)}
    tri = []
    for (i, j) in keys:
        c = [index.get(v) for v in ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1))]
        if None not in c:
            tri += [(c[0], c[1], c[2]), (c[0], c[2], c[3])]
    X = np.array([shape[k] for k in keys])
    flat = np.array(keys, float) * dsg.film.pixel - np.asarray(dsg.target.film_size, float) / 2  # film coordinates
    designed = dsg.target.point(flat, dsg.sigma)  # the alignment starts from the design's correspondence
    return float(surface_distance(X, np.array(tri), dsg.target_surface, designed=designed).rms_mm)


def panel_folds(mat, film, pixel, shape):
    """Fold angles [rad] between the rigid panels of a part, measured on a vertex shape (``{(i, j):
    point}``, the film's mid-surface) by :func:`gdfe.measure.panel_angles`: ``{(a, b): angle}``."""
    from gdfe.measure import panel_angles

    des = make_design(mat, film, pixel, eq3_ratio())
    P = des.mesh.points
    key = np.round((P[:, :2] - P[:, :2].min(axis=0)) / des.mesh.spacing[:2]).astype(int)
    pts = np.array([shape.get(tuple(k), (np.nan, np.nan, np.nan)) for k in key], float)
    if not np.all(np.isfinite(pts)):
        return {}
    return {tuple(r["panels"]): r["angle_rad"] for r in panel_angles(pts, des)}


def _fold_rows(g_folds, f_folds):
    """The two models' fold angles side by side, with their largest difference and means."""
    if not g_folds:
        return {}
    rows = [{"panels": list(k), "gdfe_rad": g_folds[k], "fem_rad": f_folds.get(k, float("nan"))} for k in sorted(g_folds)]
    return {"fold_angles": rows,
            "fold_angle_max_diff_rad": float(np.nanmax([abs(r["gdfe_rad"] - r["fem_rad"]) for r in rows])),
            "fold_angle_mean_gdfe_rad": float(np.mean([r["gdfe_rad"] for r in rows])),
            "fold_angle_mean_fem_rad": float(np.nanmean([r["fem_rad"] for r in rows]))}


def eq3_ratio():
    import gdfe

    return float(gdfe.Calibration().ratio(D))


def make_design(mat, film, pixel, R, split=1):
    """The part as a GDFE design with every cell split into ``split x split`` cells."""
    import gdfe

    ones = np.ones((split, split), int)
    m = np.kron(np.where(film, mat, 0), ones)
    f = np.kron(film.astype(int), ones).astype(bool)
    px = np.broadcast_to(np.asarray(pixel, float), (2,)) / split
    d = np.where(np.isin(m, (1, 2)), D, np.nan)
    return gdfe.grid_design(m, R, h=H, pixel=tuple(px), nz=1, film=f, d=d)


# -- shapes at the design's vertices -------------------------------------------------------------------------


def gdfe_vertices(result, design, split=1):
    """GDFE's mid-surface at the vertices of the unsplit grid: ``{(i, j): (3,) point}``."""
    P = design.mesh.points
    origin = P[:, :2].min(axis=0)
    key = np.round((P[:, :2] - origin) / design.mesh.spacing[:2]).astype(int)
    acc = {}
    for k, p in zip(map(tuple, key), result.points):
        if k[0] % split == 0 and k[1] % split == 0:
            acc.setdefault((k[0] // split, k[1] // split), []).append(p)
    return {k: np.mean(v, axis=0) for k, v in acc.items()}


def fem_vertices(result):
    import reference_fem as rf

    ij, _, x = rf.grid_vertices(result)
    return {tuple(k): p for k, p in zip(ij, x)}


def compare(a, b):
    """Distances between two vertex shapes (dicts keyed by vertex) after rigid alignment of b onto a."""
    import gdfe
    from scipy.spatial import cKDTree

    keys = sorted(set(a) & set(b))
    A = np.array([a[k] for k in keys])
    B = np.array([b[k] for k in keys])
    d = gdfe.shape_distance(A, B)
    dev = np.linalg.norm(d["aligned"] - A, axis=1)
    haus = max(cKDTree(A).query(d["aligned"])[0].max(), cKDTree(d["aligned"]).query(A)[0].max())
    return {"rms_mm": d["rms"], "max_mm": d["max"], "hausdorff_mm": float(haus), "keys": keys, "deviation": dev}


# -- one part ------------------------------------------------------------------------------------------------


def _gdfe(mat, film, pixel, R, split=1):
    import gdfe

    des = make_design(mat, film, pixel, R, split)
    t0 = time.perf_counter()
    res = gdfe.simulate(des, init="flat", max_iter=400)
    return res, des, time.perf_counter() - t0


def _fem(mat, film, pixel, refine):
    import reference_fem as rf

    des = make_design(mat, film, pixel, eq3_ratio())
    plate = rf.plate_mesh(des, d=D, refine=refine, layers_per_ply=2)
    return rf.solve_plate(plate, rf.BilayerMaterial())


def _fit_R(mat, film, pixel, fem_shape, tol):
    from scipy.optimize import minimize_scalar

    def rms(R):
        res, des, _ = _gdfe(mat, film, pixel, R)
        return compare(fem_shape, gdfe_vertices(res, des))["rms_mm"] if res.converged else np.inf

    opt = minimize_scalar(rms, bounds=(0.4, 0.99), method="bounded", options={"xatol": tol})
    return float(opt.x), float(opt.fun)


def _regions(mat, film, keys, dev):
    """Mean deviation over the cells of each material (a cell's: the mean of its four vertices)."""
    import gdfe

    at = dict(zip(keys, dev))
    sums = {}
    for i, j in np.argwhere(film):
        corners = [at.get(c) for c in ((i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1))]
        corners = [c for c in corners if c is not None]
        if corners:
            sums.setdefault(gdfe.Material(int(mat[i, j])).name.lower(), []).append(np.mean(corners))
    return {k: float(np.mean(v)) for k, v in sums.items()}


def _refinement(mat, film, pixel, cfg, fem_levels, gdfe_first):
    """Each model's levels: time and error against its own finest level (RMS after alignment)."""
    R = eq3_ratio()
    fem_rows = [{"refine": r, "seconds": res.seconds, "dofs": res.dofs, "converged": res.converged,
                 "_shape": fem_vertices(res)} for r, res in fem_levels]
    gd_rows = [gdfe_first]
    for s in cfg["gdfe_split"][1:]:
        res, des, sec = _gdfe(mat, film, pixel, R, s)
        gd_rows.append({"split": s, "seconds": sec, "n_cells": des.n_cells, "converged": bool(res.converged),
                        "_shape": gdfe_vertices(res, des, s)})
    for rows in (fem_rows, gd_rows):
        for r in rows:
            r["error_mm"] = compare(rows[-1]["_shape"], r["_shape"])["rms_mm"]
    return fem_rows, gd_rows


def _time_at(rows, tol):
    ok = [r["seconds"] for r in rows if r["error_mm"] <= tol]
    return min(ok) if ok else None


def run_part(name, cfg, out=None):
    mat, film, pixel = part_grid(name, cfg)
    R = eq3_ratio()
    g, gdes, g_sec = _gdfe(mat, film, pixel, R)
    refine = cfg["fem_refine"].get(name, (1,))
    fem_levels = [(r, _fem(mat, film, pixel, r)) for r in refine]
    fem = fem_levels[-1][1]
    fem_shape = fem_vertices(fem)
    cmp = compare(fem_shape, gdfe_vertices(g, gdes))
    size = fem.plate.size
    R_fit, rms_fit = _fit_R(mat, film, pixel, fem_shape, cfg["fit_tol"])
    row = {"part": name, "n_cells": int(film.sum()), "size_mm": size, "R_eq3": R, "R_fit": R_fit,
           "rms_mm": cmp["rms_mm"], "max_mm": cmp["max_mm"], "hausdorff_mm": cmp["hausdorff_mm"],
           "rms_rel": cmp["rms_mm"] / size, "max_rel": cmp["max_mm"] / size,
           "hausdorff_rel": cmp["hausdorff_mm"] / size, "rms_fit_mm": rms_fit, "rms_fit_rel": rms_fit / size,
           "gdfe_seconds": g_sec, "gdfe_converged": bool(g.converged), "gdfe_iterations": int(g.iterations),
           "fem_seconds": fem.seconds, "fem_converged": fem.converged, "fem_refine": fem_levels[-1][0],
           "fem_elements": fem.n_elements, "fem_dofs": fem.dofs, "fem_cost": fem.cost,
           "deviation_by_material_mm": _regions(mat, film, cmp["keys"], cmp["deviation"])}
    g_shape = gdfe_vertices(g, gdes)
    if name in FOLD_PARTS:
        row.update(_fold_rows(panel_folds(mat, film, pixel, g_shape), panel_folds(mat, film, pixel, fem_shape)))
    if name.startswith("inverse_"):
        dsg = inverse_masks(name[len("inverse_"):], cfg["inverse"])[3]
        row.update({"target": dsg.target.summary(), "gdfe_to_target_mm": target_distance(dsg, g_shape),
                    "fem_to_target_mm": target_distance(dsg, fem_shape),
                    "design_printable_rms_mm": float(dsg.printable_distance.rms_mm),
                    "design_tolerance_mm": float(dsg.tolerance_mm)})
    if len(refine) > 1:
        first = {"split": 1, "seconds": g_sec, "n_cells": gdes.n_cells, "converged": bool(g.converged),
                 "_shape": gdfe_vertices(g, gdes)}
        fem_rows, gd_rows = _refinement(mat, film, pixel, cfg, fem_levels, first)
        tol = max(fem_rows[0]["error_mm"], gd_rows[-2]["error_mm"])
        t_f, t_g = _time_at(fem_rows, tol), _time_at(gd_rows, tol)
        row.update({"fem_levels": [{k: v for k, v in r.items() if k != "_shape"} for r in fem_rows],
                    "gdfe_levels": [{k: v for k, v in r.items() if k != "_shape"} for r in gd_rows],
                    "equal_error_mm": tol, "fem_seconds_at_error": t_f, "gdfe_seconds_at_error": t_g,
                    "time_ratio_fem_over_gdfe": (t_f / t_g) if (t_f and t_g) else None})
    if out is not None:
        from gdfe.io import write_vtu

        at = dict(zip(cmp["keys"], cmp["deviation"]))
        P = gdes.mesh.points
        key = np.round((P[:, :2] - P[:, :2].min(axis=0)) / gdes.mesh.spacing[:2]).astype(int)
        field = np.array([at.get(tuple(k), np.nan) for k in key])
        write_vtu(out / f"{NAME}_{name}.vtu", g.points, gdes, {"deviation_mm": field})
        row["vtu"] = f"{NAME}_{name}.vtu"
    row["_map"] = (np.array(cmp["keys"]), cmp["deviation"], pixel)
    return row


def run(resolution="default", out=None):
    """Simulate every part with both models and compare their shapes."""
    from pathlib import Path

    check_resolution(resolution)
    cfg = SETTINGS[resolution]
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in cfg["parts"]:
        log.info("compare-shapes: %s", name)
        rows.append(run_part(name, cfg, out))
    converged = all(r["gdfe_converged"] and r["fem_converged"] for r in rows)
    worst = max(rows, key=lambda r: r["rms_rel"])
    ratios = [r["time_ratio_fem_over_gdfe"] for r in rows if r.get("time_ratio_fem_over_gdfe")]
    hl = [
        headline("largest GDFE-FEM RMS distance / part size (Eq. 3 R)", worst["rms_rel"], None, 0.25, "le",
                 note=f"{worst['part']}; after rigid alignment, at the design's vertices"),
        headline("RMS distance with R fitted to the FEM <= with Eq. 3's R (every part)",
                 int(all(r["rms_fit_mm"] <= r["rms_mm"] * (1 + 1e-6) for r in rows)), 1, None, "eq"),
        headline("FEM time / GDFE time, same part (median)",
                 float(np.median([r["fem_seconds"] / r["gdfe_seconds"] for r in rows])), None, 1.0, "ge"),
    ]
    inverse = [r for r in rows if "fem_to_target_mm" in r]
    if inverse:
        worst_inv = max(inverse, key=lambda r: r["fem_to_target_mm"] / r["design_tolerance_mm"])
        hl.append(headline("inverse designs: the FEM's fold of the printed masks within the design's tolerance of "
                           "the target (largest RMS / tolerance)",
                           worst_inv["fem_to_target_mm"] / worst_inv["design_tolerance_mm"], None, 1.0, "le",
                           expect=False,
                           note=f"{worst_inv['part']}: FEM {worst_inv['fem_to_target_mm']:.3f} mm, GDFE "
                                f"{worst_inv['gdfe_to_target_mm']:.3f} mm, tolerance "
                                f"{worst_inv['design_tolerance_mm']:.3f} mm: the masks are designed through GDFE"))
    if ratios:
        hl.append(headline("FEM / GDFE time at equal shape error (median over parts)", float(np.median(ratios)),
                           None, 1.0, "ge"))
    summary = {"ours": "; ".join(f"{r['part']}: RMS {100 * r['rms_rel']:.1f} %, max {100 * r['max_rel']:.1f} % "
                                 f"of {r['size_mm']:.1f} mm (R fit {r['R_fit']:.3f} vs Eq. 3 {r['R_eq3']:.3f})"
                                 for r in rows),
               "verdict": _verdict(rows)}
    result = {"study": NAME, "figure": "Figs. 7-8", "title": "GDFE against the plate FEM: freeform shapes",
              "resolution": resolution, "h_mm": H, "d_mm": D, "R_eq3": eq3_ratio(), "headlines": hl,
              "converged": converged, "summary": summary,
              "parts": [{k: v for k, v in r.items() if not k.startswith("_")} for r in rows],
              "_maps": {r["part"]: r["_map"] for r in rows}}
    return finish(result, out, plot)


def _verdict(rows):
    """Where and why GDFE departs from the FEM, part by part, from the numbers.

    When one R fitted to the FEM removes most of the distance, the models differ in how much the film
    contracts against its coat (the coat's stiffness, which Eq. 3's R stands for); when it does not, they
    differ in the form of the shape (the film's in-plane stretching and Poisson contraction, which GDFE's
    per-cell rest shapes do not trade against bending as the elastic bilayer does).
    """
    parts = []
    for r in rows:
        by = r["deviation_by_material_mm"]
        where = max(by, key=by.get) if by else "-"
        kept = r["rms_fit_mm"] / r["rms_mm"] if r["rms_mm"] > 0 else 1.0
        why = ("the amount of contraction (one R fitted to the FEM removes "
               f"{100 * (1 - kept):.0f} % of the RMS distance)" if kept < 0.3 else
               f"the form of the shape (R fitted to the FEM keeps {100 * kept:.0f} % of the RMS distance)")
        parts.append(f"{r['part']}: largest on {where} cells; {why}; R fit {r['R_fit']:.3f} against Eq. 3's "
                     f"{r['R_eq3']:.3f}")
    return "; ".join(parts)


def plot(result, out):
    plt = pyplot()
    maps = result["_maps"]
    n = len(maps)
    fig, axes = plt.subplots(1, n, figsize=(3.8 * n, 3.6), squeeze=False)
    for ax, (name, (keys, dev, pixel)) in zip(axes[0], maps.items()):
        px = np.broadcast_to(np.asarray(pixel, float), (2,))
        sc = ax.scatter(keys[:, 0] * px[0], keys[:, 1] * px[1], c=dev, s=12, cmap="viridis", vmin=0,
                        vmax=float(np.nanmax(dev)) or 1.0)
        row = next(p for p in result["parts"] if p["part"] == name)
        ax.set_title(f"{name}: RMS {100 * row['rms_rel']:.1f} % of size", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        fig.colorbar(sc, ax=ax, label="distance [mm]", shrink=0.7)
    fig.suptitle("GDFE (Eq. 3 R) against the plate FEM: distance of the film mid-surfaces after rigid alignment")
    from gdfe.io import save_figure

    save_figure(fig, out / f"{NAME}.png")
    plt.close(fig)


main = main_of(__name__)

if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
