"""A scan of a plate FEM part: its film's two faces, moved rigidly, with measurement noise.

The points are the FEM's nodes on the film's bottom and top faces (``z = 0`` and ``z = h`` in
the flat print), deformed: the surfaces GDFE's film has too (GDFE does not model the coat's
thickness as geometry, so a scan here sees the film, as through a transparent coat). They are
moved by a random rigid motion (a rotation uniform over all rotations, a translation of up
to the part's size along each axis) and every coordinate gets independent Gaussian noise of
standard deviation ``noise_mm``. Lengths in mm.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["Scan", "film_faces", "scan_part", "NOISE_MM"]

#: Standard deviation of the scanner's noise per coordinate [mm] (a structured-light scanner on a
#: part of a few mm).
NOISE_MM = 0.005


@dataclasses.dataclass
class Scan:
    """A scan and how it was made.

    Attributes
    ----------
    points : (k, 3) float array [mm]
    clean : (k, 3) float array [mm]
        The same points before the rigid motion and the noise.
    reference : (k, 3) float array [mm]
        Where each point was in the flat print (the FEM node it is).
    rotation : (3, 3) float array
    translation : (3,) float array [mm]
        ``points = clean @ rotation.T + translation + noise``.
    noise_mm : float
    """

    points: np.ndarray
    clean: np.ndarray
    reference: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    noise_mm: float


def film_faces(result, reference=False):
    """Deformed positions [mm] of the FEM's nodes on the film's two faces, ``(k, 3)``; with
    ``reference``, also their positions in the flat print (a second ``(k, 3)`` array)."""
    h = result.plate.h
    z = result.points[:, 2]
    tol = 1e-9 * max(1.0, result.plate.size)
    on = (np.abs(z) < tol) | (np.abs(z - h) < tol)
    return (result.deformed[on], result.points[on]) if reference else result.deformed[on]


def scan_part(result, rng, noise_mm=NOISE_MM):
    """A scan (:class:`Scan`) of a solved part, with a rigid motion and noise drawn from ``rng``."""
    from scipy.spatial.transform import Rotation

    clean, ref = film_faces(result, reference=True)
    size = result.plate.size
    Q = Rotation.random(random_state=rng).as_matrix()
    t = rng.uniform(-size, size, 3)
    pts = clean @ Q.T + t + rng.normal(0.0, noise_mm, clean.shape)
    return Scan(points=pts, clean=clean, reference=ref, rotation=Q, translation=t, noise_mm=float(noise_mm))
