"""Reading angles, curvatures and shapes off a :class:`~reference_fem.FemResult`.

Everything is read on the film's mid-plane (``z = h / 2``), which runs unbroken through panels and
hinges. Symmetric models are mirrored back to the full strip first.

Angles are measured in the xz-plane, positive counter-clockwise (from +x towards +z), so a strip
that curls towards +z has a positive turning angle. For a nonlinear result the tangent angle of the
deformed mid-line is unwrapped along the strip, so folds beyond pi/2 (or pi) come out right; for a
linear result it is the linearised rotation ``d u_z / d x``. The fold angle of a hinge is reported
positive when it folds towards its free (uncoated) face, as in Table 1 of the paper.

Lengths in mm, angles in radians, curvatures in 1/mm.
"""

from __future__ import annotations

import numpy as np

from gdfe._validation import GdfeError

__all__ = ["midline", "midsurface", "tangent_angles", "fold_angle", "curvature", "turning_angle",
           "fit_circle"]


def _mirror(X, U, axis):
    Xm, Um = X.copy(), U.copy()
    Xm[:, axis] *= -1
    Um[:, axis] *= -1
    keep = np.abs(X[:, axis]) > 1e-12
    return np.vstack([Xm[keep], X]), np.vstack([Um[keep], U])


def midsurface(result):
    """Film mid-plane of the full strip.

    Returns
    -------
    X : (k, 3) float array [mm]
        Reference positions of the mid-plane degrees of freedom.
    x : (k, 3) float array [mm]
        Their deformed positions (reference plus displacement; for a linear result the
        displacement is the small-strain one, taken at face value).
    """
    strip = result.strip
    on = np.abs(result.points[:, 2] - strip.z_mid) < 1e-9
    X, U = result.points[on], result.displacement[on]
    X, U = _mirror(X, U, 1)
    if strip.symmetry == "xy":
        X, U = _mirror(X, U, 0)
    return X, X + U


def midline(result):
    """Film mid-line on the symmetry plane ``y = 0``, sorted along x, for the full strip.

    Returns
    -------
    X : (k, 3) float array [mm]
        Reference positions.
    x : (k, 3) float array [mm]
        Deformed positions.
    """
    strip = result.strip
    on = (np.abs(result.points[:, 2] - strip.z_mid) < 1e-9) & (np.abs(result.points[:, 1]) < 1e-9)
    X, U = result.points[on], result.displacement[on]
    if strip.symmetry == "xy":
        X, U = _mirror(X, U, 0)
    order = np.argsort(X[:, 0])
    return X[order], X[order] + U[order]


def tangent_angles(result):
    """Tangent angle of the mid-line on each of its pieces.

    Returns
    -------
    s_ref : (k-1,) float array [mm]
        Reference x of the middle of each piece.
    s : (k-1,) float array [mm]
        Arc length along the deformed mid-line to the middle of each piece (reference x for a
        linear result).
    theta : (k-1,) float array [rad]
        Tangent angle, unwrapped (nonlinear) or the linearised rotation (linear).
    """
    X, x = midline(result)
    mid = 0.5 * (X[1:, 0] + X[:-1, 0])
    if result.nonlinear:
        dx = np.diff(x[:, [0, 2]], axis=0)
        theta = np.unwrap(np.arctan2(dx[:, 1], dx[:, 0]))
        ds = np.hypot(dx[:, 0], dx[:, 1])
        s = np.concatenate([[0.0], np.cumsum(ds)])
        s = 0.5 * (s[1:] + s[:-1])
    else:
        dX = np.diff(X[:, 0])
        theta = np.diff(x[:, 2] - X[:, 2]) / dX
        s = mid
    return mid, s, theta


def _chord_angle(result, lo, hi):
    """Angle of the chord of the mid-line between reference x = lo and x = hi."""
    X, x = midline(result)
    i, j = np.argmin(np.abs(X[:, 0] - lo)), np.argmin(np.abs(X[:, 0] - hi))
    if not result.nonlinear:
        return (x[j, 2] - x[i, 2] - (X[j, 2] - X[i, 2])) / (X[j, 0] - X[i, 0])
    chord = np.arctan2(x[j, 2] - x[i, 2], x[j, 0] - x[i, 0])
    mid, _, theta = tangent_angles(result)
    inside = (mid >= min(lo, hi)) & (mid <= max(lo, hi))
    ref = np.mean(theta[inside]) if inside.any() else theta[np.argmin(np.abs(mid - 0.5 * (lo + hi)))]
    return chord + 2 * np.pi * np.round((ref - chord) / (2 * np.pi))


