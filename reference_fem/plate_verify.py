"""Verification of the plate model: Timoshenko's curvature, the strip model, mesh convergence.

- :func:`plate_timoshenko_check`: a plate coated on one face all over, a small eigenstrain, the
  curvature of its mid-surface at the centre against Timoshenko's biaxial bilayer curvature
  (:func:`gdfe.timoshenko.timoshenko_curvature`), which is the exact small-strain interior
  solution of a free plate.
- :func:`plate_strip_check`: a strip drawn as a design (panel, hinge, panel) and meshed as a plate,
  against the layered-strip model (:func:`reference_fem.layered_strip`, quarter model, the
  same elements), nonlinear, with the calibrated material: the turn of the mid-line and the
  distance between the two mid-lines.
- :func:`plate_convergence`: one design on three or more in-plane refinements; the observed order
  from successive differences of the mid-surface at the design's cell vertices.

Lengths in mm, curvatures in 1/mm, angles in rad.
"""

from __future__ import annotations

import time

import numpy as np

from gdfe import _validation as v
from gdfe.paper import FIG6_D as PAPER_D, H as PAPER_H
from .material import CALIBRATED_E_RATIO

__all__ = ["plate_timoshenko_check", "plate_strip_check", "plate_convergence"]


def plate_timoshenko_check(n=8, pixel=0.5, h=PAPER_H, d=PAPER_D, nu=0.0, eigenstrain=-1e-4,
                           E_ratio=CALIBRATED_E_RATIO, refine=1,
                           layers_per_ply=2, radius=1.0):
    """Uniformly coated square plate against Timoshenko's biaxial curvature.

    Parameters
    ----------
    n : int
        Cells along each side; the plate is ``n pixel`` square [mm].
    pixel, h, d : float [mm]
    nu : float
        Poisson's ratio of both layers.
    eigenstrain : float
        The film's free in-plane strain (small: the check is of the small-strain closed form).
    E_ratio : float
        ``E_passive / E_active``.
    refine, layers_per_ply : int
        Mesh (:func:`reference_fem.plate_mesh`).
    radius : float [mm]
        Radius of the central patch of the curvature fit.

    Returns
    -------
    dict
        ``kappa_fem_per_mm`` (mean of k_xx and k_yy), ``kappa_timoshenko_per_mm``, ``rel_error``,
        ``k_xy_per_mm``, ``dofs``, ``n_elements``, ``seconds``.
    """
    import gdfe
    from gdfe.timoshenko import timoshenko_curvature
    from .material import BilayerMaterial
    from .plate import plate_mesh
    from .plate_measure import central_curvatures, midsurface
    from .plate_solve import solve_plate

    n = v.check_int("n", n, minimum=2)
    des = gdfe.from_rows(["T" * n] * n, R=0.9, h=h, pixel=pixel)  # bottom face coated: curls towards +z
    mat = BilayerMaterial.from_ratio(E_ratio, eigenstrain, nu=nu)
    plate = plate_mesh(des, d=d, refine=refine, layers_per_ply=layers_per_ply)
    t0 = time.perf_counter()
    res = solve_plate(plate, mat, linear=True)
    X, x = midsurface(res)
    c = central_curvatures(X, x, (0.5 * n * pixel, 0.5 * n * pixel), radius)
    kT = timoshenko_curvature(h, d, mat.E_active, mat.E_passive, eigenstrain, nu_active=nu, nu_passive=nu,
                              state="biaxial")
    k = 0.5 * (c["k_xx"] + c["k_yy"])
    return {"kappa_fem_per_mm": k, "kappa_timoshenko_per_mm": kT, "rel_error": abs(k / kT - 1),
            "k_xy_per_mm": c["k_xy"], "k_xx_per_mm": c["k_xx"], "k_yy_per_mm": c["k_yy"], "nu": nu,
            "dofs": res.dofs, "n_elements": res.n_elements, "converged": res.converged,
            "seconds": time.perf_counter() - t0}


