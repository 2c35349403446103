"""What the subcommands share: printing results, the solver's options, writing outputs."""

from __future__ import annotations

import contextlib
import json
import os
import sys

from gdfe.io import json_default

__all__ = ["emit", "solver_args", "solve", "write_outputs", "exit_status", "scheduler_arg", "using_scheduler"]


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


def solver_args(p, defaults_from_file=False):
    """The options of :func:`gdfe.simulate` on a subcommand's parser."""
    from gdfe.solver import METHODS

    d = None if defaults_from_file else 1
    p.add_argument("--method", choices=sorted(METHODS, key=lambda m: m != "auto"), default=None,
                   help="solver (default auto: newton for small designs, newton-cg for larger ones)")
    p.add_argument("--steps", type=int, default=d, help="frames of the contraction ramp (default 1)")
    p.add_argument("--tol", type=float, default=None, help="residual tolerance (default 1e-7, in units of h)")
    p.add_argument("--max-iter", type=int, default=None, help="iteration limit per frame")


def solve(design, args, options=None):
    """:func:`gdfe.simulate` with the options of a design file, overridden by the command line's."""
    import gdfe

    opts = dict(options or {})
    for key in ("method", "steps", "tol", "max_iter"):
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


def exit_status(res):
    """0 for a converged result; 3, with a message, for one that is not."""
    if not res.converged:
        print(f"gdfe: error: the solver did not converge (residual {res.residual:.3g} after "
              f"{res.iterations} iterations); raise --max-iter or check the design", file=sys.stderr)
        return 3
    return 0
