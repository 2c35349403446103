"""``gdfe fem``: the reference FEM (:mod:`reference_fem`) from the command line.

Subcommands: ``hinge`` (fold one specimen), ``timoshenko-check`` (free bilayer against the closed
form on a sequence of meshes), ``calibrate`` (fit E ratio and eigenstrain to folding tests),
``simulate`` (a plate meshed from any design file: VTU series over the load steps and a summary).
scikit-fem is imported only when a subcommand runs.
"""

from __future__ import annotations

import logging
from pathlib import Path

from gdfe import paper
from gdfe._validation import GdfeError, check_int, check_length, check_number
from gdfe.cli._common import (emit, file_path, json_arg, noting, out_arg, output_folder, scheduler_arg, shown,
                               using_scheduler)

__all__ = ["register"]

log = logging.getLogger(__name__)


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

    from reference_fem.linear_solvers import SOLVERS
    from reference_fem.plate import PLATE_RESOLUTIONS
    from reference_fem.plate_solve import SUPPORTS

    p = sub.add_parser("simulate", help="deform a plate meshed from a design file (film + coats, hexahedra)",
                       description="Mesh the film of a design file (TOML, SVG or FOLD) and the passive coat "
                                   "wherever each face's mask prints it, apply the film's eigenstrain in load "
                                   "steps (geometrically nonlinear) and write the deformed mesh as a VTU series "
                                   "with a summary (converged, elements, unknowns, time, cost split).")
    p.add_argument("design", type=file_path, help="design file (TOML, .svg or .fold)")
    out_arg(p, required=True, help="output folder: fem.pvd, fem_###.vtu, fem.json")
    p.add_argument("--resolution", choices=tuple(PLATE_RESOLUTIONS), default="default",
                   help="elements per design cell in-plane (coarse 1, default 2, fine 4), 2 per ply")
    p.add_argument("--refine", type=int, default=None, help="elements per design cell along x and y (over --resolution)")
    p.add_argument("--coarsen", type=int, default=1, help="merge N x N design cells first (the same masks, coarser pixel)")
    p.add_argument("--d", type=float, default=None,
                   help="coat thickness [mm] where the design gives none (cells coated on both faces, designs made from R)")
    p.add_argument("--support", choices=SUPPORTS, default="free",
                   help="free-floating (rigid motions removed) or clamped along the edge at the smallest x")
    p.add_argument("--solver", choices=SOLVERS, default="auto", help="linear solver of the Newton steps")
    p.add_argument("--E-ratio", dest="E_ratio", type=float, default=None,
                   help="E_passive / E_active (default: the Table-1 calibration)")
    p.add_argument("--eigenstrain", type=float, default=None,
                   help="free in-plane contraction of the film, R_free - 1 (default: calibrated)")
    p.add_argument("--nu", type=float, default=0.35, help="Poisson's ratio of both layers")
    p.add_argument("--linear", action="store_true", help="small-strain solve (default: geometrically nonlinear)")
    json_arg(p)
    p.set_defaults(func=_cmd_simulate)


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
        f"{res.dofs} dofs, {res.seconds:.2f} s ({res.linear_solver}), {res.iterations} iteration(s), "
        f"{'converged' if res.converged else 'NOT CONVERGED'} (residual {res.residual:.1e})",
        *([] if res.converged else [
            f"  NOT CONVERGED: the values below are at {res.load_factor:.3f} of the eigenstrain"]),
        f"  fold angle   {shown(alpha, 4):.4f} rad",
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

    from gdfe._validation import degenerate_tests

    source = TABLE1 if args.table is None else args.table
    tests = load_folding_tests(source)
    for note in degenerate_tests(Path(source).name, tests.L, tests.d, tests.h, tests.alpha):
        log.warning("%s", note)
    with using_scheduler(args.scheduler):
        fit = fit_to_table(tests.L, tests.d, tests.h, tests.alpha, model=args.model, nu=args.nu,
                           resolution=args.resolution, progress=not args.json)
    text = "\n".join([
        f"{args.model} fit to {len(tests)} folding tests ({fit.seconds:.0f} s)",
        f"  E_passive / E_active = {fit.E_ratio:.4g}{'  (at the edge of the grid)' if fit.E_ratio_at_bound else ''}",
        f"  eigenstrain          = {fit.eigenstrain:.4f}"
        f"{'  (at the bound of its fit)' if fit.eigenstrain_at_bound else ''}",
        f"  RMSE                 = {fit.rmse:.4f} rad (R^2 = {fit.r2:.3f})",
        f"  leave-one-out RMSE   = {fit.loo_rmse:.4f} rad",
    ])
    emit(fit.as_dict(), args.json, text, command="fem calibrate")
    return 0


