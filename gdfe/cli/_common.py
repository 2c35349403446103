"""What the subcommands share: printing results, the solver's options, writing outputs.

Conventions of every subcommand: ``--json`` prints the result as JSON on standard output
instead of the text (``--json -`` too), ``--json FILE.json`` writes it there and prints the
text, in the one vocabulary of :mod:`gdfe.cli._vocabulary` (old keys kept as aliases for a release); an
output folder (``--out DIR``) is written by :class:`gdfe.io.OutputFolder`, complete
or marked incomplete, a rerun replacing it; a run that the estimate calls large
(:mod:`gdfe.resources`) starts only with ``--large``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from pathlib import Path

from gdfe._validation import GdfeError, check_choice
from gdfe.io import finite_json
from gdfe.resources import LARGE_MEMORY_FRACTION, LARGE_SECONDS, format_seconds
from gdfe.solver.simulation import TRUSTED_TOL  # the loosest --tol the command line accepts

__all__ = ["emit", "solver_args", "solve", "write_outputs", "exit_status", "scheduler_arg", "using_scheduler",
           "contact_fields", "contact_text", "json_arg", "out_arg", "output_folder", "iterations_text",
           "status_word", "command_line", "file_path", "new_file_path", "new_toml_path", "TRUSTED_TOL"]


class _JsonAction(argparse.Action):
    """``--json`` (standard output), ``--json -`` (the same) or ``--json FILE.json``."""

    def __call__(self, parser, namespace, value, option_string=None):
        if value != "-" and not str(value).lower().endswith(".json"):
            parser.error(f"{option_string}: expected FILE.json, or nothing (or '-') for standard output, got "
                         f"{value!r}; to print JSON, put {option_string} after the other arguments")
        setattr(namespace, self.dest, value)


def json_arg(p, what="the result", dest="json"):
    """``--json [FILE.json]``, the same on every subcommand."""
    p.add_argument("--json", nargs="?", const="-", default=None, metavar="FILE.json", action=_JsonAction, dest=dest,
                   help=f"{what} as JSON on standard output instead of the text (--json or --json -), or written "
                        "to FILE.json beside the text")


def emit(obj, as_json, text: str, command=None) -> None:
    """The result: ``text``, or ``obj`` as JSON on standard output (``as_json`` True or ``"-"``), or both
    (``as_json`` a file name: the JSON written there, the text printed with a line saying so).

    The JSON is in the one vocabulary (:mod:`gdfe.cli._vocabulary`), with the old keys of ``command``
    (``"hinge"``, ``"fem hinge"``) and of the library's dictionaries kept as aliases for a release."""
    from gdfe.cli._vocabulary import with_aliases

    payload = finite_json(with_aliases(obj, command))
    if as_json is True or as_json == "-":
        print(json.dumps(payload, indent=2, allow_nan=False))
        return
    if as_json:
        from gdfe.io import write_text

        path = Path(as_json)
        try:
            write_text(path, json.dumps(payload, indent=2, allow_nan=False) + "\n")
        except OSError as exc:
            raise GdfeError(f"--json: cannot write {path}: {exc.strerror or exc}") from None
        text = f"{text}\nwrote {path}"
    print(text)


def file_path(text):
    """An argument naming a file: not empty (``Path('')`` would be the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected the name of a file, got {text!r}")
    return Path(text)


def new_file_path(text):
    """An argument naming a file to write: not empty, not a folder, not ``-`` (which only ``--json`` reads as
    standard output)."""
    _not_standard_output(text, "file")
    path = file_path(text)
    if path.is_dir() or text.endswith(("/", os.sep)):
        raise argparse.ArgumentTypeError(f"expected the name of a file to write, got the folder {text!r}")
    return path


def new_toml_path(text):
    """An argument naming a TOML file to write (a model file): ``NAME.toml``, so that no input (a CSV,
    a picture) is overwritten by a mistyped option."""
    path = new_file_path(text)
    if path.suffix.lower() != ".toml":
        raise argparse.ArgumentTypeError(f"expected a file name ending in .toml, got {text!r}")
    return path


def _not_standard_output(text, what):
    if text.strip() == "-":
        raise argparse.ArgumentTypeError(f"expected the name of a {what} to write, got '-' (standard output is "
                                         "only for --json)")


def _out_path(text):
    _not_standard_output(text, "folder")
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected the name of a folder, got {text!r}")
    return Path(text)


def out_arg(p, required=False, help="output folder"):
    """``--out DIR``: an output folder, complete or marked incomplete, replaced by a rerun."""
    p.add_argument("--out", type=_out_path, required=required, default=None, metavar="DIR",
                   help=f"{help} (written completely or marked incomplete by {'INCOMPLETE.txt'}; a rerun "
                        "replaces an output folder of gdfe, and no other folder is written into)")


def command_line(args):
    """The command as typed (``args.argv``, set by :func:`gdfe.cli.main`), for an output folder's marker and manifest."""
    import shlex

    return shlex.join(["gdfe", *getattr(args, "argv", [])])


