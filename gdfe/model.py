"""Deformation models: how a printed film deforms, one object for the whole package.

A :class:`DeformationModel` says what contraction every cell of a design reaches, from the
film thickness ``h``, the passive thickness ``d`` printed on each cell, the design's geometry
and, where the model uses them, process variables (oven temperature, batch). It is made
once — the paper's principle (:func:`paper_model`), a calibration refitted to folding tests
(:meth:`DeformationModel.from_calibration`, ``gdfe calibrate --model-out``) or the model a
diagnosis chose (:meth:`DeformationModel.from_effect_fit`, ``gdfe diagnose --model-out``)
— saved as a TOML model file (:meth:`DeformationModel.save`, :func:`load_model`), and used
by every design builder (``model=``), :func:`gdfe.simulate`, inverse design and the studies.

The contraction of a cell's free face, ``c = 1 - R``, is built in stages, the stages of the
diagnosis's hinge model (:mod:`gdfe.diagnosis.effects`) carried to any design:

1. **principle** — ``c(d, h)`` of a coat of thickness ``d`` on the film:

   ==============  ==================================  =====================
   principle       contraction ``c = 1 - R``           parameters
   ==============  ==================================  =====================
   ``eq1``         ``K (h/d)^1.5`` (Eq. 3, the paper)  K
   ``eq1-d1``      ``K h (h/d)^0.5``                   K [1/mm]
   ``power``       ``K (h/d)^p``                       K, p
   ``timoshenko``  ``h kappa_T(h, d)``                 E_ratio, mismatch
   ==============  ==================================  =====================

   ``kappa_T`` is Timoshenko's bilayer curvature (:func:`gdfe.timoshenko.bilayer_curvature`):
   the ``passive_stiffness`` effect of the diagnosis.
2. **per-cell mechanisms** on ``c``: ``cure_depth`` (every passive region acts as
   ``d + delta``), the process mechanisms, which need the part's process variables
   (``process={"T_C": 150, "lot": "B"}``): ``partial_activation`` (the fraction
   ``f(x) = 1 / (1 + exp(-rate (x - x50)))`` of the contraction reached at process value ``x``)
   and ``batch`` (a factor ``scale[g]`` per group label ``g``), ``film_thickening`` (the film thickens as it shrinks, ``h (1 + beta c)``:
   the fold's curvature ``c / h`` becomes ``c / (h (1 + beta c))``, so a cell contracts by
   ``c / (1 + beta c)`` on the film it is meshed on).
3. **geometric mechanisms**, which need the design's layout: ``saturation`` (the fold of
   every free run of film between two coat edges, of width ``w``, is capped as
   ``alpha_max tanh(alpha / alpha_max)`` with ``alpha = c (w + lambda) / h``: each cell of the
   run contracts by ``c tanh(alpha / alpha_max) / (alpha / alpha_max)``; a phenomenological
   cap: self-contact was the physical candidate, and none of Table 1's specimens meets itself
   below 4.6 rad, far above the diagnosed 2.73 rad (``gdfe study contact``)), and ``hinge_length`` (the contraction reaches ``lambda / 2``
   past every coat edge, so a hinge of width ``L`` folds like ``L + lambda``; cells the edge
   crosses contract by the fraction of their width it covers, so ``lambda`` acts continuously;
   a negative ``lambda`` takes the contraction back from the free side).

For the paper's hinge specimen (:func:`gdfe.hinge`) the stages give the diagnosis's closed
form, ``alpha = alpha_max tanh(c(d + delta) (L + lambda) / (h (1 + beta c) alpha_max))``, up to
GDFE's discretisation (tested).

**Predictive content.** A model may carry what a prediction with an interval needs
(:class:`Uncertainty`: the covariance of the fitted parameters, the scatter of a new test about
the model and its degrees of freedom, a fitted reading offset) and, from a diagnosis, every
model of its named set with a weight (:class:`Member`, ``weighting``); :mod:`gdfe.predictive`
makes them and :mod:`gdfe.predict` uses them. A file without them (format 1) still loads: its
predictions then take the parameters' standard errors as uncorrelated.

A cell free on both faces (``FREE_SHRINK``) has no coat to bend against: the bilayer
principle does not apply to it, and it shrinks by the model's contraction at the design's
nominal passive thickness (the paper's single R). Lengths in mm, angles in rad.
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import logging
import math
from pathlib import Path

import numpy as np

from gdfe import paper
from gdfe._validation import (GdfeError, GdfeFileNotFoundError, GdfeTypeError, check_choice, check_keys,
                              check_number, describe, read_text)
from gdfe.physical_ranges import RANGES, range_of

__all__ = ["DeformationModel", "Parameter", "Uncertainty", "Member", "PRINCIPLES", "MECHANISMS", "paper_model",
           "load_model", "as_model", "MODEL_FORMAT", "WEIGHTINGS"]

log = logging.getLogger(__name__)

#: Version of the model-file format written by :meth:`DeformationModel.save` (2: predictive content;
#: files of format 1 still load).
MODEL_FORMAT = 2

#: How the members of a model's named set may be weighted (:mod:`gdfe.predictive`).
WEIGHTINGS = ("stacking", "pseudo-bma", "single")


@dataclasses.dataclass(frozen=True)
class _Term:
    params: tuple
    units: tuple
    text: str


#: The deformation principles: their parameters, units and formula.
PRINCIPLES = {
    "eq1": _Term(("K",), ("",), "c = K (h/d)^1.5 (Eq. 3)"),
    "eq1-d1": _Term(("K",), ("1/mm",), "c = K h (h/d)^0.5"),
    "power": _Term(("K", "p"), ("", ""), "c = K (h/d)^p"),
    "timoshenko": _Term(("E_ratio", "mismatch"), ("", ""), "c = h kappa_T(h, d) (Timoshenko bilayer)"),
}

#: The mechanisms a model may switch on, in the order they act (see the module docstring).
MECHANISMS = {
    "cure_depth": _Term(("delta",), ("mm",), "every passive region acts as d + delta"),
    "partial_activation": _Term(("x50", "rate"), ("unit of the column", "1 / unit of the column"),
                                "the film reaches the fraction f(x) = 1 / (1 + exp(-rate (x - x50))) of its "
                                "contraction, x a process variable (oven temperature, time, ...)"),
    "batch": _Term((), (), "each group (film lot, print job, oven run) contracts by its own factor "
                           "scale[g] (1 for the first label in sorted order)"),
    "film_thickening": _Term(("beta",), ("",), "the film thickens to h (1 + beta c) as it shrinks"),
    "saturation": _Term(("alpha_max",), ("rad",),
                        "the fold of every free run between coat edges is capped as alpha_max tanh(alpha/alpha_max); "
                        "phenomenological: it carries the diagnosed cap to any design, it does not explain it "
                        "(self-contact, the physical candidate, does not: gdfe study contact)"),
    "hinge_length": _Term(("lambda",), ("mm",), "the contraction reaches lambda/2 past every coat edge"),
}

#: Ranges [lo, hi] outside which a parameter is physically doubtful, and why: the one table of
#: :mod:`gdfe.physical_ranges` (the diagnosis reads it too). A model with such a parameter
#: carries a warning (in the file and wherever it is used).
PHYSICAL_RANGES = {k: (r.lo, r.hi, r.why) for k, r in RANGES.items()}


#: Units of the process mechanisms' parameters, which are those of the part's process column
#: (degrees Celsius, minutes, ...): any unit the file gives is the column's, and is kept.
_COLUMN_UNITS = ("unit of the column", "1 / unit of the column")


def _check_unit(name, unit, own):
    """Refuse a parameter's ``unit`` other than its ``own`` (:data:`PRINCIPLES`, :data:`MECHANISMS`):
    the value is used in its own unit whatever the file says, so another would be a silent error."""
    if own in _COLUMN_UNITS or unit == own:
        return
    expected = f"the unit {own!r}" if own else "no unit (it is dimensionless)"
    raise GdfeError(f"{name}.unit: expected {expected}, got {unit!r}: gdfe reads {name} in "
                    f"{own or 'no unit'} only; convert the value (or leave the unit out)")


@dataclasses.dataclass(frozen=True)
class Parameter:
    """A model parameter with its uncertainty.

    Attributes
    ----------
    value : float
    se : float or None
        Standard error (None: not known).
    ci95 : (2,) tuple of float or None
        95 % interval (None: not known).
    unit : str
        The parameter's own unit (:data:`PRINCIPLES`, :data:`MECHANISMS`; filled in where empty): the
        value is read in it, so a model refuses another (a process mechanism's parameters take the
        unit of their column, whatever it is).
    at_bound : bool
        The fit stopped at a bound of the parameter's range.
    """

    value: float
    se: float | None = None
    ci95: tuple | None = None
    unit: str = ""
    at_bound: bool = False

    def as_dict(self):
        out = {"value": self.value, "unit": self.unit}
        if self.se is not None:
            out["se"] = self.se
        if self.ci95 is not None:
            out["ci95"] = list(self.ci95)
        if self.at_bound:
            out["at_bound"] = True
        return out


@dataclasses.dataclass(frozen=True)
class Uncertainty:
    """What a model's predictions need beyond its parameter values.

    Attributes
    ----------
    names : tuple of str
        The parameters of :attr:`covariance`, in its order: the model's, and ``"offset"``
        where the fit also had a reading offset.
    covariance : tuple of tuples of float
        ``(k, k)`` covariance of the fitted parameters (units of the parameters squared),
        ``s^2 (J^T W J)^-1`` at the optimum.
    noise_rad : float [rad]
        Standard deviation of a new test about the model: the residual scatter of the fit,
        ``sqrt(sum w r^2 / (n - k))``.
    dof : int
        Degrees of freedom of ``noise_rad`` (``n - k``); intervals use Student's t with them.
    reading_offset_rad : float [rad]
        The fitted reading offset (a measured angle is the fold plus it; 0 where none).
    noise_source : str
        Where ``noise_rad`` came from, in words.
    """

    names: tuple
    covariance: tuple
    noise_rad: float
    dof: int
    reading_offset_rad: float = 0.0
    noise_source: str = ""

    def __post_init__(self):
        names = tuple(str(n) for n in self.names)
        if len(set(names)) != len(names):
            raise GdfeError(f"uncertainty.names: expected distinct parameter names, got {list(names)}")
        try:
            cov = np.array(self.covariance, float)
        except (TypeError, ValueError):
            raise GdfeError(f"uncertainty.covariance: expected a {len(names)} x {len(names)} table of numbers, got "
                            f"{describe(self.covariance)}") from None
        k = len(names)
        if cov.shape != (k, k) or not np.all(np.isfinite(cov)):
            raise GdfeError(f"uncertainty.covariance: expected a finite {k} x {k} matrix (one row per name), got "
                            f"{describe(cov)}")
        if not np.allclose(cov, cov.T, rtol=1e-6, atol=1e-12 * (1 + np.abs(cov).max(initial=0))):
            raise GdfeError("uncertainty.covariance: expected a symmetric matrix")
        if k and np.linalg.eigvalsh(cov).min() < -1e-8 * max(np.abs(cov).max(), 1e-300):
            raise GdfeError("uncertainty.covariance: expected a positive semi-definite matrix (a covariance)")
        check_number("uncertainty.noise_rad", self.noise_rad, minimum=0.0)
        if isinstance(self.dof, bool) or not isinstance(self.dof, (int, np.integer)) or self.dof < 1:
            raise GdfeError(f"uncertainty.dof: expected a whole number >= 1, got {describe(self.dof)}")
        check_number("uncertainty.reading_offset_rad", self.reading_offset_rad)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "covariance", tuple(tuple(float(v) for v in row) for row in cov))
        object.__setattr__(self, "noise_rad", float(self.noise_rad))
        object.__setattr__(self, "dof", int(self.dof))
        object.__setattr__(self, "reading_offset_rad", float(self.reading_offset_rad))

    def matrix(self):
        """The covariance as a ``(k, k)`` float array."""
        return np.array(self.covariance, float).reshape(len(self.names), len(self.names))

    def as_dict(self):
        out = {"names": list(self.names), "covariance": [list(r) for r in self.covariance],
               "noise_rad": self.noise_rad, "dof": self.dof}
        if self.reading_offset_rad:
            out["reading_offset_rad"] = self.reading_offset_rad
        if self.noise_source:
            out["noise_source"] = self.noise_source
        return out


@dataclasses.dataclass(frozen=True)
class Member:
    """One model of a diagnosis's named set, with its weight in the predictions."""

    weight: float
    model: "DeformationModel"

    def __post_init__(self):
        check_number("member weight", self.weight, minimum=0.0, maximum=1.0)
        if not isinstance(self.model, DeformationModel):
            raise GdfeTypeError(f"member model: expected a gdfe.DeformationModel, got {type(self.model).__name__}")
        if self.model.ensemble:
            raise GdfeError(f"member {self.model.name!r}: expected a single model, got one with members of its own")


