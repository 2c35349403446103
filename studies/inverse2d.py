"""2-D inverse design (issue 17, not in the paper): from a target surface to the masks that fold into it.

The paper designs strips (1-D) and names 2-D-to-3-D design as future work. Here
:func:`gdfe.inverse2d.design_surface` designs the coating of both faces of a film for

1. *a dome, a saddle and a twisted strip* at several film sizes (the printer pixel fixed), each
   designed (L-BFGS-B through the GDFE equilibrium), halftoned into masks that respect ``w_min``
   and forward-simulated from the masks: the distance to the target after rigid alignment (RMS,
   max, Hausdorff) of the start (the placement's estimate), the relaxed design and the printed
   one, against the film size;
2. *the twisted strip's limit*: the strip also at twice the largest size; the end-to-end twist of
   its folds against the target's; the start's design (the helicoid's metric, both faces alike)
   and the relaxed design folded from three shapes of the helicoid's associate family (the
   helicoid, its mirror image, the catenoid strip: the same metric and the same, zero, mean
   curvature); and the start's design of a strip a fifth as thick, folded the same ways;
3. *one design at about 10^4 cells* (a 12.5 mm dome at 0.125 mm pixels at default resolution):
   its seconds, L-BFGS-B iterations and evaluations on this machine (cores and load average
   recorded);
4. *a target out of reach*: a sphere cap of radius 2 mm on a 6 mm film, whose length ratio is
   beyond isotropic shrink; its answer (the closest reachable dome, by how much the design
   misses), and that closest reachable dome designed.

Headlines (checked at every resolution): the dome's and the saddle's printed fold within the
design's tolerance (1 % of the film's size) at the largest size; the relaxed design never
farther than its start; every mask respecting ``w_min``; the cap out of reach, missed by more
than the tolerance and answered with a closest reachable dome that the design then reaches. The
twist's printed fold within 1 % of its size is recorded as not holding (the limit of 2.).

Run ``python -m studies.inverse2d [--out DIR] [--resolution R] [--json]`` or
``gdfe study inverse2d``; writes ``inverse2d.png`` and ``inverse2d.json``.
"""

from __future__ import annotations

import math
import os
import time

import numpy as np

from gdfe import paper
from gdfe.inverse2d.design import TOLERANCE_FRACTION
from studies._common import check_resolution, finish, headline, main_of, progress, pyplot

NAME = "inverse2d"
TARGETS = ("dome", "saddle", "twist")
#: The cap out of reach: film size and sphere radius [mm].
UNREACHABLE = (6.0, 2.0)
SETTINGS = {
    "coarse": {"pixel": 0.5, "sizes": (3.0, 6.0), "iterations": 8, "timing": (3.0, 0.25), "unreachable_pixel": 0.5},
    "default": {"pixel": 0.25, "sizes": (3.0, 6.0, 12.0), "iterations": 40, "timing": (12.5, 0.125),
                "unreachable_pixel": 0.25},
    "fine": {"pixel": 0.125, "sizes": (3.0, 6.0, 12.0, 24.0), "iterations": 60, "timing": (25.0, 0.125),
             "unreachable_pixel": 0.125},
}
D = paper.FIG6_D
#: The thin film [mm] the twist's placement estimate is also folded with (a fifth of the paper's h, with a
#: fifth of its d: the same contraction).
THIN_H = paper.H / 5
#: Activation steps of the twist's flat print: the thinner film buckles on its way, and in one
#: step it stops at its iteration limit short of the state the other starts reach.
FLAT_PRINT_STEPS = 8


def _sizes(cfg, name):
    """Film sizes [mm] of a target's sweep: the twist's strip (a quarter as wide, a sixteenth of the cells)
    also at twice the largest size."""
    return tuple(cfg["sizes"]) + ((2 * cfg["sizes"][-1],) if name == "twist" else ())


def _distances(dsg):
    return {"start": dsg.initial_distance.as_dict(), "relaxed": dsg.relaxed_distance.as_dict(),
            "printable": dsg.printable_distance.as_dict()}


