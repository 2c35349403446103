"""``gdfe predict M.toml SPECIMENS.csv``: fold angles of hinge specimens with intervals and their parts."""

from __future__ import annotations

from gdfe._validation import GdfeError, check_number
from gdfe.cli._common import emit, file_path, json_arg
from gdfe.diagnosis.forward import CELLS
from gdfe.predict import LEVEL

__all__ = ["register", "run"]


def register(sub):
    p = sub.add_parser(
        "predict", help="fold angles of hinge specimens with intervals (parameters, model choice, noise)",
        description="Predict the fold angle of each specimen row (L_mm, d_mm, optional h_mm and process columns) "
                    "from a model file, as it would be measured the way the model's tests were, with an interval "
                    "at --level that combines the parameters' uncertainty, the choice between the models the data "
                    "could not tell apart (weighted by stacking of held-out densities) and the noise of a test, "
                    "and each part on its own. With an alpha_rad column, the coverage of the measured angles.")
    p.add_argument("model", type=file_path, help="model file (gdfe diagnose/calibrate --model-out)")
    p.add_argument("specimens", type=file_path, help="CSV with L_mm, d_mm (h_mm, alpha_rad, process columns optional)")
    p.add_argument("--level", type=float, default=LEVEL, help=f"level of the intervals (default {LEVEL:g})")
    p.add_argument("--simulate", nargs="?", const="coarse", choices=list(CELLS), default=None,
                   help="each member's angle from a GDFE solve of the hinge (default resolution coarse) instead of "
                        "the closed form")
    p.add_argument("--noise", type=float, default=None, metavar="S",
                   help="noise of a test [rad], replacing the model file's (needed for a model file without one); "
                        "with --discrepancy, the known noise the process's white kernel is fixed at (default: fitted)")
    p.add_argument("--discrepancy", type=file_path, default=None, metavar="DATA.csv",
                   help="the Kennedy-O'Hagan predictor instead: the model file's closed form plus a Gaussian-process "
                        "discrepancy (scikit-learn) fitted to its residuals on these folding tests")
    json_arg(p, "the predictions")
    p.set_defaults(func=run)


def check_level(level):
    return check_number("--level", level, minimum=0.0, maximum=1.0, include_minimum=False, include_maximum=False)


def run(args):
    import gdfe
    from gdfe.predict import predict

    level = check_level(args.level)  # named as the user gave it, on either path
    model = gdfe.load_model(args.model)
    if args.discrepancy is not None:
        from gdfe.discrepancy import fit_discrepancy

        if args.simulate is not None:
            raise GdfeError("--discrepancy: expected no --simulate (the discrepancy corrects the closed form)")
        if args.noise is not None:
            check_number("--noise", args.noise, minimum=0.0, include_minimum=False)
        try:
            koh = fit_discrepancy(model, gdfe.load_folding_tests(args.discrepancy), noise=args.noise)
        except GdfeError as exc:  # its rows are the file's
            raise GdfeError(f"--discrepancy {args.discrepancy.name}: {exc}") from None
        pred = koh.predict(args.specimens, level=level)
    else:
        pred = predict(model, args.specimens, level=level, noise=args.noise, simulate=args.simulate)
    emit(pred.as_dict(), args.json, pred.text(), command="predict")
    return 0 if pred.converged else 3
