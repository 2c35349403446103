"""Directional heating: the fold slows as the free face turns away from a heat source above.

Under a lamp or a heat gun the free face of a hinge absorbs heat as the cosine of its angle to
the vertical (Lambert), besides what the air brings evenly. The contraction of each hinge cell
grows as it is heated,

    da_j / dt = (1 - w) + w max(0, n_j . e_z),        0 <= a_j <= 1,

with ``n_j`` the normal of cell ``j``'s free face, ``e_z`` up and ``w`` the share of directed
heat; cell ``j`` contracts by ``a_j c`` (``c`` the full contraction). The specimen lies on its
tray on one panel (``panel_a``), so up is that panel's normal and the hinge's far end turns
away first. The shape is solved by
GDFE (:func:`gdfe.simulate`, each step started from the last shape) at every time step of a
forward Euler march over ``0 <= t <= 1`` (a face kept level reaches ``a = 1``). As the fold
grows, the cells near the hinge's edges turn away and stop: the fold saturates. This is no
closed form: the cells activate unevenly along the hinge, and the fold is what GDFE makes of
them.

Lengths in mm, angles in radians.
"""

from __future__ import annotations

import numpy as np

__all__ = ["heated_fold", "STEPS"]

#: Time steps of the march per resolution.
STEPS = {"coarse": 8, "default": 12, "fine": 16}


def _free_normals(points, design, cells):
    """Unit normals of the top faces (vertices 4-7 in VTK order) of ``cells``."""
    P = points[design.mesh.cells[cells]]
    n = np.cross(P[:, 6] - P[:, 4], P[:, 7] - P[:, 5])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def heated_fold(L, c, h, w, resolution="coarse"):
    """Fold [rad] of a hinge heated from above, its convergence and the mean activation reached.

    Parameters
    ----------
    L, h : float [mm]
    c : float
        Full contraction ``1 - R`` of the free face, in (0, 1).
    w : float
        Share of the heat that comes from above, in [0, 1].
    resolution : {"coarse", "default", "fine"}
    """
    import gdfe

    from studies.diagnosis_generators.nominal import _hinge

    design = _hinge(L, 1.0 - c, h, resolution)
    cells = design.region_cells("hinge")
    a = np.zeros(cells.size)
    steps = STEPS[resolution]
    dt = 1.0 / steps
    V, ok = None, True
    for _ in range(steps):
        if V is None:
            rate = np.ones(cells.size)
        else:
            n = _free_normals(V, design, cells)
            up = _free_normals(V, design, design.region_cells("panel_a")).mean(axis=0)
            up /= np.linalg.norm(up)
            rate = (1.0 - w) + w * np.maximum(0.0, n @ up)
        a = np.minimum(1.0, a + dt * rate)
        R = design.R.copy()
        R[cells] = 1.0 - a * c
        res = gdfe.simulate(design.with_R(R), init="auto" if V is None else V)
        ok &= bool(res.converged)
        V = res.points
    return float(gdfe.fold_angle(V, design)), ok, float(a.mean())
