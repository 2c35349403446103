"""Generators of scanned parts for the blind benchmark of the shape diagnosis.

Each generator builds one effect (or none) into the "real part", the plate FEM of
:mod:`reference_fem` meshed from a small design (:mod:`.designs`), and scans the solved part
(:mod:`.scan`: the film's faces, a random rigid motion, Gaussian noise of a stated size). The
code is kept apart from the diagnosis: no module here imports :mod:`gdfe.diagnosis`
(``tests/test_blind_shape_diagnosis.py`` checks the imports), and none uses GDFE's model of an
effect. What they use:

* the **design** handed to the diagnosis (:mod:`.designs`), with the contraction ratio a
  designer calibrates on the FEM's own folding test of a hinge (:mod:`.calibration`);
* the **parts** (:mod:`.parts`): a thicker or stiffer coat on one hinge, an anisotropic film,
  a coat printed off its mask, a film whose shrink varies along the part;
* the **answers** declared per generator (:mod:`.registry`), including "cannot say" for the
  effect the diagnosis has no form for (the shrink varying along the part).

Lengths in mm.
"""

from studies.shape_generators.designs import DESIGNS, PlateDesign, plate_design
from studies.shape_generators.registry import GENERATORS, KINDS, ShapeGenerator, Sample, bending_change, generate
from studies.shape_generators.scan import NOISE_MM, Scan, scan_part

__all__ = ["DESIGNS", "PlateDesign", "plate_design", "GENERATORS", "KINDS", "ShapeGenerator", "Sample",
           "bending_change", "generate", "NOISE_MM", "Scan", "scan_part"]
