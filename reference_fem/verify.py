"""Verification of the reference FEM against closed forms.

:func:`timoshenko_check`
    A free bilayer strip with ``nu = 0`` in both layers and an isotropic eigenstrain. With
    ``nu = 0`` there is no coupling across the width, and the small-strain 3-D solution away from
    the ends is exactly ``u_x = (a + kappa z) x``, ``u_y = (a + kappa z) y``,
    ``u_z = -kappa (x^2 + y^2) / 2`` with Timoshenko's ``kappa`` (beam, biaxial and plane-strain
    formulas coincide). The curvature is read over the middle half of the strip (the ends carry
    a boundary layer a few thicknesses long).

    The triquadratic element (``hex2``) contains that field, so it matches the closed form on
    every mesh (measured: relative error 7.5e-6 at 0.6 mm and about 1e-7 on finer meshes,
    small but not round-off); the trilinear element (``hex1``) locks in bending (parasitic
    shear of order ``kappa * element length``), which makes it the element whose convergence
    can be observed: its error falls as the square of the element length.

:func:`arc_check`
    A long free bilayer strip under a uniaxial eigenstrain large enough to curl it by ~2.5 rad,
    solved geometrically nonlinearly: it should be a circular arc whose turning angle is
    Timoshenko's ``kappa * L``.
"""

from __future__ import annotations

import numpy as np

from gdfe._validation import GdfeError

from .material import BilayerMaterial
from .measure import curvature, fit_circle, midline, turning_angle
from .mesh import strip_mesh
from .solve import solve_linear, solve_nonlinear
from gdfe.paper import FIG6_D, H
from gdfe.timoshenko import timoshenko_curvature

__all__ = ["timoshenko_check", "arc_check", "TIMOSHENKO_MESHES"]

#: (element, [(in-plane element size [mm], elements per ply), ...]) of :func:`timoshenko_check`.
TIMOSHENKO_MESHES = {
    "hex1": [(0.3, 2), (0.15, 2), (0.075, 2), (0.0375, 2)],
    "hex2": [(0.6, 2), (0.3, 2), (0.15, 2)],
}


def timoshenko_check(element="hex1", meshes=None, *, length=6.0, width=1.0, h=H, d=FIG6_D,
                     E_ratio=0.5):
    """FEM curvature of a free bilayer strip against Timoshenko on a sequence of meshes.

    Parameters
    ----------
    element : {"hex1", "hex2", "hexs2"}
        Element type.
    meshes : sequence of (float, int), optional
        ``(element_size [mm], layers_per_ply)`` from coarse to fine; default
        :data:`TIMOSHENKO_MESHES` for the element (at least three).
    length, width, h, d : float [mm]
        Strip length and width, film and coat thickness.
    E_ratio : float
        ``E_passive / E_active``.

    Returns
    -------
    dict
        ``rows`` (per mesh: ``element_size_mm``, ``layers_per_ply``, ``dofs``, ``seconds``,
        ``kappa_fem_per_mm``, ``kappa_timoshenko_per_mm``, ``rel_error``), ``rate`` (slope of
        log error against log element size, a least-squares fit over all meshes), ``finest_error``
        and the set-up.
    """
    if meshes is None:
        meshes = TIMOSHENKO_MESHES.get(element, TIMOSHENKO_MESHES["hex2"])
    meshes = list(meshes)
    if len(meshes) < 3:
        raise GdfeError(f"meshes: expected at least 3 refinements, got {len(meshes)}")
    mat = BilayerMaterial(E_active=3000.0, E_passive=E_ratio * 3000.0, nu_active=0.0, nu_passive=0.0,
                   eigenstrain=-1e-3)
    kT = timoshenko_curvature(h, d, mat.E_active, mat.E_passive, mat.eigenstrain)
    rows = []
    for size, layers in meshes:
        strip = strip_mesh(length, h, d, width=width, element_size=size, layers_per_ply=layers)
        res = solve_linear(strip, mat, element=element)
        k = curvature(res)
        rows.append({"element_size_mm": float(size), "layers_per_ply": int(layers),
                     "dofs": res.dofs, "seconds": res.seconds, "kappa_fem_per_mm": k,
                     "kappa_timoshenko_per_mm": kT, "rel_error": abs(k - kT) / abs(kT),
                     "converged": res.converged})
    sizes = np.array([r["element_size_mm"] for r in rows])
    errs = np.array([r["rel_error"] for r in rows])
    rate = float(np.polyfit(np.log(sizes), np.log(errs), 1)[0])
    return {"element": element, "rows": rows, "rate": rate, "finest_error": float(errs[-1]),
            "setup": {"length_mm": length, "width_mm": width, "h_mm": h, "d_mm": d,
                      "E_ratio": E_ratio, "nu": 0.0, "eigenstrain": mat.eigenstrain,
                      "kappa_read_over": "middle half of the strip"}}


def arc_check(eigenstrain=-0.05, turn=2.5, *, h=H, d=FIG6_D, width=0.5, element_size=0.3,
              model="neohookean"):
    """Nonlinear curl of a free strip under a large uniaxial eigenstrain (``nu = 0``).

    The strip length is chosen so that Timoshenko's ``kappa * L`` equals ``turn``.

    Returns
    -------
    dict
        ``turning_angle_rad`` (FEM, end to end), ``kappa_L_rad`` (Timoshenko ``kappa * L``),
        ``rel_error``, ``circle_rms_over_radius`` (how far the mid-line is from its best-fit
        circle), ``converged``, ``iterations``, ``seconds``, ``dofs``, ``length_mm``.
    """
    mat = BilayerMaterial(E_active=3000.0, E_passive=3000.0, nu_active=0.0, nu_passive=0.0,
                   eigenstrain=(eigenstrain, 0.0, 0.0))
    kT = timoshenko_curvature(h, d, mat.E_active, mat.E_passive, eigenstrain)
    length = turn / kT
    strip = strip_mesh(length, h, d, width=width, element_size=element_size)
    res = solve_nonlinear(strip, mat, model=model)
    theta = turning_angle(res)
    _, x = midline(res)
    _, radius, rms = fit_circle(x[:, [0, 2]])
    return {"turning_angle_rad": theta, "kappa_L_rad": kT * length,
            "rel_error": abs(theta - kT * length) / (kT * length),
            "circle_radius_mm": radius, "circle_rms_over_radius": rms / radius,
            "kappa_mid_per_mm": curvature(res), "kappa_timoshenko_per_mm": kT,
            "converged": res.converged, "iterations": res.iterations, "seconds": res.seconds,
            "dofs": res.dofs, "length_mm": length, "eigenstrain": eigenstrain}
