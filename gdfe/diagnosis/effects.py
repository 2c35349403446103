"""The catalogue of unmodelled physical effects, each a parametrised extension of the hinge model.

The calibrated GDFE hinge (the baseline) predicts a fold angle in five stages, and every
effect changes one of them:

1. **geometry** -- the hinge width ``L`` and passive thickness ``d`` that act:
   ``cure_depth`` (``d -> d + delta``), ``hinge_length`` (``L -> L + lambda``);
2. **deformation principle** -- the contraction of the film's free face, ``c = 1 - R``:
   Eq. 3, ``c = K (h / d)**1.5`` (baseline), or Timoshenko's bilayer, ``c = h kappa(h, d)``
   (``passive_stiffness``);
3. **process** -- the part of that contraction a test reached: ``c -> f(x) c`` with ``x`` a
   numeric process column (oven temperature, time, exposure; ``partial_activation``), and
   ``c -> s_g c`` for a test of group ``g`` of a text column (film lot, printer;
   ``batch``);
4. **arc** -- Eq. 2, ``alpha = c L / h_eff`` with the film thickness after shrinking:
   ``h_eff = h`` (baseline) or ``h (1 + beta c)`` (``film_thickening``);
5. **activation** -- ``alpha -> alpha_max tanh(alpha / alpha_max)`` (``saturation``);
6. **measurement** -- how the fold was read: ``alpha -> alpha + offset`` (``reading_offset``,
   a protractor or image reading off by a constant).

Every effect has a **kind** (:data:`KINDS`): ``"physics"`` (stages 1-5: the part folded
otherwise than modelled), ``"measurement"`` (stage 6: the part folded as modelled, and was
read otherwise), or ``"factor"`` (an effect on a data column whose role was not declared).
A diagnosis reports a measurement effect as a measurement issue, not as physics.

The converged GDFE hinge reproduces stage 4's arc, ``(1 - R) L / h``, up to its
discretisation (see :func:`gdfe.diagnosis.gdfe_check`), so the stages are the GDFE
prediction in closed form. Pairs of effects compose stage by stage.

Every parameter is listed in :data:`EFFECTS` with its unit and meaning (:class:`Param`), and
each effect with its exact formula (:attr:`Effect.formula`), so that a fitted model can be
carried to any design. Every parameter has a physical range (:mod:`gdfe.physical_ranges`, the
table the model files read too); :meth:`Model.implausible` lists those a fit left outside
theirs. Lengths in mm, angles in radians.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from gdfe._validation import GdfeError, GdfeTypeError
from gdfe.physical_ranges import check, check_contraction, range_of
from gdfe.timoshenko import bilayer_curvature

__all__ = ["Param", "Effect", "Model", "EFFECTS", "BASELINE_PARAMS", "catalogue", "model",
           "activation_fraction", "REFERENCE_GROUP", "KINDS"]

#: Kinds of effect: the part folded otherwise than modelled, it was read otherwise, or the fold
#: follows a data column whose role was not declared.
KINDS = ("physics", "measurement", "factor")


@dataclasses.dataclass(frozen=True)
class Param:
    """One parameter of the hinge model: its name, unit and physical meaning."""

    name: str
    unit: str
    meaning: str


@dataclasses.dataclass(frozen=True)
class Effect:
    """One unmodelled physical effect.

    Attributes
    ----------
    name : str
        Catalogue name, e.g. ``"cure_depth"``.
    stage : str
        ``"geometry"``, ``"principle"``, ``"process"``, ``"arc"``, ``"activation"`` or
        ``"measurement"`` (see the module docstring).
    parameters : tuple of Param
        Its parameters (beyond the baseline's K, which ``passive_stiffness`` replaces). For
        ``batch`` one template, ``scale[g]``, stands for one parameter per group label ``g``.
    meaning : str
        What it stands for physically.
    formula : str
        What it does to the hinge model, exactly.
    column : {None, "numeric", "text"}
        The kind of data column the effect needs: a numeric process column
        (``partial_activation``) or a text group column (``batch``).
    kind : str
        One of :data:`KINDS`.
    """

    name: str
    stage: str
    parameters: tuple
    meaning: str
    formula: str
    column: str | None = None
    kind: str = "physics"

    @property
    def params(self) -> tuple:
        """Parameter names."""
        return tuple(p.name for p in self.parameters)

    @property
    def units(self) -> tuple:
        return tuple(p.unit for p in self.parameters)

    def as_dict(self) -> dict:
        return {"stage": self.stage, "params": list(self.params), "units": list(self.units),
                "parameters": [dataclasses.asdict(p) for p in self.parameters],
                "meaning": self.meaning, "formula": self.formula, "column": self.column, "kind": self.kind}


#: The baseline's parameter: Eq. 3's coefficient.
BASELINE_PARAMS = (Param("K", "", "coefficient of Eq. 1/3: c = K (h/d)^1.5 is the contraction of the "
                                  "film's free face, 1 - R"),)

#: Which group of a ``batch`` effect has scale 1: the first label in sorted order.
REFERENCE_GROUP = "the first group label in sorted order"

EFFECTS = {
    e.name: e for e in (
        Effect("cure_depth", "geometry", (Param("delta", "mm", "extra thickness of the cured coat "
                                                               "(negative: thinner than printed)"),),
               "the passive resin cures deeper (or shallower) than printed: the coat that "
               "resists the film is d + delta thick",
               "d -> d + delta in every stage"),
        Effect("hinge_length", "geometry", (Param("lambda", "mm", "extra width of the folding film "
                                                                 "(negative: narrower than printed)"),),
               "the part of the film that folds is L + lambda wide: resin bleeding into the "
               "hinge gap shortens it (lambda < 0), film under the panel edges that still "
               "shrinks lengthens it (lambda > 0)",
               "L -> L + lambda in Eq. 2: alpha = c (L + lambda) / h"),
        Effect("saturation", "activation", (Param("alpha_max", "rad", "the angle the fold levels off at"),),
               "the fold slows as it grows and levels off at alpha_max: the free face turns "
               "away from the heat, or the stored pre-strain runs out",
               "alpha -> alpha_max tanh(alpha / alpha_max)"),
        Effect("passive_stiffness", "principle",
               (Param("E_ratio", "", "Young's modulus of the coat over that of the film while it shrinks"),
                Param("mismatch", "", "free in-plane contraction of the film (strain)")),
               "the coat is an elastic layer, not a rigid constraint: the hinge bends like a "
               "Timoshenko bilayer with modulus ratio E_coat/E_film and mismatch strain, "
               "alpha = kappa(h, d) L",
               "c = h kappa_T(h, d, E_ratio, mismatch) (gdfe.timoshenko.bilayer_curvature) replaces "
               "K (h/d)^1.5; K is not a parameter"),
        Effect("film_thickening", "arc", (Param("beta", "", "thickening of the film per unit in-plane "
                                                           "contraction (2 keeps the volume)"),),
               "the film thickens as it shrinks in-plane (volume is kept), so the arc of Eq. 2 "
               "spans h (1 + beta (1 - R)) instead of h",
               "alpha = c L / (h (1 + beta c))"),
        Effect("partial_activation", "process",
               (Param("x50", "unit of the column", "value of the process column at which half of the "
                                                   "contraction is reached"),
                Param("rate", "1 / unit of the column", "steepness of the activation: > 0 it grows with "
                                                        "the column, < 0 it falls")),
               "the film shrinks only partly where the process fell short (oven temperature, "
               "time, exposure): the fraction of the contraction reached is a monotone "
               "function of a numeric process column x, fitted",
               "c -> f(x) c with f(x) = 1 / (1 + exp(-rate (x - x50))), a logistic rising from 0 to "
               "1 (rate > 0) or falling (rate < 0); K is the contraction coefficient of a fully "
               "activated film (f = 1)", column="numeric"),
        Effect("batch", "process",
               (Param("scale[g]", "", "contraction of group g relative to the reference group "
                                      f"({REFERENCE_GROUP}), one parameter per other group"),),
               "the tests of each group of a text column (film lot, print job, oven run) "
               "contract by their own factor: a batch-to-batch difference of the film's "
               "pre-strain or of the process",
               f"c -> s_g c for a test of group g; s_g = scale[g], and s = 1 for {REFERENCE_GROUP}",
               column="text"),
        Effect("reading_offset", "measurement", (Param("offset", "rad", "what the reading adds to every fold "
                                                                        "(negative: reads less)"),),
               "a measurement issue, not physics: every fold was read off by the same angle (a protractor "
               "or image reference line set off the panel, a zero not subtracted); the parts folded as "
               "the rest of the model says",
               "alpha -> alpha + offset (measured, not folded)", kind="measurement"),
    )
}

#: Effects with their own data column, and the Model argument naming it.
_COLUMN_EFFECTS = {"partial_activation": "process", "batch": "group"}


def activation_fraction(x, x50, rate):
    """The ``partial_activation`` fraction ``f(x) = 1 / (1 + exp(-rate (x - x50)))``.

    Written as ``(1 + tanh(z / 2)) / 2`` with ``z = rate (x - x50)``, its real part clipped
    to +-60 (where ``f`` is 0 or 1 to 1e-26). A complex argument is a complex step of the
    fits' derivatives (imaginary part of order 1e-20): ``f(a + ib) = f(a) + i b f'(a)`` to
    rounding, with ``f'(a) = (1 - tanh^2(a / 2)) / 4``, in real arithmetic (cheaper than a
    complex ``tanh``).

    Parameters
    ----------
    x : (n,) float array
        The process column.
    x50 : float or array
        Where ``f = 1/2`` [unit of x].
    rate : float or array
        Steepness [1 / unit of x]; its sign says whether ``f`` rises or falls with ``x``.
    """
    z = rate * (x - x50)
    if np.iscomplexobj(z):
        t = np.tanh(0.5 * np.clip(z.real, -60.0, 60.0))
        return 0.5 * (1.0 + t) + 0.25j * (1.0 - t * t) * z.imag
    return 0.5 * (1.0 + np.tanh(0.5 * np.clip(z, -60.0, 60.0)))


def _group_factor(scales, group):
    """``s_g`` of every test: ``scales`` (G - 1 parameters, scalars or arrays ending in an axis
    of length 1 that broadcasts over the tests) for groups 1.., the reference group 0 at 1."""
    arrays = np.broadcast_arrays(np.ones_like(scales[0]), *scales)
    S = np.stack(arrays)  # (G, ...)
    if S.ndim == 1:
        return S[group]
    if S.shape[-1] != 1:
        raise GdfeError("params: group scales must broadcast over the tests with a last axis of length 1")
    return np.moveaxis(S[..., 0][group], 0, -1)


class Model:
    """The hinge model with any effects of the catalogue switched on.

    Parameters
    ----------
    effects : tuple of str
        Effect names, each at most once (they compose stage by stage).
    process : str, optional
        The numeric column of ``partial_activation`` (needed with it).
    group : str, optional
        The text column of ``batch`` (needed with it).
    labels : sequence of str, optional
        The group labels of ``batch``, at least two; sorted, the first is the reference.

    Attributes
    ----------
    effects : tuple of str
    name : str
        ``"baseline"``, the effect's name, or ``"a+b"`` for a pair; an effect with a column
        carries it, e.g. ``"partial_activation[T_C]"``, ``"batch[lot]"``.
    param_names : tuple of str
        ``K`` (or ``E_ratio, mismatch`` for ``passive_stiffness``), then each effect's own in
        catalogue order; ``batch`` gives ``scale[g]`` for every group label ``g`` but the
        reference.
    process, group : str or None
    labels : tuple of str or None
    """

    def __init__(self, effects=(), process=None, group=None, labels=None):
        if isinstance(effects, str):
            raise GdfeTypeError(f"effects: expected a tuple of effect names, got {effects!r}")
        for e in effects:
            if e not in EFFECTS:
                raise GdfeError(f"effect: expected one of {', '.join(EFFECTS)}, got {e!r}")
        effects = tuple(sorted(effects, key=list(EFFECTS).index))
        if len(set(effects)) != len(effects):
            raise GdfeError(f"effects: each effect at most once, got {effects}")
        if "partial_activation" in effects:
            if not isinstance(process, str) or not process:
                raise GdfeError("process: expected the name of the numeric column of partial_activation, "
                                f"got {process!r}")
        elif process is not None:
            raise GdfeError(f"process: only partial_activation uses a process column, got {process!r} "
                            f"for {effects}")
        if "batch" in effects:
            if not isinstance(group, str) or not group:
                raise GdfeError(f"group: expected the name of the text column of batch, got {group!r}")
            if labels is None or len(set(labels)) < 2:
                raise GdfeError(f"labels: expected at least two group labels for batch, got {labels!r}")
            labels = tuple(sorted({str(v) for v in labels}))
        elif group is not None or labels is not None:
            raise GdfeError(f"group: only batch uses a group column, got {group!r} for {effects}")
        self.effects = effects
        self.process = process
        self.group = group
        self.labels = labels
        tokens = []
        for e in effects:
            col = process if e == "partial_activation" else group if e == "batch" else None
            tokens.append(f"{e}[{col}]" if col else e)
        self.name = "+".join(tokens) if tokens else "baseline"
        names = [] if "passive_stiffness" in effects else ["K"]
        for e in effects:
            if e == "batch":
                names.extend(f"scale[{lab}]" for lab in labels[1:])
            else:
                names.extend(EFFECTS[e].params)
        self.param_names = tuple(names)

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @property
    def level(self) -> int:
        """Number of effects switched on."""
        return len(self.effects)

    def with_effect(self, effect, process=None, group=None, labels=None):
        """This model with one more effect (and its column)."""
        return Model(self.effects + (effect,), process=process or self.process,
                     group=group or self.group, labels=labels if labels is not None else self.labels)

    def without(self, effect):
        """This model without ``effect``."""
        rest = tuple(e for e in self.effects if e != effect)
        return Model(rest, process=self.process if "partial_activation" in rest else None,
                     group=self.group if "batch" in rest else None,
                     labels=self.labels if "batch" in rest else None)

    def parameters(self):
        """:class:`Param` of every entry of :attr:`param_names` (unit and meaning)."""
        table = {p.name: p for p in BASELINE_PARAMS}
        for e in self.effects:
            for p in EFFECTS[e].parameters:
                table[p.name] = p
        out = []
        for n in self.param_names:
            if n.startswith("scale["):
                lab = n[len("scale["):-1]
                out.append(Param(n, "", f"contraction of {self.group} group {lab!r} relative to group "
                                        f"{self.labels[0]!r}"))
            elif n in ("x50", "rate"):
                p = table[n]
                unit = p.unit.replace("the column", self.process)
                out.append(Param(n, unit, p.meaning.replace("the process column", self.process)))
            else:
                out.append(table[n])
        return out

    def group_index(self, values):
        """Index into :attr:`labels` of each test's group label (``values``: (n,) strings)."""
        values = np.asarray(values).astype(str)
        lookup = {lab: i for i, lab in enumerate(self.labels)}
        bad = [str(v) for v in np.unique(values) if v not in lookup]
        if bad:
            raise GdfeError(f"{self.group}: expected one of the fitted groups {', '.join(self.labels)}, "
                            f"got {bad[0]!r}")
        return np.array([lookup[v] for v in values], int)

    def __repr__(self):
        return f"Model({self.name!r})"

    def __eq__(self, other):
        return isinstance(other, Model) and (self.name, self.labels) == (other.name, other.labels)

    def __hash__(self):
        return hash((self.name, self.labels))

    # -- prediction --------------------------------------------------------------------------
    def _needs(self, x, group):
        if "partial_activation" in self.effects and x is None:
            raise GdfeError(f"x: {self.name} needs the values of its process column {self.process!r}")
        if "batch" in self.effects and group is None:
            raise GdfeError(f"group: {self.name} needs the group index of every test (Model.group_index)")

    def contraction(self, params, d, h, x=None, group=None):
        """``c = 1 - R`` of the film's free face that the fitted model gives (stages 1-3) for
        coat ``d`` [mm] (the cured coat with ``cure_depth``), film ``h`` [mm], process column
        ``x`` and group index ``group``."""
        self._needs(x, group)
        p = dict(zip(self.param_names, params))
        d = d + p["delta"] if "delta" in p else d
        if "passive_stiffness" in self.effects:
            c = h * bilayer_curvature(h, d, p["E_ratio"], p["mismatch"])
        else:
            c = p["K"] * (h / d) ** 1.5
        if "partial_activation" in self.effects:
            c = c * activation_fraction(x, p["x50"], p["rate"])
        if "batch" in self.effects:
            c = c * _group_factor([p[n] for n in self.param_names if n.startswith("scale[")], group)
        return c

    def predict(self, params, L, d, h, x=None, group=None):
        """Fold angle [rad] of hinges of width ``L``, coat ``d``, film ``h`` [mm].

        Parameters
        ----------
        params : (k, ...) float array
            In the order of :attr:`param_names`; each entry may be an array broadcasting
            against the tests, and complex (the fit's complex-step derivatives).
        L, d, h : (n,) float arrays [mm]
        x : (n,) float array, optional
            The process column (``partial_activation``).
        group : (n,) int array, optional
            Index into :attr:`labels` of each test's group (``batch``).
        """
        p = dict(zip(self.param_names, params))
        c = self.contraction(params, d, h, x, group)
        if "lambda" in p:
            L = L + p["lambda"]
        alpha = c * L / h if "beta" not in p else c * L / (h * (1.0 + p["beta"] * c))
        if "alpha_max" in p:
            alpha = p["alpha_max"] * np.tanh(alpha / p["alpha_max"])
        if "offset" in p:
            alpha = alpha + p["offset"]
        return alpha

    @property
    def kinds(self) -> tuple:
        """The kind (:data:`KINDS`) of each effect, in the order of :attr:`effects`."""
        return tuple(EFFECTS[e].kind for e in self.effects)

    def implausible(self, params, L, d, h, x=None, group=None, se=None):
        """The fitted parameters outside their physical range (:mod:`gdfe.physical_ranges`),
        and the contraction of the film's free face on the tests when it is outside
        ``[0, MAX_CONTRACTION]``.

        Parameters
        ----------
        params : (k,) float array
            In the order of :attr:`param_names`.
        L, d, h : (n,) float arrays [mm]
            The tests (the reasoning says how a length compares with theirs).
        x, group : (n,) arrays, optional
            As in :meth:`predict`.
        se : (k,) float array, optional
            Standard errors of the parameters: a parameter is then implausible only when it
            lies outside its range by more than one standard error (the one-standard-error
            rule by which the diagnosis names an effect at all; a true value on the edge of
            its range is not flagged half the time); an infinite one, or one as large as the
            value itself (the data do not pin the parameter down), counts as unknown, and the
            value alone decides.

        Returns
        -------
        list of dict
            ``name``, ``value``, ``range`` ([lo, hi], None for an infinite bound), ``unit``,
            ``why`` (and ``se`` when given); empty when every parameter is plausible.
        """
        L, d = np.asarray(L, float), np.asarray(d, float)
        out = []
        se = np.full(self.n_params, np.nan) if se is None else np.asarray(se, float)
        for name, v, s in zip(self.param_names, np.real(np.asarray(params, float)), se):
            context = ""
            if name == "lambda" and v > 0:
                k = int(np.sum(L < v))
                context = f"lambda = {v:.3g} mm is wider than {k} of the {L.size} hinges tested" if k else ""
            elif name == "lambda" and v < 0:
                k = int(np.sum(L < -v))
                context = f"it would take away more than {k} of the {L.size} hinges tested" if k else ""
            elif name == "delta":
                k = int(np.sum(d < abs(v)))
                context = (f"|delta| = {abs(v):.3g} mm is more than {k} of the {d.size} coats tested are thick"
                           if k else "")
            found = check(name, v, context)
            if found is not None and np.isfinite(s) and s < abs(v):
                r = range_of(name)
                if not (v + s < r.lo or v - s > r.hi):
                    continue  # within one standard error of the range
                found["se"] = float(s)
            if found is not None:
                out.append(found)
        with np.errstate(all="ignore"):
            c = self.contraction(np.asarray(params, float), d, np.asarray(h, float), x, group)
        found = check_contraction(c)
        if found is not None:
            found["why"] += (f"; the model needs c = {found['value']:.3g} on a test, i.e. a thinner coat than "
                             "printed or more shrink than the film has")
            out.append(found)
        return out

    # -- what the fit needs --------------------------------------------------------------------
    def bounds(self, L, d, alpha, x=None):
        """Physical bounds ``(lo, hi)`` of every parameter, from the data's ranges."""
        amax = max(float(np.max(np.abs(alpha))), 0.1)
        table = {
            "K": (1e-9, np.inf),
            "delta": (-0.95 * float(np.min(d)), 1.0),  # d + delta > 0
            "lambda": (-0.95 * float(np.min(L)), 10.0),  # L + lambda > 0
            "alpha_max": (0.05 * amax, 100.0),
            "E_ratio": (1e-3, 1e3),
            "mismatch": (1e-9, 0.99),
            "beta": (0.0, 20.0),  # the film can only thicken
            "offset": (-1.0, 1.0),  # wider than a plausible reading error, so that a fit can say so
        }
        if "partial_activation" in self.effects:
            lo_x, hi_x = float(np.min(x)), float(np.max(x))
            span = max(hi_x - lo_x, 1e-12)
            table["x50"] = (lo_x - span, hi_x + span)
            table["rate"] = (-40.0 / span, 40.0 / span)  # a step over 2.5 % of the range at most
        lo, hi = [], []
        for n in self.param_names:
            a, b = (0.05, 20.0) if n.startswith("scale[") else table[n]
            lo.append(a)
            hi.append(b)
        return np.array(lo), np.array(hi)

    def starts(self, L, d, h, alpha, x=None, group=None, weights=None):
        """Starting points for a multi-start fit: a grid over the effects' parameters, with the
        linear scale (``K`` or ``mismatch``) set by least squares at each, and each group's
        scale set by least squares within its group."""
        amax = max(float(np.max(np.abs(alpha))), 0.1)
        grid = {
            "delta": [0.0, 0.1, 0.4],
            "lambda": [-0.5 * float(np.min(L)), 0.0, 1.0, 4.0],
            "alpha_max": [0.8 * amax, 1.5 * amax, 5.0 * amax],
            "E_ratio": [0.1, 1.0, 10.0],
            "beta": [0.0, 1.0, 5.0],
            "K": [0.1],
            "mismatch": [0.05],
            "offset": [0.0],
        }
        if "partial_activation" in self.effects:
            q = np.quantile(x, [0.25, 0.5, 0.75])
            span = max(float(np.ptp(x)), 1e-12)
            grid["x50"] = [float(v) for v in q]
            grid["rate"] = [4.0 / span, -4.0 / span, 20.0 / span, -20.0 / span]
        w = np.ones_like(alpha) if weights is None else weights
        lo, hi = self.bounds(L, d, alpha, x)
        names = [n for n in self.param_names if not n.startswith("scale[")]
        scale = 0 if "K" in self.param_names else self.param_names.index("mismatch")
        idx = [self.param_names.index(n) for n in names]
        out = []
        for combo in itertools.product(*(grid[n] for n in names)):
            xs = np.ones(self.n_params)
            xs[idx] = combo
            xs = np.clip(xs, lo, np.minimum(hi, 1e6))
            with np.errstate(all="ignore"):
                pred = self.predict(xs, L, d, h, x, group)
            if np.all(np.isfinite(pred)) and pred @ (w * pred) > 0:
                xs[scale] *= float(pred @ (w * alpha)) / float(pred @ (w * pred))
            if "batch" in self.effects:
                with np.errstate(all="ignore"):
                    pred = self.predict(xs, L, d, h, x, group)
                ref = group == 0
                r0 = _ratio(pred[ref], alpha[ref], w[ref])
                for j, n in enumerate(self.param_names):
                    if n.startswith("scale["):
                        g = group == self.labels.index(n[len("scale["):-1])
                        xs[j] = _ratio(pred[g], alpha[g], w[g]) / r0 if r0 > 0 else 1.0
            xs = np.clip(xs, lo + 1e-12 * (1 + np.abs(lo)), np.where(np.isfinite(hi), hi * (1 - 1e-9), 1e6))
            out.append(xs)
        return out


