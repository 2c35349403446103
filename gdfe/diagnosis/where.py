"""Where the gap lies: how the residuals of a model depend on each input and on the prediction.

For every input (and the predicted angle) the residuals are correlated with it (Pearson's r
and Spearman's rho with their p-values, and the least-squares slope), their magnitude too
(does the error grow with the input?), and they are binned at the input's terciles to see
in which regime the squared error concentrates. The regime is named in words.

Angles in radians, lengths in mm.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["residual_analysis", "describe_input"]

# input name -> (what it is, its low regime, its high regime)
_WORDS = {
    "L_mm": ("hinge width L", "short hinges", "long hinges"),
    "d_mm": ("passive thickness d", "thin passive coats", "thick passive coats"),
    "h_mm": ("film thickness h", "thin films", "thick films"),
    "predicted": ("predicted angle", "small predicted angles", "large predicted angles"),
}


def describe_input(name):
    """``(noun, low regime, high regime)`` in words for an input column."""
    return _WORDS.get(name, (name, f"low {name}", f"high {name}"))


def _bins(x, n_bins):
    """Indices of ``n_bins`` groups of ``x`` by rank (equal values stay together)."""
    from scipy.stats import rankdata

    k = ((rankdata(x, method="min") - 1) * n_bins // x.size).astype(int)
    return [np.nonzero(k == b)[0] for b in range(n_bins) if (k == b).any()]


def residual_analysis(residuals, inputs):
    """Residual trends and the regime where the error concentrates.

    Parameters
    ----------
    residuals : (n,) float array [rad]
        Measured minus predicted.
    inputs : dict of str -> (n,) float array
        The inputs (e.g. ``L_mm``, ``d_mm``, further numeric columns) and ``predicted``.

    Returns
    -------
    where : list of dict
        One per input that varies, strongest residual trend first: ``input``, ``pearson_r``,
        ``pearson_p``, ``spearman_rho``, ``spearman_p``, ``slope`` [rad per unit],
        ``abs_spearman_rho`` (magnitude of the error against the input), ``bins`` (range,
        n, mean and RMS residual, share of the squared error), ``concentration`` (largest
        bin's share of the squared error over its share of the tests), ``text``.
    regime : str
        Sentences naming the regime where the error concentrates: the mean residual in each
        bin of the input with the strongest trend, the bin with the largest RMS residual,
        and the regime the largest misses share.
    """
    from scipy import stats

    r = np.asarray(residuals, float)
    n = r.size
    sq = r**2
    total = float(sq.sum()) or 1.0
    n_bins = 3 if n >= 9 else 2
    out = []
    for name, x in inputs.items():
        x = np.asarray(x, float)
        if x.shape != r.shape or np.ptp(x) <= 1e-12 * max(1.0, np.abs(x).max()):
            continue
        pr, pp = stats.pearsonr(x, r)
        sr, sp = stats.spearmanr(x, r)
        ar, _ = stats.spearmanr(x, np.abs(r))
        slope = float(np.polyfit(x, r, 1)[0])
        bins = []
        for g in _bins(x, n_bins):
            bins.append({"range": [float(x[g].min()), float(x[g].max())], "n": int(g.size),
                         "mean": float(r[g].mean()), "rms": float(np.sqrt(sq[g].mean())),
                         "share": float(sq[g].sum() / total)})
        conc = max(b["share"] / (b["n"] / n) for b in bins)
        noun = describe_input(name)[0]
        trend = "rise" if sr > 0 else "fall"
        text = (f"residuals {trend} with {noun} (Spearman rho {sr:+.2f}, p = {sp:.2g}; "
                f"slope {slope:+.3g} rad per unit)")
        out.append({"input": name, "pearson_r": float(pr), "pearson_p": float(pp),
                    "spearman_rho": float(sr), "spearman_p": float(sp), "slope": slope,
                    "abs_spearman_rho": float(ar), "bins": bins, "concentration": float(conc),
                    "text": text})
    out.sort(key=lambda w: -abs(w["spearman_rho"]))
    return out, _regime(out, r, inputs)


def _regime(where, r, inputs):
    """Three sentences: the bias along the strongest trend, the bin with the largest RMS
    residual (at least 3 tests), and what the largest misses have in common."""
    n = r.size
    rms_all = math.sqrt(float(np.mean(r**2)))
    if not where:
        return "no input varies, so no regime can be named"
    w0 = where[0]
    noun, low, high = describe_input(w0["input"])
    parts = []
    for k, b in enumerate(w0["bins"]):
        words = _bin_words(w0, k)
        verb = "under-predicted" if b["mean"] > 0 else "over-predicted"
        parts.append(f"{verb} by {abs(b['mean']):.2f} rad on average for {words} "
                     f"({_range(w0['input'], b)})")
    bias = w0["text"][0].upper() + w0["text"][1:] + f". By {noun}: " + "; ".join(parts) + "."
    best = None
    for w in where:
        for k, b in enumerate(w["bins"]):
            if b["n"] >= 3 and (best is None or b["rms"] > best[2]["rms"]):
                best = (w, k, b)
    conc = ""
    if best is not None:
        w, k, b = best
        conc = (f" The squared error concentrates in {_bin_words(w, k)} ({_range(w['input'], b)}): "
                f"RMS residual {b['rms']:.3f} rad against {rms_all:.3f} rad overall, "
                f"{100 * b['share']:.0f} % of the squared error in {100 * b['n'] / n:.0f} % of the tests.")
    top = np.argsort(-np.abs(r))[:max(2, int(math.ceil(n / 6)))]
    common = []
    for w in where:
        x = np.asarray(inputs[w["input"]], float)
        ks = {next(k for k, b in enumerate(w["bins"]) if b["range"][0] <= xi <= b["range"][1]) for xi in x[top]}
        if len(ks) == 1 and (k := ks.pop()) in (0, len(w["bins"]) - 1):
            common.append(_bin_words(w, k))
    signs = np.sign(r[top])
    verb = ("all over-predicted" if (signs < 0).all() else "all under-predicted" if (signs > 0).all()
            else "of both signs")
    miss = (f" The {top.size} largest misses ({', '.join(f'{v:+.2f}' for v in r[top])} rad, {verb})"
            + (f" are {', '.join(common)}." if common else " share no regime of any input."))
    return bias + conc + miss


def _bin_words(w, k):
    noun, low, high = describe_input(w["input"])
    return low if k == 0 else high if k == len(w["bins"]) - 1 else f"mid-range {noun}"


def _range(name, b):
    unit = " mm" if name.endswith("_mm") else " rad" if name == "predicted" else ""
    return f"{name} {b['range'][0]:.3g}-{b['range'][1]:.3g}{unit}"
