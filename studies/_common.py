"""Shared plumbing of the figure studies: resolutions, headline numbers, output, ``main``.

Every study module has ``run(resolution, out) -> dict``, ``plot(result, out)`` and
``main(argv)`` (``main = main_of(__name__)``). The dict it returns has at least

- ``study`` (name), ``figure`` (the paper's figure), ``title``, ``resolution``;
- ``headlines``: list of :func:`headline` dicts, the numbers a regression test asserts;
- ``converged``: whether every simulation of the study converged;
- ``summary``: ``paper``, ``ours``, ``verdict``, ``discrepancy`` sentences for the report.

Keys starting with ``_`` (simulated shapes kept for the plot) are left out of the JSON.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path

from gdfe._plotting import pyplot  # noqa: F401  (the studies take pyplot from here)
from gdfe._validation import GdfeError, check_choice

RESOLUTIONS = ("coarse", "default", "fine")

log = logging.getLogger(__name__)


def check_resolution(resolution):
    """``resolution`` if it is one of :data:`RESOLUTIONS`."""
    return check_choice("resolution", resolution, RESOLUTIONS)


def n_jobs(resolution):
    """Worker processes for a study's sweep: 1 at coarse resolution (process start-up would
    cost more than the work), else the default of :func:`gdfe.parallel.parallel_map`."""
    return 1 if resolution == "coarse" else None


def headline(name, ours, paper=None, tol=None, kind="abs", expect=True, unit="", note="", paper_text=None,
             goal=False):
    """One headline number with the paper's value and the tolerance it is checked with.

    Parameters
    ----------
    name : str
    ours : float or int
    paper : float or int, optional
        The paper's value (None where the paper states no number).
    tol : float, optional
        Tolerance; its meaning depends on ``kind``.
    kind : {"abs", "rel", "le", "ge", "eq"}
        ``abs``: ``|ours - paper| <= tol``; ``rel``: ``|ours - paper| <= tol |paper|``;
        ``le``/``ge``: ``ours <= tol`` / ``ours >= tol`` (a bound, no paper number needed);
        ``eq``: ``ours == paper``.
    expect : bool
        Whether the check is expected to hold. A known, explained discrepancy is recorded
        with ``expect=False``: the regression then passes as long as the discrepancy stays.
    paper_text : str, optional
        What the paper says, where it gives no number.
    goal : bool
        A speed target (seconds on the machine at hand): reported with whether it is met
        (``holds``), never a regression, since the same code takes twice as long on a loaded
        machine; ``passed`` is then True. Speed is measured by ``gdfe bench`` and the studies,
        not gated in tests.

    Returns
    -------
    dict
        With ``holds`` (the check), ``goal`` and ``passed`` (``holds == expect``, True for a goal).
    """
    ours_f = float(ours)
    if kind == "abs":
        holds = abs(ours_f - float(paper)) <= tol
        tol_text = f"|ours - paper| <= {tol:g}"
    elif kind == "rel":
        holds = abs(ours_f - float(paper)) <= tol * abs(float(paper))
        tol_text = f"|ours - paper| <= {100 * tol:g} % of paper"
    elif kind == "le":
        holds = ours_f <= tol
        tol_text = f"ours <= {tol:g}"
    elif kind == "ge":
        holds = ours_f >= tol
        tol_text = f"ours >= {tol:g}"
    elif kind == "eq":
        holds = ours_f == float(paper)
        tol_text = "ours == paper"
    else:
        check_choice("kind", kind, ("abs", "rel", "le", "ge", "eq"))
    if not math.isfinite(ours_f):
        holds = False
    if unit:
        tol_text += f" {unit}" if kind in ("abs", "le", "ge") else ""
    if kind == "eq" and ours_f.is_integer():
        ours_f = int(ours_f)
    return {"name": name, "ours": ours_f,
            "paper": paper, "paper_text": paper_text, "tolerance": tol_text, "unit": unit,
            "expect": bool(expect), "holds": bool(holds), "goal": bool(goal),
            "passed": True if goal else bool(holds) == bool(expect), "note": note}


def progress(items, what, total=None):
    """Iterate ``items``, reporting each step of a study's sweep through the log.

    Each step is a debug record of the logger ``studies._common`` with a ``progress``
    attribute (``{"event": "steps", "stage": what, "step": k, "total": n}``, step k of n under way): the command line
    (``gdfe study``, ``gdfe report``) shows it as a bar on a terminal and as a line every ~10 s
    elsewhere; without it nothing is printed.

    Parameters
    ----------
    items : iterable
    what : str
        What is swept (``"specimens"``, ``"levels"``).
    total : int, optional
        Steps (default ``len(items)`` where it has one).
    """
    if total is None and hasattr(items, "__len__"):
        total = len(items)
    for k, item in enumerate(items):
        log.debug("%s %d/%s", what, k + 1, total if total is not None else "?",
                  extra={"progress": {"event": "steps", "stage": what, "step": k + 1, "total": total}})
        yield item


def median_time(fn, repeats):
    """Run ``fn()`` ``repeats`` times; return the median seconds, every time, and the last result.

    The one timing helper of the studies and the benchmark (wall clock, ``time.perf_counter``).
    """
    import statistics
    import time

    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, out


def error_against_finest(rows, key="alpha_rad", out="error_rad"):
    """Give every level of a refinement ``rows[k][out] = |rows[k][key] - rows[-1][key]|``."""
    ref = rows[-1][key]
    for r in rows:
        r[out] = abs(r[key] - ref)
    return rows


def save_figure(fig, out, name, dpi=120):
    """Lay out ``fig``, write it to ``out/name.png`` and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(Path(out) / f"{name}.png", dpi=dpi)
    plt.close(fig)


