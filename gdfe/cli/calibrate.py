"""``gdfe calibrate DATA.csv``: readings of Eq. 1 fitted to folding tests (:func:`gdfe.fit_reading`)."""

from __future__ import annotations

from pathlib import Path

import logging

from gdfe._validation import GdfeError, check_positive, degenerate_tests
from gdfe.calibration import MAX_BOOT, MIN_BOOT, READINGS, check_boot, held_out_rmse
from gdfe.cli._common import emit, file_path, json_arg, new_toml_path

__all__ = ["register", "run"]

log = logging.getLogger("gdfe.cli.calibrate")


def register(sub):
    p = sub.add_parser("calibrate", help="fit Eq. 1 (K) to folding tests",
                       description="Fit a reading of Eq. 1 to folding tests (CSV with L_mm, d_mm, h_mm, alpha_rad): "
                                   "eq1 = K sqrt(h/d^3) L as printed; eq1-d1 = K sqrt(h/d) L; "
                                   "power = c (L/h) (h/d)^p.")
    p.add_argument("data", type=file_path, help="CSV of folding tests")
    p.add_argument("--model", choices=READINGS + ("all",), default="eq1",
                   help="reading of Eq. 1 (default eq1, as printed)")
    p.add_argument("--boot", type=int, default=2000,
                   help=f"bootstrap resamples for the 95 %% CI: 0 (none) or {MIN_BOOT} to {MAX_BOOT:g} (default 2000)")
    p.add_argument("--d", type=float, default=None, help="also print Eq. 3's R for this passive thickness [mm]")
    p.add_argument("--model-out", type=new_toml_path, default=None, metavar="M.toml",
                   help="save the fitted reading as a deformation model file (one --model, not all)")
    json_arg(p, "the fit")
    p.set_defaults(func=run)


def run(args):
    import gdfe

    check_boot("--boot", args.boot)
    if args.model_out is not None and args.model == "all":
        raise GdfeError("--model-out: expected one --model (eq1, eq1-d1 or power), got all")
    models = READINGS if args.model == "all" else (args.model,)
    _announce(args.data, args.boot, len(models))
    tests = gdfe.load_folding_tests(args.data)
    for note in degenerate_tests(args.data.name, tests.L, tests.d, tests.h, tests.alpha,
                                 same_angles=False):  # the fit's text says when every angle is the same
        log.warning("%s", note)
    if args.d is not None:
        check_positive("--d", args.d)
        h = float(tests.h.mean())
    out = []
    text = []
    for m in models:
        f = gdfe.fit_reading(tests, m, n_boot=args.boot)
        d = f.as_dict()
        d.pop("residuals")
        block = f.text()
        if f.r2 < 0:  # worse than the mean angle: a misread row (a unit, a typo) is likelier than the reading
            doubt = (f"r2 = {f.r2:.3g}: the {m} fit predicts the angles worse than their mean does; check the "
                     f"rows of {args.data.name} (a unit, a typo, an outlier) before using it")
            block += f"\nWARNING: {doubt}"
            d.setdefault("warnings", []).append(doubt)
        if args.d is not None:
            R = float(f.ratio(args.d, h))
            if not R > 0:  # a contraction ratio <= 0: the film would vanish
                raise GdfeError(f"--d: expected a passive thickness above {f.d_min(h):.4g} mm, where Eq. 3 of the "
                                f"{m} reading gives R > 0 (h = {h:g} mm), got {args.d:g} mm (R = {R:.4g})")
            d["R_at_d"] = {"d_mm": args.d, "h_mm": h, "R": R}
            block += f"\nR      {R:.4f} at d = {args.d:g} mm (Eq. 3 of this reading, h = {h:g} mm)"
        loo = held_out_rmse(tests, m)
        d["held_out_rmse_rad"] = loo
        block += f"\nLOO    {loo:.4f} rad (leave-one-test-out RMSE)"
        if args.model_out is not None:
            model = gdfe.DeformationModel.from_calibration(f, data=args.data, held_out_rmse=loo)
            model.save(args.model_out)
            d["model_file"] = str(args.model_out)
            block += f"\nwrote  {args.model_out} (deformation model {model.name!r})"
            block += "".join(f"\nWARNING: {w}" for w in model.warnings)
        out.append(d)
        text.append(block)
    emit(out[0] if len(out) == 1 else out, args.json, "\n\n".join(text), command="calibrate")
    return 0


#: Seconds per row of reading a CSV of folding tests, and per row and bootstrap resample of a fit
#: (``gdfe calibrate`` of 10^6 rows on 2 cores: read 7.8 s, 2 000 resamples 68 s).
READ_SECONDS_PER_ROW, BOOT_SECONDS_PER_ROW = 7.8e-6, 3.4e-8


def _announce(path, boot, n_models):
    """Say the estimate of a long calibration (a CSV of many rows, many resamples) before it starts."""
    from gdfe.resources import check_work

    try:
        with open(path, "rb") as f:
            rows = sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 20), b""))
    except OSError:
        return  # load_folding_tests names the file
    seconds = rows * (READ_SECONDS_PER_ROW + n_models * BOOT_SECONDS_PER_ROW * max(boot, 1))
    check_work(path.name, 0.0, f"{rows:,} rows x {boot} bootstrap resamples x {n_models} reading(s)", "",
               seconds=seconds, logger=log)
