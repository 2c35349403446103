"""``gdfe fem``: the reference FEM (:mod:`reference_fem`) from the command line.

Subcommands: ``hinge`` (fold one specimen), ``timoshenko-check`` (free bilayer against the closed
form on a sequence of meshes), ``calibrate`` (fit E ratio and eigenstrain to folding tests).
scikit-fem is imported only when a subcommand runs.
"""

from __future__ import annotations

from gdfe import paper
from gdfe._validation import check_int, check_length, check_number
from gdfe.cli._common import emit, json_arg, scheduler_arg, using_scheduler

__all__ = ["register"]


def register(subparsers) -> None:
    """Add the ``fem`` command and its subcommands to the ``gdfe`` parser."""
    from reference_fem.mesh import HINGE_RESOLUTIONS

    fem = subparsers.add_parser("fem", help="reference finite-element bilayer model (scikit-fem)",
                                description="Reference 3-D finite-element model of the bilayer.")
    sub = fem.add_subparsers(dest="fem_command", metavar="SUBCOMMAND")
    fem.set_defaults(func=lambda args: (fem.print_help(), 2)[1])

    p = sub.add_parser("hinge", help="fold one hinge specimen",
                       description="Fold a hinge (two sandwich panels joined by a hinge coated "
                                   "on one face) and report its angle and curvature.")
    p.add_argument("--length", type=float, required=True, help="hinge width L [mm]")
    p.add_argument("--d", type=float, required=True, help="passive coat thickness d [mm]")
    p.add_argument("--h", type=float, default=paper.H, help=f"film thickness h [mm] (default {paper.H:g})")
    p.add_argument("--nonlinear", action="store_true",
                   help="geometrically nonlinear solve (default: linear, small strain)")
    p.add_argument("--E-ratio", dest="E_ratio", type=float, default=None,
                   help="E_passive / E_active (default: the Table-1 calibration)")
    p.add_argument("--eigenstrain", type=float, default=None,
                   help="free in-plane contraction of the film, R_free - 1 (default: calibrated; "
                        "write exponents as --eigenstrain=-1e-4)")
    p.add_argument("--nu", type=float, default=0.35, help="Poisson's ratio of both layers")
    p.add_argument("--width", type=float, default=1.0, help="strip width along the hinge [mm]")
    p.add_argument("--panel-length", dest="panel_length", type=float, default=2.0,
                   help="length of each panel [mm]")
    p.add_argument("--resolution", choices=tuple(HINGE_RESOLUTIONS), default="default")
    p.add_argument("--model", choices=("neohookean", "svk"), default="neohookean",
                   help="hyperelastic law of the nonlinear solve")
    p.add_argument("--max-iter", dest="max_iter", type=int, default=15,
                   help="Newton iterations per load step (nonlinear)")
    p.add_argument("--min-step", dest="min_step", type=float, default=1e-3,
                   help="smallest load step before giving up (nonlinear)")
    json_arg(p)
    p.set_defaults(func=_cmd_hinge)

    p = sub.add_parser("timoshenko-check",
                       help="free bilayer strip against Timoshenko's curvature on refined meshes")
    p.add_argument("--element", choices=("hex1", "hex2", "both"), default="both",
                   help="element family (default both: trilinear shows the convergence rate, "
                        "triquadratic matches the formula to 1e-5)")
    json_arg(p)
    p.set_defaults(func=_cmd_timoshenko_check)

    p = sub.add_parser("calibrate", help="fit E_passive/E_active and the eigenstrain to folding tests",
                       description="Least-squares fit of the linear hinge model to folding tests "
                                   "(CSV with columns L_mm, d_mm, h_mm, alpha_rad) with "
                                   "leave-one-out error.")
    p.add_argument("--table", default=None,
                   help="CSV of folding tests (default: the paper's Table 1, gdfe.TABLE1)")
    p.add_argument("--model", choices=("fem", "timoshenko"), default="fem")
    p.add_argument("--resolution", choices=tuple(HINGE_RESOLUTIONS), default="default")
    p.add_argument("--nu", type=float, default=0.35, help="Poisson's ratio of both layers")
    json_arg(p, "the fit")
    scheduler_arg(p)
    p.set_defaults(func=_cmd_calibrate)


