"""Core subcommands of ``gdfe``: ``hinge`` and ``simulate``."""

from __future__ import annotations

import math
from pathlib import Path

from gdfe.cli import CLIError, emit

__all__ = ["register"]


def register(sub):
    p = sub.add_parser("hinge", help="simulate the paper's hinge specimen (two rigid panels, one hinge)",
                       description="Simulate the paper's folding specimen and compare with Eq. 1.")
    p.add_argument("--length", "-L", type=float, required=True, help="hinge (fold) width L [mm]")
    p.add_argument("--d", type=float, help="passive-layer thickness d [mm] (R from Eq. 3)")
    p.add_argument("--h", type=float, default=0.29, help="active-film thickness h [mm] (default 0.29)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--K", type=float, default=None, help="coefficient K of Eq. 1 (default 0.3706)")
    g.add_argument("--R", type=float, default=None, help="contraction ratio, overriding Eq. 3")
    p.add_argument("--width", type=float, default=0.5, help="strip width [mm] (default 0.5)")
    p.add_argument("--panel-length", type=float, default=1.0, help="length of each panel [mm]")
    p.add_argument("--cells", type=int, default=16, help="cells across the hinge (default 16)")
    p.add_argument("--nz", type=int, default=1, help="cell layers through the film (default 1)")
    p.add_argument("--isotropy", type=float, default=1.0,
                   help="transverse/longitudinal shrink: 1 isotropic (default), 0 uniaxial")
    _solver_args(p)
    p.add_argument("--out", type=Path, help="write the VTU series, a PNG and result.json here")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=_cmd_hinge)

    p = sub.add_parser("simulate", help="simulate a design file (TOML)",
                       description="Simulate a TOML design; write a VTU series, a PNG and a JSON summary.")
    p.add_argument("design", type=Path, help="design file (.toml)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    _solver_args(p, defaults_from_file=True)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=_cmd_simulate)


def _solver_args(p, defaults_from_file=False):
    d = None if defaults_from_file else 1
    p.add_argument("--method", choices=["auto", "newton", "newton-cg", "anderson", "plain"], default=None,
                   help="solver (default auto: newton for small designs, newton-cg for larger ones)")
    p.add_argument("--steps", type=int, default=d, help="frames of the contraction ramp (default 1)")
    p.add_argument("--tol", type=float, default=None, help="residual tolerance (default 1e-7, in units of h)")
    p.add_argument("--max-iter", type=int, default=None, help="iteration limit per frame")


def _solve(design, args, options=None):
    import gdfe

    opts = dict(options or {})
    for key in ("method", "steps", "tol", "max_iter"):
        v = getattr(args, key, None)
        if v is not None:
            opts[key] = v
    return gdfe.simulate(design, **opts)


def _write_outputs(result, out, name, summary):
    from gdfe.io import render_png, write_json, write_series

    out.mkdir(parents=True, exist_ok=True)
    pvd = write_series(result, out, name=name)
    png = render_png(result, out / f"{name}.png", title=summary.get("title"))
    write_json(out / "result.json", summary)
    return {"pvd": str(pvd), "png": str(png), "json": str(out / "result.json")}


def _cmd_hinge(args):
    import gdfe

    if args.d is None and args.R is None:
        raise CLIError("give --d (passive thickness, mm) or --R (contraction ratio)")
    K = gdfe.PAPER_K if args.K is None else args.K
    if args.cells < 1:
        raise ValueError(f"--cells: expected an integer >= 1, got {args.cells}")
    design = gdfe.hinge(args.length, d=args.d, h=args.h, K=K, R=args.R, width=args.width,
                        panel_length=args.panel_length, cell_size=args.length / args.cells, nz=args.nz,
                        isotropy=args.isotropy)
    res = _solve(design, args)
    alpha = gdfe.fold_angle(res)
    R = float(design.meta["R"])
    out = {
        "alpha_rad": alpha,
        "alpha_eq1_rad": float(gdfe.Calibration(K=K, h=args.h).alpha(args.length, args.d, args.h))
        if args.d is not None else None,
        "alpha_eq2_rad": float(gdfe.angle_from_ratio(R, args.length, args.h)),
        "R": R, "K": K if args.R is None else None, "L_mm": args.length, "d_mm": args.d, "h_mm": args.h,
        "width_mm": args.width, "isotropy": args.isotropy,
        "iterations": res.iterations, "converged": res.converged, "residual": res.residual,
        "seconds": res.seconds, "n_elements": design.n_cells, "method": res.method,
    }
    ref = out["alpha_eq1_rad"] if out["alpha_eq1_rad"] is not None else out["alpha_eq2_rad"]
    out["error_rad"] = alpha - ref
    if args.out:
        out["title"] = f"hinge L={args.length:g} mm, alpha={alpha:.4f} rad"
        out["files"] = _write_outputs(res, args.out, "hinge", out)
    text = (f"hinge L={args.length:g} mm, d={args.d} mm, h={args.h:g} mm, R={R:.4f}\n"
            f"  GDFE fold angle  {alpha:.4f} rad ({math.degrees(alpha):.1f} deg)\n"
            + (f"  Eq. 1            {out['alpha_eq1_rad']:.4f} rad (error {out['error_rad']:+.4f})\n"
               if out["alpha_eq1_rad"] is not None else "")
            + f"  Eq. 2 (1-R)L/h   {out['alpha_eq2_rad']:.4f} rad\n"
            f"  {'converged' if res.converged else 'NOT CONVERGED'} in {res.iterations} iterations "
            f"(residual {res.residual:.1e}), {res.seconds:.2f} s, {design.n_cells} elements"
            + (f"\n  wrote {args.out}/hinge.pvd (open in ParaView), hinge.png, result.json" if args.out else ""))
    emit(out, args.json, text)
    return _exit_status(res)


def _exit_status(res):
    if not res.converged:
        import sys

        print(f"gdfe: error: the solver did not converge (residual {res.residual:.3g} after "
              f"{res.iterations} iterations); raise --max-iter or check the design", file=sys.stderr)
        return 3
    return 0


def _cmd_simulate(args):
    import gdfe

    design, options = gdfe.load_design(args.design)
    res = _solve(design, args, options)
    summary = {"design": str(args.design), **design.summary(), **res.summary()}
    if "panel_a" in design.regions and "panel_b" in design.regions:
        summary["fold_angle_rad"] = gdfe.fold_angle(res)
    summary["bbox_mm"] = [res.points.min(0).tolist(), res.points.max(0).tolist()]
    summary["title"] = f"{args.design.stem}: {design.n_cells} elements"
    summary["files"] = _write_outputs(res, args.out, args.design.stem, summary)
    text = (f"{args.design}: {design.n_cells} elements, "
            f"{'converged' if res.converged else 'NOT CONVERGED'} in {res.iterations} iterations "
            f"(residual {res.residual:.1e}), {res.seconds:.2f} s\n"
            f"  wrote {summary['files']['pvd']} (open in ParaView), {summary['files']['png']}, "
            f"{summary['files']['json']}")
    emit(summary, args.json, text)
    return _exit_status(res)