def twist_angle(points, film):
    """End-to-end twist [rad] of a strip's fold: the angle between its first and last cross-sections
    (their end-to-end vectors across the width) about the line through their centres, and that line's length [mm]."""
    M = film.mid.points(points)
    p = film.mid.flat
    xs = np.unique(np.round(p[:, 0], 9))
    ends, centres = [], []
    for x in (xs[0], xs[-1]):
        sel = np.isclose(p[:, 0], x)
        q = M[sel][np.argsort(p[sel, 1])]
        ends.append(q[-1] - q[0])
        centres.append(q.mean(axis=0))
    axis = centres[1] - centres[0]
    chord = float(np.linalg.norm(axis))
    axis /= chord
    a, b = (v - axis * (v @ axis) for v in ends)
    return math.atan2(float(np.cross(a, b) @ axis), float(a @ b)), chord


def _associate_start(target, film, sigma, phi):
    """The film's vertices on the member ``phi`` of the twist's associate family (pi/2: the helicoid,
    -pi/2: its mirror image, 0: the catenoid strip), mid-surface on it, faces h/2 off along its normal."""
    tau = target.params["angle_rad"] / (sigma * target.film_size[0])

    def surface(u):
        a, b = tau * u[:, 0], tau * u[:, 1]
        hel = np.column_stack([a, np.sinh(b) * np.cos(a), np.sinh(b) * np.sin(a)])
        cat = np.column_stack([b, -np.cosh(b) * np.sin(a), np.cosh(b) * np.cos(a)])
        return (math.cos(phi) * cat + math.sin(phi) * hel) / tau

    mid = film.mid
    p = mid.flat
    eps = 1e-4 * float(target.film_size[0])
    X = surface(sigma * p)
    du = surface(sigma * (p + [eps, 0])) - surface(sigma * (p - [eps, 0]))
    dv = surface(sigma * (p + [0, eps])) - surface(sigma * (p - [0, eps]))
    n = np.cross(du, dv)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    V = np.zeros((film.base.mesh.n_points, 3))
    V[mid.bottom] = X - 0.5 * film.h * n
    V[mid.top] = X + 0.5 * film.h * n
    return V


def _twist_limit(dsg):
    """Twist angles of the folds; the start's design (the helicoid's metric, no bending: both faces alike)
    and the relaxed design folded from three members of the helicoid's associate family."""
    from gdfe.inverse2d import fold

    film = dsg.film
    out = {"target_rad": dsg.target.params["angle_rad"], "width_mm": dsg.target.params["width_mm"],
           "h_mm": film.h, "message": dsg.message, "iterations": dsg.iterations}
    for key, res in (("start", dsg.initial), ("relaxed", dsg.relaxed), ("printable", dsg.printable)):
        out[f"{key}_twist_rad"] = twist_angle(res.points, film)[0]
    rho0 = 1.0 - np.asarray(dsg.initial.design.contraction) / film.c0
    out["start_faces_differ_by"] = float(np.max(np.abs(rho0[:, 0] - rho0[:, 1])))
    for key, design in (("start", dsg.initial.design), ("relaxed", dsg.relaxed.design)):
        rows = []
        for label, phi in (("helicoid", math.pi / 2), ("mirror image", -math.pi / 2), ("catenoid strip", 0.0)):
            V0 = _associate_start(dsg.target, film, dsg.sigma, phi)
            f = fold(design, start=V0, tol=None)  # the shape is wanted: gdfe.simulate's test
            ang, chord = twist_angle(f.points, film)
            rows.append({"start": label, "start_twist_rad": twist_angle(V0, film)[0], "energy": f.energy,
                         "converged": f.converged, "twist_rad": ang, "chord_mm": chord})
        e = [r["energy"] for r in rows]
        out[f"{key}_from_associates"] = rows
        out[f"{key}_energy_spread"] = float((max(e) - min(e)) / max(abs(min(e)), 1e-300))
    return out


def _twists(rows):
    """The folds' twist angles as text, each fold that did not converge marked so."""
    return ", ".join(f"{r['twist_rad']:.3g}" + ("" if r["converged"] else " (not converged)") for r in rows)


