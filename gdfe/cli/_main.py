"""The ``gdfe`` command line: the parser, the dispatch, and how errors reach the user.

Every subcommand lives in a module of its own in this package, with
``register(subparsers)`` (its arguments, choices taken from the library's registries) and
a ``run(args) -> int`` that the parser's ``func`` default points to. They are imported
statically here; each imports the heavy parts (the reference FEM, the studies, plotting)
inside the function that runs.

Errors: a :class:`gdfe.GdfeError` (something wrong in what the user gave) is printed as
one line, with exit status 1. Any other exception is a bug: it keeps its traceback, after a
line saying how to report it. ``--debug`` prints the traceback of user errors too.
"""

from __future__ import annotations

import argparse
import logging
import sys
import traceback

from gdfe._validation import GdfeError
from gdfe.cli import bench, calibrate, design, diagnose, fem, hinge, report, simulate, study, view

__all__ = ["main", "build_parser", "SUBCOMMANDS"]

#: The modules of the subcommands, in the order of ``gdfe --help``.
SUBCOMMANDS = (hinge, simulate, design, view, fem, study, report, calibrate, diagnose, bench)

#: Where bugs are reported.
ISSUES = "the project's issue tracker"


def build_parser() -> argparse.ArgumentParser:
    """The ``gdfe`` argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="gdfe",
        description="Geometry-driven finite elements for 4D-printed heat-shrinking structures.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress")
    parser.add_argument("--debug", action="store_true",
                        help="print the traceback of every error, user errors included")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in SUBCOMMANDS:
        module.register(sub)
    return parser


def main(argv=None) -> int:
    """Run the ``gdfe`` command line; return the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:  # the reader of our output went away (gdfe ... | head): stop quietly
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except GdfeError as exc:
        if args.debug:
            traceback.print_exc()
        print(f"gdfe {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except Exception:
        from gdfe import __version__

        print(f"gdfe {args.command}: internal error: this is a bug in gdfe {__version__}, not a problem "
              f"with your input. Please report it to {ISSUES} with the command line and the traceback "
              f"below.", file=sys.stderr)
        raise


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
