"""``gdfe simulate``: a design file, simulated; its VTU series, picture and numbers written."""

from __future__ import annotations

from pathlib import Path

from gdfe.cli._common import (contact_text, emit, exit_status, file_path, iterations_text, json_arg, noting, out_arg,
                               output_folder, process_arg, shown, solve, solver_args, status_word, write_outputs)
from gdfe.cli._progress import progress_mode
from gdfe.cli._uncertainty import check_uncertainty, run_ensemble, uncertainty_args, write_ensemble

__all__ = ["register", "run"]


def register(sub):
    p = sub.add_parser("simulate", help="simulate a design file (TOML)",
                       description="Simulate a TOML design; write a VTU series, a PNG and a JSON summary.")
    p.add_argument("design", type=file_path, help="design file (.toml), or a drawing (.svg, .fold)")
    out_arg(p, required=True)
    p.add_argument("--model", type=file_path, default=None,
                   help="deformation model file (TOML) replacing the design's own (its cells' R from their d)")
    process_arg(p)
    solver_args(p, defaults_from_file=True)
    p.add_argument("--export", type=_export_formats, default=(), metavar="stl[,obj,ply,fold,html,zip]",
                   help="also write the folded shape beside the VTU series: the film's surface as STL, OBJ, "
                        "PLY; every frame as FOLD; an interactive offline 3-D page (html); the design's print "
                        "package of masks (zip)")
    p.add_argument("--export-frame", type=int, default=-1, metavar="K",
                   help="frame of the ramp to export as STL/OBJ/PLY (default -1: the folded shape; 0: flat)")
    uncertainty_args(p)
    json_arg(p, "the summary")
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
    folder = output_folder(args.out, args)
    with noting(folder):
        return _run(args, folder)


def _measured(res, design):
    """The fold angles measured on the result: of a hinge specimen, of a FOLD file's creases, or
    between the rigid panels its contracting cells join (:func:`gdfe.measure.panel_angles`)."""
    import gdfe
    from gdfe.measure import panel_angles

    if "panel_a" in design.regions and "panel_b" in design.regions:
        return {"fold_angle_rad": gdfe.fold_angle(res)}
    if design.meta.get("kind") == "fold" and design.meta.get("hinges") is not None:
        from gdfe.fabrication import crease_angles

        return {"crease_angles": crease_angles(res)}
    return {"panel_angles": panel_angles(res)}


def _angles_text(summary):
    if "fold_angle_rad" in summary:
        return f"  fold angle {shown(summary['fold_angle_rad'], 4):.4f} rad\n"
    rows = summary.get("crease_angles")
    if rows is not None:
        label, key = "crease", "edge"
        if not rows:  # a FOLD design: a crease's angle is measured between the two faces it joins
            return ("  fold angles: none measured (no crease joins two faces of the FOLD file's faces_vertices; "
                    "without faces_vertices a crease's faces are not known)\n")
    else:
        rows, label, key = summary.get("panel_angles", []), "panels", "panels"
    if not rows:
        return "  fold angles: none measured (no two rigid panels joined by contracting cells)\n"
    listed = ", ".join(f"{label} {'-'.join(map(str, r[key])) if isinstance(r[key], list) else r[key]}: "
                       f"{shown(r['angle_rad'], 4):.4f} rad" for r in rows[:8])
    more = f" and {len(rows) - 8} more (in result.json)" if len(rows) > 8 else ""
    return f"  fold angles ({len(rows)}) {listed}{more}\n"


def _film_text(design):
    s = design.summary()
    if s.get("d_mm") is not None:
        d = f"d = {s['d_mm']:g} mm"
    elif "d_mm_range" in s:
        lo, hi = s["d_mm_range"]
        d = f"d = {lo:g} mm" if lo == hi else f"d = {lo:g}-{hi:g} mm"
    else:
        d = "R given (no d)"
    return f"  film h = {design.h:g} mm, {d}, nz = {int(design.mesh.cell_k.max()) + 1}\n"


