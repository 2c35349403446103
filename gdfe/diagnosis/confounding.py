"""Extra columns confounded with the design variables.

An extra column can carry the design itself: every sample of a data set made at its own film
and coat thickness, a temperature raised with the coat's thickness. An effect on such a
column fits whatever the design variables do that the baseline misses, and the data cannot
tell which of the two is at work. This module finds such columns; the diagnosis says so and
credits neither.

* A **group** column is confounded with a design variable (``L_mm``, ``d_mm``, ``h_mm``)
  that varies between its groups when the groups explain at least :data:`THRESHOLD` of that
  variable's variance (the correlation ratio ``eta^2``, the R^2 of a regression on the group
  labels; 1 when each group has one value).
* A **numeric** column is confounded with a design variable when ``|Spearman rho|`` or the
  R^2 of a straight line between the two reaches :data:`THRESHOLD`.

Lengths in mm.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["confounded", "THRESHOLD", "DESIGN"]

#: |Spearman rho|, R^2 or eta^2 at and above which a column is confounded with a design variable.
THRESHOLD = 0.9
#: The design variables and their names in words.
DESIGN = {"L_mm": ("L", "hinge width L"), "d_mm": ("d", "coat thickness d"), "h_mm": ("h", "film thickness h")}


def _varies(x):
    x = np.asarray(x, float)
    return x.size > 1 and np.ptp(x) > 1e-12 * max(1.0, float(np.abs(x).max()))


def _eta2(x, labels):
    """Share of the variance of ``x`` between the groups of ``labels``."""
    x = np.asarray(x, float)
    _, inv = np.unique(np.asarray(labels).astype(str), return_inverse=True)
    inv = inv.ravel()
    means = np.bincount(inv, weights=x) / np.bincount(inv)
    tot = float(((x - x.mean()) ** 2).sum())
    return float(((means[inv] - x.mean()) ** 2).sum() / tot) if tot > 0 else 0.0


def _spearman(x, y):
    from scipy import stats

    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rho = float(stats.spearmanr(x, y)[0])
    return rho if np.isfinite(rho) else 0.0


def _meaning(column, names, kind):
    what = "a dependence on " + " or ".join(names)
    of = "the groups of " + column if kind == "group" else column
    return (f"{column} is confounded with {', '.join(names)}: an effect of {of} cannot be told from "
            f"{what} the model lacks, nor the other way round; to separate them, test several "
            f"{', '.join(names)} within one {'group' if kind == 'group' else 'value'} of {column}")


def confounded(design, numeric=None, groups=None, threshold=THRESHOLD):
    """Extra columns confounded with the design variables.

    Parameters
    ----------
    design : dict of str -> (n,) float array
        ``L_mm``, ``d_mm``, ``h_mm`` [mm].
    numeric : dict of str -> (n,) float array, optional
        Numeric extra columns.
    groups : dict of str -> (n,) array, optional
        Group columns (labels).
    threshold : float
        See :data:`THRESHOLD`.

    Returns
    -------
    list of dict
        One per confounded column: ``column``, ``kind`` (``"numeric"`` or ``"group"``),
        ``with`` (design variables, e.g. ``["h_mm", "d_mm"]``), ``measure`` (``"eta2"``,
        ``"spearman_rho"`` or ``"r2"``), ``value`` (the largest over ``with``; per variable in
        ``values``), ``threshold`` and ``what it means``.
    """
    out = []
    design = {k: np.asarray(v, float) for k, v in design.items() if _varies(v)}
    for col, labels in (groups or {}).items():
        labels = np.asarray(labels).astype(str)
        vals = {k: _eta2(x, labels) for k, x in design.items()}
        hit = {k: v for k, v in vals.items() if v >= threshold}
        if hit and np.unique(labels).size >= 2:
            names = [DESIGN.get(k, (k,))[0] for k in hit]
            out.append({"column": col, "kind": "group", "with": list(hit), "measure": "eta2",
                        "value": max(hit.values()), "values": hit, "threshold": threshold,
                        "one_design_per_group": all(v >= 1 - 1e-12 for v in hit.values()),
                        "what it means": _meaning(col, names, "group")})
    for col, x in (numeric or {}).items():
        x = np.asarray(x, float)
        if not _varies(x):
            continue
        hit, measure = {}, {}
        for k, y in design.items():
            rho = abs(_spearman(x, y))
            r2 = float(np.corrcoef(x, y)[0, 1] ** 2)
            v, m = (rho, "spearman_rho") if rho >= r2 else (r2, "r2")
            if v >= threshold:
                hit[k], measure[k] = v, m
        if hit:
            top = max(hit, key=hit.get)
            names = [DESIGN.get(k, (k,))[0] for k in hit]
            out.append({"column": col, "kind": "numeric", "with": list(hit), "measure": measure[top],
                        "value": hit[top], "values": hit, "threshold": threshold,
                        "what it means": _meaning(col, names, "numeric")})
    return out
