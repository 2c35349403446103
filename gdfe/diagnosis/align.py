"""Alignment: the rigid motion that best takes a measured point cloud onto a simulated surface.

Iterative closest points (ICP) alternate the exact closest points ``c_i`` of the moved points
``x_i`` on the :class:`~gdfe.diagnosis.surface.Surface` with a rigid motion that reduces the
mean squared distance ``E = mean_i |x_i - c_i|^2``:

- point to point (Kabsch): the best rotation and translation taking the points onto their
  closest points, repeated while ``E`` falls by at least 1e-3 relatively;
- point to plane (Chen and Medioni), Gauss-Newton on the distances ``d_i`` linearised along
  ``n_i = (x_i - c_i) / d_i``: the small rotation ``w`` and translation ``tau`` solve, in the
  least-squares sense, ``((x_i - x0) x n_i) . w + n_i . tau = -d_i``; a step is kept while it
  lowers ``E``.

Without a start, the centroids and principal axes are matched under each of the four proper
flips of the axes, and the best of the four runs is kept.

Lengths in mm.
"""

from __future__ import annotations

import numpy as np

from gdfe._validation import check_array, check_instance, check_int, check_number
from gdfe.diagnosis.surface import Surface

__all__ = ["align_icp"]


def _proper_flips():
    """The four sign flips of three axes that are rotations."""
    out = []
    for sx in (1, -1):
        for sy in (1, -1):
            sz = sx * sy  # det +1
            out.append(np.diag([sx, sy, sz]).astype(float))
    return out


def align_icp(measured, surface, start=None, max_iter=50, tol=1e-8):
    """Rigid alignment of a point cloud to a surface by iterative closest points.

    Without ``start``, every proper flip of the principal axes (centroids matched) is tried
    and the best kept. Each run alternates exact closest points on the surface with rigid
    motions: Kabsch steps first, Gauss-Newton steps on the distances last.

    Parameters
    ----------
    measured : (k, 3) float array [mm], k >= 3
    surface : Surface
    start : ((3, 3), (3,)) tuple, optional
        A rotation and translation to start from instead.
    max_iter : int
        Most steps of each kind per run.
    tol : float
        The Gauss-Newton steps stop once the mean squared distance falls by less than this
        fraction.

    Returns
    -------
    Q : (3, 3) float array
    t : (3,) float array [mm]
        ``measured @ Q.T + t`` is aligned.
    rms : float [mm]
        RMS distance of the aligned points to the surface.
    """
    measured = check_array("measured", measured, shape=(-1, 3), min_size=3)
    check_instance("surface", surface, Surface)
    max_iter = check_int("max_iter", max_iter, minimum=0)
    tol = check_number("tol", tol, minimum=0.0)
    if start is not None:
        Q0, t0 = start
        Q0 = check_array("start[0]", Q0, shape=(3, 3))
        t0 = check_array("start[1]", t0, shape=(3,))
        return _icp(measured, surface, Q0, t0, max_iter, tol, coarse=False)
    cm, ct = measured.mean(0), surface.samples.mean(0)
    _, _, Vm = np.linalg.svd(measured - cm, full_matrices=False)
    _, _, Vt = np.linalg.svd(surface.samples - ct, full_matrices=False)
    best = None
    for D in _proper_flips():
        Q = Vt.T @ D @ Vm
        if np.linalg.det(Q) < 0:
            Q = Vt.T @ D @ np.diag([1.0, 1.0, -1.0]) @ Vm
        run = _icp(measured, surface, Q, ct - cm @ Q.T, max_iter, tol)
        if best is None or run[2] < best[2]:
            best = run
    return best


def _icp(measured, surface, Q, t, max_iter, tol, coarse=True):
    """Closest-point iterations from ``(Q, t)``: Kabsch steps until they stall (relative
    decrease below 1e-3; skipped when not ``coarse``, i.e. from a start already close), then
    Gauss-Newton steps on the point-to-surface distances (each linearised in the direction to
    its closest point, the point-to-plane step of Chen and Medioni), kept only while the mean
    squared distance falls."""
    from gdfe.measure import rigid_align

    def state(Q, t):
        moved = measured @ Q.T + t
        C, d, _ = surface.closest(moved)
        return moved, C, d, float(np.mean(d**2))

    moved, C, d, err = state(Q, t)
    for _ in range(max_iter if coarse else 0):  # point to point
        Qn, tn = rigid_align(measured, C)
        mn, Cn, dn, en = state(Qn, tn)
        if en >= err:
            break
        gain = (err - en) / max(err, 1e-300)
        Q, t, moved, C, d, err = Qn, tn, mn, Cn, dn, en
        if gain < 1e-3:
            break
    scale = float(np.sqrt(np.mean(np.sum((measured - measured.mean(0)) ** 2, 1)))) or 1.0
    for _ in range(max_iter):  # Gauss-Newton, point to plane
        diff = moved - C
        n = diff / np.maximum(d, 1e-300)[:, None]
        c0 = moved.mean(0)
        A = np.column_stack([np.cross(moved - c0, n) / scale, n])
        x = np.linalg.lstsq(A, -d, rcond=None)[0]
        w, tau = x[:3] / scale, x[3:]
        th = float(np.linalg.norm(w))
        K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / (th if th > 0 else 1.0)
        dR = np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K
        Qn, tn = dR @ Q, dR @ (t - c0) + c0 + tau
        mn, Cn, dn, en = state(Qn, tn)
        if en >= err:
            break
        small = (err - en) <= tol * err
        Q, t, moved, C, d, err = Qn, tn, mn, Cn, dn, en
        if small:
            break
    return Q, t, float(np.sqrt(err))
