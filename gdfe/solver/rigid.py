"""Rigid motions of a shape's field: the best-fit infinitesimal turn, and a field less it.

The energy does not change when the whole part moves rigidly, and the pinned vertex holds only
the translations, so a Newton step can turn the part by round-off. Two places take such turns
out of a field ``d`` ``(n, 3)`` at a shape: the stopping test measures a step less its rigid
motion about the centroid (:func:`gdfe.solver.newton.deformation`), and recycling leaves out a
direction that is nearly all a turn about the pinned vertex
(:func:`gdfe.solver.recycling.mostly_turn`). Both fit the turn ``omega x r`` to ``d`` by least
squares (:func:`turn_fit`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["turn_fit", "without_turn"]


def turn_fit(r, d):
    """The ``omega`` (3,) of the turn ``omega x r`` nearest ``d`` in the least-squares sense, or None.

    ``r`` ``(n, 3)`` are the points about the turn's centre, ``d`` ``(n, 3)`` the field. None where
    all points lie on a line through the centre (no turn about that line moves them).
    """
    M = np.einsum("ij,ij->", r, r) * np.eye(3) - np.einsum("ij,ik->jk", r, r)
    try:
        return np.linalg.solve(M, np.cross(r, d).sum(axis=0))
    except np.linalg.LinAlgError:
        return None


def without_turn(u, V, pin):
    """``u`` ``(n, 3)`` less its best-fit infinitesimal turn about the pinned vertex of ``V`` (zero at ``pin``, as ``u``)."""
    r = V - V[pin]
    omega = turn_fit(r, u)
    return u if omega is None else u - np.cross(omega, r)
