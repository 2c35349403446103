"""``gdfe design``: the paper's 1-D design pipeline (Sec. 4.2), and 2-D design from a target surface.

1-D input: a couples file (``.toml``), a sketch (``.csv`` of points, or an ``.svg`` stroke) or
``--text`` (letters of Figure 9; each distinct letter is designed and checked once, its part
named after its first place among the distinct letters, ``02_o``, and its places in the text
and count recorded, ``positions`` and ``count`` in ``design.json`` and ``copies`` in the print
package's ``print.json``, so a repeated letter is printed that many times). For each part: the strip pattern at the printer's pixel,
its masks (``NAME_top.png``, ``NAME_bottom.png``: 1-bit, black = passive, DPI set) and
design file (``NAME.toml``), the design read back from those files and simulated
(``NAME_check.pvd``), and its deviation from the target (``NAME_deviation.png``,
``NAME_deviation.json``: RMS and largest distance, overall and per segment); then a print
package of every part (``print.zip``) and ``design.json``. A part whose check misses its target by more than
``--tolerance`` RMS (default :data:`gdfe.inverse.TOLERANCE_FRACTION` of its length) is reported
NOT REACHED (``reached`` and ``tolerance_mm`` in its ``check``), and the command exits with status 4.

2-D input: ``--target dome|saddle|cylinder|twist|MESH.obj|.stl|.ply --size MM``
(:mod:`gdfe.inverse2d`): the coating of both faces whose GDFE fold matches the surface, its
printable masks, a design file that reads them back, the forward check of the printed design
and its distance to the target (``NAME.json``: ``rms_mm``, ``max_mm``, ``hausdorff_mm``), and a
figure (:func:`gdfe.inverse2d.write_design`). Exit status 3 when the printed design's fold did
not converge, 4 when it misses the target (the answer says by how much, and for a target out of
reach the closest one within it).

Every choice is printed with where it came from.
"""

from __future__ import annotations

import math
from pathlib import Path

from gdfe import paper
from gdfe._validation import GdfeError, check_length, check_positive
from gdfe.cli._common import emit, file_path, json_arg, noting, out_arg, output_folder
from gdfe.cli._uncertainty import check_uncertainty, run_ensemble, uncertainty_args, write_ensemble
from gdfe.inverse.pipeline import TOLERANCE_FRACTION as STRIP_TOLERANCE
from gdfe.inverse2d.design import DEFAULT_ITERATIONS, TOLERANCE_FRACTION
from gdfe.inverse2d.masks import PROJECTIONS

__all__ = ["register", "run"]

#: Defaults of the choices that are not the paper's, with why.
DEFAULT_PIXEL = 0.125  # mm: the pattern cell of the studies' default resolution
DEFAULT_WIDTH = 0.5  # mm: the studies' strip (narrow: the cylindrical fold Eq. 2 assumes)
DEFAULT_PENALTY = 0.1  # the paper's third level (Fig. 10)
DEFAULT_SPACING = 0.2  # mm: sampling of a sketch's curved segments


