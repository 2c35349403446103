"""``--uncertainty N``: the options and the outputs of an ensemble (:mod:`gdfe.ensemble`) on ``gdfe hinge``,
``simulate`` and ``design --target``."""

from __future__ import annotations

from gdfe._validation import GdfeError, check_int, check_number
from gdfe.cli._common import scheduler_arg, using_scheduler

__all__ = ["uncertainty_args", "check_uncertainty", "run_ensemble", "write_ensemble"]


def uncertainty_args(p):
    """``--uncertainty N``, ``--level``, ``--seed`` and ``--scheduler`` on a subcommand's parser."""
    from gdfe.ensemble import LEVEL

    g = p.add_argument_group("predictions with intervals (a model file with predictive content)")
    g.add_argument("--uncertainty", type=int, default=None, metavar="N",
                   help="fold the part again under N draws of the --model file's predictive content (its members "
                        "by weight, their parameters from their covariance), each from the nominal shape, and "
                        "report intervals of the fold angles and measures, the per-vertex spread (VTU point field "
                        "spread_mm) and NAME_uncertainty.png")
    g.add_argument("--level", type=float, default=None, help=f"level of the intervals (default {LEVEL:g})")
    g.add_argument("--seed", type=int, default=None, help="seed of the draws, an integer >= 0 (default 0)")
    scheduler_arg(p)


def check_uncertainty(args, model, option="--model"):
    """``args.uncertainty`` checked against ``model`` (None where it is not asked for): a number of draws of at
    least 2, a level in (0, 1), a seed of at least 0, and a model with predictive content."""
    from gdfe.ensemble import LEVEL, has_predictive_content

    if args.uncertainty is None:
        given = [flag for flag in ("--level", "--seed") if getattr(args, flag[2:]) is not None]
        if given:
            raise GdfeError(f"{given[0]}: an option of --uncertainty N (the draws of the model), given without it")
        return None
    args.level = LEVEL if args.level is None else args.level
    args.seed = 0 if args.seed is None else args.seed
    n = check_int("--uncertainty", args.uncertainty, minimum=2)
    check_int("--seed", args.seed, minimum=0)
    check_number("--level", args.level, minimum=0.0, maximum=1.0, include_minimum=False, include_maximum=False)
    if model is None:
        raise GdfeError(f"--uncertainty: expected {option} M.toml too, a model file with predictive content "
                        f"(gdfe diagnose or gdfe calibrate --model-out) to draw from")
    if not has_predictive_content(model):
        raise GdfeError(f"--uncertainty: the model {model.name!r} ({option}) has no predictive content (no "
                        f"[uncertainty] or [ensemble] table); write it again with gdfe diagnose --model-out or "
                        f"gdfe calibrate --model-out")
    return n


def run_ensemble(design, model, n, args, nominal, measure, labels, process=None):
    """:func:`gdfe.ensemble.fold_ensemble` with the command's solver options, level, seed and scheduler."""
    from gdfe.cli._progress import progress_mode
    from gdfe.ensemble import fold_ensemble

    options = {k: getattr(args, k, None) for k in ("method", "tol", "max_iter", "contact", "on_drift")}
    with using_scheduler(getattr(args, "scheduler", None)):
        return fold_ensemble(design, model, n, nominal=nominal, measure=measure, labels=labels, level=args.level,
                             seed=args.seed, process=process, options=options,
                             progress=progress_mode(args))


def write_ensemble(ens, result, out, name, title, threshold=None, png_name=None):
    """The spread into the last VTU of ``NAME``'s series and ``NAME_uncertainty.png`` (or ``png_name``): their
    paths. ``threshold``: ``(measure, value)`` marked in the picture."""
    from pathlib import Path

    from gdfe.ensemble import plot_band, write_spread

    vtu = write_spread(result, ens, out, name)
    png = plot_band(ens, Path(out) / (png_name or f"{name}_uncertainty.png"), title=title, threshold=threshold)
    return {"spread_vtu": str(vtu), "uncertainty_png": str(png)}
