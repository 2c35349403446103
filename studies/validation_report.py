"""``gdfe report``, the HTML validation report: every study run, its figures, paper-vs-ours numbers, versions.

``build_report(out, resolution)`` runs each study of the registry (``studies.STUDIES``)
into ``out/NAME/``, then writes ``out/index.html`` (self-contained apart from the PNGs
beside it; no network access) and ``out/report.json``. A study whose module is not
importable is skipped and noted; one that raises is reported with its error. The page opens
with an interactive 3-D view of the paper's 2.6 mm hinge folding along its contraction ramp
(:mod:`gdfe.fabrication.viewer`, drawn in the page itself).
"""

from __future__ import annotations

import datetime
import html
import importlib
import logging
import platform
import time
import traceback
from pathlib import Path

from gdfe._validation import GdfeError
from gdfe.io import write_json, write_text

__all__ = ["build_report", "software_versions"]

log = logging.getLogger(__name__)


def software_versions():
    """Versions of Python, the platform and the packages the studies use."""
    out = {"python": platform.python_version(), "platform": platform.platform()}
    for name in ("gdfe", "numpy", "scipy", "matplotlib", "skfem", "joblib", "tqdm", "pyvista", "meshio"):
        try:
            mod = importlib.import_module(name)
            out[name] = getattr(mod, "__version__", "installed")
        except Exception:  # not installed, or fails to import: say so
            out[name] = "not available"
    return out


#: The shape of the report's interactive view: the paper's Figure 6 hinge, L = 2.6 mm, d = 0.33 mm.
VIEW_HINGE = {"length": 2.6, "steps": 10}


def interactive_view():
    """The HTML fragment of the report's 3-D view: the 2.6 mm hinge folding over its ramp.

    Returns
    -------
    html : str
        The viewer (:func:`gdfe.fabrication.viewer_fragment`), or a note of why there is none.
    record : dict
        What was simulated and whether it converged.
    """
    import gdfe
    from gdfe import paper
    from gdfe.fabrication import view_data, viewer_fragment

    des = gdfe.hinge(VIEW_HINGE["length"], d=paper.FIG6_D)
    res = gdfe.simulate(des, steps=VIEW_HINGE["steps"])
    rec = {"shape": f"hinge L = {VIEW_HINGE['length']:g} mm, d = {paper.FIG6_D:g} mm",
           "steps": VIEW_HINGE["steps"], "converged": bool(res.converged), "fold_angle_rad": gdfe.fold_angle(res)}
    if not res.converged:
        return '<p class="fail">The hinge of the interactive view did not converge: no view.</p>', rec
    data = view_data(res, title=f"Figure 6 hinge, L = {VIEW_HINGE['length']:g} mm",
                     info={"fold angle": f"{rec['fold_angle_rad']:.4f} rad"})
    return viewer_fragment(data, element_id="hinge-view"), rec


def _run_one(name, module_path, resolution, out):
    rec = {"name": name, "module": module_path, "dir": name}
    t0 = time.perf_counter()
    try:
        module = importlib.import_module(module_path)
    except ModuleNotFoundError as exc:
        rec.update(status="skipped", note=f"module {module_path} is not available ({exc})")
        return rec, None
    try:
        result = module.run(resolution=resolution, out=out / name)
    except Exception as exc:  # a failing study must not stop the report
        log.exception("study %s failed", name)
        rec.update(status="error", note=f"{type(exc).__name__}: {exc}",
                   traceback=traceback.format_exc(limit=4), seconds=time.perf_counter() - t0)
        return rec, None
    rec["seconds"] = time.perf_counter() - t0
    fields = result if isinstance(result, dict) else {}
    heads = fields.get("headlines", [])
    rec["headlines"] = len(heads)
    rec["passed"] = sum(bool(h.get("passed")) for h in heads)
    rec["converged"] = bool(fields.get("converged", True))
    rec["status"] = "ok" if rec["passed"] == rec["headlines"] and rec["converged"] else "fail"
    pngs = sorted(p.name for p in (out / name).glob("*.png"))
    main = fields.get("files", {}).get("png")
    rec["figures"] = [main] if main in pngs else pngs
    rec["other_files"] = [p for p in pngs if p not in rec["figures"]]
    return rec, result


