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

The diagnosis's ``passive_stiffness`` effect (:mod:`gdfe.diagnosis.effects`) and the reference
FEM's verification (:mod:`reference_fem.verify`) both use this module: it is the project's one
implementation of the formula.

Lengths in mm, curvatures in 1/mm.
"""

from __future__ import annotations

import numpy as np

from gdfe._validation import GdfeError, check_array, check_choice, check_number, check_poisson, check_positive

__all__ = ["timoshenko_curvature", "bilayer_curvature", "laminate_curvature", "STATES"]

#: Stress states across the width (see the module docstring).
STATES = ("beam", "biaxial", "plane_strain")


def _bimetal(m, n, t, mismatch):
    """Timoshenko's formula in its own variables (any numeric type: arrays, complex steps)."""
    return 6.0 * mismatch * (1 + m) ** 2 / (t * (3 * (1 + m) ** 2 + (1 + m * n) * (m**2 + 1.0 / (m * n))))


def bilayer_curvature(h, d, E_ratio, mismatch):
    """Curvature [1/mm] of a film of thickness ``h`` on a coat ``d`` in the beam state, no checks.

    ``E_ratio`` is ``E_coat / E_film`` and ``mismatch`` the film's contraction relative to the
    coat (positive: the film shrinks), so this is :func:`timoshenko_curvature` with
    ``E_active = 1``, ``E_passive = E_ratio``, ``eigenstrain = -mismatch``. It takes arrays
    and complex numbers (the diagnosis differentiates it by complex steps) and checks nothing:
    callers validate.
    """
    return _bimetal(h / d, 1.0 / E_ratio, h + d, mismatch)


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
    h = np.asarray(check_positive("h", h), float)
    d = np.asarray(check_positive("d", d), float)
    Ea = check_positive("E_active", E_active)
    Ep = check_positive("E_passive", E_passive)
    nua = check_poisson("nu_active", nu_active)
    nup = check_poisson("nu_passive", nu_passive)
    eps = np.asarray(check_number("eigenstrain", eigenstrain, minimum=-1.0, include_minimum=False,
                                  what="a strain > -1", allow_array=True), float)
    check_choice("state", state, STATES)
    if state == "beam":
        Ea_eff, Ep_eff, mismatch = Ea, Ep, -eps
    elif state == "biaxial":
        Ea_eff, Ep_eff, mismatch = Ea / (1 - nua), Ep / (1 - nup), -eps
    else:
        Ea_eff, Ep_eff, mismatch = Ea / (1 - nua**2), Ep / (1 - nup**2), -(1 + nua) * eps
    kappa = _bimetal(h / d, Ea_eff / Ep_eff, h + d, mismatch)
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
    t = np.atleast_1d(check_array("thicknesses", thicknesses))
    E = np.atleast_1d(check_array("moduli", moduli))
    e = np.atleast_1d(check_array("eigenstrains", eigenstrains))
    if not (t.shape == E.shape == e.shape) or t.ndim != 1:
        raise GdfeError(
            "thicknesses, moduli, eigenstrains: expected 1-D arrays of one length, "
            f"got shapes {t.shape}, {E.shape}, {e.shape}"
        )
    check_positive("thicknesses", t)
    check_positive("moduli", E)
    check_number("eigenstrains", e, minimum=-1.0, include_minimum=False, what="strains > -1", allow_array=True)
    z = np.concatenate([[0.0], np.cumsum(t)])
    z0, z1 = z[:-1], z[1:]
    A = np.sum(E * (z1 - z0))
    B = np.sum(E * (z1**2 - z0**2) / 2)
    D = np.sum(E * (z1**3 - z0**3) / 3)
    N = np.sum(E * e * (z1 - z0))
    M = np.sum(E * e * (z1**2 - z0**2) / 2)
    eps0, kappa = np.linalg.solve([[A, B], [B, D]], [N, M])
    return float(kappa), float(eps0)