def finish(result, out, plot):
    """Write ``NAME.json`` and ``NAME.png`` (via ``plot``) into ``out``; return ``result``."""
    if out is None:
        return result
    from gdfe.io import write_json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    name = result["study"]
    png = out / f"{name}.png"
    result["files"] = {"png": png.name, "json": f"{name}.json"}
    plot(result, out)
    write_json(out / f"{name}.json", public(result))
    return result


def public(result):
    """The result without its private entries (keys starting with ``_``: shapes kept for plotting)."""
    return {k: v for k, v in result.items() if not k.startswith("_")}


def format_headlines(result):
    lines = [f"{result['figure']}: {result['title']}  (resolution {result['resolution']})"]
    for h in result["headlines"]:
        paper = h["paper"] if h["paper"] is not None else (h["paper_text"] or "-")
        ours = h["ours"]
        ours = f"{ours:.4g}" if isinstance(ours, float) else ours
        paper = f"{paper:.4g}" if isinstance(paper, float) else paper
        if h.get("goal"):
            lines.append(f"  {h['name']}: ours {ours} {h['unit']}  goal {paper}  [{h['tolerance']}: "
                         f"{'met' if h['holds'] else 'NOT MET'} (a speed goal, not a regression check)]")
            continue
        state = "ok" if h["passed"] else "REGRESSION"
        lines.append(f"  {h['name']}: ours {ours} {h['unit']}  paper {paper}  [{h['tolerance']}; "
                     f"{'holds' if h['holds'] else 'does not hold'}, expected {'to hold' if h['expect'] else 'not to'}: {state}]")
    s = result.get("summary", {})
    if s.get("verdict"):
        lines.append(f"  verdict: {s['verdict']}")
    if not result.get("converged", True):
        lines.append("  WARNING: a simulation did not converge")
    return "\n".join(lines)


def study_main(module, argv=None):
    """The ``__main__`` of a study: ``python -m studies.NAME [--out DIR] [--resolution R] [--json]``."""
    doc = (module.__doc__ or "").strip().splitlines()
    p = argparse.ArgumentParser(prog=f"python -m {module.__name__}", description=doc[0] if doc else None)
    p.add_argument("--out", type=Path, default=None,
                   help=f"output directory (default out/{module.NAME})")
    p.add_argument("--resolution", choices=RESOLUTIONS, default="default")
    p.add_argument("--json", action="store_true", help="print the numbers as JSON")
    args = p.parse_args(argv)
    out = args.out if args.out is not None else Path("out") / module.NAME
    try:
        return run_and_print(module, args.resolution, out, args.json)
    except GdfeError as exc:  # a user error: one line; anything else is a bug and keeps its traceback
        print(f"{p.prog}: error: {exc}", file=sys.stderr)
        return 1


def main_of(module_name):
    """The ``main(argv=None)`` of a study module: :func:`study_main` on ``sys.modules[module_name]``.

    A study defines ``main = main_of(__name__)``.
    """

    def main(argv=None):
        return study_main(sys.modules[module_name], argv)

    return main


def run_and_print(module, resolution, out, as_json):
    """Run a study and print its headlines, or its numbers as JSON (``as_json`` True or ``"-"``; a file
    name: the JSON written there beside the headlines)."""
    result = module.run(resolution=resolution, out=out)
    if as_json is True or as_json == "-":
        from gdfe.io import json_default

        print(json.dumps(public(result), indent=2, default=json_default))
    else:
        print(format_headlines(result))
        if out is not None:
            print(f"  wrote {Path(out) / (module.NAME + '.png')} and {module.NAME}.json")
        if as_json:
            from gdfe.io import write_json

            write_json(as_json, public(result))
            print(f"  wrote {as_json}")
    ok = result.get("converged", True) and all(h["passed"] for h in result["headlines"])
    return 0 if ok else 1


def exit_main(module):
    sys.exit(study_main(module))
