"""What the subcommands share: printing results, the solver's options, writing outputs."""

from __future__ import annotations

import contextlib
import json
import os
import sys

from gdfe.io import json_default

__all__ = ["emit", "solver_args", "solve", "write_outputs", "exit_status", "scheduler_arg", "using_scheduler",
           "contact_fields", "contact_text"]


def emit(obj, as_json: bool, text: str) -> None:
    """Print ``obj`` as JSON if ``as_json``, else the human-readable ``text``."""
    if as_json:
        print(json.dumps(obj, indent=2, default=json_default))
    else:
        print(text)


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
        try:
            out[name.strip()] = float(value)
        except ValueError:
            out[name.strip()] = value.strip()
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


def solve(design, args, options=None):
    """:func:`gdfe.simulate` with the options of a design file, overridden by the command line's."""
    import gdfe

    opts = dict(options or {})
    for key in ("method", "steps", "tol", "max_iter", "contact", "on_drift"):
        v = getattr(args, key, None)
        if v is not None:
            opts[key] = v
    return gdfe.simulate(design, **opts)


def write_outputs(result, out, name, summary):
    """The VTU series, a PNG and ``result.json`` of a simulation in ``out``."""
    from gdfe.io import render_png, write_json, write_series

    out.mkdir(parents=True, exist_ok=True)
    pvd = write_series(result, out, name=name)
    png = render_png(result, out / f"{name}.png", title=summary.get("title"))
    write_json(out / "result.json", summary)
    return {"pvd": str(pvd), "png": str(png), "json": str(out / "result.json")}


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
