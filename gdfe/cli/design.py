"""``gdfe design``: the paper's 1-D design pipeline (Sec. 4.2) from couples, a sketch or letters to printer files.

Input: a couples file (``.toml``), a sketch (``.csv`` of points, or an ``.svg`` stroke) or
``--text`` (letters of Figure 9). For each part: the strip pattern at the printer's pixel,
its masks (``NAME_top.png``, ``NAME_bottom.png``: 1-bit, black = passive, DPI set) and
design file (``NAME.toml``), the design read back from those files and simulated
(``NAME_check.pvd``), and its deviation from the target (``NAME_deviation.png``,
``NAME_deviation.json``: RMS and largest distance, overall and per segment); then a print
package of every part (``print.zip``) and ``design.json``. Every choice is printed with where
it came from.
"""

from __future__ import annotations

import math
from pathlib import Path

from gdfe import paper
from gdfe._validation import GdfeError, check_length
from gdfe.cli._common import emit, file_path, json_arg, noting, out_arg, output_folder

__all__ = ["register", "run"]

#: Defaults of the choices that are not the paper's, with why.
DEFAULT_PIXEL = 0.125  # mm: the pattern cell of the studies' default resolution
DEFAULT_WIDTH = 0.5  # mm: the studies' strip (narrow: the cylindrical fold Eq. 2 assumes)
DEFAULT_PENALTY = 0.1  # the paper's third level (Fig. 10)


def register(sub):
    p = sub.add_parser("design", help="design a strip from couples, a sketch or letters (paper Sec. 4.2)",
                       description="The 1-D design pipeline: couples (TOML), a sketch (CSV of points or an SVG "
                                   "stroke) or --text letters -> printer masks, a design file, the simulated "
                                   "check and its deviation report.")
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
    p.add_argument("--spacing", type=float, default=0.2,
                   help="sketch SVG: sampling of curved segments [mm] (default 0.2)")
    p.add_argument("--no-check", action="store_true", help="write the files, skip the simulated check")
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
    """The parts to design: [(name, target)], and the file's [film] and [print] entries."""
    from gdfe import inverse as inv

    if (args.input is None) == (args.text is None):
        raise GdfeError("give one input: a couples .toml, a sketch .csv/.svg, or --text LETTERS")
    if args.text is not None:
        glyphs = inv.text_glyphs(args.text)
        ch.set("input", f"letters {args.text!r} (Figure 9 glyphs)", "command line")
        return [(f"{k + 1:02d}_{g.char}", inv.target_from_letter(g.char)) for k, g in enumerate(glyphs)], {}, {}
    path = args.input
    suffix = path.suffix.lower()
    if suffix == ".toml":
        cf = inv.read_couples_toml(path)
        ch.set("input", f"couples {path}", "command line")
        return [(cf.target.name, cf.target)], cf.film, cf.print
    if suffix in (".csv", ".txt", ".svg"):
        P = inv.read_sketch(path, element_id=args.svg_id, spacing=args.spacing)
        ch.set("input", f"sketch {path} ({len(P)} points)", "command line")
        penalty = ch.pick("penalty", args.penalty, None, DEFAULT_PENALTY, "paper (Fig. 10, third level)")
        weights = ch.pick("weights", args.weights, None, "plain", "paper (sum over the vertices)")
        target = inv.target_from_sketch(P, penalty, weights=None if weights == "plain" else "length",
                                        name=path.stem)
        ch.set("segments", target.fit.segmentation.m, "fitted")
        return [(path.stem, target)], {}, {}
    raise GdfeError(f"input: expected a .toml (couples), .csv or .svg (sketch) file, got {path.name!r}")


def run(args):
    import contextlib

    folder = output_folder(args.out, args)
    with noting(folder), contextlib.ExitStack() as stack:  # the folder is entered when the files are written
        return _run(args, lambda: stack.enter_context(folder))


def _run(args, begin_output):
    import gdfe
    from gdfe import inverse as inv
    from gdfe.fabrication import write_print_package
    from gdfe.fabrication.strips import write_check, write_strip
    from gdfe.io import write_json, write_series

    ch = _Choices()
    parts, film_file, print_file = _targets(args, ch)
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
    film = {"h": h, "d": d, "K": K, "nz": 1} if d is not None else {"h": h, "R": R, "nz": 1}
    out = args.out
    begin_output()
    records, designs, status = [], {}, 0
    cache = {}
    for name, target in parts:
        plan = inv.plan_strip(target, h=h, R=R, cell=pixel, w_min=w_min, rounding=rounding, clamp=bool(clamp),
                              compensate=args.compensate)
        source = args.text if args.text is not None else str(args.input)
        couples = ", ".join(f"({c.L:.4g}, {c.r:.4g})" for c in target.couples)
        printed = write_strip(plan, out, name, width, film,
                              comment=f"gdfe design: {target.kind} {target.name!r} from {source}\n"
                                      f"couples (L, r) [mm]: {couples}")
        designs[name] = printed.design
        rec = {"name": name, "target": target.summary(), "plan": plan.summary(),
               "files": {k: str(v) for k, v in printed.files.items()}, "n_cells": printed.design.n_cells}
        if not args.no_check:
            key = (target.kind, target.name)
            if key not in cache:
                check = inv.check_strip(plan, design=printed.design)
                cache[key] = check
            check = cache[key]
            rep = write_check(check, out, name)
            rec["check"] = rep
            rec["files"]["check"] = str(write_series(check.result, out, name=f"{name}_check"))
            if not check.converged:
                status = 3
        records.append(rec)
    pkg = write_print_package(out / "print.zip", designs, d=d, K=K,
                              source=args.text if args.text is not None else args.input,
                              extra={"made_by": "gdfe design", "w_min_mm": w_min, "strip_width_mm": width})
    summary = {"choices": ch.as_dict(), "parts": records, "package": str(pkg)}
    write_json(out / "design.json", summary)
    emit(summary, args.json, _text(ch, records, out, pkg))
    return status


def _text(ch, records, out, pkg):
    lines = ["gdfe design: choices", ch.text()]
    for rec in records:
        plan = rec["plan"]
        lines.append(f"  {rec['name']}: {len(rec['target']['couples'])} couples, {plan['hinges']} hinges, strip "
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
                     f"{chk['seconds']:.2f} s; deviation RMS {dev['rms_mm']:.3f} mm, max {dev['max_mm']:.3f} mm")
        for seg in dev["segments"]:
            if seg["max_mm"] is None:
                continue
            what = "hinge " if seg["kind"] == "hinge" else f"couple {seg['target_couple']}"
            r = "straight" if seg["r_mm"] == 0 or math.isinf(seg["r_mm"]) else f"r {seg['r_mm']:.3g}"
            lines.append(f"      segment {seg['index']:>2} ({what:<9} L {seg['L_mm']:.3f} mm, {r}): "
                         f"RMS {seg['rms_mm']:.3f} mm, max {seg['max_mm']:.3f} mm")
    lines.append(f"  wrote {out}/ (masks, design files, *_deviation.png/json, *_check.pvd), {pkg}, design.json")
    return "\n".join(lines)
