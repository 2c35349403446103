"""Measurement artefacts: errors of the angle reading, not of the folding.

Each acts on the nominal GDFE folds (:mod:`.nominal`) of a data set; the film, the coat and the
hinge are as the nominal world says. What goes wrong is the measurement or the specimen:

``reading_offset``
    the protractor's (or the image's) zero is off: every angle reads ``offset`` too high;
``outliers``
    gross errors in a few rows (a misread scale, a swapped specimen): each of ``rows`` is off by
    ``+-jump``;
``growing_scatter``
    the reading's scatter grows with the angle (a wide fold's faces are harder to fit a line
    to): the standard deviation is ``g sigma alpha / mean(alpha)``, no bias;
``failed``
    a few specimens did not fold at all (the film slipped off the tray or never reached its
    glass transition): their angle is 0.

Angles in radians.
"""

from __future__ import annotations

import numpy as np

__all__ = ["offset", "outliers", "failed", "growing_scatter"]


def offset(alpha, value):
    """``alpha + value`` [rad]: a constant reading offset."""
    return np.asarray(alpha, float) + float(value)


def outliers(alpha, rows, jumps):
    """``alpha`` with ``jumps[k]`` [rad] added to row ``rows[k]``."""
    out = np.array(alpha, float)
    out[np.asarray(rows, int)] += np.asarray(jumps, float)
    return out


def failed(alpha, rows):
    """``alpha`` with the specimens of ``rows`` unfolded (angle 0)."""
    out = np.array(alpha, float)
    out[np.asarray(rows, int)] = 0.0
    return out


def growing_scatter(alpha, sigma, gain, rng):
    """Measured angles whose noise grows with the angle: standard deviation
    ``gain sigma alpha / mean(alpha)`` (mean ``gain sigma``), zero mean.

    Parameters
    ----------
    alpha : (n,) float array [rad]
        Noise-free angles.
    sigma : float [rad]
        The noise the diagnosis is told.
    gain : float
        Mean standard deviation over ``sigma``.
    rng : numpy.random.Generator
    """
    alpha = np.asarray(alpha, float)
    scale = gain * sigma * np.abs(alpha) / float(np.mean(np.abs(alpha)))
    return alpha + scale * rng.standard_normal(alpha.size)