def _run(args, folder):
    import gdfe

    design, options = gdfe.load_design(args.design, model=args.model, process=args.process)
    n_draws = check_uncertainty(args, design.model)
    res = solve(design, args, options, source=args.design.name)
    summary = {"design": str(args.design), **design.summary(), **res.summary(), "status": status_word(res),
               "frame_iterations": list(res.frame_iterations), "nz": int(design.mesh.cell_k.max()) + 1}
    if design.model is not None:
        summary["model"] = design.model.as_dict()
    summary.update(_measured(res, design))
    summary["bbox_mm"] = [res.points.min(0).tolist(), res.points.max(0).tolist()]
    summary["title"] = f"{args.design.stem}: {_angles_text(summary).strip()}"
    ens = None
    if n_draws is not None:
        ens = run_ensemble(design, design.model, n_draws, args, res, _ensemble_measure,
                           _angle_labels(summary), process=args.process)
        summary["uncertainty"] = ens.as_dict()
    exported = {}
    with folder:
        folder.status.update(converged=bool(res.converged), status=status_word(res))
        if args.export and res.converged:  # a shape that is not an equilibrium is not exported
            from gdfe.fabrication import export_result

            exported = export_result(res, args.out, args.design.stem, args.export, frame=args.export_frame)
            summary["exported"] = {k: str(v) for k, v in exported.items()}
        summary["files"] = write_outputs(res, args.out, args.design.stem, summary, progress=progress_mode(args),
                                         command="simulate")
        if ens is not None:
            summary["files"].update(write_ensemble(ens, res, args.out, args.design.stem, summary["title"]))
    text = (f"{args.design}: {design.n_cells} elements, {iterations_text(res)}, residual {res.residual:.1e}, "
            f"{res.seconds:.2f} s\n"
            + _film_text(design)
            + (design.model.text() + "\n" if design.model is not None else "")
            + _angles_text(summary)
            + f"  wrote {summary['files']['pvd']} (open in ParaView), {summary['files']['png']}, "
            f"{summary['files']['json']}"
            + (f"\n  exported {', '.join(str(v) for v in exported.values())}" if exported else "")
            + ("\n  not exported: the solver did not converge" if args.export and not res.converged else ""))
    text += "\n" + contact_text(res)
    if ens is not None:
        text += "\n" + ens.text()
    emit(summary, args.json, text, command="simulate")
    return exit_status(res, allow_penetration=args.allow_penetration)


#: A flat print at least this many times longer (x) than wide (y) is a strip: its mid-line's turn and end gap
#: are measured in an ensemble (:func:`_ensemble_measure`).
STRIP_ASPECT = 5.0


def _angle_labels(summary):
    if "fold_angle_rad" in summary:
        return ["hinge"]
    if "crease_angles" in summary:
        return [f"crease {r['edge']}" for r in summary["crease_angles"]]
    return [f"panels {'-'.join(map(str, r['panels']))}" for r in summary["panel_angles"]]


def _ensemble_measure(res):
    """The fold angles of :func:`_measured` and, of a strip, its mid-line's turn [rad] and end gap [mm], for
    :func:`gdfe.ensemble.fold_ensemble` (module-level: it travels to the workers)."""
    import numpy as np

    m = _measured(res, res.design)
    if "fold_angle_rad" in m:
        angles = [m["fold_angle_rad"]]
    else:
        angles = [r["angle_rad"] for r in m.get("crease_angles", m.get("panel_angles", []))]
    measures = {}
    extent = np.ptp(res.design.mesh.points, axis=0)
    if extent[0] >= STRIP_ASPECT * extent[1]:
        import gdfe
        from gdfe.inverse import strip_midline

        _, uv, _ = strip_midline(res)
        measures = {"turn_rad": float(gdfe.curvature_profile(res)["turn"]),
                    "end_gap_mm": float(np.linalg.norm(uv[-1] - uv[0]))}
    return angles, measures