def _ratio(pred, alpha, w):
    den = float(pred @ (w * pred))
    if not np.isfinite(den) or den <= 0:
        return 1.0
    r = float(pred @ (w * alpha)) / den
    return r if np.isfinite(r) and r > 0 else 1.0


def catalogue(pairs=True, process=(), groups=None):
    """The models the diagnoser compares: the baseline, each effect, and (optionally) each pair.

    Parameters
    ----------
    pairs : bool
        Also every pair of effects.
    process : sequence of str
        Numeric process columns: each gives a ``partial_activation`` on it (at most one per
        model).
    groups : dict of str -> sequence of str, optional
        Text group columns and their labels: each gives a ``batch`` on it. The diagnosis
        adds a batch to its chosen model rather than pairing it in this list (a batch
        cannot be held out by group; see :func:`gdfe.diagnosis.diagnose`).
    """
    plain = [e for e in EFFECTS if EFFECTS[e].column is None]
    singles = [Model((e,)) for e in plain]
    singles += [Model(("partial_activation",), process=c) for c in process]
    if groups:
        singles += [Model(("batch",), group=g, labels=labs) for g, labs in groups.items()]
    models = [Model(())] + singles
    if pairs:
        for a, b in itertools.combinations(singles, 2):
            if "batch" in a.effects + b.effects or set(a.effects) & set(b.effects):
                continue
            models.append(Model(a.effects + b.effects, process=a.process or b.process))
    return models


def model(name, labels=None):
    """The :class:`Model` of a name: ``"baseline"``, an effect, ``"a+b"``; an effect with a
    column as ``"partial_activation[T_C]"`` or ``"batch[lot]"`` (with ``labels``)."""
    if not isinstance(name, str):
        raise GdfeTypeError(f"model: expected a name, got {name!r}")
    if name == "baseline":
        return Model(())
    effects, cols = [], {}
    for token in name.split("+"):
        base, _, rest = token.partition("[")
        if rest:
            if not rest.endswith("]") or base not in _COLUMN_EFFECTS:
                raise GdfeError(f"model: expected an effect or effect[column], got {token!r}")
            cols[_COLUMN_EFFECTS[base]] = rest[:-1]
        elif base in _COLUMN_EFFECTS:
            raise GdfeError(f"model: {base} needs its column, as {base}[COLUMN], got {token!r}")
        effects.append(base)
    return Model(tuple(effects), labels=labels if "batch" in effects else None, **cols)
