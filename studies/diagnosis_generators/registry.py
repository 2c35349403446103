"""The generators of the blind benchmark, their classes, strengths and answers.

Strengths are drawn from ranges fixed beforehand from the physics (:data:`GENERATORS`'
``ranges``), never from what the diagnoser can see. Lengths in mm, angles in radians,
temperatures in degrees C.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from gdfe._validation import check_choice
from studies.diagnosis_generators import fem, heating, kinetics, outside
from studies.diagnosis_generators.nominal import BATCHES, eq3, gdfe_folds

__all__ = ["Generator", "GENERATORS", "SENSITIVITY", "KINDS", "generate"]

#: Classes of data sets: no effect, an effect of the catalogue, an effect outside it.
KINDS = ("null", "catalogue", "outside")


@dataclasses.dataclass(frozen=True)
class Generator:
    """One way of making "measured" folding tests.

    Attributes
    ----------
    name : str
    kind : {"null", "catalogue", "outside"}
    answers : tuple of str
        The diagnoser's ``best`` counted right (catalogue effects; the verdict for the others).
    forward : str
        The forward model, in words.
    ranges : dict of str -> (lo, hi)
        Where the strengths are drawn from.
    draw : callable
        ``draw(rng, specimens) -> dict`` of strengths.
    make : callable
        ``make(specimens, strengths, resolution) -> (alpha (n,), converged (n,))``;
        ``resolution`` is ``{"gdfe": ..., "fem": ...}``.
    """

    name: str
    kind: str
    answers: tuple
    forward: str
    ranges: dict
    draw: Callable
    make: Callable


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _nominal(sp, res):
    return gdfe_folds(sp.L, 1.0 - eq3(sp.K, sp.d, sp.h), sp.h, res["gdfe"])


def _fem_ratio(sp, res, L=None, d=None, E_ratio=None):
    """Nominal GDFE folds times the FEM's fold of the changed specimen over the nominal one's."""
    alpha, ok = _nominal(sp, res)
    a0 = fem.unit_folds(sp.L, sp.d, sp.h, E_ratio=E_ratio, resolution=res["fem"])
    a1 = fem.unit_folds(sp.L if L is None else L, sp.d if d is None else d, sp.h, E_ratio=E_ratio,
                        resolution=res["fem"])
    return alpha * a1 / a0, ok


def _calibrated():
    from reference_fem import CALIBRATED_E_RATIO

    return CALIBRATED_E_RATIO


def _draw_lambda(rng, sp):
    v = _u(rng, 0.3, 1.0)
    return {"lambda": v if rng.random() < 0.5 else -min(v, 0.5 * float(sp.L.min()))}


def _passive(sp, s, res):
    a = fem.unit_folds(sp.L, sp.d, sp.h, E_ratio=s["E_ratio"], resolution=res["fem"])
    target = float(np.max(eq3(sp.K, sp.d, sp.h) * sp.L / sp.h))  # the drawn largest fold
    return a * (target / float(a.max())), np.ones(sp.L.size, bool)


def _thickening(sp, s, res):
    alpha, ok = _nominal(sp, res)
    # the film's mean in-plane contraction: half the free face's (it falls to 0 at the coat)
    ratio, ok2 = fem.thickening_ratio(sp.L, sp.d, sp.h, 0.5 * eq3(sp.K, sp.d, sp.h), s["beta"], res["fem"])
    return alpha * ratio, ok & ok2


def _heated(sp, s, res):
    out = [heating.heated_fold(float(L), float(c), float(h), s["w"], res["gdfe"])
           for L, c, h in zip(sp.L, eq3(sp.K, sp.d, sp.h), sp.h)]
    return np.array([o[0] for o in out]), np.array([o[1] for o in out])


def _kinetic(sp, s, res):
    f = kinetics.fraction(sp.T_C, s["T_half"], s["b"])
    return gdfe_folds(sp.L, 1.0 - f * eq3(sp.K, sp.d, sp.h), sp.h, res["gdfe"])


def _draw_lots(rng, sp):
    u = rng.uniform(0.08, 0.2, 2) * rng.choice([-1.0, 1.0], 2)
    v = rng.uniform(-0.07, 0.07, len(BATCHES))
    return {"prestrain": [1.0, *(1.0 + u).tolist()], "thickness": (1.0 + v).tolist()}


def _lots(sp, s, res):
    """Each print batch on its own film lot: its pre-strain scales the contraction, its film is
    thicker or thinner than the nominal h the table records."""
    g = np.array([BATCHES.index(b) for b in sp.batch])
    h = sp.h * np.asarray(s["thickness"])[g]
    c = np.asarray(s["prestrain"])[g] * eq3(sp.K, sp.d, h)
    return gdfe_folds(sp.L, 1.0 - c, h, res["gdfe"])


def _draw_hidden(rng, sp):
    return {"u": _u(rng, 0.08, 0.2), "lot": rng.integers(0, 2, sp.L.size).tolist()}


def _cap(sp, s, res):
    alpha, ok = _nominal(sp, res)
    return outside.hard_cap(alpha, s["fraction"] * float(alpha.max())), ok


#: Generators reported beside the classes, not counted in them: the same effect with another
#: assumption, to show how much the answer rests on it.
SENSITIVITY = {g.name: g for g in (
    Generator("cure_depth_soft_coat", "catalogue", ("cure_depth",),
              "as cure_depth, the coat only as stiff against the film as the linear FEM's fit to Table 1 "
              "(reference_fem.CALIBRATED_E_RATIO) instead of fem.STIFF_COAT", {"delta": (0.03, 0.15)},
              lambda rng, sp: {"delta": _u(rng, 0.03, 0.15)},
              lambda sp, s, res: _fem_ratio(sp, res, d=sp.d + s["delta"], E_ratio=_calibrated())),
)}

GENERATORS = {g.name: g for g in (
    Generator("nominal", "null", ("no_gap",), "GDFE hinges, Eq. 3", {},
              lambda rng, sp: {}, lambda sp, s, res: _nominal(sp, res)),
    Generator("cure_depth", "catalogue", ("cure_depth",),
              "nominal GDFE x linear FEM with the coat d + delta over the nominal FEM",
              {"delta": (0.03, 0.15)}, lambda rng, sp: {"delta": _u(rng, 0.03, 0.15)},
              lambda sp, s, res: _fem_ratio(sp, res, d=sp.d + s["delta"])),
    Generator("hinge_length", "catalogue", ("hinge_length",),
              "nominal GDFE x linear FEM with the hinge L + lambda over the nominal FEM",
              {"lambda": (0.3, 1.0)}, _draw_lambda,
              lambda sp, s, res: _fem_ratio(sp, res, L=sp.L + s["lambda"])),
    Generator("passive_stiffness", "catalogue", ("passive_stiffness", "hinge_length+passive_stiffness"),
              "linear FEM with an elastic coat (E_coat / E_film), the film's contraction scaled",
              {"E_ratio": (0.3, 10.0)},
              lambda rng, sp: {"E_ratio": float(np.exp(rng.uniform(np.log(0.3), np.log(10.0))))}, _passive),
    Generator("film_thickening", "catalogue", ("film_thickening",),
              "nominal GDFE x nonlinear FEM whose film thickens through its thickness as it shrinks",
              {"beta": (1.0, 3.0)}, lambda rng, sp: {"beta": _u(rng, 1.0, 3.0)}, _thickening),
    Generator("saturation", "catalogue", ("saturation",),
              "GDFE hinges heated from above, each cell's contraction growing with the heat its face takes",
              {"w": (0.6, 1.0)}, lambda rng, sp: {"w": _u(rng, 0.6, 1.0)}, _heated),
    Generator("partial_activation", "catalogue", ("partial_activation[T_C]",),
              "GDFE hinges, the contraction reached by WLF-shifted stretched-exponential shrink kinetics "
              "at each oven temperature",
              {"T_half": (128.0, 148.0), "b": (0.5, 1.0)},
              lambda rng, sp: {"T_half": _u(rng, 128.0, 148.0), "b": _u(rng, 0.5, 1.0)}, _kinetic),
    Generator("batch", "catalogue", ("batch[batch]",),
              "GDFE hinges, each print batch on its own film lot (pre-strain and thickness)",
              {"prestrain": (0.08, 0.2), "thickness": (-0.07, 0.07)}, _draw_lots, _lots),
    Generator("hard_cap", "outside", ("not_explained", "partly_explained"),
              "GDFE hinges stopped at alpha_stop by a fixture", {"fraction": (0.55, 0.85)},
              lambda rng, sp: {"fraction": _u(rng, 0.55, 0.85)}, _cap),
    Generator("coat_bleed", "outside", ("not_explained", "partly_explained"),
              "GDFE hinges narrowed by b d, resin bleeding into the gap", {"b": (1.0, 3.0)},
              lambda rng, sp: {"b": _u(rng, 1.0, 3.0)},
              lambda sp, s, res: outside.coat_bleed(sp, s["b"], res["gdfe"])),
    Generator("hidden_lots", "outside", ("not_explained", "partly_explained"),
              "GDFE hinges on two unrecorded film lots", {"u": (0.08, 0.2)}, _draw_hidden,
              lambda sp, s, res: outside.hidden_lots(sp, s["u"], s["lot"], res["gdfe"])),
    Generator("overheating", "outside", ("not_explained", "partly_explained"),
              "GDFE hinges activated by the kinetics and relaxed above T_relax",
              {"T_half": (122.0, 132.0), "T_relax": (140.0, 150.0), "width": (8.0, 15.0)},
              lambda rng, sp: {"T_half": _u(rng, 122.0, 132.0), "b": _u(rng, 0.5, 1.0),
                               "T_relax": _u(rng, 140.0, 150.0), "width": _u(rng, 8.0, 15.0)},
              lambda sp, s, res: outside.overheating(sp, s["T_half"], s["b"], s["T_relax"], s["width"],
                                                     res["gdfe"])),
)}


def generate(name, specimens, strengths, resolution):
    """Noise-free folds [rad] and convergence of a data set made by generator ``name`` (of
    :data:`GENERATORS` or :data:`SENSITIVITY`)."""
    table = {**GENERATORS, **SENSITIVITY}
    check_choice("generator", name, table)
    alpha, ok = table[name].make(specimens, strengths, resolution)
    return np.asarray(alpha, float), np.asarray(ok, bool)
