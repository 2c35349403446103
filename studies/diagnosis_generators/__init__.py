"""Generators of synthetic folding tests for the blind benchmark of the fold-angle diagnosis.

Each generator builds one physical effect (or none) into a forward model that is *not* the
diagnoser's closed form, and returns noise-free "measured" fold angles of a set of specimens.
The code is kept apart from the diagnoser: no module here imports :mod:`gdfe.diagnosis`
(its catalogue, closed forms or fits; ``tests/test_diagnosis_blind.py`` checks the imports).
What the generators use:

* the **nominal world** (:mod:`.nominal`): GDFE hinge specimens (:func:`gdfe.hinge`,
  :func:`gdfe.simulate`) whose free face contracts by the paper's principle, Eq. 3, at a
  scale ``K`` drawn per data set;
* the **reference FEM** (:mod:`reference_fem`, :mod:`.fem`): the 3-D elastic bilayer with the
  effect in its geometry or material (a thicker coat, a wider hinge, an elastic coat, a film
  that thickens as it shrinks);
* **process physics** of its own: shrink kinetics of the polystyrene film (:mod:`.kinetics`,
  WLF time-temperature shift with a stretched-exponential relaxation), directional heating of
  the free face (:mod:`.heating`);
* **out-of-catalogue** effects (:mod:`.outside`): physically plausible effects the catalogue
  lacks;
* **measurement artefacts** (:mod:`.artefacts`): a reading offset, outliers, scatter growing
  with the angle, specimens that did not fold;
* effects carried by a **column** nobody declared (:mod:`.columns`): the film's anisotropic
  shrink with the hinge's angle to the draw direction, the panel's sag with its length;
* a **heating lag** of the coat alone (:mod:`.lag`).

:data:`GENERATORS` lists them by name with their class (:data:`KINDS`), what the package's rule
counts right and the physical causes that are right to credit.
Lengths in mm, angles in radians, temperatures in degrees C.
"""

from studies.diagnosis_generators.registry import (GENERATORS, KINDS, NAMING_KINDS, SENSITIVITY, Generator,
                                                    generate, measure)

__all__ = ["GENERATORS", "SENSITIVITY", "KINDS", "NAMING_KINDS", "Generator", "generate", "measure"]