def _number_of(label):
    """The finite number a group label reads as (``"2"``, ``"2.0"``), or None (``"B"``, ``"nan"``)."""
    try:
        x = float(label)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


def _provenance_file(path):
    path = Path(path)
    return {"file": path.name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}


@dataclasses.dataclass(frozen=True)
class DeformationModel:
    """How a printed film deforms: a principle, mechanisms, parameters and where they came from.

    Parameters
    ----------
    principle : {"eq1", "eq1-d1", "power", "timoshenko"}
        See :data:`PRINCIPLES`.
    params : dict of str -> Parameter or float
        Every parameter of the principle and of the mechanisms.
    mechanisms : tuple of str
        Mechanisms switched on (:data:`MECHANISMS`), in any order.
    name : str, optional
        Default: the mechanisms joined by ``+`` (``"baseline"`` for none).
    source : str
        What made it (``"paper"``, ``"gdfe calibrate"``, ``"gdfe diagnose"``, ...).
    data : dict
        The data it was fitted to: ``file``, ``sha256``, ``n_tests``, ``held_out_rmse_rad``,
        ``held_out`` (how it was held out).
    warnings : tuple of str
        Doubtful parameters and what they mean (:data:`PHYSICAL_RANGES` adds its own).
    version : str
        The gdfe version that made it.
    uncertainty : Uncertainty or None
        The covariance of its parameters and the noise of a new test (None: not known; a
        file of format 1).
    ensemble : tuple of Member
        Every model the data could not tell from this one (this one among them), with its
        weight; empty for a single model.
    weighting : str
        How the members were weighted (:data:`WEIGHTINGS`, :mod:`gdfe.predictive`).
    """

    principle: str
    params: dict
    mechanisms: tuple = ()
    name: str | None = None
    source: str = ""
    data: dict = dataclasses.field(default_factory=dict)
    warnings: tuple = ()
    version: str = ""
    columns: dict = dataclasses.field(default_factory=dict)
    labels: tuple = ()
    uncertainty: Uncertainty | None = None
    ensemble: tuple = ()
    weighting: str = ""

    def __post_init__(self):
        check_choice("principle", self.principle, PRINCIPLES)
        mech = tuple(self.mechanisms)
        for m in mech:
            check_choice("mechanism", m, MECHANISMS)
        if len(set(mech)) != len(mech):
            raise GdfeError(f"mechanisms: expected each mechanism at most once, got {list(mech)}")
        mech = tuple(m for m in MECHANISMS if m in mech)
        object.__setattr__(self, "mechanisms", mech)
        params = {}
        for k, v in dict(self.params).items():
            params[k] = v if isinstance(v, Parameter) else Parameter(check_number(k, v))
        columns = dict(self.columns)
        for m in ("partial_activation", "batch"):
            if m in mech and not isinstance(columns.get(m), str):
                raise GdfeError(f"columns: expected the name of the process column of {m}, got "
                                f"{describe(columns.get(m))}")
        columns = {m: c for m, c in columns.items() if m in mech}
        object.__setattr__(self, "columns", columns)
        labels = tuple(str(g) for g in self.labels)
        if "batch" in mech:
            if len(labels) < 2 or len(set(labels)) != len(labels):
                raise GdfeError(f"labels: expected two or more distinct group labels for batch, got {list(labels)}")
            labels = tuple(sorted(labels))
        object.__setattr__(self, "labels", labels if "batch" in mech else ())
        needed = list(PRINCIPLES[self.principle].params) + [p for m in mech for p in MECHANISMS[m].params]
        if "batch" in mech:
            needed += [f"scale[{g}]" for g in labels[1:]]
        missing = [p for p in needed if p not in params]
        if missing:
            raise GdfeError(f"params: expected {', '.join(needed)} for principle {self.principle!r} and "
                            f"mechanisms {list(mech) or 'none'}, missing {', '.join(missing)}")
        extra = sorted(set(params) - set(needed))
        if extra:
            raise GdfeError(f"params: unexpected {', '.join(extra)}; expected {', '.join(needed)}")
        units = dict(zip(PRINCIPLES[self.principle].params, PRINCIPLES[self.principle].units))
        for m in mech:
            units.update(zip(MECHANISMS[m].params, MECHANISMS[m].units))
        units.update({f"scale[{g}]": "" for g in labels})
        for k, p in params.items():
            check_number(k, p.value)
            if not p.unit:
                params[k] = dataclasses.replace(p, unit=units[k])
            else:
                _check_unit(k, p.unit, units[k])
        self._check_admissible(params)
        object.__setattr__(self, "params", {k: params[k] for k in needed})
        if self.name is None:
            object.__setattr__(self, "name", "+".join(mech) if mech else "baseline")
        object.__setattr__(self, "warnings", tuple(self.warnings) + tuple(
            w for w in self.doubts() if w not in self.warnings))
        object.__setattr__(self, "data", dict(self.data))
        self._check_predictive()

    def _check_predictive(self):
        if self.uncertainty is not None:
            if not isinstance(self.uncertainty, Uncertainty):
                raise GdfeTypeError(f"uncertainty: expected a gdfe.model.Uncertainty, got "
                                    f"{type(self.uncertainty).__name__}")
            extra = [n for n in self.uncertainty.names if n not in self.params and n != "offset"]
            if extra:
                raise GdfeError(f"uncertainty.names: expected parameters of the model ({', '.join(self.params)}) or "
                                f"offset, got {', '.join(extra)}")
        members = tuple(self.ensemble)
        object.__setattr__(self, "ensemble", members)
        if not members:
            return
        for m in members:
            if not isinstance(m, Member):
                raise GdfeTypeError(f"ensemble: expected gdfe.model.Member items, got {type(m).__name__}")
        total = sum(m.weight for m in members)
        if abs(total - 1.0) > 1e-6:
            raise GdfeError(f"ensemble: expected member weights that sum to 1, got {total:.6g}")
        check_choice("weighting", self.weighting, WEIGHTINGS)

    @staticmethod
    def _check_admissible(params):
        """Values no film can have (the model would be meaningless), unlike doubtful ones."""
        for k in ("K", "E_ratio", "alpha_max"):
            if k in params and not params[k].value > 0:
                raise GdfeError(f"{k}: expected a positive number, got {params[k].value:g}")
        if "mismatch" in params and not 0 < params["mismatch"].value < 1:
            raise GdfeError(f"mismatch: expected a strain in (0, 1), got {params['mismatch'].value:g}")
        if "beta" in params and params["beta"].value < 0:
            raise GdfeError(f"beta: expected a thickening >= 0, got {params['beta'].value:g}")

    # -- what the model says -------------------------------------------------------------------
    def value(self, name):
        """The value of parameter ``name``."""
        return self.params[name].value

    def doubts(self):
        """Sentences on parameters at a bound of their fit or outside :data:`PHYSICAL_RANGES`."""
        out = []
        for k, p in self.params.items():
            r = range_of(k)
            lo, hi, why = (r.lo, r.hi, r.why) if r is not None else (-math.inf, math.inf, "")
            unit = f" {p.unit}" if p.unit else ""
            if p.at_bound:
                out.append(f"{k} = {p.value:.4g}{unit} stopped at a bound of its fit: the data do not "
                           f"determine it, and the model extrapolates")
            if not lo <= p.value <= hi:
                out.append(f"{k} = {p.value:.4g}{unit} is outside the physical range [{lo:g}, {hi:g}] "
                           f"({why}): the fit uses it to absorb something else; trust the model's "
                           f"predictions only near the data it was fitted to")
        return out

    def process_factor(self, process=None):
        """The factor of the process mechanisms on the contraction for ``process`` (a dict of
        the part's process variables: the column of ``partial_activation``, the group label
        of ``batch``); 1 for a model without them.

        Raises
        ------
        GdfeError
            Naming the process variable the model needs and did not get.
        """
        process = {} if process is None else dict(process)
        f = 1.0
        for m in ("partial_activation", "batch"):
            if m not in self.mechanisms:
                continue
            col = self.columns[m]
            if col not in process:
                raise GdfeError(f"process: model {self.name!r} needs {col} ({m}); give it as "
                                f"process={{{col!r}: ...}} (gdfe --process {col}=VALUE)")
            v = process[col]
            if m == "partial_activation":
                x = check_number(f"process {col}", v)
                z = np.clip(self.value("rate") * (x - self.value("x50")), -60.0, 60.0)
                f *= 0.5 * (1.0 + math.tanh(0.5 * z))
            else:
                g = self.group_of(col, v)
                f *= 1.0 if g == self.labels[0] else self.value(f"scale[{g}]")
        return f

    def group_of(self, column, value):
        """The group label of ``batch`` that ``value`` (of process variable ``column``) names: the label
        written the same, or, for a number, the one label that reads as the same number (``2`` and
        ``2.0`` name the label ``"2"``, as the command line's ``--process lot=2`` gives a number).

        Raises
        ------
        GdfeError
            Naming ``column`` where ``value`` names no group, or more than one.
        """
        g = str(value)
        if g in self.labels:
            return g
        if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)):
            same = [lab for lab in self.labels if _number_of(lab) == value]
            if len(same) == 1:
                return same[0]
            if same:
                raise GdfeError(f"process {column}: {g} names more than one group the model was fitted to "
                                f"({', '.join(same)}); give the label as written in the model file")
        raise GdfeError(f"process {column}: expected one of the groups the model was fitted to "
                        f"({', '.join(self.labels)}), got {g!r}")

    def contraction(self, d, h, process=None):
        """Contraction ``c = 1 - R`` of a free face on a coat of thickness ``d`` [mm], film ``h`` [mm].

        Stages 1 and 2 (principle, ``cure_depth``, the process mechanisms at ``process``,
        ``film_thickening``); the geometric mechanisms need a design (:meth:`apply`).

        Raises
        ------
        GdfeError
            Where ``c >= 1`` (R <= 0: a film that would have to vanish), naming ``d``.
        """
        d = np.asarray(d, float)
        h = np.asarray(h, float)
        d_eff = d + self.value("delta") if "cure_depth" in self.mechanisms else d
        if np.any(d_eff <= 0):
            bad = np.atleast_1d(d)[np.atleast_1d(d_eff <= 0)][0]
            raise GdfeError(f"d: {bad:g} mm with cure_depth delta = {self.value('delta'):g} mm leaves no coat "
                            f"(model {self.name!r})")
        c = self._principle(d_eff, h) * self.process_factor(process)
        if "film_thickening" in self.mechanisms:
            c = c / (1.0 + self.value("beta") * c)
        if np.any(~(c < 1)):
            bad_mask = np.atleast_1d(~(c < 1))
            bad = float(np.atleast_1d(np.broadcast_to(d, np.shape(c)))[bad_mask][0])
            hb = float(np.atleast_1d(np.broadcast_to(h, np.shape(c)))[bad_mask][0])
            cb = float(np.atleast_1d(c)[bad_mask][0])
            d_min = self.d_min(hb, process)
            need = (f"which needs d > {d_min:.4g} mm" if math.isfinite(d_min) else
                    "which no passive thickness up to 1 m gives with these parameters")
            raise GdfeError(f"d={bad:g} mm gives R={1 - cb:.4g} by model {self.name!r} ({self.describe_principle()}, "
                            f"h={hb:g} mm); a contraction ratio must lie in (0, 1], {need}")
        return c

    def d_min(self, h=paper.H, process=None, ratio=0.0):
        """Thinnest passive layer [mm] for which the model gives R > ``ratio`` (default 0: a film that
        does not vanish) at film thickness ``h`` (for the process mechanisms: at ``process``, or fully
        activated and in the reference group where none is given)."""
        factor = 1.0 if process is None else self.process_factor(process)
        from scipy.optimize import brentq

        def excess(log_d):
            with np.errstate(all="ignore"):
                c = self._stage_c(np.exp(log_d), h, factor)
            return (c if np.isfinite(c) else 2.0) - (1.0 - ratio)

        lo, hi = np.log(1e-6), np.log(1e3)
        if excess(lo) < 0:  # never reaches R <= 0 (e.g. a thickening film)
            return 0.0
        if excess(hi) >= 0:
            return math.inf
        return float(np.exp(brentq(excess, lo, hi, xtol=1e-12)))

    def check_coats(self, d, h, process=None, ratio=0.0):
        """Refuse coats ``d`` [mm] on which the model gives a contraction ratio below ``ratio``, naming
        the thinnest (and the ratio it gives) and the thinnest coat that passes: :meth:`d_min` at
        ``ratio``, rounded up to 4 significant digits so that the number said passes."""
        d = np.atleast_1d(np.asarray(d, float))
        thinnest = self.d_min(h, process, ratio)
        if not d.size or d.min() >= thinnest:
            return
        bad = float(d.min())
        with np.errstate(all="ignore"):
            R = 1.0 - self._stage_c(bad, h, 1.0 if process is None else self.process_factor(process))
        if math.isfinite(thinnest):
            scale = 10.0 ** (3 - math.floor(math.log10(thinnest)))
            need = f"which needs d >= {math.ceil(thinnest * scale) / scale:g} mm"
        else:
            need = "which no passive thickness up to 1 m gives with these parameters"
        raise GdfeError(f"d={bad:g} mm gives R={R:.4g} by model {self.name!r} ({self.describe_principle()}, "
                        f"h={h:g} mm); a contraction ratio must lie in [{ratio:g}, 1], {need}")

    def _stage_c(self, d, h, factor=1.0):
        """Stages 1-2 without checks (:meth:`contraction`'s formula)."""
        d_eff = d + self.value("delta") if "cure_depth" in self.mechanisms else d
        if d_eff <= 0:
            return math.inf
        c = float(self._principle(d_eff, h)) * factor
        if "film_thickening" in self.mechanisms:
            c = c / (1.0 + self.value("beta") * c)
        return c

    def ratio(self, d, h=paper.H, process=None):
        """Contraction ratio ``R = 1 - c`` for passive thickness ``d`` [mm] (see :meth:`contraction`)."""
        return 1.0 - self.contraction(d, h, process)

    def _principle(self, d, h):
        p = {k: v.value for k, v in self.params.items()}
        if self.principle == "eq1":
            return p["K"] * (h / d) ** 1.5
        if self.principle == "eq1-d1":
            return p["K"] * h * np.sqrt(h / d)
        if self.principle == "power":
            return p["K"] * (h / d) ** p["p"]
        from gdfe.timoshenko import bilayer_curvature

        return h * bilayer_curvature(h, d, p["E_ratio"], p["mismatch"])

    def hinge_angle(self, L, d, h=paper.H, process=None):
        """The model's closed form for the paper's hinge specimen [rad] (what :meth:`apply` gives
        a hinge of width ``L`` up to GDFE's discretisation)."""
        c = self.contraction(d, h, process)
        L = np.asarray(L, float)
        if "hinge_length" in self.mechanisms:
            L = L + self.value("lambda")
        alpha = c * L / h
        if "saturation" in self.mechanisms:
            am = self.value("alpha_max")
            alpha = am * np.tanh(alpha / am)
        return alpha

    def describe_principle(self):
        return PRINCIPLES[self.principle].text + ", " + ", ".join(
            f"{k} = {self.value(k):.4g}" for k in PRINCIPLES[self.principle].params)

    def text(self):
        """Human-readable description (what the CLI prints)."""
        lines = [f"deformation model {self.name!r} ({self.source or 'given'}): {self.describe_principle()}"]
        for m in self.mechanisms:
            par = ", ".join(f"{k} = {self.value(k):.4g} {self.params[k].unit}".rstrip()
                            for k in MECHANISMS[m].params)
            lines.append(f"  {m}: {par} ({MECHANISMS[m].text})")
        if self.data.get("n_tests"):
            held = self.data.get("held_out_rmse_rad")
            lines.append(f"  fitted to {self.data.get('file', '?')} ({self.data['n_tests']} tests)"
                         + (f", held-out RMSE {held:.3f} rad ({self.data.get('held_out', '')})" if held is not None else ""))
        for w in self.warnings:
            lines.append(f"  WARNING: {w}")
        return "\n".join(lines)

    # -- the model on a design -------------------------------------------------------------------
    def apply(self, design, process=None):
        """The design with every cell's contraction from this model.

        Parameters
        ----------
        design : Design
            Its cells carry the passive thickness ``design.d`` they were printed with.
        process : dict, optional
            The part's process variables, for ``partial_activation`` and ``batch``.

        Returns
        -------
        Design
            A copy with ``R`` (per cell, from its ``d``), the explicit per-face contraction
            where a geometric mechanism acts, and ``model`` set to this model.
        """
        from gdfe.material import Material

        if not hasattr(design, "face_contraction") or not hasattr(design, "material"):
            raise GdfeTypeError(f"design: expected a gdfe.Design, got {type(design).__name__}")
        mat = design.material
        one_side = (mat == Material.CONTRACT_TOP) | (mat == Material.CONTRACT_BOTTOM)
        free = mat == Material.FREE_SHRINK
        d = design.d
        if d is None or np.any(~np.isfinite(d[one_side])):
            raise GdfeError("design: the model needs the passive thickness d of every cell coated on one face; "
                            "build the design with d (e.g. gdfe.hinge(L, d=0.33)) or give R instead of a model")
        R = np.ones(design.n_cells)
        if one_side.any():
            R[one_side] = 1.0 - self.contraction(d[one_side], design.h, process)
        if free.any():
            d0 = design.meta.get("d_mm")
            d0 = float(np.nanmedian(d[one_side])) if d0 is None and one_side.any() else d0
            if d0 is None:
                raise GdfeError("design: cells free on both faces shrink by the model's contraction at the "
                                "design's nominal d; give d")
            R[free] = 1.0 - self.contraction(float(d0), design.h, process)
        out = dataclasses.replace(design, R=R, contraction=None, model=self)
        if self.geometric:
            out = dataclasses.replace(out, contraction=self._geometric(out))
        return out

    @property
    def geometric(self) -> bool:
        """Whether a mechanism needs the design's layout (``saturation``, ``hinge_length``)."""
        return "saturation" in self.mechanisms or "hinge_length" in self.mechanisms

    def _geometric(self, design):
        """Per-face contraction ``(m, 2)`` after ``saturation`` and ``hinge_length``."""
        top, bottom = design.face_contraction()
        grid = _ColumnGrid(design)
        faces = [grid.to_cells(c2) for c2 in
                 self.contraction_grid(grid.to_grid(top), grid.to_grid(bottom), grid.present, grid.dx, grid.dy,
                                       design.h)]
        return np.column_stack(faces)

    def contraction_grid(self, top, bottom, present, dx, dy, h):
        """The geometric mechanisms on an in-plane grid of contractions (stage 3).

        Parameters
        ----------
        top, bottom : (nx, ny) float arrays
            Contraction ``1 - R`` of each face of every column (0 where coated), from
            :meth:`contraction`.
        present : (nx, ny) bool array
            Where the film is.
        dx, dy : float [mm]
            Column size.
        h : float [mm]

        Returns
        -------
        top, bottom : (nx, ny) float arrays
        """
        lam = self.value("lambda") if "hinge_length" in self.mechanisms else 0.0
        faces = []
        for c2 in (np.asarray(top, float), np.asarray(bottom, float)):
            free = present & (c2 > 0)
            coated = present & ~free
            if "saturation" in self.mechanisms:
                w = np.minimum(_run_width(free, coated, 0) * dx, _run_width(free, coated, 1) * dy)
                capped = free & np.isfinite(w) & (w + lam > 0)
                alpha = np.where(capped, c2 * np.where(capped, w + lam, 0.0) / h, 0.0)
                am = self.value("alpha_max")
                s = np.ones_like(c2)
                s[capped] = np.tanh(alpha[capped] / am) / (alpha[capped] / am)
                c2 = c2 * s
            if lam != 0.0:
                c2 = _spread(c2, free, coated, lam, dx, dy)
            faces.append(c2)
        return faces[0], faces[1]

    # -- files ----------------------------------------------------------------------------------
    def as_dict(self):
        out = {"format": MODEL_FORMAT, "name": self.name, "principle": self.principle,
               "mechanisms": list(self.mechanisms), "source": self.source,
               "gdfe_version": self.version,
               "parameters": {k: p.as_dict() for k, p in self.params.items()}}
        if self.columns:
            out["columns"] = dict(self.columns)
        if self.labels:
            out["labels"] = list(self.labels)
        if self.data:
            out["data"] = dict(self.data)
        out["warnings"] = list(self.warnings)
        if self.uncertainty is not None:
            out["uncertainty"] = self.uncertainty.as_dict()
        if self.ensemble:
            members = []
            for m in self.ensemble:
                entry = {k: v for k, v in m.model.as_dict().items() if k not in ("format", "gdfe_version")}
                members.append({"weight": m.weight, **entry})
            out["ensemble"] = {"weighting": self.weighting, "members": members}
        return out

    def save(self, path):
        """Write the model as a TOML file (renamed into place when complete); return the path."""
        import tomli_w

        from gdfe.io import write_text

        head = (f"# gdfe deformation model: {self.describe_principle()}"
                + (f"; mechanisms {', '.join(self.mechanisms)}" if self.mechanisms else "") + "\n"
                "# read with gdfe.load_model(PATH), gdfe simulate --model PATH, or [film] model = PATH\n")
        return write_text(path, head + tomli_w.dumps(_toml_ready(self.as_dict())))

    @classmethod
    def load(cls, path):
        """Read a model file written by :meth:`save`, checking every key and value."""
        return load_model(path)

    # -- makers ---------------------------------------------------------------------------------
    @classmethod
    def from_calibration(cls, fit, data=None, held_out_rmse=None, tests=None):
        """The model of a reading of Eq. 1 fitted to folding tests (:func:`gdfe.fit_reading`).

        Parameters
        ----------
        fit : CalibrationFit
        data : path, optional
            The CSV it was fitted to (its name and sha256 go into the model; its tests give
            the predictive content when ``tests`` is not given).
        held_out_rmse : float, optional
            Its leave-one-out RMSE [rad].
        tests : FoldingTests, optional
            The tests it was fitted to: the model then carries the covariance of its
            parameters, ``s^2 (J^T J)^-1`` by central differences of its closed form, and the
            noise ``s = sqrt(RSS / (n - k))`` (:class:`Uncertainty`).
        """
        from gdfe._version import __version__

        K = Parameter(fit.K, ci95=tuple(fit.K_ci) if fit.n and np.isfinite(fit.K_ci).all() else None)
        params = {"K": K}
        if fit.model == "power":
            params["p"] = Parameter(fit.p, ci95=tuple(fit.p_ci) if fit.n and np.isfinite(fit.p_ci).all() else None)
        info = _provenance_file(data) if data is not None else {}
        info["n_tests"] = int(fit.n)
        info["rmse_rad"] = float(fit.rmse)
        if held_out_rmse is not None:
            info["held_out_rmse_rad"] = float(held_out_rmse)
            info["held_out"] = "leave one test out"
        model = cls(principle=fit.model, params=params, name=f"calibration {fit.model}",
                    source="gdfe calibrate", data=info, version=__version__)
        if tests is None and data is not None:
            from gdfe.calibration import load_folding_tests

            tests = load_folding_tests(data)
        if tests is None or len(tests) != fit.n or fit.n <= len(params):
            return model
        return dataclasses.replace(model, uncertainty=_least_squares_uncertainty(model, tests))

    @classmethod
    def from_effect_fit(cls, fit, data=None, n_tests=None, held_out="loo"):
        """The model of a fitted catalogue effect of the diagnosis (:class:`gdfe.diagnosis.EffectFit`).

        The diagnosis's hinge model (:class:`gdfe.diagnosis.Model`) becomes the same stages
        on any design: ``passive_stiffness`` is the Timoshenko principle, the other effects
        are mechanisms of the same names. A measurement effect (``reading_offset``) is how the
        folds were read, not how a part folds: it is left out, and the model says so (in its
        warnings, and in its name: ``saturation (fitted beside reading_offset)``, apart from
        ``saturation`` fitted alone).
        """
        from gdfe._version import __version__

        measured = {"reading_offset": "offset"}
        effects = tuple(e for e in fit.model.effects if e not in measured)
        values = dict(zip(fit.model.param_names, np.asarray(fit.params, float)))
        notes = tuple(f"{e} ({measured[e]} = {values[measured[e]]:.4g} rad) was fitted too: a measurement issue, not "
                      f"how the parts fold, so it is left out of this model" for e in fit.model.effects if e in measured)
        values = {k: v for k, v in values.items() if k not in measured.values()}
        se = getattr(fit, "se", None)
        se = dict(zip(fit.model.param_names, np.asarray(se, float))) if se is not None else {}
        at_bound = set(getattr(fit, "at_bound", ()) or ())
        ci = getattr(fit, "ci95", None)
        ci = dict(zip(fit.model.param_names, np.asarray(ci, float))) if ci is not None else {}

        def interval(k):
            lohi = ci.get(k)
            return None if lohi is None or not np.all(np.isfinite(lohi)) else (float(lohi[0]), float(lohi[1]))

        params = {k: Parameter(float(v), se=_finite_or_none(se.get(k)), ci95=interval(k), at_bound=k in at_bound)
                  for k, v in values.items()}
        unknown = [e for e in effects if e not in MECHANISMS and e != "passive_stiffness"]
        if unknown:
            raise GdfeError(f"effect: {', '.join(unknown)} has no mechanism on a design; expected one of "
                            f"{', '.join(['passive_stiffness', *MECHANISMS])}")
        columns = {}
        if "partial_activation" in effects:
            columns["partial_activation"] = fit.model.process
        if "batch" in effects:
            columns["batch"] = fit.model.group
        labels = tuple(getattr(fit.model, "labels", None) or ())
        principle = "timoshenko" if "passive_stiffness" in effects else "eq1"
        info = _provenance_file(data) if data is not None else {}
        if n_tests is not None:
            info["n_tests"] = int(n_tests)
        rmse = fit.held_out_rmse(held_out) if hasattr(fit, "held_out_rmse") else None
        if rmse is not None and np.isfinite(rmse):
            info["held_out_rmse_rad"] = float(rmse)
            info["held_out"] = {"loo": "leave one test out", "logo": "leave one group out"}.get(held_out, held_out)
        mech = tuple(e for e in effects if e != "passive_stiffness")
        dropped = [e for e in fit.model.effects if e in measured]
        # named apart from the same effects fitted alone (a plan or an ensemble may hold both)
        name = fit.model.name if not dropped else (f"{'+'.join(effects) or 'baseline'} (fitted beside "
                                                   f"{'+'.join(dropped)})")
        return cls(principle=principle, params=params, mechanisms=mech, name=name,
                   source="gdfe diagnose", data=info, version=__version__, columns=columns, labels=labels,
                   warnings=notes)