def _metric_only(size, pixel, h=paper.H):
    """The twist's placement estimate (the helicoid's metric, both faces alike) on a strip of ``size`` [mm]
    and thickness ``h`` [mm], folded from the flat print and from three members of the associate family:
    does a wider or thinner strip twist?"""
    import gdfe
    from gdfe.inverse2d import Film, fold, initial_coating, make_target, scale_for

    target = make_target("twist", size)
    d = D * h / paper.H  # the same h / d: the same contraction c0 by Eq. 3
    film = Film((int(round(target.film_size[0] / pixel)), int(round(target.film_size[1] / pixel))), pixel, h, d)
    sigma, _ = scale_for(target, film)
    design = film.relaxed(initial_coating(target, film, sigma))
    flat = gdfe.simulate(design, steps=FLAT_PRINT_STEPS)
    ang, chord = twist_angle(flat.points, film)
    rows = [{"start": "flat print", "twist_rad": ang, "chord_mm": chord, "energy": flat.energy,
             "converged": bool(flat.converged)}]
    for label, phi in (("helicoid", math.pi / 2), ("mirror image", -math.pi / 2), ("catenoid strip", 0.0)):
        f = fold(design, start=_associate_start(target, film, sigma, phi), tol=None)
        ang, chord = twist_angle(f.points, film)
        rows.append({"start": label, "twist_rad": ang, "chord_mm": chord, "energy": f.energy,
                     "converged": bool(f.converged)})
    return {"size_mm": size, "width_mm": float(target.film_size[1]), "h_mm": h, "d_mm": d, "c0": film.c0,
            "pixel_mm": pixel, "cells": film.n_cells,
            "print_length_mm": float(film.shape[0]) * pixel, "folds": rows}


def _record(dsg, size):
    rec = {"size_mm": size, "cells": dsg.film.n_cells, "film_mm": [float(v) for v in dsg.target.film_size],
           "distance": _distances(dsg), "tolerance_mm": dsg.tolerance_mm, "reached": dsg.reached,
           "converged": bool(dsg.printable.converged and dsg.relaxed.converged), "masks_ok": dsg.masks_ok,
           "iterations": dsg.iterations, "evaluations": dsg.evaluations, "seconds": dsg.seconds["total"],
           "branch": dsg.branch,
           "reachability": dsg.reachability.as_dict(),
           "coated": {"top": float(dsg.top.mean()), "bottom": float(dsg.bottom.mean())}}
    return rec


def run(resolution="default", out=None):
    """Design each target at each size, the 10^4-cell design and the cap out of reach; return the numbers."""
    from gdfe.inverse2d import design_surface, make_target

    check_resolution(resolution)
    cfg = SETTINGS[resolution]
    pixel, it = cfg["pixel"], cfg["iterations"]
    jobs = [(name, size) for name in TARGETS for size in _sizes(cfg, name)]
    # the sweep's designs, then the twisted strip's starts, the timed design and the cap out of reach
    parts = progress(range(len(jobs) + 3), "designs")
    sweeps, largest = {name: [] for name in TARGETS}, {}
    for name, size in jobs:
        next(parts)
        dsg = design_surface(make_target(name, size), pixel=pixel, d=D, iterations=it)
        sweeps[name].append(_record(dsg, size))
        largest[name] = dsg
    next(parts)
    twist = _twist_limit(largest["twist"])
    twist["size_mm"] = _sizes(cfg, "twist")[-1]
    twist["thinner"] = _metric_only(twist["size_mm"], pixel, h=THIN_H)
    next(parts)
    big, timing = _timed_design(cfg)
    next(parts)
    unreachable, u, near_design = _unreachable(cfg)
    twist_folds = twist["start_from_associates"] + twist["relaxed_from_associates"] + twist["thinner"]["folds"]
    converged = (all(r["converged"] for n in TARGETS for r in sweeps[n]) and timing["converged"]
                 and unreachable["converged"] and all(r["converged"] for r in twist_folds))
    result = {"study": NAME, "figure": "not in the paper (issue 17)", "title": "2-D inverse design from a target "
              "surface", "resolution": resolution, "settings": {**cfg, "d_mm": D, "h_mm": paper.H},
              "sweeps": sweeps, "twist": twist, "timing": timing, "unreachable": unreachable,
              "headlines": _headlines(cfg, sweeps, twist, big, unreachable), "converged": converged, "summary": _summary(sweeps, twist, timing),
              "_masks": {n: (largest[n].top, largest[n].bottom, largest[n].film.pixel) for n in TARGETS},
              "_profile": _profile(u, near_design)}
    return finish(result, out, plot)


