"""``gdfe simulate``: a design file, simulated; its VTU series, picture and numbers written."""

from __future__ import annotations

from pathlib import Path

from gdfe.cli._common import contact_text, emit, exit_status, process_arg, solve, solver_args, write_outputs

__all__ = ["register", "run"]


def register(sub):
    p = sub.add_parser("simulate", help="simulate a design file (TOML)",
                       description="Simulate a TOML design; write a VTU series, a PNG and a JSON summary.")
    p.add_argument("design", type=Path, help="design file (.toml), or a drawing (.svg, .fold)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--model", type=Path, default=None,
                   help="deformation model file (TOML) replacing the design's own (its cells' R from their d)")
    process_arg(p)
    solver_args(p, defaults_from_file=True)
    p.add_argument("--export", type=_export_formats, default=(), metavar="stl[,obj,ply,fold,html,zip]",
                   help="also write the folded shape beside the VTU series: the film's surface as STL, OBJ, "
                        "PLY; every frame as FOLD; an interactive offline 3-D page (html); the design's print "
                        "package of masks (zip)")
    p.add_argument("--export-frame", type=int, default=-1, metavar="K",
                   help="frame of the ramp to export as STL/OBJ/PLY (default -1: the folded shape; 0: flat)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def _export_formats(text):
    import argparse

    from gdfe.fabrication import EXPORT_FORMATS

    formats = [f.strip().lower() for f in text.split(",") if f.strip()]
    bad = [f for f in formats if f not in EXPORT_FORMATS]
    if bad or not formats:
        raise argparse.ArgumentTypeError(f"expected formats among {', '.join(EXPORT_FORMATS)} separated by "
                                         f"commas, got {text!r}")
    return tuple(dict.fromkeys(formats))


def run(args):
    import gdfe

    design, options = gdfe.load_design(args.design, model=args.model, process=args.process)
    res = solve(design, args, options)
    summary = {"design": str(args.design), **design.summary(), **res.summary()}
    if design.model is not None:
        summary["model"] = design.model.as_dict()
    if "panel_a" in design.regions and "panel_b" in design.regions:
        summary["fold_angle_rad"] = gdfe.fold_angle(res)
    summary["bbox_mm"] = [res.points.min(0).tolist(), res.points.max(0).tolist()]
    summary["title"] = f"{args.design.stem}: {design.n_cells} elements"
    exported = {}
    if args.export and res.converged:  # a shape that is not an equilibrium is not exported
        from gdfe.fabrication import export_result

        exported = export_result(res, args.out, args.design.stem, args.export, frame=args.export_frame)
        summary["exported"] = {k: str(v) for k, v in exported.items()}
    summary["files"] = write_outputs(res, args.out, args.design.stem, summary)
    text = (f"{args.design}: {design.n_cells} elements, "
            f"{'converged' if res.converged else 'NOT CONVERGED'} in {res.iterations} iterations "
            f"(residual {res.residual:.1e}), {res.seconds:.2f} s\n"
            + (design.model.text() + "\n" if design.model is not None else "")
            + (f"  fold angle {summary['fold_angle_rad']:.4f} rad\n" if "fold_angle_rad" in summary else "")
            + f"  wrote {summary['files']['pvd']} (open in ParaView), {summary['files']['png']}, "
            f"{summary['files']['json']}"
            + (f"\n  exported {', '.join(str(v) for v in exported.values())}" if exported else "")
            + ("\n  not exported: the solver did not converge" if args.export and not res.converged else ""))
    text += "\n" + contact_text(res)
    emit(summary, args.json, text)
    return exit_status(res, allow_penetration=args.allow_penetration)