def register(sub):
    p = sub.add_parser("design", help="design a strip from couples, a sketch or letters (paper Sec. 4.2), or a "
                                      "film from a target surface (--target)",
                       description="The 1-D design pipeline: couples (TOML), a sketch (CSV of points or an SVG "
                                   "stroke) or --text letters -> printer masks, a design file, the simulated "
                                   "check and its deviation report. With --target SURFACE --size MM: 2-D design, "
                                   "the coating of both faces whose fold matches the surface (gradient-based, "
                                   "through the GDFE equilibrium), printable masks that respect --w-min, the "
                                   "printed design's fold and its distance to the target. Exit status 3 when "
                                   "the checked fold did not converge, 4 when it misses the target by more "
                                   "than --tolerance.")
    p.add_argument("input", nargs="?", type=file_path, help="couples (.toml), sketch (.csv or .svg)")
    p.add_argument("--text", help="letters of Figure 9 to design, one strip each (instead of INPUT)")
    out_arg(p, required=True)
    p.add_argument("--pixel", type=float, help=f"printer pixel = pattern cell [mm] (default {DEFAULT_PIXEL:g})")
    p.add_argument("--w-min", type=float, help="narrowest contracting feature [mm], whole pixels (default one pixel)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--d", type=float, help=f"passive thickness [mm]: R by Eq. 3 (default {paper.FIG6_D:g}, the paper's)")
    g.add_argument("--R", type=float, help="contraction ratio of the free face, instead of d")
    p.add_argument("--K", type=float, help=f"coefficient of Eq. 1/3 (default {paper.K:g}, the paper's)")
    p.add_argument("--h", type=float, help=f"active film thickness [mm] (default {paper.H:g}, the paper's)")
    p.add_argument("--width", type=float, help=f"strip width [mm], whole pixels (default {DEFAULT_WIDTH:g})")
    p.add_argument("--penalty", type=float, help=f"sketch: penalty per segment Delta (default {DEFAULT_PENALTY:g}, "
                                                 "the paper's third level)")
    p.add_argument("--weights", choices=("plain", "length"), default=None,
                   help="sketch: residual sum over vertices (plain, the paper's) or weighted by length")
    p.add_argument("--rounding", choices=("nearest", "floor", "ceil", "carry"), default=None,
                   help="blocks per couple: nearest (couples, letters) or carry (sketches) by default")
    p.add_argument("--clamp", action="store_true", default=None,
                   help="print couples tighter than the film folds fully contracting (default for sketches)")
    p.add_argument("--compensate", action="store_true",
                   help="print each couple |alpha| h/2 longer so the mid-line keeps its length (not the paper's)")
    p.add_argument("--svg-id", help="sketch SVG: id of the stroke to read (default: the only one)")
    p.add_argument("--spacing", type=float, default=None,
                   help=f"sketch SVG: sampling of curved segments [mm] (default {DEFAULT_SPACING:g})")
    p.add_argument("--no-check", action="store_true", help="write the files, skip the simulated check")
    p.add_argument("--tolerance", type=float,
                   help="RMS distance [mm] below which the target counts as reached (default: a strip's check "
                        f"{100 * STRIP_TOLERANCE:g} %% of the target's length, a 2-D design "
                        f"{100 * TOLERANCE_FRACTION:g} %% of the film's size); exit status 4 when missed")
    g = p.add_argument_group("2-D design from a target surface")
    g.add_argument("--target", metavar="SURFACE",
                   help="dome, saddle, cylinder, twist, or a triangle mesh (.obj, .stl, .ply) [mm]")
    g.add_argument("--size", type=float, help="film size [mm]: the square film's side, the twist's length, the "
                                              "largest side of a mesh's flattened outline")
    g.add_argument("--model", type=file_path, help="deformation model file (default the paper's Eq. 3)")
    g.add_argument("--iterations", type=int,
                   help=f"L-BFGS-B iterations (default {DEFAULT_ITERATIONS}; 0: the placement's estimate only)")
    g.add_argument("--radius", type=float, help="dome, saddle, cylinder: radius of curvature [mm] (default: the "
                                                "size; the cylinder's half of it)")
    g.add_argument("--angle", type=float, help="twist: angle end to end [rad] (default pi); --width: its width")
    g.add_argument("--projection", choices=PROJECTIONS, default=None,
                   help="coating fractions to masks: halftone (default), nested halftones, or threshold at 1/2")
    uncertainty_args(p)
    json_arg(p, "the summary")
    p.set_defaults(func=run)


class _Choices:
    """Each choice with its value and where it came from, in the order they were made."""

    def __init__(self):
        self.items = {}

    def set(self, key, value, source, unit=""):
        self.items[key] = (value, source, unit)
        return value

    def pick(self, key, cli, file, default, default_source, unit=""):
        if cli is not None:
            return self.set(key, cli, "command line", unit)
        if file is not None:
            return self.set(key, file, "input file", unit)
        return self.set(key, default, default_source, unit)

    def text(self):
        w = max(len(k) for k in self.items)
        lines = []
        for k, (v, src, unit) in self.items.items():
            val = f"{v:.6g}" if isinstance(v, float) else str(v)
            lines.append(f"    {k:<{w}}  {val + (' ' + unit if unit else ''):<16} {src}")
        return "\n".join(lines)

    def as_dict(self):
        return {k: {"value": v, "source": s, "unit": u} for k, (v, s, u) in self.items.items()}


