"""Effects carried by a numeric column the lab records but the diagnosis is not told about.

``anisotropic``
    the pre-strained film shrinks more along its draw direction than across it. A hinge cut at
    ``theta`` to the draw direction contracts by ``c(theta) = c_x cos^2 theta + c_y sin^2 theta``
    (the normal strain of a plane strain tensor with principal values ``c_x``, ``c_y`` along the
    hinge's normal), ``c_x`` the nominal contraction of Eq. 3 and ``c_y = r c_x``;
``sag``
    the rising panel's weight bends the soft hinge back. A panel of length ``P`` and thickness
    ``h + d`` (film and coat) at angle ``alpha`` to the tray loads the hinge with a moment per
    width ``rho g (h + d) P^2 cos(alpha) / 2``; the hot film's hinge (modulus ``E``, bending
    stiffness per width ``E h^3 / 12``, length ``L``) turns by that moment times ``12 L / (E h^3)``.
    The fold is the root of ``alpha = alpha_0 - C cos(alpha)``: less than the nominal ``alpha_0``
    below 90 degrees, more above. ``C`` is held to at most :data:`MAX_SAG` (a hinge softer than
    that lets its panel hang; such a test would not be recorded).

The nominal folds are GDFE hinge simulations (:mod:`.nominal`). Lengths in mm, angles in radians
(``theta`` in the data in degrees), moduli in MPa (N/mm^2), forces in N.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from studies.diagnosis_generators.nominal import eq3, gdfe_folds

__all__ = ["anisotropic", "sag", "sag_compliance", "WEIGHT", "MAX_SAG"]

#: Weight per volume of the printed panel (acrylate on polystyrene, 1100 kg/m^3) [N/mm^3].
WEIGHT = 1.1e-6 * 9.81
#: Largest sag ``C`` [rad].
MAX_SAG = 0.6


def anisotropic(sp, theta_deg, ratio, resolution):
    """GDFE folds [rad] of hinges cut at ``theta_deg`` [degrees] to the film's draw direction,
    the film's contraction across the draw ``ratio`` times that along it."""
    t = np.radians(np.asarray(theta_deg, float))
    c = eq3(sp.K, sp.d, sp.h) * (np.cos(t) ** 2 + ratio * np.sin(t) ** 2)
    return gdfe_folds(sp.L, 1.0 - c, sp.h, resolution)


def sag_compliance(L, d, h, panel, E):
    """``C`` [rad] of the sag: the hinge's turn under its panel's weight held level (at most
    :data:`MAX_SAG`); ``panel`` [mm], ``E`` [MPa]."""
    moment = WEIGHT * (np.asarray(h) + np.asarray(d)) * np.asarray(panel, float) ** 2 / 2.0  # N mm / mm
    return np.minimum(moment * 12.0 * np.asarray(L, float) / (E * np.asarray(h, float) ** 3), MAX_SAG)


def sag(nominal, C):
    """Folds [rad] of hinges whose nominal folds are ``nominal`` under sag ``C`` [rad] (< 1)."""
    out = []
    for a0, c in zip(np.asarray(nominal, float), np.asarray(C, float)):
        def f(a, a0=a0, c=c):
            return a - a0 + c * np.cos(a)
        out.append(brentq(f, a0 - c - 1e-9, a0 + c + 1e-9))
    return np.array(out)