def plate_strip_check(panel=1.0, hinge=1.5, width=0.5, pixel=0.25, h=PAPER_H, d=PAPER_D, material=None):
    """A panel-hinge-panel strip meshed as a plate and as a layered strip, nonlinear.

    The hinge is coated on its bottom face (free top face: it folds towards +z), the panels on both
    faces. Both models use the same in-plane element size (``pixel``), two uniform layers per ply
    and triquadratic elements.

    Returns
    -------
    dict
        ``turn_plate_rad``, ``turn_strip_rad`` (turn of the mid-line from end to end), ``turn_diff_rad``,
        ``rms_mm`` and ``max_mm`` (distance between the mid-lines after rigid alignment), ``length_mm``,
        the dofs and seconds of each, ``converged``.
    """
    import gdfe
    from .material import BilayerMaterial
    from .measure import midline, turning_angle
    from .mesh import layered_strip
    from .plate import plate_mesh
    from .plate_solve import solve_plate

    material = BilayerMaterial() if material is None else material
    npan, nh, ny = (int(round(x / pixel)) for x in (panel, hinge, width))
    rows = ["R" * npan + "T" * nh + "R" * npan] * ny
    des = gdfe.from_rows(rows, R=0.8, h=h, pixel=pixel)
    plate = plate_mesh(des, d=d, refine=1, layers_per_ply=2)
    res = solve_plate(plate, material)
    X, x = res.points, res.deformed
    tol = 1e-9
    on = (np.abs(X[:, 2] - plate.z_mid) < tol) & (np.abs(X[:, 1] - 0.5 * ny * pixel) < tol)
    order = np.argsort(X[on, 0])
    xp = x[on][order]
    dxz = np.diff(xp[:, [0, 2]], axis=0)
    theta = np.unwrap(np.arctan2(dxz[:, 1], dxz[:, 0]))
    strip = layered_strip([(npan * pixel, "both"), (nh * pixel, "bottom"), (npan * pixel, "both")], h, d,
                          width=ny * pixel, element_size=pixel, layers_per_ply=2)
    from .solve import solve_nonlinear

    rs = solve_nonlinear(strip, material)
    _, xs = midline(rs)
    a = np.column_stack([xs[:, 0], xs[:, 2], np.zeros(len(xs))])
    b = np.column_stack([xp[:, 0], xp[:, 2], np.zeros(len(xp))])
    dist = gdfe.shape_distance(a, b)
    return {"turn_plate_rad": float(theta[-1] - theta[0]), "turn_strip_rad": turning_angle(rs),
            "turn_diff_rad": float(abs(theta[-1] - theta[0] - turning_angle(rs))), "rms_mm": dist["rms"],
            "max_mm": dist["max"], "length_mm": float((2 * npan + nh) * pixel), "dofs_plate": res.dofs,
            "dofs_strip": rs.dofs, "seconds_plate": res.seconds, "seconds_strip": rs.seconds,
            "converged": bool(res.converged and rs.converged)}


def plate_convergence(design, refinements=(1, 2, 4), material=None, d=None, layers_per_ply=2, **solve):
    """Mid-surface of one design on successive in-plane refinements, and the observed order.

    The shape is the deformed mid-surface at the vertices of the design's cells (the points every
    refinement has). With solutions ``u_1, u_2, u_3`` on element sizes ``s, s/q, s/q^2`` the
    observed order is ``log(|u_1 - u_2| / |u_2 - u_3|) / log q`` (largest distance after rigid
    alignment), fitted as a line through all successive differences when there are more.

    Parameters
    ----------
    design : gdfe.Design
    refinements : sequence of int
        Elements per design cell, three or more, each the previous times the same factor.
    material : BilayerMaterial, optional
    d : float [mm], optional
        Coat thickness where the design gives none.
    **solve
        Passed to :func:`reference_fem.solve_plate`.

    Returns
    -------
    dict
        ``rows`` (refine, element size, dofs, seconds, converged, ``diff_mm`` to the next finer),
        ``order``, ``size_mm`` (the part's diagonal).
    """
    import gdfe
    from gdfe._validation import GdfeError
    from .plate import plate_mesh
    from .plate_measure import grid_vertices
    from .plate_solve import solve_plate

    refinements = [v.check_int("refinements", r) for r in refinements]
    if len(refinements) < 3:
        raise GdfeError(f"refinements: expected three or more, got {refinements}")
    q = refinements[1] / refinements[0]
    if q <= 1 or any(abs(b / a - q) > 1e-9 for a, b in zip(refinements[:-1], refinements[1:])):
        raise GdfeError(f"refinements: expected a geometric sequence with a ratio > 1, got {refinements}")
    shapes, rows = [], []
    for r in refinements:
        plate = plate_mesh(design, d=d, refine=r, layers_per_ply=layers_per_ply)
        res = solve_plate(plate, material, **solve)
        _, _, x = grid_vertices(res)
        shapes.append(x)
        rows.append({"refine": r, "element_size_mm": float(plate.in_plane_step.max()), "dofs": res.dofs,
                     "n_elements": res.n_elements, "seconds": res.seconds, "converged": res.converged})
    diffs = [gdfe.shape_distance(a, b)["max"] for a, b in zip(shapes[:-1], shapes[1:])]
    for row, dd in zip(rows, diffs):
        row["diff_mm"] = dd
    sizes = np.array([row["element_size_mm"] for row in rows[:-1]])
    order = float(np.polyfit(np.log(sizes), np.log(diffs), 1)[0])
    return {"rows": rows, "order": order, "size_mm": plate.size}
