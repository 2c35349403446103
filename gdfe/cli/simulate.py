"""``gdfe simulate``: a design file, simulated; its VTU series, picture and numbers written."""

from __future__ import annotations

from pathlib import Path

from gdfe.cli._common import emit, exit_status, solve, solver_args, write_outputs

__all__ = ["register", "run"]


def register(sub):
    p = sub.add_parser("simulate", help="simulate a design file (TOML)",
                       description="Simulate a TOML design; write a VTU series, a PNG and a JSON summary.")
    p.add_argument("design", type=Path, help="design file (.toml)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--model", type=Path, default=None,
                   help="deformation model file (TOML) replacing the design's own (its cells' R from their d)")
    solver_args(p, defaults_from_file=True)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args):
    import gdfe

    design, options = gdfe.load_design(args.design, model=args.model)
    res = solve(design, args, options)
    summary = {"design": str(args.design), **design.summary(), **res.summary()}
    if design.model is not None:
        summary["model"] = design.model.as_dict()
    if "panel_a" in design.regions and "panel_b" in design.regions:
        summary["fold_angle_rad"] = gdfe.fold_angle(res)
    summary["bbox_mm"] = [res.points.min(0).tolist(), res.points.max(0).tolist()]
    summary["title"] = f"{args.design.stem}: {design.n_cells} elements"
    summary["files"] = write_outputs(res, args.out, args.design.stem, summary)
    text = (f"{args.design}: {design.n_cells} elements, "
            f"{'converged' if res.converged else 'NOT CONVERGED'} in {res.iterations} iterations "
            f"(residual {res.residual:.1e}), {res.seconds:.2f} s\n"
            + (design.model.text() + "\n" if design.model is not None else "")
            + (f"  fold angle {summary['fold_angle_rad']:.4f} rad\n" if "fold_angle_rad" in summary else "")
            + f"  wrote {summary['files']['pvd']} (open in ParaView), {summary['files']['png']}, "
            f"{summary['files']['json']}")
    emit(summary, args.json, text)
    return exit_status(res)
