"""``gdfe study``, ``gdfe report`` and ``gdfe calibrate``: the studies on the command line.

``STUDIES`` is the registry of studies (name -> module). Each module has
``run(resolution, out) -> dict``, writes a PNG and a JSON into ``out``, and is also run
as ``python -m MODULE``.
"""

from __future__ import annotations

from pathlib import Path

from studies._common import RESOLUTIONS
from studies.calibration_models import MODELS as CALIBRATION_MODELS

__all__ = ["STUDIES", "register"]

#: Every study, in the order of the report.
STUDIES = {
    "fig02": "studies.fig02_calibration",
    "fig06": "studies.fig06_angle_validation",
    "refinement": "studies.hinge_refinement",
    "fig07": "studies.fig07_crease_fold",
    "fig08": "studies.fig08_freeform",
    "fig09": "studies.fig09_letters",
    "fig10": "studies.fig10_segmentation",
    "fig11": "studies.fig11_design_validation",
    "compare": "studies.compare_models",
    "blind-diagnosis": "studies.blind_diagnosis",
    "bench-scaling": "studies.bench_scaling",
}


def register(sub):
    p = sub.add_parser("study", help="run one study of a paper figure (writes a PNG and a JSON)",
                       description="Run one study: " + ", ".join(STUDIES) + ".")
    p.add_argument("name", choices=list(STUDIES), metavar="NAME", help="study: " + ", ".join(STUDIES))
    p.add_argument("--out", type=Path, default=None, help="output directory (default out/NAME)")
    p.add_argument("--resolution", choices=RESOLUTIONS, default="default")
    p.add_argument("--json", action="store_true", help="print the numbers as JSON")
    p.set_defaults(func=_cmd_study)

    p = sub.add_parser("report", help="run every study and write an HTML validation report",
                       description="Run every study and write DIR/index.html with figures, paper-vs-ours "
                                   "numbers, regression tolerances and software versions.")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--resolution", choices=RESOLUTIONS, default="default")
    p.add_argument("--only", nargs="+", choices=list(STUDIES), metavar="NAME", help="run only these studies")
    p.add_argument("--json", action="store_true", help="print the report's summary as JSON")
    p.set_defaults(func=_cmd_report)

    p = sub.add_parser("calibrate", help="fit Eq. 1 (K) to folding tests",
                       description="Fit a reading of Eq. 1 to folding tests (CSV with L_mm, d_mm, h_mm, alpha_rad): "
                                   "eq1 = K sqrt(h/d^3) L as printed; eq1-d1 = K sqrt(h/d) L; "
                                   "power = c (L/h) (h/d)^p.")
    p.add_argument("data", type=Path, help="CSV of folding tests")
    p.add_argument("--model", choices=CALIBRATION_MODELS + ("all",), default="eq1",
                   help="reading of Eq. 1 (default eq1, as printed)")
    p.add_argument("--boot", type=int, default=2000, help="bootstrap resamples for the 95 %% CI (default 2000)")
    p.add_argument("--d", type=float, default=None, help="also print Eq. 3's R for this passive thickness [mm]")
    p.add_argument("--json", action="store_true", help="print the fit as JSON")
    p.set_defaults(func=_cmd_calibrate)


def load(name):
    """Import a study module by its registry name."""
    import importlib

    if name not in STUDIES:
        raise ValueError(f"study: expected one of {', '.join(STUDIES)}, got {name!r}")
    return importlib.import_module(STUDIES[name])


def _cmd_study(args):
    from gdfe.cli import CLIError, emit
    from studies._common import run_and_print

    try:
        module = load(args.name)
    except ModuleNotFoundError as exc:
        raise CLIError(f"study {args.name} ({STUDIES[args.name]}) is not available: {exc}") from None
    out = args.out if args.out is not None else Path("out") / args.name
    if not hasattr(module, "NAME"):  # a study without the shared plumbing
        result = module.run(resolution=args.resolution, out=out)
        emit(result, args.json, f"{args.name}: wrote {out}")
        return 0
    return run_and_print(module, args.resolution, out, args.json)


def _cmd_report(args):
    from gdfe.cli import emit
    from gdfe.report import build_report

    names = args.only or list(STUDIES)
    summary = build_report(args.out, resolution=args.resolution, names=names)
    lines = [f"wrote {summary['index']}"]
    for s in summary["studies"]:
        lines.append(f"  {s['name']:<16} {s['status']:<8} {s.get('seconds', 0):6.1f} s  "
                     f"{s.get('passed', 0)}/{s.get('headlines', 0)} headlines pass")
    emit(summary, args.json, "\n".join(lines))
    return 0 if summary["ok"] else 1


def _cmd_calibrate(args):
    import gdfe
    from gdfe.cli import emit
    from studies import calibration_models as cm

    if args.boot < 0:
        raise ValueError(f"--boot: expected a non-negative number of resamples, got {args.boot}")
    tests = gdfe.load_folding_tests(args.data)
    if args.d is not None:
        if args.d <= 0:
            raise ValueError(f"--d: expected a positive passive thickness in mm, got {args.d:g}")
        h = float(tests.h.mean())
    models = CALIBRATION_MODELS if args.model == "all" else (args.model,)
    out = []
    text = []
    for m in models:
        f = cm.fit(tests, m, n_boot=args.boot)
        d = f.as_dict()
        d.pop("residuals")
        block = cm.format_fit(f)
        if args.d is not None:
            d["R_at_d"] = {"d_mm": args.d, "h_mm": h, "R": float(f.ratio(args.d, h))}
            block += f"\nR      {d['R_at_d']['R']:.4f} at d = {args.d:g} mm (Eq. 3 of this reading, h = {h:g} mm)"
        out.append(d)
        text.append(block)
    emit(out[0] if len(out) == 1 else out, args.json, "\n\n".join(text))
    return 0
