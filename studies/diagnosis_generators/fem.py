"""Effects built into the reference FEM's specimen: its geometry or its material.

The linear 3-D bilayer (:func:`reference_fem.hinge_mesh`, :func:`reference_fem.solve_linear`)
gives the fold of a specimen per unit film contraction, ``a(L, d, h; E)`` at a coat-to-film
modulus ratio ``E``. An effect in the geometry (a thicker coat, a wider hinge) changes the fold
of the nominal specimen by the FEM's own ratio: the measured fold is the nominal GDFE fold
times ``a(with the effect) / a(nominal)`` -- the film in each specimen contracts as the
nominal world says, and the FEM says what the changed specimen does with it. In these ratios
the coat is :data:`STIFF_COAT` times stiffer than the film: the elastic counterpart of the
nominal world's coat, which GDFE and Eq. 3 treat as rigid (a hot acrylate of tens to hundreds
of MPa on polystyrene softened above its glass transition to a few MPa). The elastic coat is
the FEM alone, ``alpha = eps a(L, d, h; E)`` with ``E`` drawn. The film that thickens as it
shrinks is the geometrically nonlinear FEM (:func:`reference_fem.solve_nonlinear`) with the
film's eigenstrain through its thickness, ``(1 + eps)^2 (1 + eps_zz) = 1`` scaled by
``beta / 2`` (2: volume kept), against the same solve without it.

FEM resolution: :data:`reference_fem.HINGE_RESOLUTIONS`. Lengths in mm, angles in radians.
"""

from __future__ import annotations

import numpy as np

__all__ = ["unit_folds", "thickening_ratio", "STIFF_COAT"]

#: Coat-to-film modulus ratio of the FEM specimens the effects are built into.
STIFF_COAT = 100.0


def unit_folds(L, d, h, E_ratio=None, resolution="coarse"):
    """Fold per unit film contraction [rad] of each specimen (linear FEM).

    Parameters
    ----------
    L, d, h : (n,) float arrays [mm]
    E_ratio : float, optional
        Coat-to-film modulus ratio (default :data:`STIFF_COAT`).
    resolution : {"coarse", "default", "fine"}
    """
    from reference_fem import unit_angles

    E = STIFF_COAT if E_ratio is None else float(E_ratio)
    return unit_angles(np.asarray(L, float), np.asarray(d, float), np.asarray(h, float), ratios=[E],
                       resolution=resolution)[:, 0]


def thickening_ratio(L, d, h, contraction, beta, resolution="coarse"):
    """Fold of the nonlinear FEM specimen whose film thickens as it shrinks, over the same
    specimen's fold without the thickening.

    Parameters
    ----------
    L, d, h : (n,) float arrays [mm]
    contraction : (n,) float array
        The film's mean in-plane contraction in each specimen (``-eps``), in (0, 1).
    beta : float
        Thickening per unit of the volume-keeping one: ``eps_zz = (beta / 2) ((1 + eps)^-2 - 1)``.
    resolution : {"coarse", "default", "fine"}

    Returns
    -------
    ratio : (n,) float array
    converged : (n,) bool array
    """
    from reference_fem import BilayerMaterial, fold_angle, hinge_mesh, solve_nonlinear

    ratios, ok = [], []
    for Li, di, hi, ci in np.broadcast(L, d, h, contraction):
        strip = hinge_mesh(float(Li), float(di), float(hi), resolution=resolution)
        eps = -float(ci)
        ezz = 0.5 * beta * ((1.0 + eps) ** -2 - 1.0)
        base = BilayerMaterial.from_ratio(STIFF_COAT, eps)
        thick = BilayerMaterial(base.E_active, base.E_passive, base.nu_active, base.nu_passive, (eps, eps, ezz))
        r0, r1 = solve_nonlinear(strip, base), solve_nonlinear(strip, thick)
        ratios.append(fold_angle(r1) / fold_angle(r0))
        ok.append(r0.converged and r1.converged)
    return np.array(ratios), np.array(ok)