def _cmd_simulate(args) -> int:
    import gdfe
    from reference_fem import CALIBRATED_E_RATIO, CALIBRATED_EIGENSTRAIN, BilayerMaterial
    from reference_fem.plate import plate_mesh
    from reference_fem.plate_output import write_plate_series
    from reference_fem.plate_solve import solve_plate
    from gdfe.io import write_json

    if args.refine is not None:
        check_int("--refine", args.refine)
    check_int("--coarsen", args.coarsen)
    if args.d is not None:
        check_length("--d", args.d)
    ratio = CALIBRATED_E_RATIO if args.E_ratio is None else check_number(
        "--E-ratio", args.E_ratio, minimum=0.0, include_minimum=False, what="a positive ratio E_passive / E_active")
    eps = CALIBRATED_EIGENSTRAIN if args.eigenstrain is None else check_number(
        "--eigenstrain", args.eigenstrain, minimum=-1.0, maximum=0.0, include_minimum=False,
        what="the film's free contraction R_free - 1 in (-1, 0] (the film shrinks when heated)")
    folder = output_folder(args.out, args)
    design, _ = gdfe.load_design(args.design)
    mat = BilayerMaterial.from_ratio(ratio, eps, nu=args.nu)
    try:
        plate = plate_mesh(design, resolution=args.resolution, refine=args.refine, coarsen=args.coarsen, d=args.d,
                           meta={"design": str(args.design)})
    except GdfeError as exc:  # the library's coarsen is the command's --coarsen
        if not str(exc).startswith("coarsen: "):
            raise
        raise GdfeError(f"--coarsen {args.coarsen}: {str(exc)[len('coarsen: '):]}") from None
    with noting(folder):
        res = solve_plate(plate, mat, support=args.support, solver=args.solver, linear=args.linear,
                          keep_steps=True, progress=None if getattr(args, "quiet", False) else _step_line())
        summary = {"design": str(args.design), **plate.summary(), **res.summary(), "dofs": res.dofs,
                   "status": "converged" if res.converged else "not converged",
                   "E_ratio": ratio, "eigenstrain": eps, "nu": args.nu, "support": args.support,
                   "nonlinear": not args.linear, "memory_mib": _peak_memory_mib()}
        with folder:
            folder.status.update(converged=bool(res.converged), status=summary["status"])
            pvd = write_plate_series(res, args.out, "fem")
            summary["files"] = {"pvd": str(pvd), "json": str(args.out / "fem.json")}
            write_json(args.out / "fem.json", summary)
    c = res.cost
    text = "\n".join([
        f"{args.design}: plate FEM, {res.n_elements} elements ({plate.summary()['n_cells']} design cells x "
        f"{plate.refine}^2 in-plane), {res.dofs} unknowns, {res.element}",
        f"  {'converged' if res.converged else f'NOT CONVERGED (stopped at {res.load_factor:.3f} of the eigenstrain)'}"
        f" in {res.iterations} Newton iterations over {summary['load_steps']} load steps "
        f"({summary['rejected_steps']} cut), residual {res.residual:.1e}, {res.seconds:.1f} s",
        f"  cost: assembly {c['assembly_s']:.1f} s ({c['assemblies']}), {res.solver} factorisation "
        f"{c['factor_s']:.1f} s ({c['factorisations']}), solves {c['solve_s']:.1f} s, other "
        f"{c['other_s'] + c['setup_s'] + c['residual_s']:.1f} s; {c['over_limit']:.2f} x its limit",
        f"  wrote {summary['files']['pvd']} (open in ParaView), {summary['files']['json']}",
    ])
    emit(summary, args.json, text, command="fem simulate")
    return 0 if res.converged else 1


def _step_line():
    """A line on standard error after every accepted load step: the solve says it is alive."""
    import sys
    import time

    t0 = time.perf_counter()

    def line(load, iterations, residual):
        print(f"gdfe: fem load {load:.3f} converged ({iterations} Newton iterations, residual {residual:.1e}), "
              f"{time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)

    return line


def _peak_memory_mib():
    """Peak resident memory of this process [MiB] (None where the system does not tell)."""
    try:
        import resource
    except ImportError:  # pragma: no cover - not on Windows
        return None
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