def _targets(args, ch):
    """The parts to design: [(name, target)], the file's [film] and [print] entries, and for --text each
    part's places in the text (1-based, spaces not counted): {name: [position, ...]}."""
    from gdfe import inverse as inv

    if (args.input is None) == (args.text is None):
        raise GdfeError("give one input: a couples .toml, a sketch .csv/.svg, or --text LETTERS")
    if args.text is not None:
        glyphs = inv.text_glyphs(args.text)
        ch.set("input", f"letters {args.text!r} (Figure 9 glyphs)", "command line")
        places = {}  # each distinct letter once, with where it stands in the text
        for k, g in enumerate(glyphs):
            places.setdefault(g.char, []).append(k + 1)
        names = {c: f"{k + 1:02d}_{c}" for k, c in enumerate(places)}
        return ([(names[c], inv.target_from_letter(c)) for c in places], {}, {},
                {names[c]: where for c, where in places.items()})
    path = args.input
    suffix = path.suffix.lower()
    if suffix == ".toml":
        cf = inv.read_couples_toml(path)
        ch.set("input", f"couples {path}", "command line")
        return [(cf.target.name, cf.target)], cf.film, cf.print, {}
    if suffix in (".csv", ".txt", ".svg"):
        P = inv.read_sketch(path, element_id=args.svg_id, spacing=DEFAULT_SPACING if args.spacing is None else args.spacing)
        ch.set("input", f"sketch {path} ({len(P)} points)", "command line")
        penalty = ch.pick("penalty", args.penalty, None, DEFAULT_PENALTY, "paper (Fig. 10, third level)")
        weights = ch.pick("weights", args.weights, None, "plain", "paper (sum over the vertices)")
        target = inv.target_from_sketch(P, penalty, weights=None if weights == "plain" else "length",
                                        name=path.stem)
        ch.set("segments", target.fit.segmentation.m, "fitted")
        return [(path.stem, target)], {}, {}, {}
    raise GdfeError(f"input: expected a .toml (couples), .csv or .svg (sketch) file, got {path.name!r}")


#: Options of the 1-D pipeline only, and of the 2-D one only: (dest, flag).
_ONLY_1D = (("input", "INPUT"), ("text", "--text"), ("R", "--R"), ("K", "--K"), ("penalty", "--penalty"),
            ("weights", "--weights"), ("rounding", "--rounding"), ("clamp", "--clamp"), ("svg_id", "--svg-id"),
            ("spacing", "--spacing"))
_ONLY_2D = (("size", "--size"), ("model", "--model"), ("iterations", "--iterations"), ("radius", "--radius"),
            ("angle", "--angle"), ("projection", "--projection"),
            ("uncertainty", "--uncertainty"), ("level", "--level"), ("seed", "--seed"))


def _check_mode(args):
    if args.target is not None:
        given = [flag for dest, flag in _ONLY_1D if getattr(args, dest) is not None]
        given += [flag for dest, flag in (("compensate", "--compensate"), ("no_check", "--no-check"))
                  if getattr(args, dest)]
        if given:
            raise GdfeError(f"{given[0]}: not an option of --target (2-D design); --target takes --size, --model, "
                            "--pixel, --w-min, --d, --h, --iterations, --radius, --angle, --width, --projection, "
                            "--tolerance")
        if args.size is None:
            raise GdfeError("--size: expected the film's size in mm with --target, got nothing")
        return
    given = [flag for dest, flag in _ONLY_2D if getattr(args, dest) is not None]
    if given:
        raise GdfeError(f"{given[0]}: an option of --target (2-D design), not of the 1-D pipeline")
    if args.no_check and args.tolerance is not None:
        raise GdfeError("--tolerance: a tolerance of the simulated check, which --no-check skips")


def run(args):
    import contextlib

    _check_mode(args)
    folder = output_folder(args.out, args)
    body = _run_target if args.target is not None else _run
    with noting(folder), contextlib.ExitStack() as stack:  # the folder is entered when the files are written
        return body(args, lambda: stack.enter_context(folder))


