"""Cost of GDFE against element count, beside the nonlinear reference FEM (issue 6).

Not a figure of the paper: the paper claims GDFE is simpler and faster than full FEM
(Sec. 1, Sec. 3.1: the n x n system "can be prefactorized ... only backward
substitutions"); this study puts numbers on it with :func:`studies.bench.run` and plots
seconds to convergence against the number of elements for the PNG-mask sheets (10^3 to
10^5 cells, 10^6 at ``resolution="fine"``), the L = 1.6 mm hinge at five GDFE
resolutions and the same hinge with the nonlinear FEM at four mesh levels.

Run ``python -m studies.bench_scaling [--out DIR] [--resolution R]`` or ``gdfe study bench-scaling``;
writes ``bench.json``, ``bench_scaling.png`` and ``bench.txt`` (the benchmark's table).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gdfe._validation import check_choice
from gdfe.io import write_text
from studies import bench

#: Sheet sizes [cells] per resolution; "coarse" is the benchmark's --quick mode.
SIZES = {"coarse": None, "default": (1_000, 10_000, 100_000), "fine": (1_000, 10_000, 100_000, 1_000_000)}


def run(resolution="default", out=None):
    """Run the benchmark at ``resolution``; write its files into ``out``; return its numbers."""
    check_choice("resolution", resolution, SIZES)
    result = bench.run(quick=resolution == "coarse", sizes=SIZES[resolution], out=out)
    if out is not None:
        write_text(Path(out) / "bench.txt", bench.format_table(result) + "\n")
    return result


def plot(result, out):
    """Seconds against elements (``bench_scaling.png`` in ``out``)."""
    Path(out).mkdir(parents=True, exist_ok=True)
    bench.plot(result, Path(out) / "bench_scaling.png")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--resolution", choices=list(SIZES), default="default")
    parser.add_argument("--out", type=Path, default=Path("out") / "bench_scaling")
    args = parser.parse_args(argv)
    result = run(args.resolution, args.out)
    print(bench.format_table(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
