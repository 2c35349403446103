"""Effects outside the diagnoser's catalogue: physically plausible, and none of its forms.

``hard_cap``
    a stop: the rising panels meet a fixture (or the oven's tray wall) at ``alpha_stop``, so
    the fold is ``min(alpha, alpha_stop)`` -- a kink, where ``saturation`` bends smoothly;
``coat_bleed``
    the liquid resin spreads into the hinge gap by ``b d`` before it cures (a thick coat
    spreads further), so the hinge that folds is ``L - b d`` wide (at least ``0.3 L``):
    the loss grows with the coat, where ``hinge_length`` is the same for every coat;
``hidden_lots``
    the film came from two lots that nobody recorded, their pre-strains ``1 - u`` and
    ``1 + u`` times the nominal, each test from either at random: scatter no column explains;
``overheating``
    the oven temperature both activates the film (shrink kinetics, :mod:`.kinetics`) and,
    above ``T_relax``, lets it relax again as the coat softens, by ``exp(-((T - T_relax) /
    width)^2)``: a fold that rises and then falls with temperature, where
    ``partial_activation`` is monotone.

Every fold is a GDFE hinge simulation (:mod:`.nominal`). Lengths in mm, angles in radians,
temperatures in degrees C.
"""

from __future__ import annotations

import numpy as np

from studies.diagnosis_generators import kinetics
from studies.diagnosis_generators.nominal import eq3, gdfe_folds

__all__ = ["hard_cap", "coat_bleed", "hidden_lots", "overheating"]


def hard_cap(nominal, alpha_stop):
    """``min(alpha, alpha_stop)`` of the nominal folds [rad]."""
    return np.minimum(nominal, alpha_stop)


def coat_bleed(sp, b, resolution):
    """GDFE folds of hinges narrowed by ``b d`` (at least to ``0.3 L``)."""
    L = np.maximum(sp.L - b * sp.d, 0.3 * sp.L)
    return gdfe_folds(L, 1.0 - eq3(sp.K, sp.d, sp.h), sp.h, resolution)


def hidden_lots(sp, u, lot, resolution):
    """GDFE folds with each test's contraction times ``1 - u`` (lot 0) or ``1 + u`` (lot 1)."""
    factor = np.where(np.asarray(lot) == 0, 1.0 - u, 1.0 + u)
    return gdfe_folds(sp.L, 1.0 - factor * eq3(sp.K, sp.d, sp.h), sp.h, resolution)


def overheating(sp, T_half, b, T_relax, width, resolution):
    """GDFE folds with the contraction reached by the kinetics, relaxed above ``T_relax``."""
    f = kinetics.fraction(sp.T_C, T_half, b) * np.exp(-(np.maximum(sp.T_C - T_relax, 0.0) / width) ** 2)
    return gdfe_folds(sp.L, 1.0 - f * eq3(sp.K, sp.d, sp.h), sp.h, resolution)
