"""Shrink kinetics of the pre-strained polystyrene film: how much of its shrink an oven run reaches.

The stretched film recovers its pre-strain as a relaxation above the glass transition: the
fraction reached after ``t`` seconds at temperature ``T`` is a stretched exponential
(Kohlrausch-Williams-Watts),

    f(T, t) = 1 - exp(-(t / tau(T))^b),        0 < b <= 1,

with a relaxation time that the Williams-Landel-Ferry equation shifts with temperature,

    log10(tau(T) / tau(T_ref)) = -C1 (T - T_g) / (C2 + T - T_g) + C1 (T_ref - T_g) / (C2 + T_ref - T_g),

``C1 = 17.44``, ``C2 = 51.6 K`` (the "universal" constants) and ``T_g = 100`` degrees C
(polystyrene). The fraction rises with ``T`` more steeply near ``T_g`` than far above it, an
asymmetric curve, not a logistic. Temperatures in degrees C, times in s.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["fraction", "tau_for_half", "C1", "C2", "T_GLASS", "OVEN_TIME"]

C1, C2 = 17.44, 51.6
#: Glass transition of polystyrene [degrees C].
T_GLASS = 100.0
#: Time in the oven [s].
OVEN_TIME = 60.0


def _log10_shift(T):
    dT = np.asarray(T, float) - T_GLASS
    return -C1 * dT / (C2 + dT)


def tau_for_half(T_half, b, t=OVEN_TIME):
    """Relaxation time [s] at ``T_half`` that makes ``f(T_half, t) = 1/2``."""
    return t / math.log(2.0) ** (1.0 / b)


def fraction(T, T_half, b, t=OVEN_TIME):
    """Fraction of the free shrink reached at oven temperature ``T`` after ``t`` s.

    Parameters
    ----------
    T : (n,) float array [degrees C]
    T_half : float [degrees C]
        Temperature at which half of the shrink is reached in ``t``.
    b : float
        Stretching exponent of the relaxation, in (0, 1].
    t : float [s]
    """
    tau = tau_for_half(T_half, b, t) * 10.0 ** (_log10_shift(T) - _log10_shift(T_half))
    return 1.0 - np.exp(-(t / tau) ** b)
