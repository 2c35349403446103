"""The verdict of a fold-angle diagnosis: is there a gap, and does the chosen model explain it?

**Noise.** The measurement noise of the angles comes, in this order, from

1. a value given by the user (``sigma=``, ``gdfe diagnose --sigma S``) [rad];
2. a ``sigma_rad`` column, one standard deviation per test [rad];
3. replicate rows, tests of the same design (equal ``L, d, h``, process columns and groups):
   the pooled within-design standard deviation (pure error), with its degrees of freedom;
4. nowhere: the noise is unknown, and said so.

**Lack of fit.** A model is *within the noise* when its residuals are what the noise
explains, at level :data:`LEVEL`:

* with a known noise, ``chi^2 = sum_i (r_i / sigma_i)^2`` on ``n - k`` degrees of freedom
  (``k`` fitted parameters) is not significantly large;
* with replicates, the classical lack-of-fit F-test: the residual sum of squares splits
  into pure error (within designs, ``n - m`` degrees of freedom for ``m`` designs) and
  lack of fit (``m - k``), and ``F = (SS_lof / (m - k)) / (SS_pe / (n - m))`` is not
  significantly large.

``sigma_needed`` is the smallest constant noise with which a model would pass the
``chi^2`` test: ``sqrt(RSS / chi2_{1-LEVEL}(n - k))``.

**Gap removed.** The gap a model leaves is its held-out mean squared error in units of the
noise, minus one: ``mean((alpha - alpha_held_out)^2 / sigma^2) - 1`` (with the noise unknown,
the held-out mean squared error itself). A model removes a *meaningful* part of the gap
when it removes at least :data:`MEANINGFUL` of the baseline's.

**Verdict** (structure: :func:`gdfe.diagnosis.where.structure` of a model's residuals
against every input, the predicted angle and every group column):

``no_gap``
    the baseline is within the noise and its residuals show no structure;
``explained``
    there is a gap, and the chosen model is within the noise with no structure left;
``measurement_issue``
    as ``explained``, but every effect of the chosen model is a measurement artefact (a
    reading offset): the gap is what a reading error makes, not physics the model can carry
    to other parts; check the reading -- if it is right, an effect outside the catalogue of
    the same form is not ruled out;
``partly_explained``
    the chosen model removes a meaningful part of the gap, but what remains is above the
    noise or shows structure (named);
``not_explained``
    there is a gap, and no candidate removes a meaningful part of it.

When the data cannot tell the chosen model from others
(:func:`gdfe.diagnosis.separate.indistinguishable`), ``explained`` and ``partly_explained``
name them all ("the data cannot tell apart: ..."), fewest effects first, and the test that
would separate them.

**Plausibility.** ``explained`` needs a plausible model: one whose every parameter lies in
its physical range (:mod:`gdfe.physical_ranges`). A chosen model that fits only with
implausible parameters describes the tests but is not credited as their cause: an
``explained`` becomes ``partly_explained``, and the verdict's text opens with "fits only
with implausible parameters: ...", each with its range and the reason, and what that means
for carrying the model to other parts.

**Measurement.** A chosen model with an effect of kind ``"measurement"`` (a reading offset)
is said to be a measurement issue, not physics.

With the noise unknown, "within the noise" cannot be tested: the verdict then rests on the
held-out choice and the residual structure alone (``no_gap``: no effect earns its parameters
and no structure; ``explained``: an effect is chosen and leaves no structure; and so on), and
its text says so and gives ``sigma_needed``.

Angles in radians.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gdfe._validation import GdfeError, check_positive

__all__ = ["Noise", "noise_of", "lack_of_fit", "decide", "Verdict", "VERDICTS", "LEVEL", "MEANINGFUL"]

#: Level of the lack-of-fit tests (and family-wise level of the structure tests).
LEVEL = 0.01
#: Part of the baseline's gap a model must remove for the removal to count.
MEANINGFUL = 0.5
#: The verdicts, in order.
VERDICTS = ("no_gap", "explained", "measurement_issue", "partly_explained", "not_explained", "structure_remains")


@dataclasses.dataclass
class Noise:
    """The noise of the measured angles and where it came from.

    Attributes
    ----------
    value : float or None [rad]
        The noise standard deviation (RMS of the per-test values of a ``sigma_rad`` column).
    source : str
        ``"given"``, ``"sigma_rad column"``, ``"replicates"`` or ``"unknown"``.
    sigma : (n,) float array or None [rad]
        Per-test standard deviation.
    dof : int or None
        Degrees of freedom of a replicate estimate (pure error).
    n_designs : int or None
        Distinct designs among the tests (replicates).
    ss_pure : float or None [rad^2]
        Pure-error sum of squares (replicates).
    """

    value: float | None
    source: str
    sigma: np.ndarray | None = None
    dof: int | None = None
    n_designs: int | None = None
    ss_pure: float | None = None

    @property
    def known(self) -> bool:
        return self.value is not None

    def text(self) -> str:
        if self.source == "given":
            return f"noise {self.value:.3g} rad (given)"
        if self.source == "sigma_rad column":
            return f"noise {self.value:.3g} rad (RMS of the sigma_rad column)"
        if self.source == "replicates":
            return (f"noise {self.value:.3g} rad from replicate rows ({self.n_designs} designs, "
                    f"{self.dof} degrees of freedom of pure error)")
        return "noise unknown (no --sigma, no sigma_rad column, no replicate rows)"

    def as_dict(self) -> dict:
        out = {"value": self.value, "source": self.source, "text": self.text()}
        if self.source == "replicates":
            out.update(dof=self.dof, n_designs=self.n_designs)
        return out


def noise_of(alpha, sigma=None, sigma_column=None, keys=None):
    """The noise of the angles: given, from a ``sigma_rad`` column, from replicates, or unknown.

    Parameters
    ----------
    alpha : (n,) float array [rad]
    sigma : float, optional
        The noise given by the user [rad], > 0.
    sigma_column : (n,) float array, optional
        Per-test noise [rad], > 0.
    keys : (n, m) float array, optional
        What makes a design (``L, d, h``, process columns, group codes): equal rows are
        replicates.

    Returns
    -------
    Noise
    """
    alpha = np.asarray(alpha, float)
    if sigma is not None:
        return Noise(value=float(check_positive("sigma", sigma)), source="given",
                     sigma=np.full(alpha.size, float(sigma)))
    if sigma_column is not None:
        s = np.asarray(sigma_column, float)
        return Noise(value=float(np.sqrt(np.mean(s**2))), source="sigma_rad column", sigma=s)
    if keys is not None:
        _, inv = np.unique(np.asarray(keys, float), axis=0, return_inverse=True)
        inv = inv.ravel()
        m = int(inv.max()) + 1
        dof = alpha.size - m
        if dof >= 2:
            means = np.bincount(inv, weights=alpha, minlength=m) / np.bincount(inv, minlength=m)
            ss = float(np.sum((alpha - means[inv]) ** 2))
            if ss > 0:
                v = float(np.sqrt(ss / dof))
                return Noise(value=v, source="replicates", sigma=np.full(alpha.size, v), dof=dof,
                             n_designs=m, ss_pure=ss)
    return Noise(value=None, source="unknown")


def _sigma_needed(rss, dof):
    from scipy import stats

    if dof <= 0:
        return None
    return float(np.sqrt(rss / stats.chi2.ppf(1.0 - LEVEL, dof)))


def lack_of_fit(residuals, n_params, noise):
    """Whether a model's residuals are within the noise.

    Parameters
    ----------
    residuals : (n,) float array [rad]
    n_params : int
    noise : Noise

    Returns
    -------
    dict
        ``test`` (``"chi2"``, ``"F"`` or None), ``statistic``, ``dof`` (a pair for F), ``p``,
        ``within`` (bool, or None when the noise is unknown), ``sigma_needed`` [rad].
    """
    from scipy import stats

    r = np.asarray(residuals, float)
    n = r.size
    rss = float(r @ r)
    out = {"test": None, "statistic": None, "dof": n - n_params, "p": None, "within": None,
           "sigma_needed": _sigma_needed(rss, n - n_params)}
    if not noise.known:
        return out
    if noise.source == "replicates" and noise.n_designs - n_params > 0:
        dof_lof, dof_pe = noise.n_designs - n_params, noise.dof
        ss_lof = max(rss - noise.ss_pure, 0.0)
        F = (ss_lof / dof_lof) / (noise.ss_pure / dof_pe)
        p = float(stats.f.sf(F, dof_lof, dof_pe))
        out.update(test="F", statistic=float(F), dof=[dof_lof, dof_pe], p=p, within=bool(p >= LEVEL))
        return out
    dof = n - n_params
    if dof <= 0:
        return out
    chi2 = float(np.sum((r / noise.sigma) ** 2))
    p = float(stats.chi2.sf(chi2, dof))
    out.update(test="chi2", statistic=chi2, dof=dof, p=p, within=bool(p >= LEVEL))
    return out


def gap(measured, held_out, noise):
    """The gap a model leaves: held-out mean squared error over the noise's, minus one
    (the held-out mean squared error [rad^2] itself when the noise is unknown)."""
    e = np.asarray(measured, float) - np.asarray(held_out, float)
    if not noise.known:
        return float(np.mean(e**2))
    return float(np.mean((e / noise.sigma) ** 2) - 1.0)


@dataclasses.dataclass
class Verdict:
    """The verdict and why.

    Attributes
    ----------
    verdict : str
        One of :data:`VERDICTS`.
    text : str
        The verdict in a sentence or two, with the numbers behind it.
    removed : float or None
        Part of the baseline's gap the chosen model removes.
    named : list of str
        The models the data cannot tell apart, the chosen one among them (fewest effects
        first; :func:`gdfe.diagnosis.separate.indistinguishable`); empty or one for a clear
        choice.
    """

    verdict: str
    text: str
    removed: float | None
    named: list = dataclasses.field(default_factory=list)

    @property
    def ambiguous(self) -> bool:
        """Whether the data cannot tell the chosen model from others (:attr:`named`)."""
        return len(self.named) > 1

    def as_dict(self):
        return {"verdict": self.verdict, "text": self.text, "removed": self.removed, "named": list(self.named),
                "ambiguous": self.ambiguous}


def _lof_words(lof, noise):
    if lof["test"] == "chi2":
        return f"chi^2 = {lof['statistic']:.1f} on {lof['dof']} dof, p = {lof['p']:.2g}"
    if lof["test"] == "F":
        return f"lack-of-fit F = {lof['statistic']:.2f} on {lof['dof'][0]}, {lof['dof'][1]} dof, p = {lof['p']:.2g}"
    return "no test"


def decide(*, best_name, best_is_baseline, lof_base, lof_best, structure_base, structure_best, gap_base,
           gap_best, noise, named=None, separation=None, implausible=None, kinds=None, effects=None,
           named_implausible=None):
    """The verdict from the lack-of-fit tests, the structure left and the gap removed.

    When the data cannot tell the chosen model from others (``named`` holds more than one
    model) and the verdict names a model (``explained``, ``partly_explained``), the text says
    so, names them all and, given ``separation``, which test would tell them apart.

    Parameters
    ----------
    best_name : str
        The chosen model (by held-out error).
    best_is_baseline : bool
    lof_base, lof_best : dict
        :func:`lack_of_fit` of the baseline and of the chosen model.
    structure_base, structure_best : list of dict
        :func:`gdfe.diagnosis.where.structure` of their residuals.
    gap_base, gap_best : float
        :func:`gap` of the two.
    noise : Noise
    named : list of str, optional
        :attr:`Verdict.named`.
    separation : str, optional
        The sentence of :func:`gdfe.diagnosis.separate.separating_test`.
    implausible : list of dict, optional
        The chosen model's parameters outside their physical range
        (:attr:`gdfe.diagnosis.fit.EffectFit.implausible`).
    kinds, effects : sequence of str, optional
        The chosen model's effects and the kind of each (``"physics"``, ``"measurement"``,
        ``"factor"``).
    named_implausible : dict of str -> list of str, optional
        For each model of ``named``, its parameters outside their physical range.

    Returns
    -------
    Verdict
    """
    v = _decide(best_name=best_name, best_is_baseline=best_is_baseline, lof_base=lof_base, lof_best=lof_best,
                structure_base=structure_base, structure_best=structure_best, gap_base=gap_base,
                gap_best=gap_best, noise=noise)
    v.named = list(named) if named else [best_name]
    if v.ambiguous and v.verdict in ("explained", "partly_explained"):
        others = [m for m in v.named if m != best_name]
        v.text = v.text.rstrip(".") + (f". The data cannot tell apart: {', '.join(v.named)}"
                   + (" (each within the noise; their held-out errors within one standard error of each other, "
                      "or their fitted angles closer than the noise can tell)" if noise.known and lof_best["within"]
                      else " (their held-out errors within one standard error of each other"
                      + (", or their fitted angles closer than the noise can tell)" if noise.known else ")"))
                   + f" ({best_name} chosen; the others: {', '.join(others)}; fewest effects first)"
                   + (f"; {separation}" if separation else ""))
        bad = {m: ps for m, ps in (named_implausible or {}).items() if ps and m in v.named}
        if bad:
            v.text = v.text.rstrip(".") + ". Of these, fit only with implausible parameters: " + "; ".join(
                f"{m} ({', '.join(ps)})" for m, ps in bad.items())
        if not v.text.endswith("."):
            v.text += "."
    measured = [e for e, k in zip(effects or (), kinds or ()) if k == "measurement"]
    if measured and len(measured) == len(effects) and v.verdict == "explained" and not implausible:
        v.verdict = "measurement_issue"
        v.text = ("a measurement issue: " + v.text.replace("explained by", "reproduced by", 1)
                  + f". {', '.join(measured)} is a reading error, not physics: the parts may have folded as "
                    "Eq. 1 says and been read otherwise, and a model of the physics carries nothing of it to other "
                    "parts; check the reading. If the reading is right, an effect outside the catalogue that "
                    "shifts the folds the same way is not ruled out.")
    elif measured and v.verdict in ("explained", "partly_explained"):
        v.text += (f" {', '.join(measured)} is a measurement issue, not physics: the parts may have folded as "
                   "modelled and been read otherwise; check the reading before changing the model.")
    if implausible and not best_is_baseline and v.verdict in ("explained", "partly_explained"):
        if v.verdict == "explained":
            v.verdict = "partly_explained"
            v.text = v.text.replace("explained by", "described by", 1)
        words = "; ".join(f"{p['name']} = {p['value']:.3g}{(' ' + p['unit']) if p['unit'] else ''} outside "
                          f"[{_bound(p['range'][0], '-inf')}, {_bound(p['range'][1], 'inf')}] ({p['why']})" for p in implausible)
        v.text = (f"fits only with implausible parameters: {words}. So {best_name} describes these tests but is not "
                  "credited as their cause: its parameters stand for something else, and carried to other parts "
                  "(other L, d, h) it extrapolates that something. " + v.text)
    return v


def _bound(v, infinite):
    return infinite if v is None else f"{v:g}"


def _decide(*, best_name, best_is_baseline, lof_base, lof_best, structure_base, structure_best, gap_base,
            gap_best, noise):
    if gap_base is None or gap_best is None:
        raise GdfeError("gap: expected the gaps of the baseline and of the chosen model")
    removed = None
    if gap_base > 0:
        removed = float(1.0 - max(gap_best, 0.0) / gap_base)
    where_left = "; ".join(s["text"] for s in structure_best[:2])
    where_base = "; ".join(s["text"] for s in structure_base[:2])
    if noise.known:
        words = noise.text()
        base_within = bool(lof_base["within"])
        if base_within and not structure_base:
            return Verdict("no_gap", f"no gap: the baseline is within the {words} "
                                     f"({_lof_words(lof_base, noise)}) and its residuals show no structure "
                                     f"against any column", removed)
        why = (f"the baseline misses by more than the {words} ({_lof_words(lof_base, noise)})"
               if not base_within else f"the baseline is within the {words} overall "
                                       f"({_lof_words(lof_base, noise)}) but its residuals show structure "
                                       f"{where_base}")
        if not best_is_baseline and lof_best["within"] and not structure_best:
            return Verdict("explained", f"explained by {best_name}: {why}; {best_name} is within the noise "
                                        f"({_lof_words(lof_best, noise)}) with no structure left", removed)
        if not best_is_baseline and removed is not None and removed >= MEANINGFUL:
            left = []
            if not lof_best["within"]:
                left.append(f"what remains is above the noise ({_lof_words(lof_best, noise)})")
            if structure_best:
                left.append(f"structure remains {where_left}")
            return Verdict("partly_explained", f"partly explained by {best_name}: {why}; it removes "
                                               f"{100 * removed:.0f} % of the held-out gap, but "
                                               + " and ".join(left), removed)
        tail = ("no effect earns its parameters on held-out data" if best_is_baseline else
                f"the best candidate, {best_name}, removes only "
                f"{100 * (removed or 0.0):.0f} % of the held-out gap")
        return Verdict("not_explained", f"not explained: {why}, and {tail}", removed)
    # the noise is unknown: held-out choice and structure only
    caveat = (" The noise is unknown (no --sigma, sigma_rad column or replicate rows), so whether a model "
              "is within the noise cannot be tested")
    need_b, need = lof_base["sigma_needed"], lof_best["sigma_needed"]
    if need_b is not None:
        caveat += (f"; the baseline would be within a noise of {need_b:.3g} rad or more"
                   + (f", {best_name} within {need:.3g} rad or more" if not best_is_baseline and need else ""))
    caveat += "."
    if best_is_baseline and not structure_base:
        return Verdict("no_gap", "no gap detected: no effect earns its parameters on held-out data and the "
                                 "baseline's residuals show no structure." + caveat, removed)
    if best_is_baseline:
        return Verdict("not_explained", f"not explained: the baseline's residuals show structure {where_base}, "
                                        "and no effect earns its parameters on held-out data." + caveat, removed)
    if not structure_best:
        return Verdict("explained", f"explained by {best_name} as far as can be told: it removes "
                                    f"{100 * (removed or 0):.0f} % of the baseline's held-out mean squared error "
                                    "and leaves no structure." + caveat, removed)
    if removed is not None and removed >= MEANINGFUL:
        return Verdict("partly_explained", f"partly explained by {best_name}: it removes {100 * removed:.0f} % "
                                           f"of the baseline's held-out mean squared error, but structure remains "
                                           f"{where_left}." + caveat, removed)
    return Verdict("not_explained", f"not explained: {best_name}, the best candidate, removes only "
                                    f"{100 * (removed or 0):.0f} % of the baseline's held-out mean squared error "
                                    f"and structure remains {where_left}." + caveat, removed)
