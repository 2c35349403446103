"""gdfe: geometry-driven finite elements for 4D-printed heat-shrinking structures.

Units are millimetres and radians throughout. The library imports numpy and scipy only;
optional packages (meshio, pillow, matplotlib, pyvista) are imported by the functions that
need them. The command line (:mod:`gdfe.cli`) is an application layer above it.
"""

from gdfe import paper
from gdfe._version import __version__
from gdfe._validation import GdfeError
from gdfe.calibration import (DEFAULT_H, PAPER_K, READINGS, TABLE1, Calibration, CalibrationFit, FoldingTests,
                              angle_from_ratio, fit_reading, load_folding_tests, ratio_from_angle)
from gdfe.design import Design, Material, from_masks, from_rows, grid_design, hinge, load_design
from gdfe.measure import curvature_profile, fold_angle, rigid_align, shape_distance
from gdfe.mesh import HexMesh, sheet_mesh
from gdfe.model import DeformationModel, load_model, paper_model
from gdfe.solver import (ConvergenceError, Penetration, Result, Solver, check_penetration, energy, rest_shapes,
                         simulate, system_matrix)
from gdfe import fabrication  # noqa: E402,F401  its readers of drawings and packages register with load_design


__all__ = [
    "paper", "GdfeError",
    "DEFAULT_H", "PAPER_K", "READINGS", "TABLE1", "Calibration", "CalibrationFit", "FoldingTests",
    "angle_from_ratio", "fit_reading", "load_folding_tests", "ratio_from_angle",
    "Design", "Material", "from_masks", "from_rows", "grid_design", "hinge", "load_design",
    "curvature_profile", "fold_angle", "rigid_align", "shape_distance",
    "HexMesh", "sheet_mesh",
    "DeformationModel", "load_model", "paper_model",
    "ConvergenceError", "Result", "Solver", "energy", "rest_shapes", "simulate", "system_matrix",
    "Penetration", "check_penetration",
    "__version__",
]