def _run(args, begin_output):
    import gdfe
    from gdfe import inverse as inv
    from gdfe.fabrication import write_print_package
    from gdfe.fabrication.strips import write_check, write_strip
    from gdfe.cli._progress import Progress, announce_estimate, progress_mode
    from gdfe.io import write_json, write_series
    from gdfe.resources import estimate_run

    ch = _Choices()
    parts, film_file, print_file, positions = _targets(args, ch)
    sketch = parts[0][1].kind == "sketch"
    h = ch.pick("h", args.h, film_file.get("h"), paper.H, "paper", "mm")
    if args.R is not None or ("R" in film_file and args.d is None):
        R = ch.pick("R", args.R, film_file.get("R"), None, "", "")
        d = K = None
    else:
        d = ch.pick("d", args.d, film_file.get("d"), paper.FIG6_D, "paper (Fig. 6 specimens)", "mm")
        K = ch.pick("K", args.K, film_file.get("K"), paper.K, "paper (Eq. 1)")
        R = ch.set("R", float(gdfe.Calibration(K=K, h=h).ratio(d)), "Eq. 3 from d, h, K")
    R = inv.check_open_ratio(R)
    pixel = ch.pick("pixel", args.pixel, print_file.get("pixel"), DEFAULT_PIXEL,
                    "default (the paper gives no printer pixel)", "mm")
    check_length("pixel", pixel)  # before w_min, which defaults to it
    w_min = ch.pick("w_min", args.w_min, print_file.get("w_min"), pixel, "default: one pixel", "mm")
    width = ch.pick("width", args.width, print_file.get("width"), DEFAULT_WIDTH,
                    "default (the studies' strip; not in the paper)", "mm")
    rounding = ch.pick("rounding", args.rounding, None, "carry" if sketch else "nearest",
                       "default for sketches (keeps the accumulated turn)" if sketch else "paper (nearest)")
    clamp = ch.pick("clamp", args.clamp, None, sketch,
                    "default for sketches (sharp turns as hinges)" if sketch else "default (refuse)")
    ch.set("compensate", bool(args.compensate), "command line" if args.compensate else "paper (no compensation)")
    ch.set("check", "none" if args.no_check else "GDFE, the design read back from its masks",
           "command line" if args.no_check else "default")
    if args.tolerance is not None:
        check_positive("--tolerance", args.tolerance)
        ch.set("tolerance", args.tolerance, "command line", "mm")
    elif not args.no_check:
        ch.set("tolerance", f"{100 * STRIP_TOLERANCE:g} % of each part's length", "default (RMS deviation)")
    film = {"h": h, "d": d, "K": K, "nz": 1} if d is not None else {"h": h, "R": R, "nz": 1}
    out = args.out
    begin_output()
    records, designs, status = [], {}, 0
    mode = progress_mode(args)
    with Progress(mode, "designing", total=len(parts), unit=" part") as progress:
        for name, target in parts:
            progress.step(name)
            plan = inv.plan_strip(target, h=h, R=R, cell=pixel, w_min=w_min, rounding=rounding,
                                  clamp=bool(clamp), compensate=args.compensate)
            source = args.text if args.text is not None else str(args.input)
            couples = ", ".join(f"({c.L:.4g}, {c.r:.4g})" for c in target.couples)
            printed = write_strip(plan, out, name, width, film,
                                  comment=f"gdfe design: {target.kind} {target.name!r} from {source}\n"
                                          f"couples (L, r) [mm]: {couples}")
            designs[name] = printed.design
            rec = {"name": name, "target": target.summary(), "plan": plan.summary(),
                   "files": {k: str(v) for k, v in printed.files.items()}, "n_cells": printed.design.n_cells}
            if name in positions:
                rec["positions"], rec["count"] = positions[name], len(positions[name])
            if not args.no_check:
                announce_estimate(estimate_run(printed.design.n_cells), mode, f"the check of {name}: ")
                check = inv.check_strip(plan, design=printed.design)
                tolerance = check.default_tolerance() if args.tolerance is None else args.tolerance
                rep = write_check(check, out, name,
                                  extra={"tolerance_mm": tolerance, "reached": check.reached(tolerance)})
                rec["check"] = rep
                rec["files"]["check"] = str(write_series(check.result, out, name=f"{name}_check"))
                if not check.converged:
                    status = 3
                elif not rep["reached"] and status != 3:
                    status = 4
            records.append(rec)
            progress.advance()
    pkg = write_print_package(out / "print.zip", designs, d=d, K=K,
                              source=args.text if args.text is not None else args.input,
                              extra={"made_by": "gdfe design", "w_min_mm": w_min, "strip_width_mm": width,
                                     **({"copies": {n: len(p) for n, p in positions.items()}} if positions else {})})
    summary = {"choices": ch.as_dict(), "parts": records, "package": str(pkg)}
    if positions:
        summary["letters"] = {"text": args.text, "count": sum(map(len, positions.values())), "distinct": len(positions)}
    write_json(out / "design.json", summary)
    emit(summary, args.json, _text(ch, records, out, pkg), command="design")
    return status


