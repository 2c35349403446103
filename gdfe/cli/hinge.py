"""``gdfe hinge``: the paper's folding specimen, simulated and compared with Eq. 1."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

from gdfe import paper
from gdfe._validation import GdfeError, check_int
from gdfe.cli._common import (contact_fields, contact_text, emit, exit_status, file_path, iterations_text, json_arg,
                               noting, out_arg, output_folder, process_arg, shown, solve, solver_args, status_word,
                               write_outputs)
from gdfe.cli._progress import progress_mode
from gdfe.cli._uncertainty import check_uncertainty, run_ensemble, uncertainty_args, write_ensemble
from gdfe.mesh import DEFAULT_NZ

__all__ = ["register", "run"]


def register(sub):
    p = sub.add_parser("hinge", help="simulate the paper's hinge specimen (two rigid panels, one hinge)",
                       description="Simulate the paper's folding specimen and compare with Eq. 1.")
    p.add_argument("--length", "-L", type=float, required=True, help="hinge (fold) width L [mm]")
    p.add_argument("--d", type=float, help="passive-layer thickness d [mm] (R from Eq. 3)")
    p.add_argument("--h", type=float, default=paper.H, help=f"active-film thickness h [mm] (default {paper.H:g})")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--K", type=float, default=None, help=f"coefficient K of Eq. 1 (default {paper.K:g})")
    g.add_argument("--R", type=float, default=None, help="contraction ratio, overriding Eq. 3")
    g.add_argument("--model", type=file_path, default=None,
                   help="deformation model file (TOML, from gdfe calibrate/diagnose --model-out): R from --d")
    p.add_argument("--width", type=float, default=0.5, help="strip width [mm] (default 0.5)")
    p.add_argument("--panel-length", type=float, default=1.0, help="length of each panel [mm]")
    p.add_argument("--cells", type=int, default=None,
                   help="cells across the hinge (default 16, more where cells of L/16 would be longer than half "
                        "the strip's width: square cells)")
    p.add_argument("--nz", type=int, default=DEFAULT_NZ,
                   help=f"cell layers through the film (default {DEFAULT_NZ}, as for every design)")
    p.add_argument("--isotropy", type=float, default=1.0,
                   help="transverse/longitudinal shrink: 1 isotropic (default), 0 uniaxial")
    process_arg(p)
    solver_args(p)
    uncertainty_args(p)
    out_arg(p, help="write the VTU series, a PNG and result.json into this folder")
    json_arg(p)
    p.set_defaults(func=run)


def run(args):
    folder = output_folder(args.out, args)
    with noting(folder):
        return _run(args, folder)


def _run(args, folder):
    import gdfe

    model = _checked_model(args)
    n_draws = check_uncertainty(args, model)
    K = gdfe.PAPER_K if args.K is None else args.K
    design = _design(args, K, model)
    res = solve(design, args)
    out = _record(args, design, res, K, model)
    ens = None
    if n_draws is not None:
        ens = run_ensemble(design, model, n_draws, args, res, _hinge_measure, ["hinge"], process=args.process)
        out["uncertainty"] = ens.as_dict()
    if folder is not None:
        alpha = out["fold_angle_rad"]
        out["title"] = f"hinge L={args.length:g} mm: fold angle {shown(alpha, 4):.4f} rad ({shown(math.degrees(alpha), 1):.1f} deg)"
        with folder:
            folder.status.update(converged=bool(res.converged), status=status_word(res))
            out["files"] = write_outputs(res, args.out, "hinge", out, progress=progress_mode(args),
                                         command="hinge")
            if ens is not None:
                out["files"].update(write_ensemble(ens, res, args.out, "hinge", out["title"]))
    emit(out, args.json, _text(args, design, res, out, model, ens), command="hinge")
    return exit_status(res, allow_penetration=args.allow_penetration)


def _checked_model(args):
    """The deformation model of ``--model`` (or None), once ``--d`` and ``--R`` are checked."""
    import gdfe

    if args.d is None and args.R is None:
        raise GdfeError("give --d (passive thickness, mm) or --R (contraction ratio)")
    if args.d is not None and args.R is not None:
        raise GdfeError(f"--d, --R: expected one of them, got --d {args.d:g} and --R {args.R:g}: --R sets the "
                        f"contraction directly, so --d would be used for nothing but a misleading Eq. 1 "
                        f"comparison; give --d for R from Eq. 3 (or --model), or --R alone")
    model = gdfe.load_model(args.model) if args.model is not None else None
    if model is not None and args.d is None:
        raise GdfeError("--model: expected --d too (the model gives R from the passive thickness)")
    return model


def _design(args, K, model):
    """The hinge specimen of the arguments; a bad cell size is named as ``--cells``."""
    import gdfe

    cell_size = None if args.cells is None else args.length / check_int("--cells", args.cells)
    try:
        return gdfe.hinge(args.length, d=args.d, h=args.h, K=K, R=args.R, width=args.width,
                          panel_length=args.panel_length, cell_size=cell_size, nz=args.nz,
                          isotropy=args.isotropy, model=model, process=args.process)
    except GdfeError as exc:
        if cell_size is None or not str(exc).startswith("cell_size: "):
            raise
        raise GdfeError(f"--cells {args.cells}: {str(exc)[len('cell_size: '):]}") from None


def _record(args, design, res, K, model):
    """The fold angle beside Eq. 1, Eq. 2 and the model's closed form, and the solve's record."""
    import gdfe

    alpha = gdfe.fold_angle(res)
    R = float(design.meta["R"])
    out = {
        "fold_angle_rad": alpha,
        "fold_angle_eq1_rad": float(gdfe.Calibration(K=K, h=args.h).alpha(args.length, args.d, args.h))
        if args.d is not None else None,
        "fold_angle_eq2_rad": float(gdfe.angle_from_ratio(R, args.length, args.h)),
        "R": R, "K": K if args.R is None else None, "length_mm": args.length, "d_mm": args.d,
        "h_mm": args.h, "width_mm": args.width, "panel_length_mm": design.meta.get("panel_length_mm", args.panel_length), "isotropy": args.isotropy, "nz": args.nz, "status": status_word(res),
        "iterations": res.iterations, "frame_iterations": list(res.frame_iterations), "converged": res.converged,
        "residual": res.residual,
        "seconds": res.seconds, "n_cells": design.n_cells, "method": res.method,
        "newton_steps": [step.as_dict() for step in res.newton_steps],
    }
    out["contraction_source"] = design.meta.get("contraction_source")
    for key in ("process", "process_used", "process_unused"):
        if key in design.meta:
            out[key] = design.meta[key]
    if model is not None:
        out["model"] = model.as_dict()
        out["model_file"] = _model_file(args.model)
        out["fold_angle_model_rad"] = float(model.hinge_angle(args.length, args.d, args.h, args.process))
        ref = out["fold_angle_model_rad"]
    else:
        ref = out["fold_angle_eq1_rad"] if out["fold_angle_eq1_rad"] is not None else out["fold_angle_eq2_rad"]
    out["error_rad"] = alpha - ref
    if "panel_lengthened_from_mm" in design.meta:  # the model's contraction reached through the panels
        out["panel_lengthened_from_mm"] = design.meta["panel_lengthened_from_mm"]
        out["panel_reach_mm"] = design.meta["panel_reach_mm"]
    out.update(contact_fields(res))
    return out


def _text(args, design, res, out, model, ens):
    """The command's text: the model (with its warnings), the fold angle beside its reference (the model's closed
    form, or Eq. 1 and 2), the solve, the contact check and, where asked, the uncertainty and the files written."""
    alpha = out["fold_angle_rad"]
    lengthened = ""
    if "panel_lengthened_from_mm" in out:
        lengthened = (f"  panels lengthened to {out['panel_length_mm']:.3g} mm: the model's contraction reaches "
                      f"{out['panel_reach_mm']:.3g} mm into them; the fold is measured on their outer "
                      f"{out['panel_lengthened_from_mm']:.3g} mm\n")
    d_text = f"d={args.d:g} mm" if args.d is not None else "R given (no d)"
    # the model as gdfe simulate says it: its principle, mechanisms, data and warnings
    described = textwrap.indent(model.text(), "  ") + "\n" if model is not None else ""
    return (f"hinge L={args.length:g} mm, {d_text}, h={args.h:g} mm, R={out['R']:.4f}, nz={args.nz}\n"
            + described
            + f"  GDFE fold angle  {shown(alpha, 4):.4f} rad ({shown(math.degrees(alpha), 1):.1f} deg)\n"
            + (f"  model {model.name}: closed form {out['fold_angle_model_rad']:.4f} rad (error {shown(out['error_rad'], 4):+.4f})\n"
               if model is not None else
               f"  Eq. 1            {out['fold_angle_eq1_rad']:.4f} rad (error {shown(out['error_rad'], 4):+.4f})\n"
               if out["fold_angle_eq1_rad"] is not None else "")
            + f"  Eq. 2 (1-R)L/h   {out['fold_angle_eq2_rad']:.4f} rad\n" + lengthened
            + f"  {iterations_text(res)}, residual {res.residual:.1e}, {res.seconds:.2f} s, {design.n_cells} elements\n"
            + contact_text(res)
            + (f"\n{ens.text()}" if ens is not None else "")
            + (f"\n  wrote {args.out}/hinge.pvd (open in ParaView), hinge.png, result.json" if args.out else ""))


def _model_file(path):
    """``{"file", "sha256"}`` of the model file the command read."""
    import hashlib

    return {"file": str(path), "sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest()}


def _hinge_measure(res):
    """The fold angle of a hinge specimen, for :func:`gdfe.ensemble.fold_ensemble` (module-level: it travels to
    the workers)."""
    import gdfe

    return [gdfe.fold_angle(res)], {}
