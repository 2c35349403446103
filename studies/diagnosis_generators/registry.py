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
from studies.diagnosis_generators import artefacts, columns, fem, heating, kinetics, lag, outside
from studies.diagnosis_generators.nominal import BATCHES, DESIGN_SETS, eq3, gdfe_folds

__all__ = ["Generator", "GENERATORS", "SENSITIVITY", "KINDS", "NAMING_KINDS", "generate", "measure"]

#: Classes of data sets: no effect (the nominal world, or another valid physics); an effect of the
#: catalogue; an effect outside it; the oven temperature's (the process, its column declared); a
#: measurement artefact; an effect carried by a numeric column nobody declared; an effect of the
#: coat thickness alone at one film thickness; an effect of the catalogue beside irrelevant columns.
KINDS = ("null", "catalogue", "outside", "process", "artefact", "column", "d_only", "red_herring")
#: Classes scored by naming the effect built in (the others by the verdict).
NAMING_KINDS = ("catalogue", "process", "red_herring")
#: Verdicts that credit nothing with the whole gap.
NOT_EXPLAINED = ("no_gap", "not_explained", "partly_explained")


@dataclasses.dataclass(frozen=True)
class Generator:
    """One way of making "measured" folding tests.

    Attributes
    ----------
    name : str
    kind : one of :data:`KINDS`
    answers : tuple of str
        What the package's rule counts right: a named model (catalogue effects) or the verdict.
    forward : str
        The forward model, in words.
    ranges : dict of str -> (lo, hi)
        Where the strengths are drawn from.
    draw : callable
        ``draw(rng, specimens) -> dict`` of strengths.
    make : callable
        ``make(specimens, strengths, resolution) -> (alpha (n,), converged (n,))``;
        ``resolution`` is ``{"gdfe": ..., "fem": ...}``.
    physics : tuple of str, optional
        The physical causes that are right to credit (model terms such as ``"cure_depth"`` or
        ``"partial_activation[T_C]"``); default: the terms of the model names in ``answers``.
        Crediting any other physical cause is wrong by the strict rule
        (:func:`studies.blind_diagnosis.wrong_physics_credited`).
    designs : tuple of str
        Design sets it is run on (:data:`.nominal.DESIGNS`).
    columns : tuple of str
        Strengths that are per-test columns of the data (recorded beside ``T_C`` and ``batch``).
    herrings : tuple of str
        Columns that have nothing to do with the folds: naming a model of one is wrong.
    scatter : str, optional
        The strength that scales a noise growing with the angle (:func:`measure`).
    flags : bool
        Whether the artefact found by the diagnosis (rows flagged as outliers or failed, noise
        growing with the angle) counts right.
    """

    name: str
    kind: str
    answers: tuple
    forward: str
    ranges: dict
    draw: Callable
    make: Callable
    physics: tuple = None
    designs: tuple = DESIGN_SETS
    columns: tuple = ()
    herrings: tuple = ()
    scatter: str = None
    flags: bool = False

    def right_physics(self):
        """The physical causes (model terms) that are right to credit."""
        if self.physics is not None:
            return tuple(self.physics)
        return tuple(dict.fromkeys(t for a in self.answers if a not in NOT_EXPLAINED + ("explained",)
                                   for t in a.split("+")))


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


def _stiff(sp, s, res):
    """The linear FEM's elastic bilayer with a stiff coat, its uniform film contraction scaled so
    that the largest fold is the drawn one: another valid physics of the folds, not Eq. 1's."""
    a = fem.unit_folds(sp.L, sp.d, sp.h, E_ratio=s["E_ratio"], resolution=res["fem"])
    target = float(np.max(eq3(sp.K, sp.d, sp.h) * sp.L / sp.h))
    return a * (target / float(a.max())), np.ones(sp.L.size, bool)


def _rows(rng, n, k):
    return sorted(rng.choice(n, k, replace=False).tolist())