def _least_squares_uncertainty(model, tests):
    """:class:`Uncertainty` of a model fitted by least squares to ``tests`` (no process mechanisms):
    the Jacobian of its hinge closed form by central differences."""
    names = tuple(model.params)
    mu = model.hinge_angle(tests.L, tests.d, tests.h)
    J = np.empty((len(tests), len(names)))
    for j, k in enumerate(names):
        v = model.value(k)
        step = 1e-5 * max(abs(v), 1e-3)
        angles = []
        for x in (v + step, v - step):
            params = {q: dataclasses.replace(p, value=x if q == k else p.value) for q, p in model.params.items()}
            angles.append(dataclasses.replace(model, params=params, warnings=()).hinge_angle(tests.L, tests.d, tests.h))
        J[:, j] = (angles[0] - angles[1]) / (2 * step)
    n, k = J.shape
    s2 = float(np.sum((tests.alpha - mu) ** 2)) / (n - k)
    cov = s2 * np.linalg.pinv(J.T @ J)
    return Uncertainty(names=names, covariance=0.5 * (cov + cov.T), noise_rad=float(np.sqrt(s2)), dof=n - k,
                       noise_source=f"residual scatter of the fit, sqrt(RSS / (n - k)) with n = {n}, k = {k}")


def _toml_ready(obj):
    """``obj`` without the None and empty-string values TOML cannot hold (recursively)."""
    if isinstance(obj, dict):
        return {k: _toml_ready(v) for k, v in obj.items() if v is not None and not (isinstance(v, str) and v == "")}
    if isinstance(obj, list):
        return [_toml_ready(v) for v in obj]
    return obj


