"""The ``gdfe`` command line: the parser, the dispatch, and how errors reach the user.

Every subcommand lives in a module of its own in this package, with
``register(subparsers)`` (its arguments, choices taken from the library's registries) and
a ``run(args) -> int`` that the parser's ``func`` default points to. They are imported
statically here; each imports the heavy parts (the reference FEM, the studies, plotting)
inside the function that runs.

Errors: a mistake in the arguments is one line (exit status 2). A :class:`gdfe.GdfeError` (something wrong in what the user gave) is printed as
one line, with exit status 1. Any other exception is a bug: it keeps its traceback, after a
line saying how to report it. ``--debug`` prints the traceback of user errors too. Ctrl-C
stops a command with one line saying what it left (an output folder is then marked
incomplete) and exit status 130.

With ``--json`` an error is JSON too: besides its line on standard error, the command prints
(on standard output; with ``--json FILE.json`` into that file, in place of the result) one
object, ``{"error": {"type": ..., "message": ..., "argument": ..., "exit_status": ...}}``:
``type`` is ``"usage"`` for a mistake in the arguments (exit status 2), ``"GdfeError"`` for a
user error (1), ``"interrupted"`` for Ctrl-C (130) and ``"bug"`` for any other exception
(whose traceback still goes to standard error; ``exit_status`` 1, the status of a Python
error); ``argument`` is the option or argument the message names, where it names one.

The global options (``-v``, ``-q``, ``--progress``, ``--debug``) are accepted before or
after the subcommand; the log says each distinct warning once.
"""

from __future__ import annotations

import argparse
import contextlib
import contextvars
import json
import logging
import re
import sys
import traceback

from gdfe._validation import GdfeError
from gdfe.cli import bench, calibrate, data, design, diagnose, fem, hinge, plan, predict, report, simulate, study, view

__all__ = ["main", "build_parser", "SUBCOMMANDS"]

#: The modules of the subcommands, in the order of ``gdfe --help``.
SUBCOMMANDS = (hinge, simulate, design, view, fem, study, report, calibrate, diagnose, predict, plan, data, bench)

#: Where bugs are reported.
ISSUES = "the project's issue tracker"


def _global_options(parser, top):
    """The options every subcommand takes, before or after its name (``top``: the main parser's defaults)."""
    from gdfe import __version__

    d = (lambda v: v) if top else (lambda v: argparse.SUPPRESS)
    parser.add_argument("-v", "--verbose", action="store_true", default=d(False), help="log what the solver does")
    parser.add_argument("-q", "--quiet", action="store_true", default=d(False),
                        help="no progress (bars, lines, estimates) on standard error")
    parser.add_argument("--progress", action="store_true", default=d(False),
                        help="progress bars even when standard error is not a terminal (else: a line every "
                             "~10 s there)")
    parser.add_argument("--debug", action="store_true", default=d(False),
                        help="print the traceback of every error, user errors included")
    parser.add_argument("--version", action="version", version=f"gdfe {__version__}")


