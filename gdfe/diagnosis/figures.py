"""The figures and files of a diagnosis: plots (residual maps, before/after), a readable
summary and the JSON (``gdfe diagnose --report DIR``).

matplotlib is imported inside the functions.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

__all__ = ["write_report", "write_shape_report"]

log = logging.getLogger(__name__)


def _plt():
    from gdfe._plotting import pyplot

    return pyplot()


def _save(plt, fig, path):
    """Lay out ``fig``, write it to ``path`` as PNG and close it."""
    from gdfe.io import save_figure

    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def write_report(diag, out):
    """Write ``residual_map.png``, ``before_after.png``, ``effects.png``, ``summary.md`` and
    ``diagnosis.json`` of a :class:`~gdfe.diagnosis.Diagnosis` into directory ``out``.

    Returns
    -------
    dict of str -> str
        The files written.
    """
    from gdfe.io import write_json, write_text

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = {"residual_map": _residual_map(diag, out / "residual_map.png"),
             "before_after": _before_after(diag, out / "before_after.png"),
             "effects": _effects_bar(diag, out / "effects.png")}
    files["json"] = write_json(out / "diagnosis.json", diag.as_dict())
    files["summary"] = out / "summary.md"
    write_text(files["summary"], _summary_md(diag, files))
    return {k: str(v) for k, v in files.items()}


def _residual_map(diag, path):
    plt = _plt()
    t, b = diag.tests, diag.baseline
    inputs = {k: v for k, v in diag.inputs.items() if np.ptp(v) > 0}
    inputs["predicted"] = b.predicted
    ncol = len(inputs) + 1
    fig, axes = plt.subplots(1, ncol, figsize=(4.2 * ncol, 3.8))
    lim = float(np.abs(b.residuals).max()) or 1.0
    ax = axes[0]
    sc = ax.scatter(t.L, t.d, c=b.residuals, cmap="RdBu_r", vmin=-lim, vmax=lim, s=80, edgecolors="k")
    fig.colorbar(sc, ax=ax, label="measured - baseline [rad]")
    ax.set(xlabel="hinge width L [mm]", ylabel="passive thickness d [mm]", title="residual map (baseline)")
    for ax, (name, x) in zip(axes[1:], inputs.items()):
        ax.axhline(0, color="0.6", lw=0.8)
        ax.scatter(x, b.residuals, label="baseline", color="C3")
        ax.scatter(x, diag.best.residuals, label=f"best: {diag.best.name}", color="C0", marker="s", s=18)
        w = next((w for w in diag.where if w["input"] == name), None)
        if w:
            for bn in w["bins"]:
                ax.plot(bn["range"], [bn["mean"]] * 2, color="C3", lw=2, alpha=0.6)
            ax.set_title(f"Spearman rho {w['spearman_rho']:+.2f} (p={w['spearman_p']:.2g})", fontsize=9)
        ax.set(xlabel=name + (" [rad]" if name == "predicted" else ""), ylabel="residual [rad]")
    axes[1].legend(fontsize=7)
    return _save(plt, fig, path)


def _before_after(diag, path):
    plt = _plt()
    t, b, best = diag.tests, diag.baseline, diag.best
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.4))
    hi = float(max(t.alpha.max(), b.predicted.max(), best.predicted.max())) * 1.08
    for ax, f, col in ((axes[0], b, "C3"), (axes[1], best, "C0")):
        ax.plot([0, hi], [0, hi], color="0.6", lw=0.8)
        ax.scatter(f.predicted, t.alpha, color=col, label="fit")
        ax.scatter(f.loo_predicted, t.alpha, facecolors="none", edgecolors=col, label="held out (LOO)")
        ho = diag.held_out_rmse(f)
        ax.set(xlim=(0, hi), ylim=(0, hi), xlabel="predicted angle [rad]", ylabel="measured angle [rad]",
               title=f"{'baseline' if f is b else f.name}\nRMSE {f.rmse:.3f}, held-out {ho:.3f} rad")
        ax.legend(fontsize=8)
    return _save(plt, fig, path)


def _effects_bar(diag, path):
    plt = _plt()
    fits = [diag.baseline] + diag.fits
    names = [f.name for f in fits]
    fig, ax = plt.subplots(figsize=(8, 0.32 * len(fits) + 1.2))
    y = np.arange(len(fits))[::-1]
    ax.barh(y + 0.2, [f.rmse for f in fits], height=0.4, color="0.7", label="RMSE (fit)")
    ax.barh(y - 0.2, [f.loo_rmse for f in fits], height=0.4,
            color=["C0" if f is diag.best else "C1" for f in fits], label="LOO RMSE (held out)")
    if diag.held_out == "logo":
        ax.scatter([f.logo_rmse for f in fits], y - 0.2, color="k", marker="|", s=120, label="LOGO RMSE")
    ax.axvline(diag.baseline.loo_rmse, color="C3", lw=0.8, ls="--")
    ax.set_yticks(y, names, fontsize=8)
    ax.set_xlabel("angle error [rad]")
    ax.legend(fontsize=8, loc="lower right")
    return _save(plt, fig, path)


def _summary_md(diag, files):
    b, best = diag.baseline, diag.best
    ho = "leave-one-group-out" if diag.held_out == "logo" else "leave-one-out"
    lines = ["# Diagnosis of folding tests", "",
             f"**Verdict: {diag.verdict.verdict}** -- {diag.verdict.text}", "",
             f"Noise: {diag.noise.text()}.", "",
             f"{len(diag.tests)} tests. Models are compared on {ho} held-out error.", "",
             "## Baseline", "",
             f"The GDFE hinge with the deformation principle (Eq. 3) refitted: K = {b.params[0]:.4g}, "
             f"RMSE {b.rmse:.3f} rad, held-out RMSE {diag.held_out_rmse(b):.3f} rad."]
    if diag.check and diag.check.get("baseline"):
        c = diag.check["baseline"]
        lines.append(f"Closed form against GDFE solves of the same tests ({c['cells']} cells across each "
                     f"hinge): max |difference| {c['max_abs_diff']:.4f} rad, RMS {c['rms_diff']:.4f} rad.")
    lines += ["", "## Where the gap lies", "", diag.regime, ""]
    for w in diag.where:
        lines.append(f"- {w['input']}: {w['text']}")
    lines += ["", "## Which effect", "",
              "| model | k | RMSE | LOO | " + ("LOGO | " if diag.held_out == "logo" else "") + "shrink | AICc |",
              "|---|---|---|---|" + ("---|" if diag.held_out == "logo" else "") + "---|---|"]
    for f in [b] + diag.fits:
        mark = " **(best)**" if f is best else ""
        lines.append(f"| {f.name}{mark} | {f.model.n_params} | {f.rmse:.3f} | {f.loo_rmse:.3f} | "
                     + (f"{f.logo_rmse:.3f} | " if diag.held_out == "logo" else "")
                     + f"{100 * diag.shrink(f):.0f} % | {f.aicc:.1f} |")
    params = ", ".join(f"{k} = {v:.4g}" for k, v in best.param_dict().items())
    lines += ["", f"Best: **{best.name}** ({params}): held-out RMSE {diag.held_out_rmse(b):.3f} -> "
                  f"{diag.held_out_rmse(best):.3f} rad, {100 * diag.shrink(best):.0f} % of the baseline's "
                  f"held-out error removed. Not ruled out by the held-out errors (within one standard "
                  f"error of the best or below it): {', '.join(diag.candidates)}.", ""]
    if len(diag.named) > 1:
        lines += [f"Indistinguishable on these data (fewest effects first): {', '.join(f.name for f in diag.named)}"
                  + (f"; {diag.separation['text']}" if diag.separation else "") + ".", ""]
    from gdfe.diagnosis.effects import EFFECTS

    for e in best.model.effects:
        lines.append(f"- `{e}`: {EFFECTS[e].meaning}.")
    if best.at_bound:
        lines.append(f"- parameters on a bound of their physical range: {', '.join(best.at_bound)}.")
    for w in diag.warnings:
        lines.append(f"- warning: {w}")
    lines += ["", "After the best model: " + diag.regime_best, "",
              "## Files", ""] + [f"- {k}: `{Path(v).name}`" for k, v in files.items() if k != "summary"]
    # effects on undeclared columns under their reported names (factor[C]; gdfe.diagnosis.columns)
    return diag.display("\n".join(lines)) + "\n"


def write_shape_report(result, out):
    """Write ``deviation.png`` (per-region deviation before/after) and ``summary.md`` of a
    :class:`~gdfe.diagnosis.shape.ShapeDiagnosis` into ``out``."""
    from gdfe.io import write_json, write_text

    plt = _plt()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = [r["name"] for r in result.regions]
    def values(key):
        return [np.nan if r.get(key) is None else r[key] for r in result.regions]

    before, after = values("rms"), values("rms_after")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    x = np.arange(len(names))
    axes[0].bar(x - 0.27, before, 0.27, label="before (part aligned)", color="C3")
    axes[0].bar(x, values("local_rms"), 0.27, label="before (region aligned alone)", color="C1")
    axes[0].bar(x + 0.27, after, 0.27, label="after correction", color="C0")
    axes[0].set_xticks(x, names, rotation=45, ha="right", fontsize=8)
    axes[0].set(ylabel="RMS deviation [mm]", title="deviation per region")
    axes[0].legend(fontsize=8)
    single = values("single_fit_rms")
    axes[1].bar(x, single, color=["C0" if n in result.named else "0.7" for n in names])
    axes[1].axhline(result.rms_before, color="C3", ls="--", lw=0.8, label="no correction")
    axes[1].set_xticks(x, names, rotation=45, ha="right", fontsize=8)
    axes[1].set(ylabel="overall RMS, only this region corrected [mm]",
                title="which region explains the gap (named: " + (", ".join(result.named) or "none") + ")")
    axes[1].legend(fontsize=8)
    files = {"deviation": _save(plt, fig, out / "deviation.png"),
             "json": write_json(out / "shape_diagnosis.json", result.as_dict()),
             "summary": out / "summary.md"}
    write_text(files["summary"], result.text() + "\n")
    return {k: str(v) for k, v in files.items()}