def _finite_or_none(x):
    return float(x) if x is not None and np.isfinite(x) else None


def paper_model(K=paper.K):
    """The paper's deformation principle: Eq. 3 with ``K`` (default the printed 0.3706)."""
    return DeformationModel(principle="eq1", params={"K": K}, name="paper" if K == paper.K else "eq3",
                            source="the GDFE paper (Eq. 3)" if K == paper.K else "Eq. 3")


def as_model(model, base=None):
    """A :class:`DeformationModel` from a model, a model file's path (relative to ``base``), or None."""
    if model is None or isinstance(model, DeformationModel):
        return model
    if isinstance(model, (str, Path)):
        path = Path(model)
        if base is not None and not path.is_absolute():
            path = Path(base) / path
        return load_model(path)
    raise GdfeTypeError(f"model: expected a gdfe.DeformationModel or the path of a model file, "
                        f"got {type(model).__name__}")


# -- reading model files --------------------------------------------------------------------------
_TOP_KEYS = ("format", "name", "principle", "mechanisms", "source", "gdfe_version", "parameters", "data",
             "warnings", "columns", "labels", "uncertainty", "ensemble")
_MEMBER_KEYS = ("weight", "name", "principle", "mechanisms", "source", "parameters", "data", "warnings", "columns",
                "labels", "uncertainty")
