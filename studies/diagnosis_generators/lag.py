"""Heating lag: a thicker coat keeps the film below it cooler for longer.

The oven heats the specimen through its coat; the film under a coat of thickness ``d`` warms
with a time constant that grows as the square of the distance heat diffuses,
``tau(d) = d^2 / D`` (``D`` an effective diffusivity of the coat with its contact to the tray,
0.0015-0.004 mm^2/s: a 0.3 mm coat lags by 20-60 s, as long as the oven run, where the coat's own
diffusivity alone, ~0.1 mm^2/s, would give a second). The film shrinks only once warm, so in
``t`` seconds it reaches the fraction

    f(d) = 1 - exp(-t / tau(d))

of its free shrink, and the free face contracts by ``f(d)`` times Eq. 3's contraction. The fold
is a GDFE hinge simulation (:mod:`.nominal`). The effect depends on ``d`` alone: at one film
thickness it is one more way for the fold to fall with the coat.

Lengths in mm, times in s.
"""

from __future__ import annotations

import numpy as np

from studies.diagnosis_generators.nominal import eq3, gdfe_folds

__all__ = ["reached", "lagged_folds", "OVEN_TIME"]

#: Time in the oven [s].
OVEN_TIME = 60.0


def reached(d, D, t=OVEN_TIME):
    """Fraction of the free shrink reached under a coat of thickness ``d`` [mm] in ``t`` [s],
    effective diffusivity ``D`` [mm^2/s]."""
    tau = np.asarray(d, float) ** 2 / D
    return 1.0 - np.exp(-t / tau)


def lagged_folds(sp, D, resolution):
    """GDFE folds [rad] and convergence of the specimens heated with the lag."""
    return gdfe_folds(sp.L, 1.0 - reached(sp.d, D) * eq3(sp.K, sp.d, sp.h), sp.h, resolution)