def _timed_design(cfg):
    """One design of the dome at about 10^4 cells, timed: the design and its timing record."""
    from gdfe.inverse2d import design_surface, make_target

    it = cfg["iterations"]
    t_size, t_pixel = cfg["timing"]
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    big = design_surface(make_target("dome", t_size), pixel=t_pixel, d=D, iterations=it)
    wall = time.perf_counter() - t0
    timing = {"target": "dome", "size_mm": t_size, "pixel_mm": t_pixel, "cells": big.film.n_cells,
              "iterations": big.iterations, "evaluations": big.evaluations, "message": big.message,
              "seconds": wall, "seconds_by_step": big.seconds, "per_evaluation_s": big.seconds["optimisation"] / max(big.evaluations, 1),
              "cores": os.cpu_count(), "load_average_before": list(load0), "load_average_after": list(os.getloadavg()),
              "distance": _distances(big), "reached": big.reached, "converged": bool(big.printable.converged),
              "history": [{"evaluation": r["evaluation"], "rms_mm": r["rms_mm"], "seconds": r["seconds"]}
                          for r in big.history]}
    return big, timing


def _unreachable(cfg):
    """A cap out of reach and the closest reachable dome, designed: their record, the cap's design and the dome's."""
    from gdfe.inverse2d import closest_reachable, design_surface, make_target, scale_for

    it = cfg["iterations"]
    u_size, u_radius = UNREACHABLE
    cap = make_target("dome", u_size, radius=u_radius)
    u = design_surface(cap, pixel=cfg["unreachable_pixel"], d=D, iterations=it)
    t_near, near = closest_reachable(cap, u.film)
    near_design = design_surface(near, pixel=cfg["unreachable_pixel"], d=D, iterations=it)
    unreachable = {"size_mm": u_size, "radius_mm": u_radius, "pixel_mm": cfg["unreachable_pixel"],
                   "reachability": u.reachability.as_dict(), "verdict": u.verdict(), "reached": u.reached,
                   "distance": _distances(u), "tolerance_mm": u.tolerance_mm, "closest": u.closest,
                   "closest_design": {"radius_mm": near.params["radius_mm"], "t": t_near,
                                      "reachable": scale_for(near, near_design.film)[1].reachable,
                                      "distance": _distances(near_design), "reached": near_design.reached,
                                      "verdict": near_design.verdict()},
                   "converged": bool(u.printable.converged and near_design.printable.converged),
                   "masks_ok": bool(u.masks_ok and near_design.masks_ok)}
    return unreachable, u, near_design