_UNCERTAINTY_KEYS = ("names", "covariance", "noise_rad", "dof", "reading_offset_rad", "noise_source")
_PARAM_KEYS = ("value", "unit", "se", "ci95", "at_bound")
_DATA_KEYS = ("file", "sha256", "n_tests", "rmse_rad", "held_out_rmse_rad", "held_out")


def _unknown(where, keys, known):
    check_keys(where, keys, known)


def _num(where, v, *, integer=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
        raise GdfeError(f"{where}: expected {'an integer' if integer else 'a number'}, got {describe(v)}")
    if not math.isfinite(v):
        raise GdfeError(f"{where}: expected a finite number, got {v}")
    return v


def _str(where, v):
    if not isinstance(v, str):
        raise GdfeError(f"{where}: expected a string, got {describe(v)}")
    return v


def load_model(path):
    """Read a deformation model file (TOML, :meth:`DeformationModel.save`).

    Every key and value is checked: an unknown key (with a "did you mean"), a wrong type, a
    parameter a film cannot have or in a unit other than its own, a top level that is not the
    member of the same name in ``[ensemble]``, a missing file — each is a :class:`gdfe.GdfeError`
    naming the file and the key. Files of format 1 (no predictive content) load as before.
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python < 3.11
        import tomli as tomllib
    if isinstance(path, (bytes, bool)) or not isinstance(path, (str, Path)) or str(path) == "":
        raise GdfeTypeError(f"model: expected the path of a model file, got {describe(path)}")
    path = Path(path)
    if not path.is_file():
        raise GdfeFileNotFoundError(f"model file not found: {path}")
    try:
        doc = tomllib.loads(read_text(path, "TOML model file"))
    except tomllib.TOMLDecodeError as exc:
        raise GdfeError(f"{path.name}: not valid TOML: {exc}") from None
    name = path.name
    _unknown(name, doc, _TOP_KEYS)
    if "format" in doc and _num(f"{name}: format", doc["format"], integer=True) > MODEL_FORMAT:
        raise GdfeError(f"{name}: format {doc['format']} is newer than this gdfe reads ({MODEL_FORMAT})")
    members, weighting = _ensemble(name, doc.get("ensemble"))
    model = _model_of(name, doc, ensemble=members, weighting=weighting)
    _check_nominal(name, model)
    for w in model.warnings:
        if w not in doc.get("warnings", []):
            log.warning("%s: %s", name, w)
    return model


def _ensemble(where, spec):
    """The members and weighting of an ``[ensemble]`` table (none when absent)."""
    if spec is None:
        return (), ""
    if not isinstance(spec, dict):
        raise GdfeError(f"{where}: ensemble: expected a table, got {describe(spec)}")
    _unknown(f"{where}: ensemble", spec, ("weighting", "members"))
    members = spec.get("members")
    if not isinstance(members, list) or not members or not all(isinstance(m, dict) for m in members):
        raise GdfeError(f"{where}: ensemble.members: expected one or more tables ([[ensemble.members]]), got "
                        f"{describe(members)}")
    weighting = _str(f"{where}: ensemble.weighting", spec.get("weighting", ""))
    if weighting not in WEIGHTINGS:
        raise GdfeError(f"{where}: ensemble.weighting: expected one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
    out = []
    for i, m in enumerate(members):
        here = f"{where}: ensemble.members[{i}]"
        _unknown(here, m, _MEMBER_KEYS)
        if "weight" not in m:
            raise GdfeError(f"{here}: missing key 'weight'")
        weight = float(_num(f"{here}.weight", m["weight"]))
        model = _model_of(here, m)  # its errors name the member already
        try:
            out.append(Member(weight, model))
        except GdfeError as exc:
            raise GdfeError(f"{here}: {exc}") from None
    return tuple(out), weighting


def _check_nominal(where, model):
    """Refuse a file whose top level (the nominal model: its fold) is not the member of the same name (whose
    draws give the intervals): a hand-edited value would put the intervals about another model."""
    same = [(i, m.model) for i, m in enumerate(model.ensemble) if m.model.name == model.name]
    if not same:
        return
    i, member = same[0]
    here = f"ensemble.members[{i}] ({member.name!r})"
    for key in ("principle", "mechanisms", "columns", "labels"):
        if getattr(model, key) != getattr(member, key):
            raise GdfeError(f"{where}: {key}: expected the same as {here}, the member the top level names, got "
                            f"{getattr(model, key)!r} against its {getattr(member, key)!r}")
    for k, p in model.params.items():
        if not math.isclose(p.value, member.value(k), rel_tol=1e-9, abs_tol=1e-300):
            raise GdfeError(f"{where}: parameters.{k}: expected {member.value(k):.10g}, the value of {here}, the "
                            f"member the top level names, got {p.value:.10g}: the nominal fold would come from one "
                            f"model and the intervals from another; give both the same value (or remove the "
                            f"[ensemble] table to use the top level alone)")


def _uncertainty_of(where, spec):
    if spec is None:
        return None
    if not isinstance(spec, dict):
        raise GdfeError(f"{where}: uncertainty: expected a table, got {describe(spec)}")
    _unknown(f"{where}: uncertainty", spec, _UNCERTAINTY_KEYS)
    for k in ("names", "covariance", "noise_rad", "dof"):
        if k not in spec:
            raise GdfeError(f"{where}: uncertainty: missing key {k!r}")
    names = spec["names"]
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise GdfeError(f"{where}: uncertainty.names: expected a list of parameter names, got {describe(names)}")
    cov = spec["covariance"]
    if not isinstance(cov, list) or not all(isinstance(r, list) for r in cov):
        raise GdfeError(f"{where}: uncertainty.covariance: expected a list of rows, got {describe(cov)}")
    for r in cov:
        for v in r:
            _num(f"{where}: uncertainty.covariance", v)
    try:
        return Uncertainty(names=tuple(names), covariance=cov, noise_rad=_num(f"{where}: uncertainty.noise_rad",
                                                                            spec["noise_rad"]),
                           dof=_num(f"{where}: uncertainty.dof", spec["dof"], integer=True),
                           reading_offset_rad=_num(f"{where}: uncertainty.reading_offset_rad",
                                                   spec.get("reading_offset_rad", 0.0)),
                           noise_source=_str(f"{where}: uncertainty.noise_source", spec.get("noise_source", "")))
    except GdfeError as exc:
        raise GdfeError(f"{where}: {exc}") from None


def _model_of(name, doc, ensemble=(), weighting=""):
    """The :class:`DeformationModel` of a model file's table (the file itself, or a member)."""
    for key in ("principle", "parameters"):
        if key not in doc:
            raise GdfeError(f"{name}: missing key {key!r}")
    principle = _str(f"{name}: principle", doc["principle"])
    if principle not in PRINCIPLES:
        raise GdfeError(f"{name}: principle: expected one of {', '.join(PRINCIPLES)}, got {principle!r}")
    mech = doc.get("mechanisms", [])
    if not isinstance(mech, list):
        raise GdfeError(f"{name}: mechanisms: expected a list of names, got {describe(mech)}")
    for m in mech:
        if m not in MECHANISMS:
            raise GdfeError(f"{name}: mechanisms: expected names among {', '.join(MECHANISMS)}, got {m!r}")
    params = doc["parameters"]
    if not isinstance(params, dict):
        raise GdfeError(f"{name}: parameters: expected a table, got {describe(params)}")
    needed = [*PRINCIPLES[principle].params, *(p for m in mech for p in MECHANISMS[m].params)]
    _unknown(f"{name}: [parameters]", {k: v for k, v in params.items() if not k.startswith("scale[")}, needed)
    parsed = {}
    for k, spec in params.items():
        where = f"{name}: parameters.{k}"
        if isinstance(spec, (int, float)) and not isinstance(spec, bool):
            spec = {"value": spec}
        if not isinstance(spec, dict):
            raise GdfeError(f"{where}: expected a number or a table with 'value', got {describe(spec)}")
        _unknown(where, spec, _PARAM_KEYS)
        if "value" not in spec:
            raise GdfeError(f"{where}: missing key 'value'")
        ci = spec.get("ci95")
        if ci is not None and (not isinstance(ci, list) or len(ci) != 2):
            raise GdfeError(f"{where}.ci95: expected [low, high], got {describe(ci)}")
        at_bound = spec.get("at_bound", False)
        if not isinstance(at_bound, bool):
            raise GdfeError(f"{where}.at_bound: expected true or false, got {describe(at_bound)}")
        parsed[k] = Parameter(value=float(_num(f"{where}.value", spec["value"])),
                              se=None if spec.get("se") is None else float(_num(f"{where}.se", spec["se"])),
                              ci95=None if ci is None else tuple(float(_num(f"{where}.ci95", x)) for x in ci),
                              unit=_str(f"{where}.unit", spec.get("unit", "")), at_bound=at_bound)
    data = doc.get("data", {})
    if not isinstance(data, dict):
        raise GdfeError(f"{name}: data: expected a table, got {describe(data)}")
    _unknown(f"{name}: data", data, _DATA_KEYS)
    for k in ("n_tests",):
        if k in data:
            _num(f"{name}: data.{k}", data[k], integer=True)
    for k in ("rmse_rad", "held_out_rmse_rad"):
        if k in data:
            _num(f"{name}: data.{k}", data[k])
    warnings = doc.get("warnings", [])
    if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
        raise GdfeError(f"{name}: warnings: expected a list of strings, got {describe(warnings)}")
    columns = doc.get("columns", {})
    if not isinstance(columns, dict) or not all(isinstance(v, str) for v in columns.values()):
        raise GdfeError(f"{name}: columns: expected a table of column names, got {describe(columns)}")
    _unknown(f"{name}: columns", columns, ("partial_activation", "batch"))
    labels = doc.get("labels", [])
    if not isinstance(labels, list) or not all(isinstance(v, str) for v in labels):
        raise GdfeError(f"{name}: labels: expected a list of group labels, got {describe(labels)}")
    uncertainty = _uncertainty_of(name, doc.get("uncertainty"))
    try:
        return DeformationModel(principle=principle, params=parsed, mechanisms=tuple(mech),
                                name=doc.get("name"), source=doc.get("source", ""), data=data,
                                warnings=tuple(warnings), version=doc.get("gdfe_version", ""),
                                columns=columns, labels=tuple(labels), uncertainty=uncertainty,
                                ensemble=ensemble, weighting=weighting)
    except GdfeError as exc:
        raise GdfeError(f"{name}: {exc}") from None


# -- geometry of the mechanisms -------------------------------------------------------------------
class _ColumnGrid:
    """The in-plane grid of a design's cell columns (every layer of a column alike)."""

    def __init__(self, design):
        ij = design.mesh.cell_ij
        self.i, self.j = ij[:, 0], ij[:, 1]
        self.shape = (int(self.i.max()) + 1, int(self.j.max()) + 1)
        self.dx, self.dy = (float(s) for s in design.mesh.spacing[:2])
        self.present = np.zeros(self.shape, bool)
        self.present[self.i, self.j] = True

    def to_grid(self, values):
        out = np.zeros(self.shape)
        out[self.i, self.j] = values  # every layer of a column holds the same value
        return out

    def to_cells(self, grid):
        return grid[self.i, self.j]


def _run_width(free, coated, axis):
    """Length (in cells) of every free cell's run along ``axis`` when a coated cell ends it on
    both sides; ``inf`` where the run ends at the film's edge or a hole."""
    f = np.moveaxis(free, axis, 0)
    c = np.moveaxis(coated, axis, 0)
    n = f.shape[0]
    idx = np.arange(n)[:, None] * np.ones(f.shape[1:], int)[None]
    stop = ~f  # a run ends at any cell that is not free
    last = np.maximum.accumulate(np.where(stop, idx, -1), axis=0)  # previous stopping cell (or -1)
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(stop, idx, n), 0), axis=0), 0)
    cols = np.arange(f.shape[1])[None]
    left_coat = np.where(last >= 0, c[np.clip(last, 0, n - 1), cols], False)
    right_coat = np.where(nxt < n, c[np.clip(nxt, 0, n - 1), cols], False)
    width = np.where(f & left_coat & right_coat, (nxt - last - 1).astype(float), np.inf)
    return np.moveaxis(width, 0, axis)


