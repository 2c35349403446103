"""One-dimensional inverse design (paper Sec. 4.2-4.3): couples, patterns, strips, curves, segmentation.

A planar curve is a chain of *couples* ``(L_i, r_i)``, circular arcs joined tangentially
(:mod:`gdfe.inverse.couples`); a couple turning by ``alpha`` needs the contracting length
``L_c = |alpha| h / (1 - R)`` (Eq. 2), printed as contracting cells spread over a straight strip
(:mod:`gdfe.inverse.patterns`). The strip is simulated and its mid-line read off
(:mod:`gdfe.inverse.strips`), and compared with the target curve after the best rigid motion of
the plane (:mod:`gdfe.inverse.curves`). A freeform sketch is first split into couples and sharp
turns by an exact segmentation of its tangent-angle graph (:mod:`gdfe.inverse.segmentation`).

All lengths in millimetres, angles in radians.
"""

from gdfe.inverse.couples import Couple, arc_points, as_couples, check_open_ratio, contracting_length, max_curvature
from gdfe.inverse.curves import align_2d, closest_on_polyline, compare_curves
from gdfe.inverse.patterns import ROUNDINGS, StripPattern, strip_pattern, with_hinges
from gdfe.inverse.segmentation import (Segmentation, SketchFit, fit_segments, fit_sketch, segment_cost_matrix,
                                       tangent_graph)
from gdfe.inverse.strips import bent_start, simulate_strip, strip_midline

__all__ = [
    "Couple", "as_couples", "check_open_ratio", "contracting_length", "max_curvature",
    "arc_points", "StripPattern", "strip_pattern", "with_hinges", "ROUNDINGS",
    "bent_start", "simulate_strip", "strip_midline", "align_2d", "closest_on_polyline", "compare_curves",
    "tangent_graph", "Segmentation", "segment_cost_matrix", "fit_segments", "SketchFit", "fit_sketch",
]
