"""``gdfe plan DATA.csv --n K``: the next folding tests to print, those that best tell the named models apart."""

from __future__ import annotations

from gdfe.cli._common import emit, file_path, json_arg
from gdfe.plan import D_RANGE, L_RANGE

__all__ = ["register", "run"]


def register(sub):
    p = sub.add_parser(
        "plan", help="the next folding tests to print: those that best tell apart the models the data cannot",
        description="Diagnose the folding tests, then propose --n hinge specimens within the printable ranges whose "
                    "angles are expected to tell most about which model of the named set is right (mutual "
                    "information, the members equally likely before; the named set and the models whose held-out "
                    "error is within one standard error of the chosen one's), with the expected reduction of that "
                    "uncertainty and each member's prediction of each test.")
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
    json_arg(p, "the plan")
    p.set_defaults(func=run)


def run(args):
    import numpy as np

    import gdfe
    from gdfe._validation import check_int, check_positive
    from gdfe.diagnosis import diagnose
    from gdfe.plan import models_to_tell_apart, parse_range, plan_tests
    from gdfe.predictive import from_diagnosis

    check_int("--n", args.n, minimum=1)
    if args.sigma is not None:
        check_positive("--sigma", args.sigma)
    L, d = parse_range("--L", args.L), parse_range("--d", args.d)
    tests = gdfe.load_folding_tests(args.data)
    h = parse_range("--h", args.h) if args.h is not None else (float(np.min(tests.h)), float(np.max(tests.h)))
    diag = diagnose(tests, sigma=args.sigma)
    model = from_diagnosis(diag, data=args.data, members=models_to_tell_apart(diag))
    plan = plan_tests(model, args.n, L, d, h, seed=args.seed)
    obj = {"n_tests": len(tests), "best": diag.best.name, "named": [f.name for f in diag.named], **plan.as_dict()}
    emit(obj, args.json, plan.text(), command="plan")
    return 0