def _spread(c2, free, coated, lam, dx, dy):
    """Contraction moved ``lam / 2`` across every coat edge (into the coat for ``lam > 0``,
    out of the free side for ``lam < 0``), cells covered in part contracting by the fraction
    of their width along the edge normal that the reach covers."""
    from scipy.ndimage import distance_transform_edt

    half = abs(lam) / 2.0
    out = c2.copy()
    if lam > 0:
        target, into = free, coated  # cells of the coat take the contraction of the nearest free cell
    else:
        target, into = coated, free  # free cells give it up near the nearest coat
    if not target.any() or not into.any():
        return out
    dist, (ii, jj) = distance_transform_edt(~target, sampling=(dx, dy), return_indices=True)
    gi, gj = np.indices(c2.shape)
    ux, uy = (gi - ii) * dx, (gj - jj) * dy
    norm = np.hypot(ux, uy)
    with np.errstate(invalid="ignore", divide="ignore"):
        width = np.where(norm > 0, (np.abs(ux) * dx + np.abs(uy) * dy) / norm, min(dx, dy))
    frac = np.clip((half + width - dist) / width, 0.0, 1.0)
    if lam > 0:
        out = np.where(into, frac * c2[ii, jj], out)
    else:
        out = np.where(into, (1.0 - frac) * c2, out)
    return out