def _draw_outliers(rng, sp):
    return {"rows": _rows(rng, sp.L.size, 2), "jumps": (0.5 * rng.choice([-1.0, 1.0], 2)).tolist()}


def _draw_failed(rng, sp):
    return {"rows": _rows(rng, sp.L.size, int(rng.integers(2, 4)))}


def _with_nominal(fn):
    def make(sp, s, res):
        alpha, ok = _nominal(sp, res)
        return fn(alpha, s), ok
    return make


def _draw_theta(rng, sp):
    return {"ratio": _u(rng, 0.5, 0.8), "theta_deg": rng.uniform(0.0, 90.0, sp.L.size).round(1).tolist()}


def _draw_panel(rng, sp):
    return {"E_MPa": _u(rng, 3.0, 8.0), "panel_mm": rng.uniform(3.0, 10.0, sp.L.size).round(2).tolist()}


def _sagged(sp, s, res):
    alpha, ok = _nominal(sp, res)
    C = columns.sag_compliance(sp.L, sp.d, sp.h, np.asarray(s["panel_mm"]), s["E_MPa"])
    return columns.sag(alpha, C), ok


#: Operators of the red herring's text column.
OPERATORS = ("ana", "ben", "chen")


def _draw_herring(rng, sp):
    return {"delta": _u(rng, 0.05, 0.12), "humidity_pct": rng.uniform(30.0, 60.0, sp.L.size).round(1).tolist(),
            "operator": rng.choice(OPERATORS, sp.L.size).tolist()}


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
    Generator("partial_activation", "process", ("partial_activation[T_C]",),
              "GDFE hinges, the contraction reached by WLF-shifted stretched-exponential shrink kinetics "
              "at each oven temperature",
              {"T_half": (128.0, 148.0), "b": (0.5, 1.0)},
              lambda rng, sp: {"T_half": _u(rng, 128.0, 148.0), "b": _u(rng, 0.5, 1.0)}, _kinetic),
    Generator("batch", "catalogue", ("batch[batch]", "factor[batch]"),
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
    # a null of another valid physics, and the nominal world at one film thickness
    Generator("nominal_one_h", "null", ("no_gap",), "GDFE hinges, Eq. 3, every film 0.29 mm thick", {},
              lambda rng, sp: {}, lambda sp, s, res: _nominal(sp, res), designs=("one_h",)),
    Generator("stiff_coat", "null", ("no_gap", "passive_stiffness", "hinge_length", "hinge_length+passive_stiffness"),
              "linear FEM elastic bilayer with a stiff coat (E_coat / E_film 30-300), the film's contraction "
              "uniform and scaled: no gap when it is Eq. 1 within the noise, else the catalogue's elastic coat "
              "(passive_stiffness) and the FEM's fold spreading past the coat's end (hinge_length) are right",
              {"E_ratio": (30.0, 300.0)},
              lambda rng, sp: {"E_ratio": float(np.exp(rng.uniform(np.log(30.0), np.log(300.0))))}, _stiff,
              designs=("table1", "random", "one_h")),
    # measurement artefacts on the nominal folds: no physical cause is right
    Generator("reading_offset", "artefact", NOT_EXPLAINED + ("reading_offset",),
              "nominal GDFE folds read 0.15 rad too high (a constant offset)", {"offset": (0.15, 0.15)},
              lambda rng, sp: {"offset": 0.15}, _with_nominal(lambda a, s: artefacts.offset(a, s["offset"])),
              physics=(), designs=("random30", "table1")),
    Generator("outliers", "artefact", NOT_EXPLAINED,
              "nominal GDFE folds, two rows off by +-0.5 rad", {"jump": (0.5, 0.5)}, _draw_outliers,
              _with_nominal(lambda a, s: artefacts.outliers(a, s["rows"], s["jumps"])),
              physics=(), designs=("random30", "table1"), flags=True),
    Generator("growing_scatter", "artefact", NOT_EXPLAINED,
              "nominal GDFE folds read with a scatter growing with the angle (sd gain sigma alpha / mean alpha)",
              {"gain": (1.5, 3.0)}, lambda rng, sp: {"gain": _u(rng, 1.5, 3.0)},
              lambda sp, s, res: _nominal(sp, res), physics=(), designs=("random30", "table1"), scatter="gain",
              flags=True),
    Generator("failed_specimens", "artefact", NOT_EXPLAINED,
              "nominal GDFE folds, 2-3 specimens that did not fold (angle 0)", {"failed": (2, 3)}, _draw_failed,
              _with_nominal(lambda a, s: artefacts.failed(a, s["rows"])),
              physics=(), designs=("random30", "table1"), flags=True),
    # out-of-catalogue effects carried by a numeric column the diagnosis is not told about
    Generator("anisotropic_film", "column", NOT_EXPLAINED + ("factor[theta_deg]",),
              "GDFE hinges cut at theta to the film's draw direction, c(theta) = c_x cos^2 + c_y sin^2 "
              "(column theta_deg, not declared)", {"ratio": (0.5, 0.8), "theta_deg": (0.0, 90.0)},
              _draw_theta, lambda sp, s, res: columns.anisotropic(sp, s["theta_deg"], s["ratio"], res["gdfe"]),
              physics=(), columns=("theta_deg",)),
    Generator("panel_sag", "column", NOT_EXPLAINED + ("factor[panel_mm]",),
              "GDFE hinges bent back by their panel's weight, the sag growing as the panel length squared "
              "(column panel_mm, not declared)", {"E_MPa": (3.0, 8.0), "panel_mm": (3.0, 10.0)},
              _draw_panel, _sagged, physics=(), columns=("panel_mm",)),
    # a heating lag that depends on the coat alone, at one film thickness
    Generator("heating_lag", "d_only", NOT_EXPLAINED,
              "GDFE hinges whose film under a coat d reaches 1 - exp(-t / tau), tau = d^2 / D, of its shrink; "
              "one film thickness", {"D": (0.0015, 0.004)}, lambda rng, sp: {"D": _u(rng, 0.0015, 0.004)},
              lambda sp, s, res: lag.lagged_folds(sp, s["D"], res["gdfe"]), physics=(),
              designs=("one_h", "table1")),
    # a real effect beside irrelevant columns
    Generator("cure_depth_herring", "red_herring", ("cure_depth",),
              "as cure_depth (delta 0.05-0.12 mm), with a random humidity column and a random operator column",
              {"delta": (0.05, 0.12), "humidity_pct": (30.0, 60.0)}, _draw_herring,
              lambda sp, s, res: _fem_ratio(sp, res, d=sp.d + s["delta"]),
              columns=("humidity_pct", "operator"), herrings=("humidity_pct", "operator")),
)}


def generate(name, specimens, strengths, resolution):
    """Noise-free folds [rad] and convergence of a data set made by generator ``name`` (of
    :data:`GENERATORS` or :data:`SENSITIVITY`)."""
    table = {**GENERATORS, **SENSITIVITY}
    check_choice("generator", name, table)
    alpha, ok = table[name].make(specimens, strengths, resolution)
    return np.asarray(alpha, float), np.asarray(ok, bool)


def measure(name, clean, strengths, sigma, rng):
    """The measured angles [rad] of noise-free ``clean`` ones: Gaussian noise of standard
    deviation ``sigma``, or for a generator with a growing scatter, noise that grows with the
    angle (:func:`.artefacts.growing_scatter`); read as magnitudes (a specimen that stayed flat
    reads a small positive angle)."""
    g = {**GENERATORS, **SENSITIVITY}[name]
    if g.scatter is not None:
        return np.abs(artefacts.growing_scatter(clean, sigma, strengths[g.scatter], rng))
    return np.abs(np.asarray(clean, float) + sigma * rng.standard_normal(np.size(clean)))