def output_folder(path, args, name="--out"):
    """An :class:`gdfe.io.OutputFolder` for ``path`` (checked now; entered when the command writes), or None."""
    from gdfe.io import OutputFolder

    return None if path is None else OutputFolder(path, command=command_line(args), name=name)


#: The tightest --tol the command line accepts (units of h): below it the Newton step's estimate of the
#: distance to the solution is round-off (a 384-cell hinge stalls at 4e-13, a 1 200-cell drawing at
#: 3e-12, in double precision), and the solve runs to its iteration limit.
ROUNDOFF_TOL = 1e-10

#: Errors of the file system that are the environment's, not a bug: no space, no permission, read-only.
_ENVIRONMENT_ERRNOS = {"ENOSPC", "EACCES", "EPERM", "EROFS", "EDQUOT", "ENOTDIR", "EISDIR", "ENAMETOOLONG", "EEXIST"}


@contextlib.contextmanager
def noting(*folders):
    """Run a command's body: on Ctrl-C note what each output folder was left as (for the one line
    :func:`gdfe.cli.main` prints); a full disk or a missing permission is a user error, not a bug."""
    import errno

    try:
        yield
    except KeyboardInterrupt as exc:
        exc.gdfe_left = [f.left or f"nothing was written to {f.path} (it is unchanged)" for f in folders if f]
        raise
    except OSError as exc:
        if errno.errorcode.get(exc.errno) not in _ENVIRONMENT_ERRNOS:
            raise
        where = exc.filename or (folders[0].path if folders and folders[0] else "a file")
        left = "; ".join(f.left for f in folders if f and f.left)
        raise GdfeError(f"cannot write {where}: {exc.strerror}" + (f" ({left})" if left else "")) from None


def status_word(res):
    """``converged`` or ``NOT CONVERGED`` for a result's text, PNG title and JSON ``status``."""
    return "converged" if res.converged else "NOT CONVERGED"


def shown(x, digits):
    """``x`` rounded to the ``digits`` it is printed with, a negative zero made 0: a fold of round-off
    size (-1e-14 rad where nothing contracts) prints as 0.0000, not -0.0000."""
    return round(float(x), digits) + 0.0


def iterations_text(res):
    """``converged in 33 iterations over 5 frames (4-9 per frame)`` (or in N iterations, one frame)."""
    per = list(res.frame_iterations)
    head = f"{status_word(res)} in {res.iterations} iterations"
    if len(per) > 1:
        head += f" over {len(per)} frames ({min(per)}-{max(per)} per frame)"
    return head


def scheduler_arg(p):
    """``--scheduler ADDRESS``: run the command's independent simulations on a Dask cluster."""
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler (tcp://host:8786) for the independent simulations (default: "
                        "$GDFE_SCHEDULER, else local processes)")


@contextlib.contextmanager
def using_scheduler(address):
    """The command's :func:`gdfe.parallel.parallel_map` calls go to ``address`` (None: unchanged)."""
    from gdfe.parallel import SCHEDULER_ENV

    if address is None:
        yield
        return
    old = os.environ.get(SCHEDULER_ENV)
    os.environ[SCHEDULER_ENV] = address
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(SCHEDULER_ENV, None)
        else:
            os.environ[SCHEDULER_ENV] = old