def _cmd_hinge(args) -> int:
    from gdfe.timoshenko import timoshenko_curvature
    from reference_fem import (CALIBRATED_E_RATIO, CALIBRATED_EIGENSTRAIN, BilayerMaterial, curvature, fold_angle,
                               hinge_mesh, solve_linear, solve_nonlinear)

    for name in ("length", "d", "h", "width", "panel_length"):
        check_length(f"--{name.replace('_', '-')}", getattr(args, name))
    check_int("--max-iter", args.max_iter)
    check_number("--min-step", args.min_step, minimum=0.0, maximum=1.0, include_minimum=False,
                 what="a load step in (0, 1]")
    ratio = CALIBRATED_E_RATIO if args.E_ratio is None else args.E_ratio
    eps = CALIBRATED_EIGENSTRAIN if args.eigenstrain is None else check_number(
        "--eigenstrain", args.eigenstrain, minimum=-1.0, maximum=0.0, include_minimum=False,
        what="the film's free contraction R_free - 1 in (-1, 0] (the film shrinks when heated)")
    mat = BilayerMaterial.from_ratio(ratio, eps, nu=args.nu)
    strip = hinge_mesh(args.length, args.d, args.h, width=args.width,
                       panel_length=args.panel_length, resolution=args.resolution)
    if args.nonlinear:
        res = solve_nonlinear(strip, mat, model=args.model, max_iter=args.max_iter,
                              min_step=args.min_step)
    else:
        res = solve_linear(strip, mat)
    kT = timoshenko_curvature(args.h, args.d, mat.E_active, mat.E_passive, mat.eigenstrain,
                              nu_active=mat.nu_active, nu_passive=mat.nu_passive, state="biaxial")
    alpha, kappa = fold_angle(res), curvature(res)
    out = {"length_mm": args.length, "d_mm": args.d, "h_mm": args.h, "E_ratio": ratio,
           "eigenstrain": eps, "nu": args.nu, "width_mm": args.width,
           "fold_angle_rad": alpha, "kappa_per_mm": kappa, "kappa_L_rad": kappa * args.length,
           "timoshenko_kappa_per_mm": kT, "timoshenko_fold_angle_rad": kT * args.length,
           **res.summary(), "model": args.model if args.nonlinear else "linear",
           "resolution": args.resolution}
    text = "\n".join([
        f"hinge L = {args.length:g} mm, d = {args.d:g} mm, h = {args.h:g} mm "
        f"(E_passive/E_active = {ratio:.4g}, eigenstrain = {eps:.4g}, nu = {args.nu:g})",
        f"  solve        {'nonlinear (' + args.model + ')' if args.nonlinear else 'linear'}, "
        f"{res.dofs} dofs, {res.seconds:.2f} s, {res.iterations} iteration(s), "
        f"{'converged' if res.converged else 'NOT CONVERGED'} (residual {res.residual:.1e})",
        *([] if res.converged else [
            f"  NOT CONVERGED: the values below are at {res.load_factor:.3f} of the eigenstrain"]),
        f"  fold angle   {alpha:.4f} rad",
        f"  curvature    {kappa:.4f} 1/mm (kappa L = {kappa * args.length:.4f} rad)",
        f"  Timoshenko   {kT:.4f} 1/mm (kappa L = {kT * args.length:.4f} rad)",
    ])
    emit(out, args.json, text, command="fem hinge")
    return 0 if res.converged else 1


def _cmd_timoshenko_check(args) -> int:
    from reference_fem import timoshenko_check

    elements = ("hex1", "hex2") if args.element == "both" else (args.element,)
    checks = [timoshenko_check(el) for el in elements]
    lines = []
    for c in checks:
        s = c["setup"]
        lines.append(f"{c['element']}: free bilayer strip {s['length_mm']:g} x {s['width_mm']:g} mm, "
                     f"h = {s['h_mm']:g}, d = {s['d_mm']:g} mm, E_p/E_a = {s['E_ratio']:g}, nu = 0")
        lines.append(f"  {'size [mm]':>9} {'layers':>6} {'dofs':>7} {'kappa FEM':>12} "
                     f"{'Timoshenko':>12} {'rel. error':>10}")
        for r in c["rows"]:
            lines.append(f"  {r['element_size_mm']:9.4f} {r['layers_per_ply']:6d} {r['dofs']:7d} "
                         f"{r['kappa_fem_per_mm']:12.6e} {r['kappa_timoshenko_per_mm']:12.6e} "
                         f"{r['rel_error']:10.2e}")
        lines.append(f"  observed rate {c['rate']:.2f}, finest error {c['finest_error']:.2e}")
    ok = all(c["finest_error"] < 0.01 for c in checks)
    emit({"checks": checks, "passed": ok}, args.json, "\n".join(lines), command="fem timoshenko-check")
    return 0 if ok else 1


def _cmd_calibrate(args) -> int:
    from gdfe.calibration import TABLE1, load_folding_tests
    from reference_fem import fit_to_table

    tests = load_folding_tests(TABLE1 if args.table is None else args.table)
    with using_scheduler(args.scheduler):
        fit = fit_to_table(tests.L, tests.d, tests.h, tests.alpha, model=args.model, nu=args.nu,
                           resolution=args.resolution, progress=not args.json)
    text = "\n".join([
        f"{args.model} fit to {len(tests)} folding tests ({fit.seconds:.0f} s)",
        f"  E_passive / E_active = {fit.E_ratio:.4g}{'  (at the edge of the grid)' if fit.at_bound else ''}",
        f"  eigenstrain          = {fit.eigenstrain:.4f}",
        f"  RMSE                 = {fit.rmse:.4f} rad (R^2 = {fit.r2:.3f})",
        f"  leave-one-out RMSE   = {fit.loo_rmse:.4f} rad",
    ])
    emit(fit.as_dict(), args.json, text, command="fem calibrate")
    return 0
