"""The contraction ratio a designer would use: calibrated on the reference FEM's folding test.

A hinge specimen (:func:`gdfe.hinge`: a 1 mm hinge between 1 mm panels, 1 mm wide, 0.5 mm cells,
d = 0.33 mm) is folded by the plate FEM (the Table-1 calibration of the FEM's material, one
quadratic element per ply); its fold angle, the angle between the two panels' directions along
the strip, gives ``R`` by Eq. 2 (:func:`gdfe.calibration.ratio_from_angle`). That is the folding
test of the material the parts are printed in, as a designer would calibrate GDFE before
printing a part; the parts themselves are never used. Lengths in mm, angles in radians.
"""

from __future__ import annotations

import functools

import numpy as np

from studies.shape_generators.designs import D, H, PIXEL

__all__ = ["folding_test", "calibrated_R", "fem_options"]

#: The plate FEM's mesh for every part of the benchmark: one element per design cell in-plane, one
#: quadratic element through each ply.
FEM_MESH = {"refine": 1, "layers_per_ply": 1}


def fem_options():
    """Keyword arguments of :func:`reference_fem.plate_mesh` for the benchmark's parts."""
    return dict(FEM_MESH, d=D)


def fold_between_panels(ij, x):
    """Fold angle [rad] of a strip along x: the angle between the directions of its first and
    last column of cells (mean over the vertices across the strip)."""
    imax = int(ij[:, 0].max())

    def direction(i0, i1):
        a = x[ij[:, 0] == i1].mean(0) - x[ij[:, 0] == i0].mean(0)
        return a / np.linalg.norm(a)

    c = float(np.clip(direction(0, 1) @ direction(imax - 1, imax), -1.0, 1.0))
    return float(np.arccos(c))


@functools.lru_cache(maxsize=None)
def folding_test(length=1.0):
    """The FEM's fold of a hinge specimen of width ``length`` [mm]: ``(alpha_rad, seconds,
    converged)``."""
    import gdfe
    import reference_fem as rf

    spec = gdfe.hinge(length, d=D, h=H, width=1.0, panel_length=1.0, cell_size=PIXEL)
    res = rf.solve_plate(rf.plate_mesh(spec, **fem_options()), rf.BilayerMaterial())
    ij, _, x = rf.grid_vertices(res)
    return fold_between_panels(ij, x), float(res.seconds), bool(res.converged)


def calibrated_R(length=1.0):
    """``R`` of Eq. 2 from the FEM's folding test (:func:`folding_test`)."""
    from gdfe.calibration import ratio_from_angle

    alpha, _, _ = folding_test(length)
    return float(ratio_from_angle(alpha, length, H))
