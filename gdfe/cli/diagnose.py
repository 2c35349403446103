"""``gdfe diagnose`` (fold-angle data) and ``gdfe diagnose-shape`` (scans against simulations)."""

from __future__ import annotations

from pathlib import Path

from gdfe._validation import GdfeError, check_positive
from gdfe.cli._common import emit, file_path, json_arg, new_toml_path, noting, output_folder
from gdfe.diagnosis.baselines import BASELINES
from gdfe.diagnosis.columns import ROLES, parse_role
from gdfe.diagnosis.forward import CELLS
from gdfe.diagnosis.shape import ALIGNMENTS

__all__ = ["register"]


def register(sub):
    p = sub.add_parser(
        "diagnose", help="where folding tests and the calibrated GDFE hinge part ways, and why",
        description="Fit the calibrated GDFE hinge (Eq. 1-3) to folding tests, locate its residuals, "
                    "rank a catalogue of physical effects by held-out error, and give a verdict against "
                    "the noise: no_gap, explained, measurement_issue, partly_explained, not_explained or structure_remains. A numeric "
                    "extra column the folds follow is a factor (factor[COL]) unless --role declares it a "
                    "process variable (then partial_activation[COL]); text columns with repeated labels are "
                    "groups (leave-one-group-out; factor[COL], or batch[COL] for a declared group role); "
                    "a sigma_rad column is the noise of each test. Fold angles are magnitudes (>= 0); "
                    "--signed takes |alpha|. Exit status 3 when the chosen model's fit did not converge.")
    p.add_argument("data", type=file_path, help="CSV with columns L_mm, d_mm, h_mm, alpha_rad (more allowed)")
    p.add_argument("--sigma", type=float, default=None, metavar="S",
                   help="noise of the measured angles [rad] (default: a sigma_rad column, else replicate "
                        "rows, else unknown)")
    p.add_argument("--process", default=None, metavar="COL[,COL]",
                   help="numeric columns a monotone dependence may be fitted on (factor[COL], or "
                        "partial_activation[COL] for a declared process role; default: every numeric column "
                        "that varies; '' for none)")
    p.add_argument("--role", action="append", default=[], metavar="COL=ROLE",
                   help="declare what a column is (repeatable), e.g. T_C=oven_temperature; roles: "
                        + ", ".join(ROLES))
    p.add_argument("--baseline", choices=BASELINES, default="eq1",
                   help="the form of the law the gap is measured against (default eq1, Eq. 1 as printed); "
                        "every form is fitted and the report splits the gap into form and effects")
    p.add_argument("--signed", action="store_true",
                   help="the angles are signed (a direction): take |alpha| (default: a negative angle is an error)")
    json_arg(p, "the diagnosis", dest="json_out")
    p.add_argument("--report", type=_folder, metavar="DIR",
                   help="write plots and summary.md into this folder (complete, or marked incomplete)")
    p.add_argument("--group", help="column with a group label for leave-one-group-out "
                                   "(default: 'group' if present)")
    p.add_argument("--no-pairs", action="store_true", help="fit single effects only")
    p.add_argument("--check", choices=["none", *CELLS], default="coarse",
                   help="resolution of the GDFE solves that check the closed forms (default coarse)")
    p.add_argument("--model-out", type=new_toml_path, default=None, metavar="M.toml",
                   help="save the chosen model as a deformation model file (gdfe simulate/hinge --model)")
    p.add_argument("--effect", default=None, metavar="NAME",
                   help="with --model-out: save this fitted model of the catalogue instead of the chosen one "
                        "(e.g. saturation, cure_depth+hinge_length)")
    p.set_defaults(func=_cmd_diagnose)

    p = sub.add_parser(
        "diagnose-shape", help="where a scanned part deviates from the simulation of its design",
        description="Align a measured shape (PLY, VTU, OBJ or CSV of x,y,z) to the simulated design, "
                    "check that it is the part, report the deviation per element and region, and fit a "
                    "per-region correction of the contraction ratio. Exit status 4 when the scan does not "
                    "match the design (another part, degenerate or random points, a scale error), 3 when a "
                    "simulation did not converge.")
    p.add_argument("design", type=file_path, help="design file (.toml)")
    p.add_argument("measured", type=file_path, help="point cloud or mesh: .ply, .vtu, .obj or .csv (x,y,z)")
    json_arg(p, dest="json_out")
    p.add_argument("--report", type=_folder, metavar="DIR",
                   help="write plots and summary.md into this folder (complete, or marked incomplete)")
    p.add_argument("--align", choices=ALIGNMENTS, default="auto",
                   help="correspondences (a mesh of the design) or ICP; default: decide from the file")
    p.add_argument("--no-correct", action="store_true", help="skip the per-region correction fit")
    p.add_argument("--floor", type=float, metavar="MM",
                   help="model floor: the RMS deviation [mm] of a scan of a part printed as designed from its "
                        "simulation; a gap is localised only beyond it")
    p.set_defaults(func=_cmd_diagnose_shape)


