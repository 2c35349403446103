"""One-dimensional inverse design (paper Sec. 4.2-4.3): couples, patterns, strips, curves, segmentation.

A planar curve is a chain of *couples* ``(L_i, r_i)``, circular arcs joined tangentially
(:mod:`gdfe.inverse.couples`); a couple turning by ``alpha`` needs the contracting length
``L_c = |alpha| h / (1 - R)`` (Eq. 2), printed as contracting cells spread over a straight strip
(:mod:`gdfe.inverse.patterns`). The strip is simulated and its mid-line read off
(:mod:`gdfe.inverse.strips`), and compared with the target curve after the best rigid motion of
the plane (:mod:`gdfe.inverse.curves`). A freeform sketch is first split into couples and sharp
turns by an exact segmentation of its tangent-angle graph (:mod:`gdfe.inverse.segmentation`).
The letters of Figure 9 are chains of couples (:mod:`gdfe.inverse.letters`); the whole
pipeline, target -> plan -> simulated check -> deviation per segment, is
:mod:`gdfe.inverse.pipeline` and :mod:`gdfe.inverse.deviation`, and the files it reads
(couples TOML, sketch CSV or SVG path) :mod:`gdfe.inverse.sources`.

All lengths in millimetres, angles in radians.
"""

from gdfe.inverse.couples import Couple, arc_points, as_couples, check_open_ratio, contracting_length, max_curvature
from gdfe.inverse.curves import align_2d, closest_on_polyline, compare_curves
from gdfe.inverse.deviation import Deviation, plot_deviation, strip_deviation
from gdfe.inverse.letters import LETTERS, Glyph, glyph, text_glyphs
from gdfe.inverse.patterns import ROUNDINGS, StripPattern, strip_pattern, with_hinges
from gdfe.inverse.pipeline import (TOLERANCE_FRACTION, StripCheck, StripPlan, TargetCurve, check_strip,
                                   midline_compensated, plan_strip, target_from_couples, target_from_letter,
                                   target_from_sketch)
from gdfe.inverse.segmentation import (Segmentation, SketchFit, fit_segments, fit_sketch, segment_cost_matrix,
                                       tangent_graph)
from gdfe.inverse.sources import CouplesFile, read_couples_toml, read_sketch, read_sketch_csv
from gdfe.inverse.strips import bent_start, simulate_strip, strip_midline

__all__ = [
    "Couple", "as_couples", "check_open_ratio", "contracting_length", "max_curvature",
    "arc_points", "StripPattern", "strip_pattern", "with_hinges", "ROUNDINGS",
    "bent_start", "simulate_strip", "strip_midline", "align_2d", "closest_on_polyline", "compare_curves",
    "tangent_graph", "Segmentation", "segment_cost_matrix", "fit_segments", "SketchFit", "fit_sketch",
    "Glyph", "LETTERS", "glyph", "text_glyphs",
    "TargetCurve", "target_from_couples", "target_from_letter", "target_from_sketch", "midline_compensated",
    "StripPlan", "plan_strip", "StripCheck", "check_strip", "TOLERANCE_FRACTION",
    "Deviation", "strip_deviation", "plot_deviation",
    "CouplesFile", "read_couples_toml", "read_sketch", "read_sketch_csv",
]
