"""The catalogue of unmodelled physical effects, each a parametrised extension of the hinge model.

The calibrated GDFE hinge (the baseline) predicts a fold angle in four stages, and every
effect changes one of them:

1. **geometry** -- the hinge width ``L`` and passive thickness ``d`` that act:
   ``cure_depth`` (``d -> d + delta``), ``hinge_length`` (``L -> L + lambda``);
2. **deformation principle** -- the contraction of the film's free face, ``c = 1 - R``:
   Eq. 3, ``c = K (h / d)**1.5`` (baseline), or Timoshenko's bilayer, ``c = h kappa(h, d)``
   (``passive_stiffness``);
3. **arc** -- Eq. 2, ``alpha = c L / h_eff`` with the film thickness after shrinking:
   ``h_eff = h`` (baseline) or ``h (1 + beta c)`` (``film_thickening``);
4. **activation** -- ``alpha -> alpha_max tanh(alpha / alpha_max)`` (``saturation``).

The converged GDFE hinge reproduces stage 3's arc, ``(1 - R) L / h``, up to its
discretisation (see :func:`gdfe.diagnosis.gdfe_check`), so the stages are the GDFE
prediction in closed form. Pairs of effects compose stage by stage.

Lengths in mm, angles in radians.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from gdfe._validation import GdfeError, GdfeTypeError
from gdfe.timoshenko import bilayer_curvature

__all__ = ["Effect", "Model", "EFFECTS", "catalogue", "model"]


@dataclasses.dataclass(frozen=True)
class Effect:
    """One unmodelled physical effect.

    Attributes
    ----------
    name : str
        Catalogue name, e.g. ``"cure_depth"``.
    stage : str
        ``"geometry"``, ``"principle"``, ``"arc"`` or ``"activation"`` (see the module docstring).
    params : tuple of str
        Its parameters (beyond the baseline's K, which ``passive_stiffness`` replaces).
    units : tuple of str
    meaning : str
        What it stands for physically.
    """

    name: str
    stage: str
    params: tuple
    units: tuple
    meaning: str


EFFECTS = {
    e.name: e for e in (
        Effect("cure_depth", "geometry", ("delta",), ("mm",),
               "the passive resin cures deeper (or shallower) than printed: the coat that "
               "resists the film is d + delta thick"),
        Effect("hinge_length", "geometry", ("lambda",), ("mm",),
               "the part of the film that folds is L + lambda wide: resin bleeding into the "
               "hinge gap shortens it (lambda < 0), film under the panel edges that still "
               "shrinks lengthens it (lambda > 0)"),
        Effect("saturation", "activation", ("alpha_max",), ("rad",),
               "the fold slows as it grows and levels off at alpha_max: the free face turns "
               "away from the heat, or the stored pre-strain runs out"),
        Effect("passive_stiffness", "principle", ("E_ratio", "mismatch"), ("", ""),
               "the coat is an elastic layer, not a rigid constraint: the hinge bends like a "
               "Timoshenko bilayer with modulus ratio E_coat/E_film and mismatch strain, "
               "alpha = kappa(h, d) L"),
        Effect("film_thickening", "arc", ("beta",), ("",),
               "the film thickens as it shrinks in-plane (volume is kept), so the arc of Eq. 2 "
               "spans h (1 + beta (1 - R)) instead of h"),
    )
}


class Model:
    """The hinge model with any effects of the catalogue switched on.

    Parameters
    ----------
    effects : tuple of str
        Effect names, each at most once (they compose stage by stage).

    Attributes
    ----------
    name : str
        ``"baseline"``, the effect's name, or ``"a+b"`` for a pair.
    param_names : tuple of str
        ``K`` (or ``E_ratio, mismatch`` for ``passive_stiffness``), then each effect's own.
    """

    def __init__(self, effects=()):
        for e in effects:
            if e not in EFFECTS:
                raise GdfeError(f"effect: expected one of {', '.join(EFFECTS)}, got {e!r}")
        effects = tuple(sorted(effects, key=list(EFFECTS).index))
        if len(set(effects)) != len(effects):
            raise GdfeError(f"effects: each effect at most once, got {effects}")
        self.effects = effects
        self.name = "+".join(effects) if effects else "baseline"
        names = [] if "passive_stiffness" in effects else ["K"]
        for e in effects:
            names.extend(EFFECTS[e].params)
        self.param_names = tuple(names)

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def __repr__(self):
        return f"Model({self.name!r})"

    # -- prediction --------------------------------------------------------------------------
    def predict(self, params, L, d, h):
        """Fold angle [rad] of hinges of width ``L``, coat ``d``, film ``h`` [mm].

        Parameters
        ----------
        params : (k, ...) float array
            In the order of :attr:`param_names`; each entry may be an array broadcasting
            against the tests, and complex (the fit's complex-step derivatives).
        L, d, h : (n,) float arrays [mm]
        """
        p = dict(zip(self.param_names, params))
        if "lambda" in p:
            L = L + p["lambda"]
        if "delta" in p:
            d = d + p["delta"]
        if "passive_stiffness" in self.effects:
            c = h * bilayer_curvature(h, d, p["E_ratio"], p["mismatch"])
        else:
            c = p["K"] * (h / d) ** 1.5
        alpha = c * L / h if "beta" not in p else c * L / (h * (1.0 + p["beta"] * c))
        if "alpha_max" in p:
            alpha = p["alpha_max"] * np.tanh(alpha / p["alpha_max"])
        return alpha

    def contraction(self, params, d, h):
        """``1 - R`` of the film's free face that the fitted principle gives for coat ``d`` [mm]."""
        p = dict(zip(self.param_names, np.asarray(params, float)))
        d = np.asarray(d, float) + p.get("delta", 0.0)
        if "passive_stiffness" in self.effects:
            return h * bilayer_curvature(h, d, p["E_ratio"], p["mismatch"])
        return p["K"] * (h / d) ** 1.5

    # -- what the fit needs --------------------------------------------------------------------
    def bounds(self, L, d, alpha):
        """Physical bounds ``(lo, hi)`` of every parameter, from the data's ranges."""
        lo, hi = [], []
        amax = max(float(np.max(np.abs(alpha))), 0.1)
        table = {
            "K": (1e-9, np.inf),
            "delta": (-0.95 * float(np.min(d)), 1.0),  # d + delta > 0
            "lambda": (-0.95 * float(np.min(L)), 10.0),  # L + lambda > 0
            "alpha_max": (0.05 * amax, 100.0),
            "E_ratio": (1e-3, 1e3),
            "mismatch": (1e-9, 0.99),
            "beta": (0.0, 20.0),  # the film can only thicken
        }
        for n in self.param_names:
            lo.append(table[n][0])
            hi.append(table[n][1])
        return np.array(lo), np.array(hi)

    def starts(self, L, d, h, alpha):
        """Starting points for a multi-start fit: a grid over the effects' parameters, with the
        linear scale (``K`` or ``mismatch``) set by least squares at each."""
        amax = max(float(np.max(np.abs(alpha))), 0.1)
        grid = {
            "delta": [0.0, 0.1, 0.4],
            "lambda": [-0.5 * float(np.min(L)), 0.0, 1.0, 4.0],
            "alpha_max": [0.8 * amax, 1.5 * amax, 5.0 * amax],
            "E_ratio": [0.1, 1.0, 10.0],
            "beta": [0.0, 1.0, 5.0],
            "K": [0.1],
            "mismatch": [0.05],
        }
        lo, hi = self.bounds(L, d, alpha)
        out = []
        for combo in itertools.product(*(grid[n] for n in self.param_names)):
            x = np.clip(np.array(combo, float), lo, np.minimum(hi, 1e6))
            scale = 0 if "K" in self.param_names else self.param_names.index("mismatch")
            pred = self.predict(x, L, d, h)
            if np.all(np.isfinite(pred)) and pred @ pred > 0:
                x[scale] *= float(pred @ alpha) / float(pred @ pred)
            x = np.clip(x, lo + 1e-12 * (1 + np.abs(lo)), np.where(np.isfinite(hi), hi * (1 - 1e-9), 1e6))
            out.append(x)
        return out


def catalogue(pairs=True):
    """All models the diagnoser compares: the baseline, each effect, and (optionally) each pair."""
    names = list(EFFECTS)
    models = [Model(())] + [Model((e,)) for e in names]
    if pairs:
        models += [Model(pair) for pair in itertools.combinations(names, 2)]
    return models


def model(name):
    """The :class:`Model` of a name: ``"baseline"``, an effect, or ``"a+b"``."""
    if not isinstance(name, str):
        raise GdfeTypeError(f"model: expected a name, got {name!r}")
    if name == "baseline":
        return Model(())
    return Model(tuple(name.split("+")))