def _text(ch, records, out, pkg):
    lines = ["gdfe design: choices", ch.text()]
    for rec in records:
        plan = rec["plan"]
        copies = (f" (x{rec['count']}: letters {', '.join(map(str, rec['positions']))} of the text)"
                  if rec.get("count", 1) > 1 else "")
        lines.append(f"  {rec['name']}{copies}: {len(rec['target']['couples'])} couples, {plan['hinges']} hinges, strip "
                     f"{plan['strip_mm']:.3f} mm, {rec['n_cells']} cells; masks {Path(rec['files']['top']).name}, "
                     f"{Path(rec['files']['bottom']).name}; design {Path(rec['files']['design']).name}")
        chk = rec.get("check")
        if chk is None:
            continue
        if chk["deviation"] is None:
            lines.append(f"    check: NOT CONVERGED (residual {chk['residual']:.2e} after {chk['iterations']} "
                         "iterations): no deviation reported")
            continue
        dev = chk["deviation"]
        lines.append(f"    check: converged in {chk['iterations']} iterations (residual {chk['residual']:.1e}), "
                     f"{chk['seconds']:.2f} s; deviation RMS {dev['rms_mm']:.3f} mm, max {dev['max_mm']:.3f} mm"
                     + (f", within the tolerance {chk['tolerance_mm']:.3g} mm" if chk["reached"] else ""))
        if not chk["reached"]:
            worst = max((seg for seg in dev["segments"] if seg["max_mm"] is not None), key=lambda seg: seg["rms_mm"])
            lines.append(f"    NOT REACHED: the printed strip misses the target by {dev['rms_mm']:.3f} mm RMS "
                         f"(max {dev['max_mm']:.3f} mm), tolerance {chk['tolerance_mm']:.3g} mm; most in segment "
                         f"{worst['index']} (RMS {worst['rms_mm']:.3f} mm)")
        for seg in dev["segments"]:
            if seg["max_mm"] is None:
                continue
            what = "hinge " if seg["kind"] == "hinge" else f"couple {seg['target_couple']}"
            r = "straight" if seg["r_mm"] == 0 or math.isinf(seg["r_mm"]) else f"r {seg['r_mm']:.3g}"
            lines.append(f"      segment {seg['index']:>2} ({what:<9} L {seg['L_mm']:.3f} mm, {r}): "
                         f"RMS {seg['rms_mm']:.3f} mm, max {seg['max_mm']:.3f} mm")
    lines.append(f"  wrote {out}/ (masks, design files, *_deviation.png/json, *_check.pvd), {pkg}, design.json")
    return "\n".join(lines)


# -- 2-D design from a target surface -------------------------------------------------------------------------
#: Bytes of memory per byte of a target mesh's file while it is read, merged and flattened (meshio's arrays,
#: the merged vertices, the conformal map's sparse system): a generous bound, for the guard before reading.
TARGET_BYTES_PER_FILE_BYTE = 60
#: Seconds per triangle of the checks and the conformal flattening, about (a mesh's file holds some 50
#: bytes per triangle in binary STL, more in text formats).
TARGET_SECONDS_PER_TRIANGLE, TARGET_FILE_BYTES_PER_TRIANGLE = 2e-5, 50


