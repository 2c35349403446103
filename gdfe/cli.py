"""The ``gdfe`` command line.

Every subcommand is a small function ``_cmd_NAME(args) -> int``; :func:`main` takes
``argv`` so that tests call ``main([...])`` directly. Subcommands that live beside the
core (the reference FEM, the studies, the diagnosis, the benchmark) register themselves
through a ``register(subparsers)`` function in their own module, which must import
nothing heavy at module level.
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import sys

__all__ = ["main", "CLIError"]

# Modules that contribute subcommands: each has ``register(subparsers)``.
_PLUGINS = (
    "gdfe._cli_core",
    "reference_fem.cli",
    "studies.cli",
    "gdfe.diagnosis.cli",
    "gdfe.bench",
)


class CLIError(Exception):
    """An error reported to the user as one line, with a non-zero exit status."""


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gdfe",
        description="Geometry-driven finite elements for 4D-printed heat-shrinking structures.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in _PLUGINS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:  # a plugin that is not there yet
            if exc.name and name.startswith(exc.name):
                continue
            raise
        module.register(sub)
    return parser


def emit(obj, as_json: bool, text: str) -> None:
    """Print ``obj`` as JSON if ``as_json``, else the human-readable ``text``."""
    if as_json:
        print(json.dumps(obj, indent=2, default=_json_default))
    else:
        print(text)


def _json_default(o):
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def main(argv=None) -> int:
    """Run the ``gdfe`` command line; return the exit status."""
    parser = _build_parser()
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
    except (CLIError, ValueError, TypeError, FileNotFoundError) as exc:
        print(f"gdfe {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