def _subparsers(parser):
    """Every subcommand parser below ``parser`` (``fem hinge`` too)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):
                yield sub
                yield from _subparsers(sub)


#: Where the JSON of the command being parsed goes: None (no --json), "-" (standard output) or a file.
_JSON_TARGET = contextvars.ContextVar("gdfe_json_target", default=None)


def _json_target(argv):
    """Where ``--json`` in ``argv`` sends the JSON (read before parsing, for the errors of parsing):
    None, ``"-"`` or ``FILE.json``."""
    target = None
    for i, token in enumerate(argv):
        if token == "--":
            break
        if token == "--json":
            nxt = argv[i + 1] if i + 1 < len(argv) else None
            target = nxt if nxt is not None and (nxt == "-" or nxt.lower().endswith(".json")) else "-"
        elif token.startswith("--json="):
            target = token.partition("=")[2] or "-"
    return target


def _argument(message):
    """The option or argument an error message names (``--d: expected ...``, ``argument --length/-L:
    ...``, ``length: expected ...``), or None."""
    for pattern in (r"^argument ([^\s/:]+)", r"arguments are required: ([^\s,/]+)", r"unrecognized arguments: (\S+)",
                    r"^(--?[A-Za-z][\w-]*)\b", r"^([A-Za-z_]\w*)(?::|=\S)"):
        m = re.search(pattern, message)
        if m:
            return m.group(1)
    return None


def _options(parser, args):
    """The running subcommand's arguments: dest -> the option as typed (``length`` -> ``--length``; a
    positional argument keeps its name), to name in an error the option that a library argument came from."""
    prog = _name(args)
    for sub in _subparsers(parser):
        if sub.prog == prog:
            return {a.dest: (next((o for o in a.option_strings if o.startswith("--")), a.option_strings[0])
                             if a.option_strings else a.dest) for a in sub._actions}
    return {}


def _as_options(message, options):
    """``message`` with a library's switch (``pass clamp=True``) named as the command's option (``pass
    --clamp``) where the running command has that option."""
    def option(m):
        flag = (options or {}).get(m.group(1), "")
        return flag if flag.startswith("--") else m.group(0)

    return re.sub(r"\b([A-Za-z_]\w*)=True\b", option, message)


def error_object(kind, message, exit_status, options=None):
    """The JSON of an error: ``{"error": {"type", "message", "argument" (where named), "exit_status"}}``;
    ``options`` (dest -> option) turns a library argument's name into the command's option."""
    err = {"type": kind, "message": message}
    argument = _argument(message)
    if argument is not None and options:
        argument = options.get(argument, argument)
    if argument is not None:
        err["argument"] = argument
    err["exit_status"] = exit_status
    return {"error": err}


def _emit_error(target, kind, message, exit_status, options=None):
    """With ``--json`` (``target`` not None), the error as JSON on standard output or into the file."""
    if target is None:
        return
    text = json.dumps(error_object(kind, message, exit_status, options), indent=2)
    if target == "-":
        print(text, flush=True)
        return
    from gdfe.io import write_text

    try:
        write_text(target, text + "\n")
    except (OSError, GdfeError):  # the file cannot be written (often the very error): its one line on standard error says it
        pass


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on standard error (exit status 2), naming
    the command and where its options are listed, instead of the usage block and a line; with
    ``--json`` also a JSON error object (:func:`error_object`, type ``"usage"``)."""

    def error(self, message):
        _emit_error(_JSON_TARGET.get(), "usage", f"{message} (options: {self.prog} --help)", 2)
        self.exit(2, f"{self.prog}: error: {message} (options: {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``gdfe`` argument parser with every subcommand."""
    parser = _Parser(
        prog="gdfe",
        description="Geometry-driven finite elements for 4D-printed heat-shrinking structures.",
    )
    _global_options(parser, top=True)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in SUBCOMMANDS:
        module.register(sub)
    for p in _subparsers(parser):
        _global_options(p, top=False)
    return parser


class _Once(logging.Filter):
    """Let each distinct message of a logger through once (a sweep repeats the same warning)."""

    def __init__(self):
        super().__init__()
        self.seen = set()

    def filter(self, record):
        key = (record.name, record.levelno, record.getMessage())
        if key in self.seen:
            return False
        self.seen.add(key)
        return True


@contextlib.contextmanager
def _logging(verbose):
    """The command's log on standard error (INFO with ``-v``, else WARNING), each distinct message
    once; the root logger is left as it was when the command ends (``main`` may run in a notebook)."""
    root = logging.getLogger()
    level = root.level
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    handler.addFilter(_Once())
    root.setLevel(logging.INFO if verbose else logging.WARNING)
    root.addHandler(handler)
    try:
        yield
    finally:
        root.removeHandler(handler)
        root.setLevel(level)


def _name(args):
    """``gdfe hinge``, ``gdfe fem hinge``: the command in messages."""
    sub = getattr(args, "fem_command", None)
    return f"gdfe {args.command}" + (f" {sub}" if sub else "")


def main(argv=None) -> int:
    """Run the ``gdfe`` command line; return the exit status."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    token = _JSON_TARGET.set(_json_target(argv))
    try:
        args = parser.parse_args(argv)
    finally:
        _JSON_TARGET.reset(token)
    args.argv = argv
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    with _logging(args.verbose):
        return _dispatch(args, _options(parser, args))


def _dispatch(args, options=None):
    """Run the subcommand; turn user errors, Ctrl-C and a closed pipe into an exit status (and, with
    ``--json``, a JSON error object)."""
    target = getattr(args, "json", None) or getattr(args, "json_out", None)
    from gdfe.parallel import stopping_workers

    try:
        if target not in (None, "-"):  # refused before anything is written, not after the other outputs
            from gdfe.io import check_creatable

            check_creatable(target, "--json", what="file")
        with stopping_workers():  # SIGTERM and Ctrl-C stop the worker processes too
            return int(args.func(args) or 0)
    except KeyboardInterrupt as exc:
        left = "; ".join(getattr(exc, "gdfe_left", [])) or "no output folder was being written"
        status = 128 + getattr(exc, "signum", 2)  # 130 for Ctrl-C, 143 for SIGTERM
        how = "interrupted" if status == 130 else f"stopped by signal {status - 128}"
        print(f"{_name(args)}: {how}: {left}", file=sys.stderr)
        _emit_error(target, "interrupted", f"{how}: {left}", status)
        return status
    except BrokenPipeError:  # the reader of our output went away (gdfe ... | head): stop quietly
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except GdfeError as exc:
        if args.debug:
            traceback.print_exc()
        text = _as_options(" ".join(str(exc).split()), options)  # one line, whatever a library underneath put in it
        print(f"{_name(args)}: error: {text}", file=sys.stderr)
        _emit_error(target, "GdfeError", text, 1, options)
        return 1
    except Exception as exc:
        from gdfe import __version__

        print(f"{_name(args)}: internal error: this is a bug in gdfe {__version__}, not a problem "
              f"with your input. Please report it to {ISSUES} with the command line and the traceback "
              f"below.", file=sys.stderr)
        _emit_error(target, "bug", f"{type(exc).__name__}: {' '.join(str(exc).split())}", 1)
        raise


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
