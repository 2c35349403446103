"""Studies: one script per paper figure, the comparisons, the benchmark and the HTML report.

``STUDIES`` is the registry (name -> module). Every study module has
``run(resolution, out) -> dict`` and writes a PNG and a JSON into ``out``; each is also
run as ``python -m MODULE`` and as ``gdfe study NAME``. ``gdfe report`` runs them all
(:mod:`studies.validation_report`). Studies sit above the library (``gdfe``) and beside the
reference FEM, which they may use; the library never imports them.
"""

from __future__ import annotations

import importlib

from studies._common import RESOLUTIONS

__all__ = ["STUDIES", "RESOLUTIONS", "load"]

#: Every study, in the order of the report.
STUDIES = {
    "fig02": "studies.fig02_calibration",
    "fig06": "studies.fig06_angle_validation",
    "refinement": "studies.hinge_refinement",
    "fig07": "studies.fig07_crease_fold",
    "fig08": "studies.fig08_freeform",
    "fig09": "studies.fig09_letters",
    "fig10": "studies.fig10_segmentation",
    "fig11": "studies.fig11_design_validation",
    "compare": "studies.compare_models",
    "blind-diagnosis": "studies.blind_diagnosis",
    "transfer": "studies.transfer",
    "bench-scaling": "studies.bench_scaling",
    "hinge-error": "studies.hinge_error",
    "stopping": "studies.stopping",
    "contact": "studies.contact",
    "inverse2d": "studies.inverse2d",
    "compare-shapes": "studies.compare_shapes",
    "blind-shape-diagnosis": "studies.blind_shape_diagnosis",
    "uncertainty": "studies.uncertainty",
    "plan": "studies.plan",
}


def load(name):
    """Import a study module by its registry name."""
    from gdfe._validation import check_choice

    check_choice("study", name, STUDIES)
    return importlib.import_module(STUDIES[name])
