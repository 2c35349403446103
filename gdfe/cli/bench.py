"""``gdfe bench``: the benchmark of :mod:`studies.bench` (hinges, mask sheets, lower bound, FEM)."""

from __future__ import annotations


from gdfe.cli._common import emit, json_arg, noting, out_arg, output_folder
from gdfe.solver.newton import COARSE_SOLVERS

__all__ = ["register", "run"]


#: The fewest cells of a benchmark sheet (a 2 x 2 sheet), and the most any machine could hold
#: (:func:`gdfe.resources.check_work` refuses what this one cannot).
MIN_CELLS, MAX_CELLS = 4, 10**12


def _sizes(text):
    """Cell counts, as numbers (written as integers or as 1e5); checked by :func:`_check_sizes`."""
    import argparse

    try:
        return [float(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected cell counts separated by commas (e.g. 1e3,1e4), got "
                                         f"{text!r}") from None


def _sizes_or_none(text):
    return [] if text.strip().lower() in ("", "none", "0") else _sizes(text)


def register(subparsers):
    """Add the ``bench`` subcommand."""
    p = subparsers.add_parser("bench", help="benchmark GDFE (hinges, mask sheets, lower bound, FEM)",
                              description="GDFE's speed, against its own lower bound and the reference FEM.")
    p.add_argument("--quick", action="store_true", help="tiny sizes, one repeat, no FEM (seconds)")
    json_arg(p, "the numbers")
    out_arg(p, help="write bench.json, bench.txt, bench_scaling.png and the masks into this folder")
    p.add_argument("--sizes", type=_sizes, help="corrugation sheet sizes in cells, comma-separated (e.g. 1e3,1e4,1e5,1e6)")
    p.add_argument("--freeform-sizes", type=_sizes_or_none,
                   help="sizes of the Figure 8 plates in cells (default 1e5; 'none' for none)")
    p.add_argument("--no-hinges", dest="hinges", action="store_false", help="skip the Figure 6 hinges")
    p.add_argument("--no-fem", dest="fem", action="store_false", default=None, help="skip the FEM comparison")
    p.add_argument("--fem", dest="fem", action="store_true", help="run the FEM comparison even with --quick")
    p.add_argument("--coarse-solver", choices=COARSE_SOLVERS, default=None,
                   help="how the sheets' Newton-CG solves its coarse matrix: factorised (default) or by "
                        "smoothed-aggregation V-cycles (needs pyamg)")
    p.add_argument("--large", action="store_true",
                   help="run even when the estimate of a sheet size says it is long or takes most of the memory")
    p.set_defaults(func=run)


def _check_sizes(args):
    """Every sheet size a whole count that fits the machine, and a large one asked for with --large
    (estimates printed); ``args.sizes`` and ``args.freeform_sizes`` become integers."""
    import math

    from gdfe._validation import GdfeError
    from gdfe.resources import estimate_run

    for option, dest in (("--sizes", "sizes"), ("--freeform-sizes", "freeform_sizes")):
        sizes = getattr(args, dest)
        for v in sizes or []:
            if not math.isfinite(v) or v != int(v) or not MIN_CELLS <= v <= MAX_CELLS:
                raise GdfeError(f"{option}: expected whole cell counts from {MIN_CELLS} to {MAX_CELLS:.0e}, got "
                                f"{v:g}")
        if sizes is not None:
            setattr(args, dest, [int(v) for v in sizes])
        for n in getattr(args, dest) or []:
            est = estimate_run(n)
            if not est.fits:
                raise GdfeError(f"{option}: a sheet of {n:,} cells would not fit in memory: {est.text()}; "
                                f"give smaller sizes")
            if est.large and not args.large:
                raise GdfeError(f"{option}: a sheet of {n:,} cells is a large run: {est.text()}; pass --large to "
                                f"run it")


def run(args):
    from contextlib import nullcontext

    from studies import bench

    _check_sizes(args)
    folder = output_folder(args.out, args)
    with noting(folder), (folder or nullcontext()):
        res = bench.run(quick=args.quick, sizes=args.sizes, fem=args.fem, out=args.out,
                        freeform_sizes=args.freeform_sizes, hinges=args.hinges, coarse_solver=args.coarse_solver)
    emit(res, args.json, bench.format_table(res), command="bench")
    accelerated = [r for r in res["hinges"] if r["method"] in ("newton", "newton-cg")]
    sheets = [r for r in res["sheets"] if "skipped" not in r]
    ok = all(r["converged"] for r in accelerated + sheets)
    return 0 if ok else 1
