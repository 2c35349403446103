"""Where the gap lies: how the residuals of a model depend on each input, on the prediction
and on the groups of the tests.

For every numeric input (and the predicted angle) the residuals are correlated with it
(Pearson's r and Spearman's rho with their p-values, and the least-squares slope), their
magnitude too (does the error grow with the input?), and they are binned at the input's
terciles to see in which regime the squared error concentrates; a Kruskal-Wallis test of the
bins says whether the residuals differ between them (a trend that need not be monotone).
For every text column (batch, operator, printer) the residuals are compared between its
groups (Kruskal-Wallis, mean residual per group). The regime is named in words.

:func:`structure` reads the p-values of all these tests together: an entry shows structure
when one of its p-values is below ``level`` divided by the number of tests made (Bonferroni),
so that searching many columns does not find structure in noise.

Angles in radians, lengths in mm.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

__all__ = ["residual_analysis", "group_analysis", "describe_input", "structure", "strong_trends",
           "STRUCTURE_LEVEL", "TREND_LEVEL", "TREND_RHO"]

#: Family-wise level of :func:`structure`.
STRUCTURE_LEVEL = 0.01
#: Level of a single test, and the |Spearman rho| at or above which :func:`strong_trends` reports a trend.
TREND_LEVEL = 0.05
TREND_RHO = 0.8

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


def _p(value):
    """A p-value, 1 where a test is undefined (constant residuals)."""
    value = float(value)
    return value if math.isfinite(value) else 1.0


def residual_analysis(residuals, inputs, groups=None):
    """Residual trends and the regime where the error concentrates.

    Parameters
    ----------
    residuals : (n,) float array [rad]
        Measured minus predicted.
    inputs : dict of str -> (n,) float array
        The inputs (e.g. ``L_mm``, ``d_mm``, further numeric columns) and ``predicted``.
    groups : dict of str -> (n,) array, optional
        Text columns; a sentence names the group that differs most where the groups differ
        (:func:`group_analysis`).

    Returns
    -------
    where : list of dict
        One per input that varies, strongest residual trend first: ``input``, ``pearson_r``,
        ``pearson_p``, ``spearman_rho``, ``spearman_p``, ``slope`` [rad per unit],
        ``abs_spearman_rho`` (magnitude of the error against the input), ``bins`` (range,
        n, mean and RMS residual, share of the squared error), ``bins_p`` (Kruskal-Wallis
        test of the residuals between the bins), ``concentration`` (largest bin's share of
        the squared error over its share of the tests), ``p`` (the smaller of ``spearman_p``
        and ``bins_p``), ``n_tests`` (2), ``text``.
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
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pr, pp = stats.pearsonr(x, r) if np.ptp(r) > 0 else (0.0, 1.0)
            sr, sp = stats.spearmanr(x, r) if np.ptp(r) > 0 else (0.0, 1.0)
            ar, _ = stats.spearmanr(x, np.abs(r)) if np.ptp(np.abs(r)) > 0 else (0.0, 1.0)
        sr, ar, pr = (float(v) if math.isfinite(float(v)) else 0.0 for v in (sr, ar, pr))
        slope = float(np.polyfit(x, r, 1)[0])
        bins = []
        members = _bins(x, n_bins)
        for g in members:
            bins.append({"range": [float(x[g].min()), float(x[g].max())], "n": int(g.size),
                         "mean": float(r[g].mean()), "rms": float(np.sqrt(sq[g].mean())),
                         "share": float(sq[g].sum() / total)})
        bp = _kruskal([r[g] for g in members])
        conc = max(b["share"] / (b["n"] / n) for b in bins)
        noun = describe_input(name)[0]
        trend = "rise" if sr > 0 else "fall"
        text = (f"residuals {trend} with {noun} (Spearman rho {sr:+.2f}, p = {sp:.2g}; "
                f"slope {slope:+.3g} rad per unit)")
        out.append({"input": name, "kind": "numeric", "pearson_r": float(pr), "pearson_p": _p(pp),
                    "spearman_rho": float(sr), "spearman_p": _p(sp), "slope": slope,
                    "abs_spearman_rho": float(ar), "bins": bins, "bins_p": bp,
                    "concentration": float(conc), "p": min(_p(sp), bp), "n_tests": 2, "text": text})
    out.sort(key=lambda w: -abs(w["spearman_rho"]))
    regime = _regime(out, r, inputs)
    if groups:
        by = group_analysis(r, groups)
        strong = [g for g in by if g["p"] < STRUCTURE_LEVEL]
        if strong:
            regime += " " + " ".join(g["text"][0].upper() + g["text"][1:] + "." for g in strong)
    return out, regime


def _kruskal(samples):
    """Kruskal-Wallis p-value of residual samples (1 where undefined: one sample, all equal)."""
    from scipy import stats

    samples = [s for s in samples if len(s) > 0]
    if len(samples) < 2 or np.ptp(np.concatenate(samples)) <= 0:
        return 1.0
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _p(stats.kruskal(*samples).pvalue)


