"""Closed-form curvature of a bilayer with a mismatch strain (Timoshenko's bimetal strip).

Two bonded layers, the active film of thickness ``h`` with free strain ``eps*`` and the passive layer of
thickness ``d`` with none, bend into an arc. With the film as layer 1 (``m = h / d``,
``n = E1' / E2'``, ``t = h + d``) and the mismatch ``delta = -eps*_eff`` (film shorter than the coat),
the curvature is

    kappa = 6 delta (1 + m)^2 / (t (3 (1 + m)^2 + (1 + m n) (m^2 + 1 / (m n))))

which is unchanged by swapping the layers (m -> 1/m, n -> 1/n), so which one is "layer 1" does not
matter. ``kappa > 0`` means the bilayer curls towards the contracting film (the film on the concave
side). The effective moduli ``E'`` and mismatch depend on the state across the width:

``"beam"``
    Narrow strip, uniaxial stress: ``E' = E``, ``eps*_eff = eps*_xx``. Exact for a 3-D solid only when
    ``nu = 0`` or when the eigenstrain is uniaxial and the strip is narrow.
``"biaxial"``
    Wide plate with equal-biaxial (isotropic in-plane) eigenstrain, bent into a spherical cap:
    ``E' = E / (1 - nu)``, ``eps*_eff = eps*``. This is the exact small-strain interior solution of a
    free plate of any width. With equal Poisson's ratios the ratio ``n`` and so ``kappa`` equal the
    beam value; the correction only matters when ``nu_active != nu_passive``.
``"plane_strain"``
    Cylindrical bending with the transverse strain suppressed (``eps_yy = 0``) and isotropic in-plane
    eigenstrain: ``E' = E / (1 - nu^2)``, ``eps*_eff = (1 + nu_active) eps*``. The upper bound that a
    very wide strip, forced into a cylinder at large deflection, approaches.

Lengths in mm, curvatures in 1/mm.
"""

from __future__ import annotations

import numpy as np

from . import _validate as v

__all__ = ["timoshenko_curvature", "laminate_curvature"]

_STATES = {"beam", "biaxial", "plane_strain"}


def timoshenko_curvature(h, d, E_active, E_passive, eigenstrain, *, nu_active=0.0,
                         nu_passive=0.0, state="beam"):
    """Curvature of a film/coat bilayer by Timoshenko's bimetal formula.

    Parameters
    ----------
    h : float or array [mm]
        Thickness of the active film, > 0.
    d : float or array [mm]
        Thickness of the passive layer, > 0.
    E_active, E_passive : float [MPa]
        Young's moduli, > 0 (only their ratio matters).
    eigenstrain : float or array
        Free strain of the film along the bending direction, ``R_free - 1`` > -1
        (negative: the film contracts).
    nu_active, nu_passive : float
        Poisson's ratios (used by the ``"biaxial"`` and ``"plane_strain"`` states).
    state : {"beam", "biaxial", "plane_strain"}
        Stress state across the width; see the module docstring.

    Returns
    -------
    kappa : float or array [1/mm]
        Curvature, positive when the bilayer curls towards the contracting film.

    Examples
    --------
    Two equal layers of total thickness ``t`` curl with ``kappa = 3 delta / (2 t)``:

    >>> round(timoshenko_curvature(0.5, 0.5, 1.0, 1.0, -0.01), 6)
    0.015
    """
    h = _positive_array("h", h)
    d = _positive_array("d", d)
    Ea = v.positive("E_active", E_active)
    Ep = v.positive("E_passive", E_passive)
    nua = v.poisson("nu_active", nu_active)
    nup = v.poisson("nu_passive", nu_passive)
    eps = np.asarray(eigenstrain, dtype=float)
    if not np.all(np.isfinite(eps)) or np.any(eps <= -1.0):
        raise ValueError(f"eigenstrain must be greater than -1, got {eigenstrain!r}")
    v.choice("state", state, _STATES)
    if state == "beam":
        Ea_eff, Ep_eff, mismatch = Ea, Ep, -eps
    elif state == "biaxial":
        Ea_eff, Ep_eff, mismatch = Ea / (1 - nua), Ep / (1 - nup), -eps
    else:
        Ea_eff, Ep_eff, mismatch = Ea / (1 - nua**2), Ep / (1 - nup**2), -(1 + nua) * eps
    m = h / d
    n = Ea_eff / Ep_eff
    t = h + d
    kappa = 6.0 * mismatch * (1 + m) ** 2 / (
        t * (3 * (1 + m) ** 2 + (1 + m * n) * (m**2 + 1.0 / (m * n)))
    )
    return float(kappa) if np.ndim(kappa) == 0 else kappa


def laminate_curvature(thicknesses, moduli, eigenstrains):
    """Curvature and mid-strain of a stack of bonded layers in uniaxial bending.

    Solves force and moment balance for the linear strain ``eps(z) = eps0 + kappa * z`` (z measured
    from the bottom face, upwards): ``sum_i E_i int_i (eps(z) - eps*_i) (1, z) dz = 0``.

    Parameters
    ----------
    thicknesses : (k,) float array [mm]
        Layer thicknesses from the bottom up, > 0.
    moduli : (k,) float array [MPa]
        Young's moduli (or effective moduli) of the layers, > 0.
    eigenstrains : (k,) float array
        Free strains of the layers, > -1.

    Returns
    -------
    kappa : float [1/mm]
        ``d eps / d z``; positive when the top fibres end up longer, i.e. the stack curls
        towards its bottom face.
    eps0 : float
        Strain at the bottom face ``z = 0``.
    """
    t = np.atleast_1d(np.asarray(thicknesses, dtype=float))
    E = np.atleast_1d(np.asarray(moduli, dtype=float))
    e = np.atleast_1d(np.asarray(eigenstrains, dtype=float))
    if not (t.shape == E.shape == e.shape) or t.ndim != 1:
        raise ValueError(
            "thicknesses, moduli and eigenstrains must be 1-D arrays of one length, "
            f"got shapes {t.shape}, {E.shape}, {e.shape}"
        )
    if np.any(~(t > 0)):
        raise ValueError(f"thicknesses must all be positive, got {t.tolist()}")
    if np.any(~(E > 0)):
        raise ValueError(f"moduli must all be positive, got {E.tolist()}")
    if np.any(~(e > -1)):
        raise ValueError(f"eigenstrains must all be greater than -1, got {e.tolist()}")
    z = np.concatenate([[0.0], np.cumsum(t)])
    z0, z1 = z[:-1], z[1:]
    A = np.sum(E * (z1 - z0))
    B = np.sum(E * (z1**2 - z0**2) / 2)
    D = np.sum(E * (z1**3 - z0**3) / 3)
    N = np.sum(E * e * (z1 - z0))
    M = np.sum(E * e * (z1**2 - z0**2) / 2)
    eps0, kappa = np.linalg.solve([[A, B], [B, D]], [N, M])
    return float(kappa), float(eps0)


def _positive_array(name, value):
    try:
        x = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if x.size == 0 or not np.all(np.isfinite(x)) or np.any(x <= 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return x
