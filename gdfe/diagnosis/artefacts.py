"""Measurement artefacts of fold-angle data: failed specimens, gross outliers, noise that grows.

A gap between folding tests and the model need not be physics. Besides the catalogue's
``reading_offset`` (a constant reading error, fitted and ranked like any effect,
:mod:`gdfe.diagnosis.effects`), :func:`screen` looks for three artefacts of the measurement
and says them as such:

**Failed specimens**: folds with ``|alpha| <`` :data:`NEAR_ZERO` rad, a hinge that did not fold
at all (not activated, torn, stuck), flagged by CSV row (``row = i + 2``).

**Gross outliers**: the chosen model refitted with a robust loss (``soft_l1``, quadratic
within one noise unit, linear beyond; :func:`gdfe.diagnosis.fit.robust_fit`), and the tests
whose robust residual exceeds :data:`OUTLIER_Z` times their noise (the known noise, else
``1.4826 median |r|``, the noise of a Gaussian sample with that median absolute residual)
flagged by row. A Gaussian test lies that far out with probability 6e-5. The diagnosis is
then repeated without the flagged rows, and the verdict is given with and without them.

**Noise that grows with the angle**: the magnitude of the robust residuals against the
predicted angle, Spearman's rank correlation (one-sided, larger residuals at larger angles),
significant at :data:`gdfe.diagnosis.verdict.LEVEL`. When found (and the tests carry no
``sigma_rad`` column of their own), the diagnosis is repeated with each test's noise growing
with its predicted angle as the residuals say, ``sigma_i = s (a + b |p_i|) / rms`` (``s`` the
noise's RMS; ``a, b`` a variance function fitted to the robust residuals, the constant part
``a`` at least :data:`MIN_CONSTANT` of the mean; :func:`relative_noise`), i.e. fits and
held-out errors weighted by ``1 / sigma_i^2``, and that weighted diagnosis is the one reported.

Angles in radians.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gdfe.calibration import FoldingTests
from gdfe.diagnosis.fit import robust_fit
from gdfe.diagnosis.verdict import LEVEL

__all__ = ["Artefacts", "screen", "failed_specimens", "growing_noise", "NEAR_ZERO", "OUTLIER_Z"]

#: A fold below this [rad] is a failed specimen (it did not fold), not a measurement of the model.
NEAR_ZERO = 0.05
#: Robust residuals beyond this many noise units are gross outliers.
OUTLIER_Z = 4.0
#: Least constant part of a growing noise, as a share of its mean (:func:`relative_noise`).
MIN_CONSTANT = 0.2
#: Fewest tests a repeat without flagged rows needs.
MIN_TESTS = 5


@dataclasses.dataclass
class Artefacts:
    """What :func:`screen` found.

    Attributes
    ----------
    failed : list of int
        CSV rows of folds below :data:`NEAR_ZERO` rad.
    outliers : list of int
        CSV rows of gross outliers of the robust fit of ``model``.
    model : str
        The model refitted robustly.
    robust_params : dict of str -> float
    robust_residuals : (n,) float array [rad]
    scale : float [rad]
        The noise unit of the outlier test (RMS over the tests).
    growing : dict
        ``detected``, ``rho``, ``p`` (Spearman of |residual| against the predicted angle),
        ``weighted`` (whether the reported diagnosis is weighted by a noise growing with the angle), ``text``.
    without : dict or None
        The diagnosis without the flagged rows: ``rows``, ``verdict``, ``text``, ``best``,
        ``named``; None when no row is flagged (or too few would remain).
    """

    failed: list
    outliers: list
    model: str
    robust_params: dict
    robust_residuals: np.ndarray
    scale: float
    growing: dict
    without: dict | None = None

    @property
    def flagged(self) -> list:
        return sorted(set(self.failed) | set(self.outliers))

    def sentences(self) -> list:
        """The artefacts in words, one sentence each."""
        out = []
        if self.failed:
            out.append(f"failed specimens (|alpha| < {NEAR_ZERO:g} rad, did they fold at all?): rows "
                       + ", ".join(map(str, self.failed)))
        if self.outliers:
            out.append(f"gross outliers of a robust fit of {self.model} (beyond {OUTLIER_Z:g} x {self.scale:.3g} rad): "
                       f"rows {', '.join(map(str, self.outliers))}")
        if self.growing["detected"]:
            out.append(self.growing["text"])
        if self.without is not None:
            out.append(f"without rows {', '.join(map(str, self.without['rows']))}: verdict {self.without['verdict']} "
                       f"(best {self.without['best']}" + (f"; the data cannot tell apart: {', '.join(self.without['named'])}"
                                                          if len(self.without["named"]) > 1 else "") + ")")
        return out

    def as_dict(self) -> dict:
        return {"failed_specimens": {"rows": self.failed, "threshold_rad": NEAR_ZERO},
                "outliers": {"rows": self.outliers, "model": self.model, "loss": "soft_l1",
                             "threshold": OUTLIER_Z, "scale_rad": self.scale, "robust_params": self.robust_params},
                "growing_noise": self.growing, "without_flagged": self.without,
                "text": self.sentences()}


def failed_specimens(alpha, threshold=NEAR_ZERO):
    """CSV rows (``i + 2``) of folds ``|alpha| < threshold`` [rad]."""
    return [int(i) + 2 for i in np.nonzero(np.abs(np.asarray(alpha, float)) < threshold)[0]]


def growing_noise(residuals, predicted, level=LEVEL):
    """Whether the residuals' magnitude grows with the predicted angle (Spearman, one-sided).

    Returns
    -------
    dict
        ``detected``, ``rho``, ``p``, ``weighted`` (False; :func:`screen` sets it) and ``text``.
    """
    from scipy import stats

    r = np.abs(np.asarray(residuals, float))
    p = np.abs(np.asarray(predicted, float))
    if r.size < 5 or np.ptp(p) == 0 or np.ptp(r) == 0:
        return {"detected": False, "rho": None, "p": None, "weighted": False, "text": "not tested"}
    rho, pv = stats.spearmanr(r, p)
    pv = float(pv / 2 if rho > 0 else 1 - pv / 2)
    found = bool(pv < level)
    text = (f"the noise grows with the fold angle (Spearman rho = {rho:.2f} of |residual| against the predicted "
            f"angle, one-sided p = {pv:.2g})" if found else
            f"no sign that the noise grows with the angle (Spearman rho = {rho:.2f}, p = {pv:.2g})")
    return {"detected": found, "rho": float(rho), "p": pv, "weighted": False, "text": text}


def relative_noise(predicted, residuals=None):
    """Noise of each test relative to the RMS: ``(n,)`` with a mean square of 1.

    With ``residuals``, the noise's growth is estimated from them (a variance function,
    ``sigma_i = a + b |p_i|`` with ``a, b >= 0`` fitted by non-negative least squares to
    ``sqrt(pi / 2) |r_i|``, whose mean is ``sigma_i`` for Gaussian noise), so that a constant
    part of the noise keeps the small folds from weights they do not earn; ``a`` is held at
    :data:`MIN_CONSTANT` of the mean noise or more. Without, proportional to ``|p_i|``.
    ``|p_i|`` is floored at :data:`NEAR_ZERO`."""
    from scipy.optimize import nnls

    p = np.maximum(np.abs(np.asarray(predicted, float)), NEAR_ZERO)
    if residuals is None:
        s = p
    else:
        r = np.sqrt(np.pi / 2) * np.abs(np.asarray(residuals, float))
        (a, b), _ = nnls(np.column_stack([np.ones_like(p), p]), r)
        mean = a + b * float(np.mean(p))
        if mean <= 0:
            return np.ones_like(p)
        s = np.maximum(a, MIN_CONSTANT * mean) + b * p
    return s / np.sqrt(np.mean(s**2))


def subset(tests, keep):
    """The tests of the boolean mask ``keep`` (extra columns too)."""
    keep = np.asarray(keep, bool)
    extra = {k: np.asarray(v)[keep].tolist() for k, v in tests.extra.items()}
    return FoldingTests(tests.L[keep], tests.d[keep], tests.h[keep], tests.alpha[keep], extra=extra)


def screen(diag, rerun):
    """Look for measurement artefacts in a diagnosis and repeat it where they matter.

    Parameters
    ----------
    diag : Diagnosis
        The diagnosis of all the tests, unweighted unless the tests carry a ``sigma_rad``
        column.
    rerun : callable
        ``rerun(tests, relative_sigma=None, main=False) -> Diagnosis``: the same diagnosis of
        other tests, with each test's noise relative to the RMS (weights
        ``1 / relative_sigma^2``); ``main`` when it is to be reported in place of ``diag``.

    Returns
    -------
    Diagnosis
        ``diag``, or its weighted repeat when the noise grows with the angle; its
        ``artefacts`` set to an :class:`Artefacts`.
    """
    t = diag.tests
    best = diag.best
    cols = diag.columns
    x = cols.process[best.model.process] if best.model.process else None
    g = best.model.group_index(cols.groups[best.model.group]) if best.model.group else None
    own_sigma = diag.noise.source == "sigma_rad column"
    sigma = diag.noise.sigma if diag.noise.known else None

    def robust(rel):
        if sigma is not None:
            scale = sigma * (rel if rel is not None else 1.0)
            params, res = robust_fit(best, t.L, t.d, t.h, t.alpha, scale, x=x, group=g)
            return params, res, scale
        unit = rel if rel is not None else np.ones(len(t))
        s0 = max(1.4826 * float(np.median(np.abs(best.residuals / unit))), 1e-6)
        params, res = robust_fit(best, t.L, t.d, t.h, t.alpha, s0 * unit, x=x, group=g)
        s = max(1.4826 * float(np.median(np.abs(res / unit))), 1e-6)
        return params, res, s * unit

    params, res, scale = robust(None)
    pred = t.alpha - res
    growing = growing_noise(res, pred)
    rel = None
    if growing["detected"] and not own_sigma:
        rel = relative_noise(pred, res)
        params, res, scale = robust(rel)
    failed = failed_specimens(t.alpha)
    outliers = [int(i) + 2 for i in np.nonzero(np.abs(res) > OUTLIER_Z * scale)[0]]
    out = diag
    if rel is not None:
        out = rerun(t, relative_sigma=rel, main=True)
        growing["weighted"] = True
        lo, hi = int(np.argmin(np.abs(pred))), int(np.argmax(np.abs(pred)))
        growing["text"] += (f"; fits, held-out errors and the lack-of-fit test weighted by 1/sigma_i^2, each test's "
                            f"noise sigma_i = a + b |alpha| fitted to the residuals ({rel[hi] / rel[lo]:.1f} times "
                            f"larger at the largest fold, {abs(pred[hi]):.2f} rad, than at the smallest, "
                            f"{abs(pred[lo]):.2f} rad)")
    elif growing["detected"]:
        growing["text"] += "; the tests' own sigma_rad column weights them"
    art = Artefacts(failed=failed, outliers=outliers, model=best.name,
                    robust_params=dict(zip(best.model.param_names, map(float, params))),
                    robust_residuals=res, scale=float(np.sqrt(np.mean(np.asarray(scale) ** 2))), growing=growing)
    rows = art.flagged
    keep = np.ones(len(t), bool)
    keep[np.array(rows, int) - 2] = False
    if rows and keep.sum() >= MIN_TESTS:
        sub = rerun(subset(t, keep), relative_sigma=None if rel is None else rel[keep] / np.sqrt(np.mean(rel[keep] ** 2)))
        art.without = {"rows": rows, "verdict": sub.verdict.verdict, "text": sub.verdict.text,
                       "best": sub.best.name, "named": [f.name for f in sub.named] or [sub.best.name],
                       "plausible": sub.best.plausible}
    out.artefacts = art
    if growing["weighted"]:
        out.verdict.text += f" Measurement: {growing['text']}."
    if art.without is not None:
        out.verdict.text += (f" With rows {', '.join(map(str, rows))} left out (flagged as failed specimens or gross "
                             f"outliers), the verdict is {art.without['verdict']} (best {art.without['best']}"
                             + ("" if art.without["plausible"] else ", with implausible parameters") + ").")
    return out


def with_relative_noise(noise, relative_sigma):
    """The noise and weights of a diagnosis whose tests' noise is ``relative_sigma`` (mean
    square 1) times the RMS noise: ``(Noise, weights)``, weights ``1 / relative_sigma^2``."""
    rel = np.asarray(relative_sigma, float)
    if noise.known:
        noise = dataclasses.replace(noise, sigma=noise.value * rel)
    return noise, 1.0 / rel**2