def _check_target_mesh(target):
    """A target mesh's file: its size guarded before it is read, and the surface checked (one disc-like
    piece, manifold, oriented, not passing through itself) before it is flattened."""
    from pathlib import Path

    from gdfe._validation import check_surface_mesh
    from gdfe.inverse2d import MESH_SUFFIXES, read_triangle_mesh
    from gdfe.resources import check_work

    path = Path(target)
    if path.suffix.lower() not in MESH_SUFFIXES or not path.is_file():
        return  # an analytic target, or a missing file that make_target names
    size = path.stat().st_size
    triangles = size / TARGET_FILE_BYTES_PER_TRIANGLE
    check_work(f"--target {path.name}", size * TARGET_BYTES_PER_FILE_BYTE,
               f"a mesh file of {size / 2**20:.4g} MiB (about {triangles:.3g} triangles)",
               "decimate the mesh (e.g. in MeshLab) first", seconds=triangles * TARGET_SECONDS_PER_TRIANGLE)
    V, T = read_triangle_mesh(path)
    check_surface_mesh(f"--target {path.name}", V, T)


def _run_target(args, begin_output):
    from gdfe.cli._progress import Progress, announce_estimate, progress_mode
    from gdfe.inverse2d import design_surface, make_target, write_design
    from gdfe.resources import estimate_design
    from gdfe.model import as_model, paper_model

    ch = _Choices()
    _check_target_mesh(args.target)
    target = make_target(args.target, args.size, radius=args.radius, angle=args.angle,
                         width=args.width if args.target == "twist" else None)
    if args.width is not None and args.target != "twist":
        raise GdfeError(f"--width: the strip width of the twist target (or of a 1-D strip), not of {args.target!r}")
    ch.set("target", f"{target.name}: {target.source}", "command line")
    film_mm = " x ".join(f"{v:.4g}" for v in target.film_size)
    ch.set("size", float(args.size), "command line", "mm")
    ch.set("film", f"{film_mm} mm" + (" (the mesh's flattened outline)" if target.kind == "mesh" else ""),
           "from the size")
    h = ch.pick("h", args.h, None, paper.H, "paper", "mm")
    d = ch.pick("d", args.d, None, paper.FIG6_D, "paper (Fig. 6 specimens)", "mm")
    model = as_model(args.model) if args.model is not None else paper_model()
    n_draws = check_uncertainty(args, model if args.model is not None else None)
    ch.set("model", model.name + (f" ({args.model})" if args.model else ""),
           "command line" if args.model else "paper (Eq. 3)")
    if args.model is not None:  # the file's content, so that the design can be traced to it
        import hashlib

        ch.set("model_sha256", hashlib.sha256(Path(args.model).read_bytes()).hexdigest(), "the model file")
    pixel = ch.pick("pixel", args.pixel, None, DEFAULT_PIXEL, "default (the paper gives no printer pixel)", "mm")
    w_min = ch.pick("w_min", args.w_min, None, pixel, "default: one pixel", "mm")
    iterations = ch.pick("iterations", args.iterations, None, DEFAULT_ITERATIONS, "default")
    projection = ch.pick("projection", args.projection, None, "halftone",
                         "default (error diffusion of the coating fractions)")
    tolerance = ch.pick("tolerance", args.tolerance, None, TOLERANCE_FRACTION * float(max(target.film_size)),
                        f"default: {100 * TOLERANCE_FRACTION:g} % of the film's size", "mm")

    mode = progress_mode(args)
    if isinstance(pixel, (int, float)) and pixel > 0 and isinstance(iterations, int) and iterations >= 0:
        cells = math.prod(max(1, round(float(v) / pixel)) for v in target.film_size)
        announce_estimate(estimate_design(cells, iterations), mode)

    def callback(rec):  # the bar counts folds: L-BFGS-B evaluations, about one per iteration
        n = rec["evaluation"]
        progress.step(f"after {n} fold{'s' if n != 1 else ''} (RMS {rec['rms_mm']:.3g} mm)")
        progress.advance()

    with Progress(mode, "designing", total=iterations + 1 if isinstance(iterations, int) else None,
                  unit=" fold") as progress:
        result = design_surface(target, pixel=pixel, w_min=w_min, d=d, h=h, model=model, iterations=iterations,
                                projection=projection, tolerance_mm=tolerance, callback=callback)
    opts = result.options
    ch.set("block", f"{opts['block_pixels']} x {opts['block_pixels']} pixels", "from w_min and pixel")
    ch.set("filter radius", opts["filter_radius_mm"], "default: two blocks", "mm")
    begin_output()
    name = target.name
    written = write_design(result, args.out, name=name)
    summary = written.summary
    ens = None
    if n_draws is not None:
        ens = _target_ensemble(result, model, n_draws, args)
        summary["uncertainty"] = {**ens.as_dict(), "within_tolerance": ens.within("rms_mm", result.tolerance_mm)}
        summary["files"].update({k: str(v) for k, v in write_ensemble(
            ens, result.printable, args.out, f"{name}_check", f"{name}: the printed fold under {n_draws} draws",
            threshold=("tolerance_mm", result.tolerance_mm), png_name=f"{name}_uncertainty.png").items()})
        from gdfe.io import write_json

        write_json(written.files["json"], summary)
    text = _text_target(ch, result, args.out, written.files)
    if ens is not None:
        w = summary["uncertainty"]["within_tolerance"]
        text += (f"\n{ens.text()}\n    within the tolerance ({result.tolerance_mm:.3g} mm RMS): probability "
                 f"{w['probability']:.2f} ({100 * ens.level:g} % interval {w['interval'][0]:.2f}-"
                 f"{w['interval'][1]:.2f}, {w['draws']} draws)")
    emit(summary, args.json, text, command="design")
    if not result.printable.converged:
        return 3
    return 0 if result.reached else 4