def group_analysis(residuals, groups):
    """How the residuals differ between the groups of each text column.

    Parameters
    ----------
    residuals : (n,) float array [rad]
    groups : dict of str -> (n,) array
        Text columns (a label per test).

    Returns
    -------
    list of dict
        One per column with at least two groups, smallest p first: ``input``, ``kind``
        (``"group"``), ``kruskal_p`` (= ``p``), ``n_tests`` (1), ``groups`` (label, n, mean
        and RMS residual, largest mean deviation first), ``text``.
    """
    r = np.asarray(residuals, float)
    out = []
    for name, labels in groups.items():
        labels = np.asarray(labels).astype(str)
        if labels.shape != r.shape:
            continue
        uniq, inv = np.unique(labels, return_inverse=True)
        if uniq.size < 2:
            continue
        p = _kruskal([r[inv == k] for k in range(uniq.size)])
        rows = [{"label": str(lab), "n": int((inv == k).sum()), "mean": float(r[inv == k].mean()),
                 "rms": float(np.sqrt(np.mean(r[inv == k] ** 2)))} for k, lab in enumerate(uniq)]
        rows.sort(key=lambda g: -abs(g["mean"]))
        top = rows[0]
        verb = "under-predicted" if top["mean"] > 0 else "over-predicted"
        text = (f"residuals differ between the {uniq.size} groups of {name} (Kruskal-Wallis p = {p:.2g}); "
                f"{name} {top['label']!r} ({top['n']} tests) is {verb} by {abs(top['mean']):.3f} rad on average")
        out.append({"input": name, "kind": "group", "kruskal_p": p, "p": p, "n_tests": 1,
                    "groups": rows, "text": text})
    out.sort(key=lambda g: g["p"])
    return out


def structure(entries, level=STRUCTURE_LEVEL):
    """The entries of a residual analysis that show structure, at family-wise level ``level``.

    Parameters
    ----------
    entries : list of dict
        Entries of :func:`residual_analysis` and :func:`group_analysis` (each with ``p`` and
        ``n_tests``).
    level : float
        Family-wise level: an entry shows structure when its ``p`` is below ``level`` over
        the number of tests made (Bonferroni).

    Returns
    -------
    list of dict
        ``input``, ``kind``, ``p``, ``threshold`` and ``text`` of each, smallest ``p`` first.
    """
    m = sum(int(e.get("n_tests", 1)) for e in entries) or 1
    thr = level / m
    out = []
    for e in entries:
        if e["p"] < thr:
            if e["kind"] == "numeric" and e["bins_p"] < e["spearman_p"]:
                means = ", ".join(f"{b['mean']:+.3f}" for b in e["bins"])
                text = (f"against {e['input']}: the mean residual differs between its terciles ({means} rad; "
                        f"Kruskal-Wallis p = {e['bins_p']:.2g})")
            elif e["kind"] == "numeric":
                text = f"against {e['input']}: {e['text']}"
            else:
                text = f"by {e['input']}: {e['text']}"
            out.append({"input": e["input"], "kind": e["kind"], "p": float(e["p"]), "threshold": thr,
                        "text": text})
    out.sort(key=lambda e: e["p"])
    return out


def strong_trends(entries, level=TREND_LEVEL, rho=TREND_RHO):
    """Strong residual trends that the family-wise test of :func:`structure` does not confirm.

    On a few tests no trend can pass :func:`structure` (with 5 tests Spearman's smallest
    p-value is about 0.017, above any Bonferroni threshold of a handful of tests), yet a
    trend with ``|rho| >= rho`` at ``p < level`` on its own test is what a reader of the
    residuals sees. The diagnosis does not call such data free of a gap.

    Parameters
    ----------
    entries : list of dict
        Entries of :func:`residual_analysis` (numeric ones are read).
    level, rho : float

    Returns
    -------
    list of dict
        ``input``, ``kind``, ``spearman_rho``, ``p``, ``text``, strongest first.
    """
    out = []
    for e in entries:
        if e.get("kind") == "numeric" and abs(e["spearman_rho"]) >= rho \
                and e["spearman_p"] < level:
            out.append({"input": e["input"], "kind": "numeric", "spearman_rho": float(e["spearman_rho"]),
                        "p": float(e["spearman_p"]), "text": f"against {e['input']}: {e['text']}"})
    out.sort(key=lambda e: e["p"])
    return out


#: The largest misses named one by one in the text of :func:`_regime` (the rest by their smallest size).
MISSES_LISTED = 6

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
    shown = ", ".join(f"{v:+.2f}" for v in r[top[:MISSES_LISTED]]) + " rad"
    if top.size > MISSES_LISTED:
        shown += f" and {top.size - MISSES_LISTED} more down to {abs(r[top[-1]]):.2f} rad in size"
    miss = (f" The {top.size} largest misses ({shown}, {verb})"
            + (f" are {', '.join(common)}." if common else " share no regime of any input."))
    return bias + conc + miss


def _bin_words(w, k):
    noun, low, high = describe_input(w["input"])
    return low if k == 0 else high if k == len(w["bins"]) - 1 else f"mid-range {noun}"


def _range(name, b):
    unit = " mm" if name.endswith("_mm") else " rad" if name == "predicted" else ""
    return f"{name} {b['range'][0]:.3g}-{b['range'][1]:.3g}{unit}"