def _process(text):
    """``NAME=VALUE[,NAME=VALUE...]`` -> dict; values that read as numbers are numbers."""
    import argparse

    out = {}
    for item in filter(None, (t.strip() for t in text.split(","))):
        name, eq, value = item.partition("=")
        if not eq or not name.strip() or not value.strip():
            raise argparse.ArgumentTypeError(f"expected NAME=VALUE pairs separated by commas, got {item!r}")
        name = name.strip()
        if name in out:
            raise argparse.ArgumentTypeError(f"expected each name once, got {name} more than once in {text!r}: which "
                                             f"value the part was made at cannot be told")
        try:
            out[name] = float(value)
        except ValueError:
            out[name] = value.strip()
    return out


def process_arg(p):
    """``--process NAME=VALUE,...``: the part's process variables for a model's process mechanisms."""
    p.add_argument("--process", type=_process, default=None, metavar="NAME=VALUE,...",
                   help="process variables of the part for the deformation model (e.g. T_C=150,lot=B)")


def solver_args(p, defaults_from_file=False):
    """The options of :func:`gdfe.simulate` on a subcommand's parser."""
    from gdfe.solver import METHODS

    d = None if defaults_from_file else 1
    p.add_argument("--method", choices=sorted(METHODS, key=lambda m: m != "auto"), default=None,
                   help="solver (default auto: newton for small designs, newton-cg for larger ones)")
    p.add_argument("--steps", type=int, default=d, help="frames of the contraction ramp (default 1)")
    p.add_argument("--tol", type=float, default=None,
                   help="tolerance in units of h (default: Newton methods stop when their estimated distance to "
                        "the solution is below 1e-6 of the part's size; alternation 1e-7)")
    p.add_argument("--on-drift", choices=("warn", "stop"), default=None,
                   help="when a Newton solve drifts between near-equal states (a buckled sheet): warn and go on "
                        "(default) or stop there, not converged")
    p.add_argument("--max-iter", type=int, default=None, help="iteration limit per frame")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--contact", dest="contact", action="store_const", const="on", default=None,
                   help="solve with self-contact, so the film never passes through itself (needs the IPC "
                        "Toolkit: pip install 'gdfe[contact]'); default: contact only where the contact-free "
                        "solve penetrates itself")
    g.add_argument("--no-contact", dest="contact", action="store_const", const="off",
                   help="solve without self-contact (the result is still checked for self-penetration)")
    p.add_argument("--allow-penetration", action="store_true",
                   help="exit with status 0 even when the result passes through itself")
    p.add_argument("--large", action="store_true",
                   help=f"run even when the estimate (printed) says the run is long (over "
                        f"{format_seconds(LARGE_SECONDS)}) or takes more than "
                        f"{100 * LARGE_MEMORY_FRACTION:g} %% of the machine's memory")


