"""Diagnosis: where simulations of fabricated parts miss their measurements, and why.

Fold-angle data (:func:`diagnose`): the calibrated GDFE hinge against folding tests, a
catalogue of unmodelled physical effects (process columns and groups included) fitted and
ranked on held-out tests, and a verdict against the noise: ``no_gap``, ``explained``,
``partly_explained`` or ``not_explained``.
Shapes (:func:`diagnose_shape`): a scanned part against the simulation of its design,
first checked to be that part, then localised to the design's regions and corrected region
by region.

Angles in radians, lengths in mm.
"""

from gdfe.diagnosis.align import align_icp
from gdfe.diagnosis.angles import Diagnosis, diagnose
from gdfe.diagnosis.effects import EFFECTS, Effect, Model, Param, activation_fraction, catalogue, model
from gdfe.diagnosis.fit import EffectFit, evaluate, select
from gdfe.diagnosis.verdict import VERDICTS, Noise, Verdict
from gdfe.diagnosis.forward import gdfe_check, simulate_fold, simulate_model
from gdfe.diagnosis.regions import design_regions
from gdfe.diagnosis.scan import load_measured
from gdfe.diagnosis.shape import ShapeDiagnosis, diagnose_shape
from gdfe.diagnosis.surface import Surface
from gdfe.diagnosis.where import residual_analysis

__all__ = [
    "Diagnosis", "diagnose",
    "EFFECTS", "Effect", "Model", "Param", "activation_fraction", "catalogue", "model",
    "EffectFit", "evaluate", "select", "VERDICTS", "Noise", "Verdict",
    "gdfe_check", "simulate_fold", "simulate_model",
    "ShapeDiagnosis", "Surface", "align_icp", "design_regions", "diagnose_shape", "load_measured",
    "residual_analysis",
]
