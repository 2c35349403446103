"""The nominal world: GDFE hinge specimens contracting by the paper's principle.

A data set is 18 specimens ``(L, d, h)`` [mm] -- Table 1's, or random ones (also at one film
thickness, ``"one_h"``, or 30 of them, ``"random30"``) -- with the columns a
lab would record beside them: the oven temperature ``T_C`` of each test and the print ``batch``
(three batches of six). Without an effect, the fold of a specimen is the GDFE simulation of
:func:`gdfe.hinge` (a narrow strip, 16/24/32 cells across the hinge at coarse/default/fine
resolution) with its free face contracting by Eq. 3, ``1 - R = K (h / d)^1.5``, at a scale ``K``
drawn so that the largest fold of the data set lies in :data:`MAX_FOLD`.

Lengths in mm, angles in radians, temperatures in degrees C.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gdfe import paper
from gdfe._validation import GdfeError, check_choice

__all__ = ["Specimens", "specimens", "eq3", "gdfe_fold", "gdfe_folds", "CELLS", "MAX_FOLD", "T_RANGE",
           "DESIGN_SETS", "DESIGNS", "N_RANDOM", "BATCHES", "ONE_H"]

#: Cells across the hinge per resolution.
CELLS = {"coarse": 16, "default": 24, "fine": 32}
#: Largest fold of a data set without its effect [rad] (Table 1's largest is 2.88 rad).
MAX_FOLD = (2.5, 3.0)
#: Oven temperatures recorded with the tests [degrees C].
T_RANGE = (120.0, 160.0)
#: Design sets every generator is run on (unless it names its own).
DESIGN_SETS = ("table1", "random")
#: Every design set: besides those, 18 random specimens at one film thickness and 30 random ones.
DESIGNS = ("table1", "random", "one_h", "random30")
N_RANDOM = 18
#: Film thickness of the ``"one_h"`` design set [mm] (Table 1's).
ONE_H = paper.H
#: Print batches recorded with the tests.
BATCHES = ("b1", "b2", "b3")
#: Largest cell [mm] and the strip's width [mm] (narrow: the fold does not depend on it).
MAX_CELL, NARROW = 0.36, 0.5


@dataclasses.dataclass(frozen=True)
class Specimens:
    """A data set's specimens and their recorded columns.

    Attributes
    ----------
    L, d, h : (n,) float arrays [mm]
    T_C : (n,) float array [degrees C]
        Oven temperature of each test.
    batch : (n,) str array
        Print batch of each test.
    K : float
        Scale of the nominal contraction (Eq. 3).
    design : str
        ``"table1"`` or ``"random"``.
    """

    L: np.ndarray
    d: np.ndarray
    h: np.ndarray
    T_C: np.ndarray
    batch: np.ndarray
    K: float
    design: str

    def __len__(self):
        return int(self.L.size)


def eq3(K, d, h):
    """Eq. 3: the contraction ``1 - R`` of the free face for coat ``d`` on film ``h`` [mm]."""
    return K * (np.asarray(h, float) / np.asarray(d, float)) ** 1.5


def specimens(design, rng):
    """The specimens of a data set: Table 1's 18 (``h = 0.29 mm``) or 18 random ones (``L``
    uniform in 1.5-6 mm, ``d`` log-uniform in 0.1-0.5 mm, ``h`` uniform in 0.2-0.4 mm; at
    ``"one_h"`` every ``h`` is :data:`ONE_H`; ``"random30"``: 30 of them), with
    oven temperatures uniform in :data:`T_RANGE`, three batches of six at random, and ``K``
    giving a largest nominal fold in :data:`MAX_FOLD`."""
    import gdfe

    check_choice("design", design, DESIGNS)
    if design == "table1":
        t = gdfe.load_folding_tests(gdfe.TABLE1)
        L, d, h = t.L.copy(), t.d.copy(), t.h.copy()
    else:
        n = 30 if design == "random30" else N_RANDOM
        L = rng.uniform(1.5, 6.0, n)
        d = np.exp(rng.uniform(np.log(0.1), np.log(0.5), n))
        h = np.full(n, ONE_H) if design == "one_h" else rng.uniform(0.2, 0.4, n)
    n = L.size
    T = rng.uniform(*T_RANGE, n)
    batch = np.array(BATCHES)[rng.permutation(np.arange(n) % len(BATCHES))]
    target = rng.uniform(*MAX_FOLD)
    K = target / float(np.max(eq3(1.0, d, h) * L / h))
    return Specimens(L=L, d=d, h=h, T_C=T, batch=batch, K=float(K), design=design)


def _hinge(L, R, h, resolution):
    import gdfe

    cell = min(L / CELLS[resolution], MAX_CELL)
    return gdfe.hinge(L, R=R, h=h, cell_size=cell, panel_length=4 * cell, width=min(NARROW, 2 * cell))


def gdfe_fold(L, R, h, resolution="coarse"):
    """Fold angle [rad] and convergence of one GDFE hinge of width ``L``, film ``h`` [mm], free
    face contracting by ``R``."""
    import gdfe

    check_choice("resolution", resolution, CELLS)
    if not 0.0 < R <= 1.0:
        raise GdfeError(f"R: expected a contraction ratio in (0, 1], got {R:g}")
    res = gdfe.simulate(_hinge(L, R, h, resolution))
    return float(gdfe.fold_angle(res)), bool(res.converged)


def gdfe_folds(L, R, h, resolution="coarse"):
    """:func:`gdfe_fold` of every specimen: ``(alpha (n,), converged (n,))``."""
    out = [gdfe_fold(float(a), float(b), float(c), resolution) for a, b, c in np.broadcast(L, R, h)]
    return np.array([o[0] for o in out]), np.array([o[1] for o in out])
