"""Two-dimensional inverse design: from a target surface to the masks that fold into it.

The paper designs strips (1-D, :mod:`gdfe.inverse`) and names 2-D-to-3-D design as future
work. Here a target surface (:mod:`~gdfe.inverse2d.targets`: a dome, saddle, cylinder or
twisted strip, or a triangle mesh) is placed on the film through conformal coordinates, a
continuous coating fraction per cell and face is optimised by L-BFGS-B with the gradient
through the GDFE equilibrium (:mod:`~gdfe.inverse2d.adjoint`), halftoned into printer masks
that respect ``w_min`` (:mod:`~gdfe.inverse2d.masks`), and both the relaxed and the printed
design are folded from the flat print and measured against the target after rigid alignment
(:mod:`~gdfe.inverse2d.distance`). :func:`design_surface` runs it all
(:mod:`~gdfe.inverse2d.design`); :mod:`~gdfe.inverse2d.report` writes the masks, a design
file, the JSON and the figure.

Lengths in mm, angles in rad.
"""

from gdfe.inverse2d.adjoint import Fold, contraction_gradient, exact_hessian, fold, rest_derivative, rigid_gauge
from gdfe.inverse2d.design import (DEFAULT_ITERATIONS, Objective, Reachability, SurfaceDesign, closest_reachable,
                                   design_surface, initial_coating, natural_curvature, reachable_sizes, scale_for,
                                   target_start)
from gdfe.inverse2d.distance import Distance, TriangleSurface, patch, surface_distance
from gdfe.inverse2d.film import Film, MidSurface
from gdfe.inverse2d.masks import (PROJECTIONS, block_size, density_filter, halftone, min_feature_ok, nested_halftone,
                                  project, threshold)
from gdfe.inverse2d.report import DesignFiles, plot_design, read_back, write_design
from gdfe.inverse2d.targets import (ANALYTIC, MESH_SUFFIXES, Target, conformal_flattening, cylinder, dome,
                                    load_target, make_target, mesh_target, read_triangle_mesh, saddle, twist)

__all__ = [
    "Fold", "fold", "exact_hessian", "rigid_gauge", "rest_derivative", "contraction_gradient",
    "Reachability", "SurfaceDesign", "scale_for", "closest_reachable", "reachable_sizes", "natural_curvature",
    "initial_coating",
    "target_start", "Objective", "design_surface", "DEFAULT_ITERATIONS",
    "Distance", "TriangleSurface", "patch", "surface_distance",
    "Film", "MidSurface",
    "PROJECTIONS", "block_size", "density_filter", "halftone", "nested_halftone", "threshold", "project",
    "min_feature_ok", "DesignFiles", "write_design", "plot_design", "read_back",
    "ANALYTIC", "MESH_SUFFIXES", "Target", "dome", "saddle", "cylinder", "twist", "make_target", "load_target",
    "mesh_target", "read_triangle_mesh", "conformal_flattening",
]
