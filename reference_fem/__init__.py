"""Reference finite-element model of heat-shrinking bilayers (scikit-fem), and closed forms.

A 3-D solid model of the paper's specimens: a pre-strained film (active layer, thickness ``h``)
coated with passive material (thickness ``d``) on one or both faces. The film carries a contraction
eigenstrain ``eps* = R_free - 1``; panels (coated on both faces) shrink and stay flat, hinges
(coated on one face) fold towards their free face. Solved with small strains
(:func:`solve_linear`) or with finite strains and rotations (:func:`solve_nonlinear`,
total Lagrangian, ``F = F_e F*``). Plates meshed from any GDFE design (:func:`plate_mesh`,
:func:`solve_plate`) carry the coat wherever the design prints it. It is the yardstick for GDFE's angles, shapes and speed.

Units: millimetres, radians, MPa.

>>> from reference_fem import BilayerMaterial, hinge_mesh, solve_linear, fold_angle
>>> strip = hinge_mesh(length=1.6, d=0.33, h=0.29, resolution="coarse")
>>> res = solve_linear(strip, BilayerMaterial())
>>> res.converged
True
"""

from .calibrate import DEFAULT_RATIOS, TableFit, fit_to_table, unit_angles
from .material import CALIBRATED_E_RATIO, CALIBRATED_EIGENSTRAIN, DEFAULT_E_PASSIVE, BilayerMaterial
from .measure import curvature, fit_circle, fold_angle, midline, midsurface, tangent_angles, turning_angle
from .mesh import HINGE_RESOLUTIONS, LayeredStrip, Segment, hinge_mesh, layered_strip, strip_mesh
from .solve import FemResult, solve_linear, solve_nonlinear
from .plate import PLATE_RESOLUTIONS, DesignGrid, Plate, design_grid, plate_mesh
from .plate_solve import PlateResult, solve_plate
from .plate_measure import central_curvatures, grid_vertices
from .plate_output import write_plate_series, write_plate_vtu
from gdfe.timoshenko import laminate_curvature, timoshenko_curvature
from .verify import arc_check, timoshenko_check

__all__ = [
    "BilayerMaterial",
    "CALIBRATED_E_RATIO",
    "CALIBRATED_EIGENSTRAIN",
    "DEFAULT_E_PASSIVE",
    "Segment",
    "LayeredStrip",
    "layered_strip",
    "hinge_mesh",
    "strip_mesh",
    "HINGE_RESOLUTIONS",
    "FemResult",
    "solve_linear",
    "solve_nonlinear",
    "fold_angle",
    "curvature",
    "turning_angle",
    "tangent_angles",
    "midline",
    "midsurface",
    "fit_circle",
    "timoshenko_curvature",
    "laminate_curvature",
    "timoshenko_check",
    "arc_check",
    "TableFit",
    "fit_to_table",
    "unit_angles",
    "DEFAULT_RATIOS",
    "Plate",
    "DesignGrid",
    "design_grid",
    "plate_mesh",
    "PLATE_RESOLUTIONS",
    "PlateResult",
    "solve_plate",
    "grid_vertices",
    "central_curvatures",
    "write_plate_vtu",
    "write_plate_series",
]