def _folder(text):
    import argparse

    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected the name of a folder, got {text!r}")
    return Path(text)


def _cmd_diagnose(args):
    folder = output_folder(args.report, args, name="--report")
    with noting(folder):
        return _diagnose(args, folder)


def _diagnose(args, folder):
    from gdfe.diagnosis.angles import diagnose

    if args.sigma is not None:
        check_positive("--sigma", args.sigma)
    if args.effect is not None and args.model_out is None:
        raise GdfeError("--effect: expected --model-out too (it names the model to save)")
    process = None if args.process is None else [c.strip() for c in args.process.split(",") if c.strip()]
    roles = dict(parse_role(r) for r in args.role)
    diag = diagnose(args.data, group=args.group, sigma=args.sigma, process=process, pairs=not args.no_pairs,
                    check=None if args.check == "none" else args.check, roles=roles, baseline=args.baseline,
                    signed=args.signed)
    obj = diag.as_dict()
    text = diag.text()
    if args.model_out is not None:
        obj["model_file"], line = _save_model(diag, args)
        text += "\n" + line
    if folder is not None:
        from gdfe.diagnosis.figures import write_report

        with folder:
            files = write_report(diag, args.report)
        obj["report"] = files
        text += f"\nreport: {files['summary']}"
    emit(obj, args.json_out, text, command="diagnose")
    return 0 if diag.best.success else 3


def _save_model(diag, args):
    """The chosen (or ``--effect``) fit as a deformation model file; returns (path, text)."""
    fits = [diag.baseline] + list(diag.fits)
    if args.effect is None:
        fit = diag.best
    else:
        names = [diag.display(f) for f in fits]
        matches = [f for f in fits if args.effect in (f.name, diag.display(f))
                   or f.model.name.split("[")[0] == args.effect]
        if not matches:
            raise GdfeError(f"--effect: expected one of the fitted models {', '.join(names)}, got {args.effect!r}")
        fit = matches[0]
    if not fit.model.effects and diag.baseline_name != "eq1":
        raise GdfeError(f"--model-out: the {diag.baseline_name} baseline is not a deformation model of the GDFE hinge; "
                        f"save a model of the catalogue (--effect NAME), or calibrate the reading with gdfe calibrate")
    from gdfe.predictive import from_diagnosis

    model = from_diagnosis(diag, fit, data=args.data)
    model.save(args.model_out)
    members = "".join(f"\n  {m.model.name}: weight {m.weight:.3f}" for m in model.ensemble)
    text = (f"wrote {args.model_out} (deformation model {model.name!r}, with its parameters' covariance and noise"
            + (f"; the named set weighted by {model.weighting} of held-out densities:{members}" if members else "")
            + "; gdfe predict reads it)") + "".join(f"\nWARNING: {w}" for w in model.warnings)
    return str(args.model_out), text


def _cmd_diagnose_shape(args):
    folder = output_folder(args.report, args, name="--report")
    with noting(folder):
        return _diagnose_shape(args, folder)


def _diagnose_shape(args, folder):
    from gdfe.diagnosis.shape import diagnose_shape

    res = diagnose_shape(args.design, args.measured, align=args.align, correct=not args.no_correct,
                         floor=args.floor)
    obj = res.as_dict()
    text = res.text()
    if folder is not None:
        from gdfe.diagnosis.figures import write_shape_report

        with folder:
            obj["report"] = write_shape_report(res, args.report)
        text += f"\nreport: {obj['report']['summary']}"
    emit(obj, args.json_out, text, command="diagnose-shape")
    if not res.matches:
        return 4
    return 0 if res.converged else 3