def fold_angle(result, panel_fraction=0.5):
    """Fold angle of a hinge: the turn from one panel to the other.

    Each panel's direction is the chord of the mid-line over the outer ``panel_fraction`` of the
    panel (away from the hinge), placed on the branch of the unwrapped tangent angle.

    Parameters
    ----------
    result : FemResult
        Solution of a :func:`~reference_fem.hinge_mesh` model.
    panel_fraction : float
        Part of each panel used, in (0, 1].

    Returns
    -------
    float [rad]
        Positive when the hinge folds towards its free face.
    """
    strip = result.strip
    if strip.meta.get("kind") != "hinge":
        raise GdfeError(f"result: fold_angle expected a hinge model (hinge_mesh), got kind "
                         f"{strip.meta.get('kind')!r}; use turning_angle for strips")
    if not 0 < panel_fraction <= 1:
        raise GdfeError(f"panel_fraction: expected a number in (0, 1], got {panel_fraction!r}")
    e = strip.x_edges
    a_left = _chord_angle(result, e[0], e[0] + panel_fraction * (e[1] - e[0]))
    a_right = _chord_angle(result, e[-1] - panel_fraction * (e[-1] - e[-2]), e[-1])
    sign = 1.0 if strip.meta.get("free_face", "top") == "top" else -1.0
    return float(sign * (a_right - a_left))


def turning_angle(result):
    """Total turn of the mid-line from its left end to its right end [rad], + towards +z."""
    _, _, theta = tangent_angles(result)
    return float(theta[-1] - theta[0])


def curvature(result, lo=None, hi=None):
    """Mean curvature of the mid-line between reference x = lo and x = hi.

    The slope of the tangent angle against arc length (a least-squares line), so the result is
    the curvature of the deformed mid-line (the second derivative of ``u_z`` for a linear result).

    Parameters
    ----------
    result : FemResult
    lo, hi : float [mm], optional
        Reference x range; default: the middle half of the hinge for a hinge model, the middle
        half of the strip otherwise.

    Returns
    -------
    float [1/mm]
        Positive when curling towards +z (for a hinge: towards its free face).
    """
    strip = result.strip
    if lo is None or hi is None:
        if strip.meta.get("kind") == "hinge":
            half = 0.25 * strip.meta["hinge_length_mm"]
        else:
            half = 0.25 * strip.length
        lo, hi = -half, half
    mid, s, theta = tangent_angles(result)
    inside = (mid >= lo - 1e-12) & (mid <= hi + 1e-12)
    if inside.sum() < 2:
        raise GdfeError(f"curvature: expected two or more mid-line pieces in x = [{lo}, {hi}] mm, got fewer")
    kappa = np.polyfit(s[inside], theta[inside], 1)[0]
    sign = -1.0 if (strip.meta.get("kind") == "hinge"
                    and strip.meta.get("free_face") == "bottom") else 1.0
    return float(sign * kappa)


def fit_circle(points):
    """Least-squares circle through points in a plane.

    Algebraic (Kasa) fit followed by Gauss-Newton on the geometric distances.

    Parameters
    ----------
    points : (k, 2) float array [mm]

    Returns
    -------
    centre : (2,) float array [mm]
    radius : float [mm]
    rms : float [mm]
        Root-mean-square distance of the points from the circle.
    """
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3:
        raise GdfeError(f"points: expected a (k, 2) array with k >= 3, got shape {p.shape}")
    shift = p.mean(axis=0)
    q = p - shift
    A = np.column_stack([2 * q, np.ones(len(q))])
    sol = np.linalg.lstsq(A, (q**2).sum(axis=1), rcond=None)[0]
    c = sol[:2]
    r = np.sqrt(sol[2] + c @ c)
    for _ in range(20):
        dv = q - c
        dist = np.linalg.norm(dv, axis=1)
        res = dist - r
        J = np.column_stack([-dv / dist[:, None], -np.ones(len(q))])
        step = np.linalg.lstsq(J, -res, rcond=None)[0]
        c, r = c + step[:2], r + step[2]
        if np.linalg.norm(step) < 1e-14 * max(1.0, r):
            break
    res = np.linalg.norm(q - c, axis=1) - r
    return c + shift, float(r), float(np.sqrt(np.mean(res**2)))
