"""Strip patterns: the contracting and rigid cells that fold a straight strip into a chain of couples.

A couple of turning angle ``alpha`` needs the contracting length (Eq. 2)

    L_c = |alpha| h / (1 - R),

which is spread uniformly over the couple as contracting cells alternated with rigid
ones (:func:`strip_pattern`). A printer that cannot print features narrower than
``w_min`` quantises the contracting cells to ``n_b = rounding(L_c / w_min)`` blocks of
width ``w_min``; block ``j`` is centred at ``(j + 1/2) / n_b`` of the couple, and the
printed turn is ``(1 - R) n_b w_min / h``.

The pattern is printed on a straight strip along x and the strip curls in the x-z
plane. Seen from -y (x to the right, z up) a ``CONTRACT_TOP`` cell turns the strip
anticlockwise, so ``r > 0`` maps to ``CONTRACT_TOP`` and ``r < 0`` to ``CONTRACT_BOTTOM``,
and a curve's 2-D coordinates ``(u, v)`` are the strip's ``(x, z)``.

A sharp turn ``t`` of a chain becomes a maximum-curvature hinge (:func:`with_hinges`): a
fully contracting couple of radius ``h / (1 - R)`` and length ``|t| h / (1 - R)``.

All lengths in millimetres, angles in radians.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gdfe._validation import GdfeError, check_array, check_choice, check_number, check_positive
from gdfe.calibration import DEFAULT_H
from gdfe.paper import R_ROUNDED
from gdfe.design import Material, grid_design
from gdfe.inverse.couples import Couple, as_couples, check_open_ratio
from gdfe.model import as_model

__all__ = ["StripPattern", "strip_pattern", "with_hinges", "ROUNDINGS"]


@dataclasses.dataclass
class StripPattern:
    """The printed pattern of a chain of couples on a straight strip along x.

    Attributes
    ----------
    material : (n,) int array
        :class:`gdfe.Material` of each column of cells along the strip.
    cell : float [mm]
        Column width (the simulation's cell size along x).
    segment : (n,) int array
        Couple that each column belongs to.
    couples : list of Couple
        The couples as asked for.
    h, R : float
        Film thickness [mm] and contraction ratio of the free faces.
    w_min : float or None [mm]
        Printer resolution the contracting blocks were quantised to (None: the cell).
    rounding : str
        How the number of contracting blocks was rounded.
    L_c : (k,) float array [mm]
        Contracting length each couple needs, ``|alpha| h / (1 - R)``.
    L_c_printed : (k,) float array [mm]
        Contracting length printed after quantisation.
    blocks : (k,) int array
        Contracting blocks per couple.
    angle : (k,) float array [rad]
        Turning angle each couple asks for.
    angle_printed : (k,) float array [rad]
        Turning angle of the printed contracting length by Eq. 2, ``(1 - R) L_c_printed / h``.
    clamped : (k,) bool array
        Couples tighter than the film can fold, printed fully contracting instead.
    model : DeformationModel or None
        The deformation model the pattern was planned with (then ``R`` is its ratio at
        ``d`` and ``angle_printed`` the turn the model gives the printed columns, its
        geometric mechanisms included); None for the paper's rule with a given ``R``.
    d : float or None [mm]
        Passive thickness the strip is printed with (for the model).
    """

    material: np.ndarray
    cell: float
    segment: np.ndarray
    couples: list
    h: float
    R: float
    w_min: float | None
    rounding: str
    L_c: np.ndarray
    L_c_printed: np.ndarray
    blocks: np.ndarray
    angle: np.ndarray
    angle_printed: np.ndarray
    clamped: np.ndarray
    model: object = None
    d: float | None = None

    @property
    def length(self) -> float:
        """Printed strip length [mm]."""
        return float(self.material.size * self.cell)

    def printed_couples(self):
        """Couples with the printed lengths and the turn of the printed contracting cells."""
        out = []
        for i in range(len(self.couples)):
            L = float((self.segment == i).sum() * self.cell)
            a = float(self.angle_printed[i])
            out.append(Couple(L, L / a if a != 0 else 0.0))
        return out

    def rows(self) -> str:
        """The pattern as one text row (``R``, ``T``, ``B``), as :func:`gdfe.from_rows` reads it."""
        chars = {int(Material.RIGID): "R", int(Material.CONTRACT_TOP): "T", int(Material.CONTRACT_BOTTOM): "B"}
        return "".join(chars[int(m)] for m in self.material)

    def design(self, width=0.5, ny=1, nz=1, isotropy=1.0):
        """The strip as a :class:`gdfe.Design` (regions ``seg0``, ``seg1``, ...).

        Parameters
        ----------
        width : float [mm]
            Strip width along y.
        ny : int
            Cells across the strip.
        nz : int
            Cell layers through the film.
        isotropy : float
            See :class:`gdfe.Design`.
        """
        width = check_positive("width", width)
        mat = np.repeat(self.material[:, None], ny, axis=1)
        regions = {f"seg{i}": np.repeat((self.segment == i)[:, None], ny, axis=1)
                   for i in range(len(self.couples))}
        meta = {"kind": "strip", "couples": [[c.L, c.r] for c in self.couples], "R": self.R,
                "cell_mm": self.cell, "w_min_mm": self.w_min, "rounding": self.rounding}
        if self.model is not None:
            meta["d_mm"] = self.d
            one = (mat == int(Material.CONTRACT_TOP)) | (mat == int(Material.CONTRACT_BOTTOM))
            return grid_design(mat, h=self.h, pixel=(self.cell, width / ny), nz=nz, isotropy=isotropy,
                               regions2d=regions, meta=meta, d=np.where(one, self.d, np.nan), model=self.model)
        return grid_design(mat, self.R, h=self.h, pixel=(self.cell, width / ny), nz=nz, isotropy=isotropy,
                           regions2d=regions, meta=meta)


_ROUNDING = {"nearest": lambda x: np.floor(x + 0.5), "floor": np.floor, "ceil": np.ceil,
             "carry": lambda x: np.floor(x + 0.5)}

#: The ``rounding`` modes of :func:`strip_pattern`.
ROUNDINGS = tuple(_ROUNDING)


def strip_pattern(couples, h=DEFAULT_H, R=None, cell=None, w_min=None, rounding="nearest", clamp=False,
                  model=None, d=None):
    """Contracting and rigid cells along a strip that folds into the curve of the couples.

    Each couple gets ``round(L / cell)`` columns. Its contracting length
    ``L_c = |L / r| h / (1 - R)`` is printed as ``n_b`` blocks of width ``w_min``
    (``n_b = rounding(L_c / w_min)``; without a printer resolution a block is one cell),
    spread uniformly along the couple with rigid cells between them: block ``j`` is
    centred at ``(j + 1/2) / n_b`` of the couple. Contracting cells are ``CONTRACT_TOP``
    for ``r > 0`` (anticlockwise) and ``CONTRACT_BOTTOM`` for ``r < 0``.

    Parameters
    ----------
    couples : sequence of Couple or (L, r)
    h : float [mm]
        Film thickness.
    R : float
        Contraction ratio of the free face, strictly between 0 and 1.
    cell : float [mm], optional
        Column width. Default: 0.125 mm, or ``w_min`` divided into the fewest equal
        parts no wider than 0.125 mm.
    w_min : float [mm], optional
        Narrowest contracting feature the printer makes; must be a whole number of cells.
    rounding : {"nearest", "floor", "ceil", "carry"}
        How ``L_c / w_min`` is rounded to a number of blocks. "nearest" rounds each couple
        on its own (halves up). "carry" rounds to the nearest too, but adds to each couple the
        turn the couples before it lost or gained by rounding (as far as the couple can take
        it: never below zero blocks, never the opposite way, straight couples stay straight),
        so the printed strip's accumulated turn stays within half a block of the target's;
        couples shorter than a block, like the hinges of :func:`with_hinges`, then keep
        their turn.
    clamp : bool
        A couple tighter than the film can fold (``L_c > L``) raises :class:`GdfeError`
        unless ``clamp``, which prints it fully contracting (the maximum curvature, ``(1-R)/h``).
    model : DeformationModel or path of a model file, optional
        Plan with this deformation model at passive thickness ``d`` instead of a given ``R``
        (default ``R`` 0.7, the paper's): ``R`` is the model's at ``d``; where the model has
        geometric mechanisms (a contraction that spreads past coat edges, a capped fold) the
        number of blocks of each couple is then chosen so that the turn the model gives the
        printed columns is closest to the couple's (two sweeps along the strip, since a block
        spreads into its neighbours).
    d : float [mm], optional
        Passive thickness, with ``model``.

    Returns
    -------
    StripPattern
    """
    couples = as_couples(couples)
    h = check_positive("h", h)
    model, R, d = _planning_ratio(model, R, d, h)
    rounding = check_choice("rounding", rounding, ROUNDINGS)
    w_min, cell, b = _printer_grid(w_min, cell)
    geometric = model is not None and model.geometric
    material, segment, L_c, L_cp, blocks, clamped = _paper_rule_columns(couples, h, R, cell, b, rounding,
                                                                        clamp, geometric)
    k = len(couples)
    angle = np.array([c.angle for c in couples])
    if geometric:
        material, blocks = _refine_for_model(material, segment, couples, blocks, b, model, R, h, cell)
        L_cp = np.array([float((material[segment == i] != int(Material.RIGID)).sum() * cell)
                         for i in range(k)])
        angle_p = _model_turns(material, segment, k, model, R, h, cell)
        clamped = _model_clamps(material, segment, couples, angle, model, R, h, cell, d, clamp)
    else:
        angle_p = np.sign(angle) * (1.0 - R) * L_cp / h
    return StripPattern(material=material, cell=cell, segment=segment,
                        couples=couples, h=h, R=R, w_min=w_min, rounding=rounding, L_c=L_c,
                        L_c_printed=L_cp, blocks=blocks, angle=angle, angle_printed=angle_p,
                        clamped=clamped, model=model, d=d)


def _planning_ratio(model, R, d, h):
    """The checked model, the contraction ratio the strip is planned with (``R``, or the model's
    at ``d``; the paper's 0.7 without either) and the checked ``d``."""
    model = as_model(model)
    if model is not None:
        if R is not None:
            raise GdfeError("R, model: expected a contraction ratio R or a deformation model, not both")
        if d is None:
            raise GdfeError("d: expected the passive thickness [mm] the model gives R from")
        d = float(check_positive("d", d))
        R = float(model.ratio(d, h))
    return model, check_open_ratio(0.7 if R is None else R), d


def _printer_grid(w_min, cell):
    """The checked printer resolution ``w_min``, the column width and the columns of one block."""
    if w_min is not None:
        w_min = check_number("w_min", w_min, minimum=0.0, include_minimum=False,
                             what="a positive printer resolution in mm")
    if cell is None:
        cell = 0.125 if w_min is None else w_min / math.ceil(w_min / 0.125 - 1e-9)
    cell = check_positive("cell", cell)
    if w_min is None:
        return w_min, cell, 1
    b = int(round(w_min / cell))
    if b < 1 or abs(b * cell - w_min) > 1e-6 * w_min:
        raise GdfeError(f"w_min: expected a whole number of cells ({cell:g} mm), got {w_min:g} mm")
    return w_min, cell, b


def _paper_rule_columns(couples, h, R, cell, b, rounding, clamp, geometric):
    """Each couple's columns by the paper's rule (its blocks spread uniformly, :func:`_blocks`).

    Returns the columns' materials and couples, and per couple the contracting length asked and
    printed, the blocks and whether it is clamped. A couple tighter than the film folds is an
    error unless ``clamp``, or a geometric model, which decides it later.
    """
    k = len(couples)
    materials, segments = [], []
    L_c, L_cp = np.zeros(k), np.zeros(k)
    blocks, clamped = np.zeros(k, int), np.zeros(k, bool)
    turn_per_block = b * cell * (1.0 - R) / h
    debt = 0.0  # target minus printed accumulated turn [rad] ("carry")
    for i, c in enumerate(couples):
        n = max(1, int(round(c.L / cell)))
        L_c[i] = abs(c.angle) * h / (1.0 - R)
        want = L_c[i] / (b * cell)
        if rounding == "carry" and c.angle != 0:
            want = max(0.0, math.copysign(1.0, c.angle) * (c.angle + debt)) / turn_per_block
        nb = int(_ROUNDING[rounding](want - 1e-12)) if want > 0 else 0
        if rounding == "carry" and L_c[i] <= n * cell:
            nb = min(nb, n // b)  # a carried turn never makes a feasible couple infeasible
        col = np.full(n, int(Material.RIGID))
        code = int(Material.CONTRACT_TOP if c.curvature > 0 else Material.CONTRACT_BOTTOM)
        if nb * b > n:
            if not clamp and not geometric:  # a geometric model may still fold it: decided below
                rmin = h / (1.0 - R)
                raise GdfeError(
                    f"couples[{i}]: radius {abs(c.r):g} mm needs a contracting length {L_c[i]:.4g} mm "
                    f"longer than the couple ({c.L:g} mm); the film folds no tighter than "
                    f"h/(1-R) = {rmin:.4g} mm (pass clamp=True to print it fully contracting)")
            clamped[i] = True
            col[:] = code
            nb = n // b if n >= b else 0
            L_cp[i] = n * cell
        else:
            col = _blocks(n, nb, b, code)
            L_cp[i] = float((col == code).sum() * cell) if nb else 0.0
        blocks[i] = nb
        debt += c.angle - math.copysign(1.0, c.angle) * (1.0 - R) * L_cp[i] / h
        materials.append(col)
        segments.append(np.full(n, i))
    return np.concatenate(materials), np.concatenate(segments), L_c, L_cp, blocks, clamped


def _model_clamps(material, segment, couples, angle, model, R, h, cell, d, clamp):
    """The couples that turn less than their ``angle`` even with all their columns contracting: this
    model cannot fold them at this ``d`` (an overshoot is the model's block quantum, not a clamp). The
    first is an error unless ``clamp``."""
    k = len(couples)
    most = np.zeros(k)
    for i, cp in enumerate(couples):
        full = material.copy()
        full[segment == i] = int(Material.CONTRACT_TOP if cp.curvature > 0 else Material.CONTRACT_BOTTOM)
        most[i] = abs(_model_turns(full, segment, k, model, R, h, cell)[i]) if cp.angle != 0 else 0.0
    clamped = np.abs(angle) > most + 1e-9
    if clamped.any() and not clamp:
        i = int(np.nonzero(clamped)[0][0])
        raise GdfeError(f"couples[{i}]: radius {abs(couples[i].r):g} mm turns by {abs(angle[i]):.4g} rad, but the "
                        f"most model {model.name!r} gives it at d = {d:g} mm is {most[i]:.4g} rad "
                        f"(its contraction there is {1 - R:.4g}: the film folds no tighter than "
                        f"h/c = {h / (1 - R):.4g} mm); print a thinner coat, or pass clamp=True")
    return clamped


def _blocks(n, nb, b, code):
    """``n`` columns with ``nb`` blocks of ``b`` contracting columns spread uniformly (the paper's rule)."""
    col = np.full(n, int(Material.RIGID))
    for j in range(nb):
        centre = (j + 0.5) * n / nb
        s0 = int(np.clip(math.floor(centre - b / 2 + 0.5), 0, n - b))
        col[s0:s0 + b] = code
    return col


def _model_turns(material, segment, k, model, R, h, cell):
    """Turn [rad] the model gives each couple's columns (its geometric mechanisms included)."""
    c = 1.0 - R
    top = np.where(material == int(Material.CONTRACT_TOP), c, 0.0)[:, None]
    bottom = np.where(material == int(Material.CONTRACT_BOTTOM), c, 0.0)[:, None]
    t2, b2 = model.contraction_grid(top, bottom, np.ones_like(top, bool), cell, cell, h)
    rate = (t2[:, 0] - b2[:, 0]) / h
    return np.bincount(segment, rate * cell, k)


def _refine_for_model(material, segment, couples, blocks, b, model, R, h, cell, sweeps=2):
    """Per couple, the number of blocks whose model turn is closest to the couple's."""
    material = material.copy()
    blocks = blocks.copy()
    k = len(couples)
    for _ in range(sweeps):
        for i, cp in enumerate(couples):
            if cp.angle == 0:
                continue
            cols = np.nonzero(segment == i)[0]
            n = cols.size
            code = int(Material.CONTRACT_TOP if cp.curvature > 0 else Material.CONTRACT_BOTTOM)
            best = None
            for nb in range(0, n // b + 1):
                trial = material.copy()
                trial[cols] = _blocks(n, nb, b, code)
                miss = abs(_model_turns(trial, segment, k, model, R, h, cell)[i] - cp.angle)
                if best is None or miss < best[0] - 1e-12:
                    best = (miss, nb, trial)
            _, blocks[i], material = best
    return material, blocks


def with_hinges(couples, turns, h=DEFAULT_H, R=R_ROUNDED, min_turn=1e-3):
    """Replace the sharp turns of a chain by maximum-curvature hinges (paper Sec. 4.2).

    A turn ``t`` before couple ``i`` becomes a fully contracting couple of length
    ``|t| h / (1 - R)`` and radius ``sign(t) h / (1 - R)`` inserted before it; turns
    smaller than ``min_turn`` [rad] are dropped. The first turn (at the start of the
    curve) only rotates the whole curve and is dropped too.

    Returns
    -------
    list of Couple
    """
    couples = as_couples(couples)
    h = check_positive("h", h)
    R = check_open_ratio(R)
    turns = check_array("turns", turns, shape=(len(couples),))
    min_turn = check_number("min_turn", min_turn, minimum=0.0)
    rmin = h / (1.0 - R)
    out = []
    for i, c in enumerate(couples):
        t = turns[i]
        if i > 0 and abs(t) >= min_turn:
            out.append(Couple(abs(t) * rmin, math.copysign(rmin, t)))
        out.append(c)
    return out