def _headlines(cfg, sweeps, twist, big, unreachable):
    """The study's headline checks: the designs' distances, the masks, and the cap out of reach said so."""
    big_size = cfg["sizes"][-1]
    rel = {n: sweeps[n][-1]["distance"]["printable"]["rms_mm"] / sweeps[n][-1]["size_mm"] for n in TARGETS}
    worst_start = max(r["distance"]["relaxed"]["rms_mm"] / max(r["distance"]["start"]["rms_mm"], 1e-300)
                      for n in ("dome", "saddle") for r in sweeps[n])
    masks_ok = all(r["masks_ok"] for n in TARGETS for r in sweeps[n]) and big.masks_ok and unreachable["masks_ok"]
    u_size, u_radius = UNREACHABLE
    u_rms = unreachable["distance"]["printable"]["rms_mm"]
    near_radius = unreachable["closest_design"]["radius_mm"]
    near_rms = unreachable["closest_design"]["distance"]["printable"]["rms_mm"]
    return [
        headline(f"dome: printed fold's RMS distance over the film size at {big_size:g} mm", rel["dome"], None,
                 TOLERANCE_FRACTION, "le", note="the design's tolerance, 1 % of the film's size"),
        headline(f"saddle: printed fold's RMS distance over the film size at {big_size:g} mm", rel["saddle"], None,
                 TOLERANCE_FRACTION, "le", note="the design's tolerance, 1 % of the film's size"),
        headline("dome, saddle: relaxed design's RMS distance over its start's, worst size", worst_start, None, 1.0,
                 "le", note="the optimisation never ends farther from the target than its start"),
        headline(f"twist: printed fold's RMS distance over the strip's length at {twist['size_mm']:g} mm",
                 sweeps["twist"][-1]["distance"]["printable"]["rms_mm"] / twist["size_mm"], None, TOLERANCE_FRACTION,
                 "le",
                 expect=False,
                 note=(f"the fold twists by {twist['printable_twist_rad']:.3g} rad of {twist['target_rad']:.3g}: "
                       "isotropic shrink bends a cell alike in every direction, the helicoid's mean curvature is "
                       "zero; the twist must come from one-sided coats varying over a strip narrow for its thickness")),
        headline("every mask respects w_min", float(masks_ok), 1.0, kind="eq"),
        headline(f"cap of radius {u_radius:g} mm on a {u_size:g} mm film: reachability margin in contraction",
                 unreachable["reachability"]["margin"], None, 0.0, "le", note="< 0: out of reach"),
        headline("cap out of reach: printed fold's RMS distance over the tolerance", u_rms / unreachable["tolerance_mm"], None, 1.0,
                 "ge", note="missed, and said so"),
        headline(f"closest reachable dome (radius {near_radius:.3g} mm): printed RMS over the film size",
                 near_rms / u_size, None, TOLERANCE_FRACTION, "le", note="the answer's shape is one the design reaches"),
    ]


def _summary(sweeps, twist, timing):
    """The study's summary: the paper, our numbers, the verdict and why the twisted strip is not reached."""
    return {
        "paper": "the paper designs 1-D strips only and names 2-D-to-3-D design as future work",
        "ours": "; ".join(f"{n} at {sweeps[n][-1]['size_mm']:g} mm: printed RMS {sweeps[n][-1]['distance']['printable']['rms_mm']:.3g} mm "
                          f"(relaxed {sweeps[n][-1]['distance']['relaxed']['rms_mm']:.3g}, start "
                          f"{sweeps[n][-1]['distance']['start']['rms_mm']:.3g})" for n in TARGETS)
                + (f"; {timing['cells']} cells: {timing['seconds']:.0f} s, {timing['iterations']} iterations "
                   f"({timing['message'].lower()}), "
                   f"{timing['evaluations']} evaluations on {timing['cores']} cores (load "
                   f"{timing['load_average_before'][0]:.1f})"),
        "verdict": ("dome and saddle are designed within 1 % of the film's size; a cap out of reach gets the closest "
                    "reachable dome and the distance it misses by"),
        "discrepancy": (f"the twisted strip is not reached: its printed fold twists by {twist['printable_twist_rad']:.3g} "
                        f"rad of {twist['target_rad']:.3g} (relaxed {twist['relaxed_twist_rad']:.3g}); folded from "
                        "the helicoid, its mirror image and the catenoid strip, the start's design (the helicoid's "
                        "metric, both faces alike) twists by "
                        + _twists(twist["start_from_associates"])
                        + " rad and the relaxed design by "
                        + _twists(twist["relaxed_from_associates"])
                        + f" rad (energies within {twist['relaxed_energy_spread']:.2g} relative); at a fifth of the "
                          f"thickness ({THIN_H:.3g} mm) the start's design twists by "
                        + _twists(twist["thinner"]["folds"])
                        + " rad from the flat print and the three shapes. Isotropic shrink bends a cell alike in every "
                          "direction and the helicoid's mean curvature is zero: the placement's estimate has both "
                          "faces alike and folds untwisted, and a twist must come from one-sided coats varying over "
                          "the strip, which a strip narrow for its thickness resists: RMS over length "
                        + ", ".join(f"{r['distance']['printable']['rms_mm'] / r['size_mm']:.3g} at {r['size_mm']:g} mm"
                                    for r in sweeps["twist"])),
    }