class _TargetDistance:
    """The distance of a fold of the printed design from the target surface (RMS and largest, mm): the measure of
    an ensemble (:func:`gdfe.ensemble.fold_ensemble`), which travels to the workers."""

    def __init__(self, mid, surface, designed):
        self.mid, self.surface, self.designed = mid, surface, designed

    def __call__(self, res):
        from gdfe.inverse2d.distance import surface_distance

        d = surface_distance(self.mid.points(res.points), self.mid.triangles, self.surface, designed=self.designed)
        return [], {"rms_mm": d.rms_mm, "max_mm": d.max_mm}


def _target_ensemble(result, model, n, args):
    """The printed design of ``result`` folded under ``n`` draws of ``model``, measured against the target."""
    mid = result.film.mid
    measure = _TargetDistance(mid, result.target_surface, result.target.point(mid.flat, result.sigma))
    return run_ensemble(result.printable.design, model, n, args, result.printable, measure, [])


def _distance_text(d):
    return f"RMS {d.rms_mm:.4g} mm, max {d.max_mm:.4g} mm, Hausdorff {d.hausdorff_mm:.4g} mm"


def _text_target(ch, r, out, files):
    film = r.film
    lines = ["gdfe design --target: choices", ch.text()]
    lines.append(f"  film: {film.shape[0]} x {film.shape[1]} pixels = {film.shape[0] * film.pixel:.4g} x "
                 f"{film.shape[1] * film.pixel:.4g} mm, {film.n_cells} cells; a free face contracts by c0 = {film.c0:.4f}")
    lines.append(f"  placement: sigma {r.sigma:.4g}; reachability: {r.reachability.text()}")
    if r.closest is not None:
        lines.append(f"  closest within reach: {r.closest['text']}")
    lines.append(f"  optimisation: {r.iterations} L-BFGS-B iterations, {r.evaluations} evaluations (fold + adjoint), "
                 f"{r.seconds['optimisation']:.1f} s; {r.message}"
                 + (f"; {r.unconverged_folds} folds did not converge" if r.unconverged_folds else ""))
    lines.append(f"  start (placement estimate), folded from flat: {_distance_text(r.initial_distance)}")
    lines.append(f"  relaxed design, folded from flat:             {_distance_text(r.relaxed_distance)}")
    pd_ = r.printable
    top = r.top[film.mask] if film.mask is not None else r.top
    bottom = r.bottom[film.mask] if film.mask is not None else r.bottom
    lines.append(f"  printed fold (the masks), folded from flat:   {_distance_text(r.printable_distance)}; "
                 f"{'converged' if pd_.converged else 'NOT CONVERGED'} in {pd_.iterations} iterations")
    lines.append(f"  masks: top {100 * top.mean():.1f} % coated, bottom {100 * bottom.mean():.1f} % coated, "
                 f"{'respect' if r.masks_ok else 'DO NOT respect'} w_min")
    lines.append(f"  {r.verdict()}")
    lines.append(f"  seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in r.seconds.items()))
    names = ", ".join(Path(v).name for k, v in files.items())
    lines.append(f"  wrote {out}/ ({names})")
    return "\n".join(lines)
