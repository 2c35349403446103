"""The generators of the shape benchmark: what each builds into the part, its strengths and the
answer declared for it.

Strengths are drawn from ranges fixed beforehand from the physics, never from what the
diagnosis sees. Every answer is declared here, before any diagnosis runs:

- ``null`` (the part as designed): nothing to find, the right answer is that there is no gap;
- ``catalogue``, effects the shape diagnosis has a form for:

  - a thicker or a stiffer coat on one hinge: the form of a region whose contraction differs
    from the design's covers it; the right answer names that hinge alone and says it bends
    *less* or *more* than designed, the direction Timoshenko's bilayer gives for the change
    (:func:`bending_change`; with the FEM's coat 8.58 times stiffer and thicker than the film,
    both make the hinge bend less). Thickness and stiffness cannot be told apart by one shape:
    both count right with the same answer;
  - an anisotropic film: the right answer is the film-anisotropy form with the weaker axis
    right;
  - one face's coat printed off its mask: the right answer is the coat-offset form of that face
    along that axis, its shift of the same sign and within one pixel of the truth;

- ``outside`` (a film whose contraction varies linearly along the part, a part heated
  unevenly): no form reproduces it, though a region's contraction or the anisotropy may imitate
  part of it; right only when nothing is credited (no gap localised, "cannot tell which", or
  the scan said not to match the design), wrong when a form is credited.

Lengths in mm.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

from gdfe._validation import check_choice
from studies.shape_generators.calibration import calibrated_R
from studies.shape_generators.designs import D, H, plate_design
from studies.shape_generators.parts import offset_material, solve_part
from studies.shape_generators.scan import NOISE_MM, scan_part

__all__ = ["ShapeGenerator", "GENERATORS", "KINDS", "Sample", "generate", "solve_key", "bending_change"]

#: Classes of generators.
KINDS = ("null", "catalogue", "outside")


@dataclasses.dataclass(frozen=True)
class ShapeGenerator:
    """One way of making a "real part".

    Attributes
    ----------
    name, kind : str
    forward : str
        The effect, in words.
    ranges : dict of str -> (lo, hi)
        Where the strengths are drawn from.
    draw : callable
        ``draw(rng, design) -> dict`` of strengths (and the region, where there is one).
    make : callable
        ``make(design, R, strengths) -> reference_fem.PlateResult``.
    """

    name: str
    kind: str
    forward: str
    ranges: dict
    draw: Callable
    make: Callable

    def answer(self, strengths):
        """The declared answer: ``{"says": "no gap" | "cannot say" | "region" | "form", "region": ...,
        "bends": ..., "form": ...}``; a film anisotropy adds ``weak_axis`` (``"x"``, ``"y"``), a
        coat offset ``face``, ``axis`` and ``pixels``."""
        none = {"region": None, "bends": None, "form": None}
        if self.kind == "null":
            return {"says": "no gap", **none}
        if self.kind == "outside":
            return {"says": "cannot say", **none}
        if self.name == "anisotropic_film":
            return {"says": "form", **none, "form": "anisotropy", "weak_axis": "xy"[strengths["weak_axis"]]}
        if self.name == "coat_offset":
            return {"says": "form", **none, "form": "offset", "face": strengths["face"],
                    "axis": "xy"[strengths["axis"]], "pixels": int(strengths["pixels"])}
        change = bending_change(d_factor=strengths.get("d_factor", 1.0), E_factor=strengths.get("E_factor", 1.0))
        return {"says": "region", "region": strengths["region"], "bends": "less" if change < 1.0 else "more",
                "form": "region"}


def bending_change(d_factor=1.0, E_factor=1.0):
    """Curvature of the FEM's bilayer with the coat ``d_factor`` times thicker and ``E_factor``
    times stiffer, over the nominal one (Timoshenko, plane strain; ``< 1``: it bends less)."""
    import reference_fem as rf
    from gdfe.timoshenko import timoshenko_curvature

    m = rf.BilayerMaterial()
    eps = m.eigenstrain_xyz[0]

    def k(df, ef):
        return timoshenko_curvature(H, D * df, m.E_active, m.E_passive * ef, eps, nu_active=m.nu_active,
                                    nu_passive=m.nu_passive, state="plane_strain")

    return float(k(d_factor, E_factor) / k(1.0, 1.0))


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _region(rng, design):
    return str(design.hinges[int(rng.integers(len(design.hinges)))])


#: Where the strengths are drawn from. ``spread``: the two ends of a part heated unevenly (by a heat
#: gun, on a hot plate's edge, near an oven's element) a few kelvin apart, where the film's shrink
#: rises steeply with temperature, shrink 20-40 % of the mean apart.
RANGES = {"d_factor": (1.3, 2.0), "E_factor": (1.5, 3.0), "ratio": (0.7, 0.9), "pixels": (1, 3),
          "spread": (0.2, 0.4)}

GENERATORS = {
    "null": ShapeGenerator(
        "null", "null", "the part as designed", {},
        draw=lambda rng, des: {},
        make=lambda des, R, s: solve_part(des, R)),
    "thicker_coat": ShapeGenerator(
        "thicker_coat", "catalogue", "one hinge's coat thicker by a factor", {"d_factor": RANGES["d_factor"]},
        draw=lambda rng, des: {"region": _region(rng, des), "d_factor": _u(rng, *RANGES["d_factor"])},
        make=lambda des, R, s: solve_part(des, R, d_factor={s["region"]: s["d_factor"]})),
    "stiffer_coat": ShapeGenerator(
        "stiffer_coat", "catalogue", "one hinge's coat stiffer by a factor", {"E_factor": RANGES["E_factor"]},
        draw=lambda rng, des: {"region": _region(rng, des), "E_factor": _u(rng, *RANGES["E_factor"])},
        make=lambda des, R, s: solve_part(des, R, stiffer=(s["region"], s["E_factor"]))),
    "anisotropic_film": ShapeGenerator(
        "anisotropic_film", "catalogue", "the film contracts less along one axis (ratio), mean kept",
        {"ratio": RANGES["ratio"]},
        draw=lambda rng, des: {"ratio": _u(rng, *RANGES["ratio"]), "weak_axis": int(rng.integers(2))},
        make=lambda des, R, s: solve_part(des, R, anisotropy=(s["ratio"], s["weak_axis"]))),
    "coat_offset": ShapeGenerator(
        "coat_offset", "catalogue", "one face's coat printed 1-3 pixels off its mask along x or y",
        {"pixels": RANGES["pixels"]},
        draw=lambda rng, des: {"face": ("top", "bottom")[int(rng.integers(2))], "axis": int(rng.integers(2)),
                               "pixels": int(rng.integers(1, 4)) * (1 if rng.random() < 0.5 else -1)},
        make=lambda des, R, s: solve_part(des, R, material=offset_material(des, s["face"], s["axis"],
                                                                           s["pixels"]))),
    "contraction_gradient": ShapeGenerator(
        "contraction_gradient", "outside",
        "the film's shrink varies linearly along x or y, its ends spread apart by 20-40 % of the mean, mean kept",
        {"spread": RANGES["spread"]},
        draw=lambda rng, des: {"spread": _u(rng, *RANGES["spread"]) * (1 if rng.random() < 0.5 else -1),
                               "axis": int(rng.integers(2))},
        make=lambda des, R, s: solve_part(des, R, gradient=(s["spread"], s["axis"]))),
}


@dataclasses.dataclass
class Sample:
    """One scanned part.

    Attributes
    ----------
    generator, design : str
    strengths : dict
    answer : dict
        The declared answer (:meth:`ShapeGenerator.answer`).
    R : float
        The contraction ratio of the design handed to the diagnosis (:func:`calibrated_R`).
    scan : Scan
    fem : dict
        The FEM's summary: ``converged``, ``seconds``, ``n_elements``, ``dofs``.
    """

    generator: str
    design: str
    strengths: dict
    answer: dict
    R: float
    scan: object
    fem: dict


def solve_key(name, design, strengths, R):
    """The key of a solved part in the cache of :func:`generate`."""
    return (name, design, tuple(sorted(strengths.items())), float(R))


def generate(name, design, rng, noise_mm=NOISE_MM, solved=None):
    """A scanned part of generator ``name`` on design ``design`` (a name of
    :data:`~.designs.DESIGNS`), strengths and scan drawn from ``rng``.

    ``solved``: an optional cache (dict) of FEM solves keyed by generator, design and strengths
    (the null part is the same every time; only its scan differs).
    """
    check_choice("generator", name, GENERATORS)
    gen = GENERATORS[name]
    des = plate_design(design)
    strengths = gen.draw(rng, des)
    R = calibrated_R()
    key = solve_key(name, design, strengths, R)
    if solved is not None and key in solved:
        res = solved[key]
    else:
        res = gen.make(des, R, strengths)
        if solved is not None:
            solved[key] = res
    scan = scan_part(res, rng, noise_mm)
    fem = {"converged": bool(res.converged), "seconds": float(res.seconds), "n_elements": int(res.n_elements),
           "dofs": int(res.dofs), "load_factor": float(res.load_factor)}
    return Sample(generator=name, design=design, strengths=strengths, answer=gen.answer(strengths), R=R,
                  scan=scan, fem=fem)
