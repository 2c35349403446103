"""Starting shapes of the first frame besides the linearised start: the flat and the multilevel start.

The linearised start (:mod:`gdfe.solver.linearised`) serves most designs. Large sheets
start from the solution of the design coarsened 2 x 2 in the plane
(:func:`multilevel_start`, with :func:`gdfe.multilevel.coarsen`), which finds the
large-scale shape at a quarter of the cost; :func:`flat_start` perturbs the flat print.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np

from gdfe.multilevel import coarsen
from gdfe.solver.methods import Solver, auto_method

__all__ = ["MULTILEVEL_COARSEST", "MULTILEVEL_TOL", "MULTILEVEL_ITER", "StartLevel", "flat_start", "multilevel_start"]

log = logging.getLogger(__name__)

#: ``init="multilevel"`` coarsens until a level has at most this many cells.
MULTILEVEL_COARSEST = 2_000
#: Tolerance of the coarse levels of ``init="multilevel"`` (their shape is only a start).
MULTILEVEL_TOL = 1e-3
#: Iteration limit of each coarse level of ``init="multilevel"``: on the 10^6-cell corrugation
#: the 3 969- and 62 500-cell levels ran 50 iterations without converging (buckled states a
#: fine level does not share), minutes for a start.
MULTILEVEL_ITER = 20


@dataclasses.dataclass(frozen=True)
class StartLevel:
    """One level of a multilevel start (:func:`multilevel_start`, :attr:`gdfe.Result.start_levels`).

    Attributes
    ----------
    cells : int
        The level's cells.
    method : str
        The method that solved it.
    iterations : int
        Its solve's iterations (at most :data:`MULTILEVEL_ITER`).
    cg_iterations : int
        Its CG iterations (0 where its Newton steps are factorised).
    residual_h : float
        Its plain step's residual at the end (units of h; the level asks :data:`MULTILEVEL_TOL`).
    converged : bool
        Whether it met :data:`MULTILEVEL_TOL`; a level that stops at its limit or where it
        drifts (``drifted``) is still the next level's start.
    drifted : bool
        Whether it stopped where it drifted between near-equal states.
    energy : float
        Its energy at the end [mm^5] (a coarse level's, not comparable with the design's).
    seconds : float
        The wall time of its solve, its own set-up included (not the levels below it).
    newton_steps : list of gdfe.solver.newton.NewtonStep
        Its Newton steps (empty for an alternation).
    """

    cells: int
    method: str
    iterations: int
    cg_iterations: int
    residual_h: float
    converged: bool
    drifted: bool
    energy: float
    seconds: float
    newton_steps: list = dataclasses.field(default_factory=list)

    def as_dict(self, steps=True):
        """The record as a dict of plain Python values (for JSON); without its steps unless ``steps``."""
        out = dataclasses.asdict(self)  # the steps as dicts too
        if not steps:
            del out["newton_steps"]
        return out


def flat_start(design, seed=0):
    """The flat print with a seeded perturbation of 1e-4 h out of plane, ``(n, 3)`` [mm].

    The flat print itself is a fixed point of the alternation, so it must be perturbed
    to bend at all.
    """
    V = design.mesh.points.copy()
    rng = np.random.default_rng(seed)
    return V + np.column_stack([np.zeros((len(V), 2)), 1e-4 * design.h * rng.standard_normal(len(V))])


def multilevel_start(design, activation, record=None):
    """Start ``(n, 3)`` [mm] for ``design``: the solved shape of its 2 x 2 coarsening, interpolated.

    Recursively down to :data:`MULTILEVEL_COARSEST` cells, whose level starts from the
    linearised start; every coarse level is solved by :func:`auto_method`'s method to
    :data:`MULTILEVEL_TOL` (at most :data:`MULTILEVEL_ITER` iterations), and stops where it drifts between
    near-equal states (``on_drift="stop"``): its shape is only the next level's start.
    ``record``, a list, is given a :class:`StartLevel` for every level, the coarsest first.
    """
    coarse, prolong = coarsen(design)
    log.debug("multilevel: %d cells coarsened to %d", design.n_cells, coarse.n_cells,
              extra={"progress": {"event": "coarsened", "cells": coarse.n_cells}})
    if coarse.n_cells > MULTILEVEL_COARSEST:
        V = multilevel_start(coarse, activation, record)
        t0 = time.perf_counter()
        solver = Solver(coarse)
    else:
        t0 = time.perf_counter()
        solver = Solver(coarse)
        V = solver.linearised_start(coarse.mesh.points.copy(), activation)
    method = auto_method(coarse)
    stats = solver.solve(V, activation, method=method, tol=MULTILEVEL_TOL, max_iter=MULTILEVEL_ITER,
                         on_drift="stop")
    solver.drop_caches()  # the level's Hessian and multigrid refer back to the solver: not left to the cyclic collector
    if record is not None:
        record.append(StartLevel(cells=coarse.n_cells, method=method, iterations=stats.iterations,
                                 cg_iterations=stats.cg_iterations, residual_h=float(stats.residual),
                                 converged=bool(stats.converged), drifted=stats.drift is not None,
                                 energy=float(stats.energies[-1]), seconds=time.perf_counter() - t0,
                                 newton_steps=list(stats.newton_steps)))
    log.debug("multilevel: %d cells, %d iterations, residual %.2e", coarse.n_cells, stats.iterations,
              stats.residual, extra={"progress": {"event": "level", "cells": coarse.n_cells}})
    return prolong @ stats.points
