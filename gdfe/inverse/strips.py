"""Strips: simulating a printed strip pattern and reading off the curve it folds into.

A strip is a :class:`gdfe.Design` one column of cells per step along x (e.g.
:meth:`gdfe.inverse.StripPattern.design`). By Eq. 2 a column whose cells contract on one
face turns at the rate

    k = (c_top - c_bottom) / h        (c = 1 - R of each face, 0 where coated),

averaged over the column's cells. :func:`bent_start` integrates these rates along the strip
into a starting shape, :func:`simulate_strip` solves from it, and :func:`strip_midline` reads
the curve in the x-z plane off the solved shape.

All lengths in millimetres, angles in radians.
"""

from __future__ import annotations

import numpy as np

from gdfe._validation import check_instance
from gdfe.design import Design

__all__ = ["bent_start", "simulate_strip", "strip_midline"]


def _column_rates(design):
    """Signed curvature [1/mm] each column of a strip would take by Eq. 2 (mean over its cells)."""
    mesh = design.mesh
    ci = mesh.cell_ij[:, 0]
    ncol = int(ci.max()) + 1
    top, bottom = design.face_contraction()  # a deformation model may have spread or capped them
    rate = (top - bottom) / design.h
    return np.bincount(ci, rate, ncol) / np.maximum(np.bincount(ci, minlength=ncol), 1)


def bent_start(design):
    """A starting shape for a strip: every column already turned as Eq. 2 says.

    The strip's flat mid-line is mapped onto the curve whose curvature in each column is
    the Eq. 2 rate of its contracting cells; every vertex keeps its offset from the
    mid-surface along the curve's normal. The solver then only corrects this guess,
    which takes far fewer iterations than starting from the flat print for strips that
    roll up by a full turn.

    Parameters
    ----------
    design : Design
        A strip along x.

    Returns
    -------
    (n, 3) float array [mm]
    """
    check_instance("design", design, Design)
    mesh = design.mesh
    P = mesh.points
    dx = float(mesh.spacing[0])
    rate = _column_rates(design)
    ncol = rate.size
    th = np.concatenate([[0.0], np.cumsum(rate * dx)])
    step = np.where(np.abs(rate) < 1e-12, dx * np.cos(th[:-1]),
                    (np.sin(th[1:]) - np.sin(th[:-1])) / np.where(np.abs(rate) < 1e-12, 1.0, rate))
    stepz = np.where(np.abs(rate) < 1e-12, dx * np.sin(th[:-1]),
                     (np.cos(th[:-1]) - np.cos(th[1:])) / np.where(np.abs(rate) < 1e-12, 1.0, rate))
    cu = np.concatenate([[0.0], np.cumsum(step)])
    cv = np.concatenate([[0.0], np.cumsum(stepz)])
    x0 = P[:, 0].min()
    xb = x0 + np.arange(ncol + 1) * dx
    x = P[:, 0]
    t = np.interp(x, xb, th)
    u = np.interp(x, xb, cu)
    v = np.interp(x, xb, cv)
    off = P[:, 2] - design.h / 2
    return np.column_stack([x0 + u - off * np.sin(t), P[:, 1], design.h / 2 + v + off * np.cos(t)])


def simulate_strip(design, tol=1e-7, max_iter=400):
    """Simulate a strip design from :func:`bent_start` with the damped Newton solver.

    :func:`gdfe.simulate` with ``init=bent_start(design)``: same energy, same stopping
    criterion and same fixed point; only the starting shape differs (the flat print's
    linearised solution converges slowly for strips that roll up by a full turn).

    Returns
    -------
    gdfe.Result
        Check ``converged``.
    """
    import gdfe

    return gdfe.simulate(design, method="newton", init=bent_start(design), tol=tol, max_iter=max_iter)


def strip_midline(result, design=None):
    """Mid-line of a simulated strip: its two end faces' centroids and every column's centroid.

    Parameters
    ----------
    result : gdfe.Result or (n, 3) float array [mm]
        The simulated strip (or its vertices, with ``design``).
    design : Design, optional
        The strip's design, when ``result`` does not carry it.

    Returns
    -------
    s : (c + 2,) float array [mm]
        Arc length of each point in the flat print, from the strip's start (0 and the strip
        length for the end faces, column centres between).
    uv : (c + 2, 2) float array [mm]
        The points' (x, z) coordinates: the curve in the plane the strip curls in.
    off_plane : float [mm]
        Largest spread of the points along y (0 for a strip that curls in a plane).
    """
    from gdfe.measure import _points_design, column_frames

    points, design = _points_design(result, design)
    cols, _, centre = column_frames(points, design)
    flat = design.mesh.points
    dx = float(design.mesh.spacing[0])
    x0, x1 = flat[:, 0].min(), flat[:, 0].max()
    tol = 1e-9 * max(1.0, abs(x1))
    first = points[np.abs(flat[:, 0] - x0) <= tol].mean(axis=0)
    last = points[np.abs(flat[:, 0] - x1) <= tol].mean(axis=0)
    pts = np.vstack([first, centre, last])
    s = np.concatenate([[0.0], (cols + 0.5) * dx, [x1 - x0]])
    return s, pts[:, [0, 2]], float(np.ptp(pts[:, 1]))