def _profile(u, near):
    """Sections y ~ 0 of the cap, the closest reachable dome and their printed folds (aligned), for the plot."""
    def section(points, width):
        sel = np.abs(points[:, 1]) < width
        order = np.argsort(points[sel, 0])
        return points[sel][order][:, [0, 2]]

    w = 0.6 * u.film.pixel
    band = 0.02 * float(max(u.target.film_size))
    return {"target": section(u.target_surface.vertices, band), "fold": section(u.printable_distance.aligned, w),
            "near_target": section(near.target_surface.vertices, band),
            "near_fold": section(near.printable_distance.aligned, w)}


def plot(result, out):
    from studies._draw import save_figure

    plt = pyplot()
    fig, axes = plt.subplots(2, 4, figsize=(17, 8))
    styles = {"start": ":", "relaxed": "--", "printable": "-"}
    for k, name in enumerate(TARGETS):
        ax = axes[0, k]
        rows = result["sweeps"][name]
        sizes = [r["size_mm"] for r in rows]
        for j, metric in enumerate(("rms_mm", "max_mm", "hausdorff_mm")):
            for which, ls in styles.items():
                ax.loglog(sizes, [max(r["distance"][which][metric], 1e-6) for r in rows], ls, marker="o", ms=3,
                          color=f"C{j}", label=f"{which} {metric[:-3]}" if k == 0 else None)
        ax.loglog(sizes, [TOLERANCE_FRACTION * s for s in sizes], "k-", lw=0.6, alpha=0.5,
                  label="1 % of size" if k == 0 else None)
        ax.set(title=f"{name}: distance to target", xlabel="film size [mm]", ylabel="distance [mm]")
        ax.set_xticks(sizes, [f"{v:g}" for v in sizes])
        ax.minorticks_off()
        if k == 0:
            ax.legend(fontsize=6, ncol=2)
        top, bottom, pixel = result["_masks"][name]
        img = np.ones(top.shape + (3,))
        img[top] = (0.85, 0.25, 0.2)
        img[bottom] = (0.2, 0.35, 0.85)
        img[top & bottom] = (0.25, 0.2, 0.3)
        nx, ny = top.shape
        axes[1, k].imshow(img.transpose(1, 0, 2), origin="lower", extent=(0, nx * pixel, 0, ny * pixel),
                          interpolation="nearest")
        axes[1, k].set(title=f"{name} at {sizes[-1]:g} mm, masks:\ntop coat red, bottom blue, both dark",
                       xlabel="x [mm]", ylabel="y [mm]")
    t = result["timing"]
    ax = axes[0, 3]
    ax.semilogy([h["seconds"] for h in t["history"]], [max(h["rms_mm"], 1e-9) for h in t["history"]], "k.-", lw=0.8)
    ax.set(xlabel="seconds", ylabel="RMS distance (folds continued) [mm]",
           title=f"{t['cells']} cells: {t['iterations']} iterations, {t['evaluations']} evaluations,\n"
                 f"{t['seconds']:.0f} s ({t['cores']} cores, load {t['load_average_before'][0]:.1f})")
    ax = axes[1, 3]
    prof = result["_profile"]
    u = result["unreachable"]
    ax.plot(*prof["target"].T, "k-", lw=1, label=f"cap R = {u['radius_mm']:g} mm (out of reach)")
    ax.plot(*prof["fold"].T, "C3.", ms=3, label=f"its printed fold: RMS {u['distance']['printable']['rms_mm']:.3g} mm")
    near = u["closest_design"]
    ax.plot(*prof["near_target"].T, "C0-", lw=1, label=f"closest reachable: R = {near['radius_mm']:.3g} mm")
    ax.plot(*prof["near_fold"].T, "C0.", ms=3, label=f"its printed fold: RMS {near['distance']['printable']['rms_mm']:.3g} mm")
    ax.set_aspect("equal")
    ax.set(xlabel="x [mm]", ylabel="z [mm]", title="a target out of reach, and the answer")
    ax.legend(fontsize=6)
    save_figure(fig, out, NAME, title="2-D inverse design: distance to target against film size, masks, cost, reach")


main = main_of(__name__)


if __name__ == "__main__":
    raise SystemExit(main())
