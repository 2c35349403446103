"""Physical ranges of the hinge model's parameters: one table, read by the model files and the diagnosis.

Every parameter a deformation model (:mod:`gdfe.model`) or a diagnosed effect
(:mod:`gdfe.diagnosis.effects`) can carry has a range ``[lo, hi]`` that the materials and the
process allow, with the reasoning in words. The ranges come from the process, never from a
fit to data:

* pre-strained polystyrene shrink film, ``h`` about 0.1-0.5 mm, which shrinks in-plane by at
  most 50-60 % when heated above its glass transition;
* a DLP-printed acrylate coat, ``d`` about 0.05-1 mm, printed in layers of 25-100 um, whose
  cure depth misses the printed thickness by tens of micrometres;
* fold angles read with a protractor or from a photograph.

The film's and the coat's thicknesses ``h`` and ``d`` have ranges too, and so has the
contraction ``1 - R`` of a free face (at most :data:`MAX_CONTRACTION`): a design built outside
them is warned of (:mod:`gdfe.design`), as a length in micrometres where one in mm is meant.

A fitted parameter outside its range is *implausible*: the fit used it to absorb something
else (another effect, a measurement artefact, a misread column), so the model may describe
these tests but is not a cause, and it should not be carried to other designs.

Lengths in mm, angles in radians.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["Range", "RANGES", "MAX_CONTRACTION", "MICROMETRE_HINT", "looks_like_micrometres", "range_of", "check",
           "check_contraction"]


@dataclasses.dataclass(frozen=True)
class Range:
    """The physical range of one parameter.

    Attributes
    ----------
    lo, hi : float
        Bounds [unit]; infinite where only one side is bounded.
    unit : str
    why : str
        The physical reasoning behind the bounds.
    """

    lo: float
    hi: float
    unit: str
    why: str

    def contains(self, value) -> bool:
        return bool(self.lo <= float(value) <= self.hi)

    def as_list(self) -> list:
        """``[lo, hi]`` with infinite bounds as None (JSON has no infinity)."""
        return [None if math.isinf(v) else float(v) for v in (self.lo, self.hi)]


#: The free in-plane shrink of pre-strained polystyrene: no face of the film contracts more.
MAX_CONTRACTION = 0.6

#: A thickness [mm] above its range and above this, that lies inside the range read as micrometres,
#: looks like micrometres (290 for a film of 0.29 mm).
MICROMETRE_HINT = 10.0

def looks_like_micrometres(name, value) -> bool:
    """Whether a thickness ``value`` [mm] of ``name`` (``"h"``, ``"d"``) reads as one in micrometres: above
    :data:`MICROMETRE_HINT` and inside its range once divided by 1000 (290 for a film of 0.29 mm)."""
    return bool(value > MICROMETRE_HINT and RANGES[name].contains(value / 1000.0))


#: Parameter name -> :class:`Range`. ``scale[g]`` (one per group of a ``batch`` effect) is
#: listed as ``"scale"``; see :func:`range_of`.
RANGES = {
    "K": Range(0.0, math.inf, "",
               "a contraction coefficient is positive; how large it may be is bounded through the contraction "
               f"it gives, c <= {MAX_CONTRACTION:g} (see 'contraction')"),
    "p": Range(0.0, 5.0, "", "the exponent of h/d of a bilayer lies between 0 and about 3"),
    "E_ratio": Range(0.3, 10.0, "",
                     "a stiff DLP acrylate against polystyrene shrinking near its glass transition is about 0.3 to "
                     "10 times as stiff; a coat far stiffer than that is rigid, which is Eq. 3's own limit, and "
                     "one far softer would not hold a fold"),
    "mismatch": Range(0.0, MAX_CONTRACTION, "",
                      "the mismatch strain is the film's free shrink: pre-strained polystyrene shrinks in-plane "
                      "by at most 50-60 %"),
    "delta": Range(-0.1, 0.1, "mm",
                   "a DLP cure depth misses the printed coat by tens of micrometres (a layer of 25-100 um at "
                   "most), not by a sizeable part of the coat itself"),
    "lambda": Range(-0.5, 1.0, "mm",
                    "resin bleeding into the hinge gap or film still shrinking under the coat edge reaches a few "
                    "tenths of a millimetre, not the size of the hinges themselves"),
    "beta": Range(0.0, 2.0, "",
                  "a film that keeps its volume while shrinking in-plane by c thickens by about 2c (beta = 2); "
                  "it cannot thicken more than its volume allows, nor thin as it shrinks"),
    "alpha_max": Range(0.5, 2 * math.pi, "rad",
                       "a fold that stalls below 0.5 rad or beyond a full turn is not a cap of the activation"),
    "x50": Range(-math.inf, math.inf, "unit of the column",
                 "where half the contraction is reached may lie anywhere; the logistic keeps the fraction reached "
                 "between 0 and 1"),
    "rate": Range(-math.inf, math.inf, "1 / unit of the column",
                  "the activation may rise or fall with the process variable, steeply or not"),
    "scale": Range(0.5, 2.0, "",
                   "lots of one pre-strained film, or runs of one process, differ in shrink by tens of percent; a "
                   "group that contracts half or twice as much as another is another material or a failed process"),
    "offset": Range(-0.3, 0.3, "rad",
                    "a protractor or photograph reading of a fold is off by at most about 0.3 rad (17 degrees), "
                    "e.g. a reference line drawn on a panel instead of along it"),
    "contraction": Range(0.0, MAX_CONTRACTION, "",
                         "the contraction 1 - R of the film's free face that a model gives on a test: pre-strained "
                         "polystyrene shrinks in-plane by at most 50-60 %, so no test contracts more"),
    "h": Range(0.02, 2.0, "mm",
               "pre-strained polystyrene shrink films are about 0.1-0.5 mm thick; a sheet several times thinner "
               "does not hold a fold, one several times thicker is a plate, not a film"),
    "d": Range(0.01, 5.0, "mm",
               "a DLP-printed coat is about 0.05-1 mm thick, printed in layers of 25-100 um; a coat thinner than "
               "a layer is not printed, one several times the thickest folds nothing"),
}


def range_of(name):
    """The :class:`Range` of parameter ``name`` (``scale[g]`` -> ``"scale"``), or None."""
    if name.startswith("scale["):
        name = "scale"
    return RANGES.get(name)


def check(name, value, context=""):
    """Whether ``value`` of parameter ``name`` is inside its physical range.

    Parameters
    ----------
    name : str
    value : float
    context : str, optional
        A clause added to the reasoning (what the value means for the tests at hand).

    Returns
    -------
    dict or None
        None when inside (or when ``name`` has no range); else ``name``, ``value``, ``range``
        (``[lo, hi]``, None for an infinite bound), ``unit`` and ``why``.
    """
    r = range_of(name)
    if r is None or r.contains(value):
        return None
    why = r.why + (f"; {context}" if context else "")
    return {"name": name, "value": float(value), "range": r.as_list(), "unit": r.unit, "why": why}


def check_contraction(c):
    """:func:`check` of the largest contraction ``c`` (any shape) a model gives on its tests."""
    c = np.real(np.ravel(np.asarray(c)))
    worst = c[int(np.argmax(np.maximum(c - MAX_CONTRACTION, -c)))]
    return check("contraction", worst)

# The film's in-plane anisotropy and the coats' registration, the forms of a shape diagnosis
# beyond one region's contraction (gdfe.diagnosis.shape_forms).
RANGES["isotropy"] = Range(
    0.5, 1.0, "",
    "the weaker in-plane shrink of the film over the stronger: a biaxially pre-strained polystyrene film is drawn "
    "along both axes, and lots whose two draw ratios differ shrink tens of percent less across the draw than along "
    "it; a film that shrinks less than half as much one way as the other is uniaxially oriented, another material")
RANGES["coat_offset"] = Range(
    -3.0, 3.0, "pixels",
    "a coat printed on a film laid by hand in the printer's vat, or placed by its corner on the build plate, misses "
    "its mask by up to a few of the printer's pixels; a coat further off is misplaced, not misregistered")
