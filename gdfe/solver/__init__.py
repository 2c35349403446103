"""The GDFE solver (paper Sec. 3.1): minimise the energy of Eq. 5 over the vertices of a design.

The energy (:mod:`gdfe.solver.energy`) is minimised by alternating two steps, as the
paper does: the **orientation step** (for fixed vertices, every cell's rotation is the
one closest to its cross-covariance; one batched polar decomposition) and the
**assembly step** (for fixed rotations, the vertices solve one sparse n x n system shared
by x, y and z, factorised once per design; one vertex is held, which fixes the
translations without changing the shape). Each step lowers the energy.

The default method (``method="auto"``) is damped Newton on the same energy with the
rotations eliminated (:mod:`gdfe.solver.newton`): ``"newton"`` factorises the 3n x 3n
Hessian, ``"newton-cg"`` solves its steps by preconditioned conjugate gradients, and
``"auto"`` picks by size (:func:`auto_method`). ``"plain"`` is the paper's alternation and
``"anderson"`` accelerates it (:mod:`gdfe.solver.alternation`). The first frame starts
from the small-rotation solution (:mod:`gdfe.solver.linearised`), which already bends
the right way, or on large sheets from a coarsened design's solution
(:mod:`gdfe.solver.starts`). Every method stops at a fixed point of the paper's
alternation, and reports the residual of its plain step.

Self-contact (``contact=`` of :func:`simulate`): a barrier on the film's boundary surface in
the Newton energy and collision-free steps (:mod:`gdfe.solver.contact`, with the IPC
Toolkit), and the penetration check every result carries
(:mod:`gdfe.solver.penetration`, NumPy and SciPy only).

Modules: :mod:`~gdfe.solver.linalg` (sparse factorisation backends),
:mod:`~gdfe.solver.energy` (the energy, rest shapes, rotations, the two steps),
:mod:`~gdfe.solver.newton`, :mod:`~gdfe.solver.alternation`,
:mod:`~gdfe.solver.linearised`, :mod:`~gdfe.solver.methods` (:class:`Solver`),
:mod:`~gdfe.solver.starts`, :mod:`~gdfe.solver.contact`, :mod:`~gdfe.solver.penetration`,
:mod:`~gdfe.solver.simulation` (:func:`simulate`).
"""

from gdfe.solver.contact import CONTACT_MODES, Contact, ContactReport, contact_available, default_dhat
from gdfe.solver.energy import D8, Assembly, Orientation, RestState, SolveStats, energy, rest_shapes, system_matrix
from gdfe.solver.linalg import FACTOR_BACKENDS, factor_backend, factorise
from gdfe.solver.linearised import DIRECT_START_CELLS
from gdfe.solver.methods import AUTO_NEWTON_CELLS, METHODS, Solver, auto_method
from gdfe.solver.newton import DRIFT_ENERGY, DRIFT_SHRINK, DRIFT_WINDOW, ENERGY_ROUNDOFF, MU_MIN, ON_DRIFT, STEP_TOL_FACTOR
from gdfe.solver.penetration import Penetration, PenetrationCheck, check_penetration
from gdfe.solver.simulation import (ALTERNATION_TOL, CONTACT_LEVELS, INITS, MULTILEVEL_CELLS, SHAPE_ACCURACY,
                                    ConvergenceError, Result, default_tol, simulate)
from gdfe.solver.starts import MULTILEVEL_COARSEST, MULTILEVEL_TOL


def face_contraction(design):
    """Contraction ``1 - R`` of the top and bottom face of every cell: :meth:`gdfe.Design.face_contraction`."""
    return design.face_contraction()


__all__ = [
    "Result", "ConvergenceError", "simulate", "rest_shapes", "system_matrix", "energy", "face_contraction",
    "Solver", "METHODS", "auto_method", "factor_backend", "factorise",
    "Orientation", "Assembly", "RestState", "SolveStats",
    "AUTO_NEWTON_CELLS", "DIRECT_START_CELLS", "MULTILEVEL_CELLS", "MULTILEVEL_COARSEST", "MULTILEVEL_TOL",
    "INITS", "FACTOR_BACKENDS", "MU_MIN", "STEP_TOL_FACTOR", "ENERGY_ROUNDOFF", "D8",
    "CONTACT_MODES", "CONTACT_LEVELS", "Contact", "ContactReport", "contact_available", "default_dhat",
    "Penetration", "PenetrationCheck", "check_penetration",
    "SHAPE_ACCURACY", "ALTERNATION_TOL", "default_tol", "ON_DRIFT", "DRIFT_WINDOW", "DRIFT_ENERGY", "DRIFT_SHRINK",
]