def solve(design, args, options=None, source=None):
    """:func:`gdfe.simulate` with the options of a design file, overridden by the command line's.

    Before it starts: the options are checked (those of a design file with its name,
    ``source``), ``tol`` must be at most :data:`TRUSTED_TOL`, and the run's estimate
    (:func:`gdfe.resources.estimate_run`) must fit the machine, and, where it is large, be
    confirmed with ``--large``. The solve shows its progress (:class:`SolveProgress`).
    """
    import gdfe
    from gdfe.cli._progress import SolveProgress, announce_estimate, progress_mode
    from gdfe.resources import estimate_run
    from gdfe.solver import METHODS, MULTILEVEL_CELLS

    opts = dict(options or {})
    where = f"{source}: [simulate] " if source else ""
    for key, choices in (("method", METHODS), ("contact", ("auto", "on", "off")), ("on_drift", ("warn", "stop"))):
        if key in opts:
            check_choice(f"{where}{key}", opts[key], choices)
    for key in ("method", "steps", "tol", "max_iter", "contact", "on_drift"):
        v = getattr(args, key, None)
        if v is not None:
            opts[key] = v
    tol = opts.get("tol")
    name = "--tol" if getattr(args, "tol", None) is not None else f"{where}tol"
    if isinstance(tol, (int, float)) and not isinstance(tol, bool) and 0 < tol < ROUNDOFF_TOL:
        raise GdfeError(f"{name}: expected at least {ROUNDOFF_TOL:g} (units of h), got {tol:g}: below round-off, "
                        f"where the distance to the solution cannot be measured, so no solve would ever stop")
    if isinstance(tol, (int, float)) and not isinstance(tol, bool) and tol > TRUSTED_TOL:
        raise GdfeError(f"{name}: expected at most {TRUSTED_TOL:g} (units of h; the default scales with the part), "
                        f"got {tol:g}: a looser tolerance can stop far from the shape (gdfe study stopping measures "
                        f"it), so its result would not be converged")
    steps = opts.get("steps", 1)
    if isinstance(steps, int) and not isinstance(steps, bool) and steps >= 1:
        est = estimate_run(design.n_cells, steps, design.mesh.n_points, design.mesh.spacing)
        if not est.fits:
            raise GdfeError(f"this run would not fit in memory: {est.text()}; coarsen the design or use fewer --steps")
        if est.large and not getattr(args, "large", False):
            raise GdfeError(f"this run is large: {est.text()}; pass --large to run it anyway, or coarsen the design "
                            "(or fewer --steps)")
        announce_estimate(est, progress_mode(args))
    multilevel = opts.get("init", "auto") == "auto" and design.n_cells > MULTILEVEL_CELLS
    with SolveProgress(progress_mode(args), frames=steps if isinstance(steps, int) else 1, cells=design.n_cells,
                       multilevel=multilevel, contact=opts.get("contact", "auto")):
        return gdfe.simulate(design, **opts)


def write_outputs(result, out, name, summary, progress=None, command=None):
    """The VTU series, a PNG (its title marked NOT CONVERGED where it is not) and ``result.json`` in ``out``
    (``summary`` in the vocabulary of ``command``'s JSON, :func:`emit`)."""
    from gdfe.cli._vocabulary import with_aliases
    from gdfe.io import render_png, write_json, write_series

    out.mkdir(parents=True, exist_ok=True)
    pvd = write_series(result, out, name=name, progress=progress)
    title = summary.get("title") or name
    if not result.converged:
        title = f"NOT CONVERGED (residual {result.residual:.2g} after {result.iterations} iterations): {title}"
    png = render_png(result, out / f"{name}.png", title=title)
    files = {"pvd": str(pvd), "png": str(png), "json": str(out / "result.json")}
    write_json(out / "result.json", with_aliases({**summary, "files": files}, command))
    return files


def contact_fields(res):
    """The self-contact keys of a command's JSON: ``penetration_mm`` (0 when none), ``contact`` (used or not) and details."""
    summary = res.summary()
    return {k: summary[k] for k in ("penetration_mm", "contact", "penetration", "contact_info") if k in summary}


def contact_text(res):
    """One line on self-contact and self-penetration for a command's text output."""
    rep = res.contact
    how = (f"with self-contact (gap {rep.dhat_mm:.3g} mm, {rep.pairs} surface pairs within it)" if rep.used
           else "without self-contact")
    return f"  {how}: {res.penetration.text()}"


def exit_status(res, allow_penetration=False):
    """0 for a converged result free of self-penetration; 3 (not converged) or 4 (it penetrates itself), with a message."""
    if not res.converged:
        print(f"gdfe: error: the solver did not converge (residual {res.residual:.3g} after "
              f"{res.iterations} iterations); raise --max-iter or check the design", file=sys.stderr)
        return 3
    if res.penetrates and not allow_penetration:
        depth = max(p.depth_mm for p in res.frame_penetration)
        if res.contact.used:
            hint = "the contact solve should prevent this: please report it"
        elif not res.contact.available:
            hint = "install the IPC Toolkit for self-contact (pip install 'gdfe[contact]') and rerun"
        else:
            hint = "rerun with --contact"
        print(f"gdfe: error: the simulated film passes through itself ({depth:.3g} mm deep); {hint}, or pass "
              f"--allow-penetration to accept it", file=sys.stderr)
        return 4
    return 0