def build_report(out, resolution="default", names=None, progress=None):
    """Run the studies and write ``out/index.html``.

    Parameters
    ----------
    out : str or Path
        Output directory (created).
    resolution : {"coarse", "default", "fine"}
    names : list of str, optional
        Studies to run (default: all of ``studies.STUDIES``).
    progress : bool, optional
        Report each study as it starts and ends through the log (default True): info records
        of ``studies.validation_report`` with a ``progress`` attribute, which ``gdfe report``
        shows as a bar on a terminal and as lines elsewhere; False: none.

    Returns
    -------
    dict
        ``index`` (path of index.html), ``ok`` (every study ran, converged and passed its
        regression checks; skipped studies do not count against it), ``studies`` (one
        record per study), ``versions``.
    """
    from studies import STUDIES
    from studies._common import check_resolution

    check_resolution(resolution)
    names = list(STUDIES) if names is None else list(names)
    unknown = [n for n in names if n not in STUDIES]
    if unknown:
        raise GdfeError(f"names: unknown studies {unknown}; expected some of {', '.join(STUDIES)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    progress = progress is None or bool(progress)
    t0 = time.perf_counter()
    records, results = [], {}
    for k, name in enumerate(names):
        step = {"event": "study", "name": name, "step": k + 1, "total": len(names)}
        if progress:
            log.info("study %s (%d/%d)", name, k + 1, len(names), extra={"progress": {**step, "status": None}})
        rec, res = _run_one(name, STUDIES[name], resolution, out)
        if progress:
            log.info("study %s: %s, %.1f s", name, rec["status"], rec.get("seconds", 0.0),
                     extra={"progress": {**step, "status": rec["status"], "seconds": rec.get("seconds", 0.0)}})
        records.append(rec)
        results[name] = res
    if progress:
        log.info("building the interactive view",
                 extra={"progress": {"event": "stage", "stage": "building the interactive view"}})
    try:
        view_html, view_rec = interactive_view()
    except Exception as exc:  # the view must not stop the report
        log.exception("interactive view failed")
        view_html = f'<p class="fail">No interactive view: {html.escape(f"{type(exc).__name__}: {exc}")}</p>'
        view_rec = {"error": f"{type(exc).__name__}: {exc}"}
    summary = {
        "resolution": resolution,
        "generated": datetime.datetime.now().isoformat(timespec="seconds"),
        "seconds": time.perf_counter() - t0,
        "versions": software_versions(),
        "studies": records,
        "view": view_rec,
        "ok": all(r["status"] in ("ok", "skipped") for r in records),
    }
    index = write_text(out / "index.html", _html(summary, results, view_html))
    write_json(out / "report.json", {**summary, "results": {
        k: _public(v) for k, v in results.items() if isinstance(v, dict)}})
    summary["index"] = str(index)
    return summary


def _public(result):
    return {k: v for k, v in result.items() if not str(k).startswith("_")}


def _regression_cell(h):
    """The regression column of a headline: pass or FAIL, or for a speed goal whether it was met."""
    if h.get("goal"):
        return "speed goal " + ("met" if h.get("holds") else "<span class=fail>not met</span>")
    return "<span class=pass>pass</span>" if h.get("passed") else "<span class=fail>FAIL</span>"


def _fmt(v):
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    return html.escape(str(v))


_CSS = """
body { font-family: sans-serif; max-width: 1150px; margin: 2em auto; color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 2em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .9em; }
th, td { border: 1px solid #ccc; padding: .25em .5em; text-align: left; vertical-align: top; }
th { background: #f3f3f3; }
.pass { color: #137333; font-weight: bold; } .fail { color: #b3261e; font-weight: bold; }
.skip { color: #8a6d00; font-weight: bold; }
img { max-width: 100%; border: 1px solid #ddd; margin: .5em 0; }
.note { color: #555; font-size: .9em; }
"""


def _status(s):
    cls = {"ok": "pass", "fail": "fail", "error": "fail", "skipped": "skip"}.get(s, "")
    return f'<span class="{cls}">{html.escape(s)}</span>'


def _html(summary, results, view_html=""):
    e = html.escape
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             "<title>gdfe validation report</title>", f"<style>{_CSS}</style></head><body>",
             "<h1>gdfe validation report: Kwok &amp; Chen 2017, GDFE</h1>",
             f"<p>Resolution <b>{e(summary['resolution'])}</b>, generated {e(summary['generated'])} in "
             f"{summary['seconds']:.0f} s. Units: mm and rad. Each study computes the numbers of one figure "
             "of the paper; each headline number is checked against the paper's value with the stated "
             "tolerance. <i>Expected</i> says whether the check is expected to hold: a known, explained "
             "discrepancy is kept as a regression check that it stays as measured.</p>"]
    # overview
    parts.append("<h2>Overview</h2><table><tr><th>study</th><th>status</th><th>headlines passing</th>"
                 "<th>time [s]</th><th>figure</th></tr>")
    for r in summary["studies"]:
        figs = " ".join(f'<a href="{e(r["dir"])}/{e(f)}">{e(f)}</a>' for f in r.get("figures", []))
        hl = f"{r.get('passed', 0)}/{r.get('headlines', 0)}" if r["status"] in ("ok", "fail") else ""
        parts.append(f'<tr><td><a href="#{e(r["name"])}">{e(r["name"])}</a></td><td>{_status(r["status"])}</td>'
                     f"<td>{hl}</td><td>{r.get('seconds', 0):.1f}</td><td>{figs}</td></tr>")
    parts.append("</table>")
    if view_html:
        parts.append("<h2>Interactive view</h2><p>The paper's 2.6 mm hinge (Figure 6) over its contraction ramp: "
                     "drag to turn, wheel to zoom, the slider sets the activation (0 flat print, 1 folded).</p>")
        parts.append(view_html)
    # per study
    results = {k: v if isinstance(v, dict) else {} for k, v in results.items()}
    for r in summary["studies"]:
        res = results.get(r["name"], {})
        title = res.get("title", "")
        fig = res.get("figure", "")
        parts.append(f'<h2 id="{e(r["name"])}">{e(r["name"])}: {e(str(fig))} {e(str(title))}</h2>')
        if r["status"] in ("skipped", "error"):
            parts.append(f'<p>{_status(r["status"])}: {e(r.get("note", ""))}</p>')
            if r.get("traceback"):
                parts.append(f"<pre>{e(r['traceback'])}</pre>")
            continue
        for f in r.get("figures", []):
            parts.append(f'<img src="{e(r["dir"])}/{e(f)}" alt="{e(r["name"])} figure {e(f)}">')
        if r.get("other_files"):
            parts.append('<p class="note">Other files: ' + ", ".join(
                f'<a href="{e(r["dir"])}/{e(f)}">{e(f)}</a>' for f in r["other_files"]) + "</p>")
        heads = res.get("headlines", [])
        if heads:
            parts.append("<table><tr><th>headline</th><th>paper</th><th>ours</th><th>tolerance</th>"
                         "<th>holds</th><th>expected</th><th>regression</th><th>note</th></tr>")
            for h in heads:
                paper = h.get("paper")
                paper = _fmt(paper) if paper is not None else e(h.get("paper_text") or "(no number)")
                if h.get("paper") is not None and h.get("paper_text"):
                    paper += f'<br><span class="note">{e(h["paper_text"])}</span>'
                unit = e(h.get("unit", ""))
                parts.append(
                    f"<tr><td>{e(h['name'])}</td><td>{paper}</td><td>{_fmt(h['ours'])} {unit}</td>"
                    f"<td>{e(h.get('tolerance', ''))}</td><td>{_fmt(h.get('holds'))}</td>"
                    f"<td>{'holds' if h.get('expect', True) else 'does not hold'}</td>"
                    f"<td>{_regression_cell(h)}</td>"
                    f"<td class=note>{e(h.get('note', ''))}</td></tr>")
            parts.append("</table>")
        if not r.get("converged", True):
            parts.append('<p class="fail">A simulation of this study did not converge.</p>')
        s = res.get("summary", {})
        if s:
            parts.append("<p>" + "<br>".join(f"<b>{e(k)}</b>: {e(str(v))}" for k, v in s.items() if v) + "</p>")
    # closing note
    parts.append("<h2>Closing note</h2><table><tr><th>figure</th><th>paper</th><th>ours</th><th>verdict</th>"
                 "<th>discrepancy: measured cause or open question</th></tr>")
    for r in summary["studies"]:
        res = results.get(r["name"], {})
        s = res.get("summary", {})
        if r["status"] in ("skipped", "error"):
            parts.append(f"<tr><td>{e(r['name'])}</td><td colspan=4>{_status(r['status'])}: "
                         f"{e(r.get('note', ''))}</td></tr>")
            continue
        fig = res.get("figure", r["name"])
        parts.append(f"<tr><td>{e(str(fig))}</td><td>{e(str(s.get('paper', '')))}</td>"
                     f"<td>{e(str(s.get('ours', '')))}</td><td>{e(str(s.get('verdict', '')))}</td>"
                     f"<td>{e(str(s.get('discrepancy', '')))}</td></tr>")
    parts.append("</table>")
    # versions
    parts.append("<h2>Software</h2><table>")
    for k, v in summary["versions"].items():
        parts.append(f"<tr><th>{e(k)}</th><td>{e(str(v))}</td></tr>")
    parts.append("</table></body></html>")
    return "\n".join(parts) + "\n"
