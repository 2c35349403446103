"""``gdfe bench``: the benchmark of :mod:`studies.bench` (hinges, mask sheets, lower bound, FEM)."""

from __future__ import annotations

from pathlib import Path

from gdfe.cli._common import emit

__all__ = ["register", "run"]


def _sizes(text):
    return [int(float(x)) for x in text.split(",")]


def _sizes_or_none(text):
    return [] if text.strip().lower() in ("", "none", "0") else _sizes(text)


def register(subparsers):
    """Add the ``bench`` subcommand."""
    p = subparsers.add_parser("bench", help="benchmark GDFE (hinges, mask sheets, lower bound, FEM)",
                              description="GDFE's speed, against its own lower bound and the reference FEM.")
    p.add_argument("--quick", action="store_true", help="tiny sizes, one repeat, no FEM (seconds)")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
    p.add_argument("--out", type=Path, help="write bench.json, bench_scaling.png and the masks here")
    p.add_argument("--sizes", type=_sizes, help="corrugation sheet sizes in cells, comma-separated (e.g. 1e3,1e4,1e5,1e6)")
    p.add_argument("--freeform-sizes", type=_sizes_or_none,
                   help="sizes of the Figure 8 plates in cells (default 1e5; 'none' for none)")
    p.add_argument("--no-hinges", dest="hinges", action="store_false", help="skip the Figure 6 hinges")
    p.add_argument("--no-fem", dest="fem", action="store_false", default=None, help="skip the FEM comparison")
    p.add_argument("--fem", dest="fem", action="store_true", help="run the FEM comparison even with --quick")
    p.set_defaults(func=run)


def run(args):
    from studies import bench

    res = bench.run(quick=args.quick, sizes=args.sizes, fem=args.fem, out=args.out,
                    freeform_sizes=args.freeform_sizes, hinges=args.hinges)
    emit(res, args.json, bench.format_table(res))
    accelerated = [r for r in res["hinges"] if r["method"] in ("newton", "newton-cg")]
    sheets = [r for r in res["sheets"] if "skipped" not in r]
    ok = all(r["converged"] for r in accelerated + sheets)
    return 0 if ok else 1
