"""``gdfe plan DATA.csv --n K [--target DESIGN]``: the next folding tests to print, those that best tell the named
models apart, or those that narrow the prediction of a design's fold angles most."""

from __future__ import annotations

from gdfe.cli._common import emit, file_path, json_arg
from gdfe.plan import D_RANGE, L_RANGE

__all__ = ["register", "run"]


def register(sub):
    p = sub.add_parser(
        "plan", help="the next folding tests to print: those that best tell apart the models the data cannot, or "
                     "(--target) those that narrow a part's predicted fold angles most",
        description="Diagnose the folding tests, then propose --n hinge specimens within the printable ranges whose "
                    "angles are expected to tell most about which model of the named set is right (mutual "
                    "information, the members equally likely before; the named set and the models whose held-out "
                    "error is within one standard error of the chosen one's), with the expected reduction of that "
                    "uncertainty and each member's prediction of each test. With --target DESIGN: the specimens "
                    "expected to narrow the prediction of the design's fold angles most, with each fold's interval "
                    "before and its expected width after the tests.")
    p.add_argument("data", type=file_path, help="CSV of folding tests (L_mm, d_mm, h_mm, alpha_rad)")
    p.add_argument("--n", type=int, default=3, help="tests to propose (default 3)")
    p.add_argument("--L", default=f"{L_RANGE[0]:g}:{L_RANGE[1]:g}", metavar="LO:HI",
                   help=f"hinge widths that can be printed [mm] (default {L_RANGE[0]:g}:{L_RANGE[1]:g})")
    p.add_argument("--d", default=f"{D_RANGE[0]:g}:{D_RANGE[1]:g}", metavar="LO:HI",
                   help=f"passive-layer thicknesses [mm] (default {D_RANGE[0]:g}:{D_RANGE[1]:g})")
    p.add_argument("--h", default=None, metavar="LO:HI",
                   help="film thicknesses [mm] (default: the tests' own, or 0.29)")
    p.add_argument("--sigma", type=float, default=None, metavar="S", help="noise of the measured angles [rad]")
    p.add_argument("--seed", type=int, default=0, help="seed of the Monte Carlo expectation (default 0)")
    p.add_argument("--target", type=file_path, default=None, metavar="DESIGN",
                   help="a design to print (TOML, .svg, .fold): propose instead the tests expected to narrow the "
                        "prediction of its fold angles most (the expected fall of their summed variance, under the "
                        "model file gdfe diagnose --model-out writes), with each fold's interval before and its "
                        "expected width after 1, 2, ... tests")
    p.add_argument("--level", type=float, default=None,
                   help="with --target: level of the intervals (default 0.9)")
    json_arg(p, "the plan")
    p.set_defaults(func=run)


def run(args):
    import numpy as np

    from gdfe._validation import GdfeError, check_int, check_number, check_positive
    from gdfe.diagnosis import diagnose
    from gdfe.plan import models_to_tell_apart, parse_range, plan_tests
    from gdfe.plan_target import target_folds
    from gdfe.predictive import from_diagnosis

    check_int("--n", args.n, minimum=1)
    if args.sigma is not None:
        check_positive("--sigma", args.sigma)
    if args.level is not None and args.target is None:
        raise GdfeError("--level: an option of --target DESIGN (the intervals of the part's folds), given without it")
    if args.level is not None:
        check_number("--level", args.level, minimum=0.0, maximum=1.0, include_minimum=False, include_maximum=False)
    check_int("--seed", args.seed, minimum=0)
    L, d = parse_range("--L", args.L), parse_range("--d", args.d)
    target = target_folds(args.target, "--target") if args.target is not None else None
    h = parse_range("--h", args.h) if args.h is not None else None
    diag = diagnose(args.data, sigma=args.sigma)  # from the file: degenerate tests refused as gdfe diagnose does
    tests = diag.tests
    h = h if h is not None else (float(np.min(tests.h)), float(np.max(tests.h)))
    if target is not None:
        return _run_target(args, diag, target, L, d, h)
    model = from_diagnosis(diag, data=args.data, members=models_to_tell_apart(diag))
    plan = plan_tests(model, args.n, L, d, h, seed=args.seed)
    obj = {"n_tests": len(tests), "best": diag.best.name, "named": [f.name for f in diag.named], **plan.as_dict()}
    emit(obj, args.json, plan.text(), command="plan")
    return 0


def _run_target(args, diag, target, L, d, h):
    """``--target DESIGN``: the tests expected to narrow the prediction of the design's fold angles most, under
    the model file of the diagnosis (its named set weighted by stacking, as ``gdfe diagnose --model-out``)."""
    from gdfe.plan_target import plan_for_target
    from gdfe.predict import LEVEL
    from gdfe.predictive import from_diagnosis

    model = from_diagnosis(diag, data=args.data)
    level = LEVEL if args.level is None else args.level
    plan = plan_for_target(model, target, args.n, L, d, h, level=level, seed=args.seed, name="--target")
    obj = {"n_tests": len(diag.tests), "best": diag.best.name, "named": [f.name for f in diag.named], **plan.as_dict()}
    emit(obj, args.json, plan.text(), command="plan")
    return 0
