"""Forms of a shape gap beyond one region's contraction, and the rule that credits one of them.

A shape diagnosis (:func:`gdfe.diagnosis.diagnose_shape`) explains a scan's deviation from the
simulated design by *forms*: the design changed one way, re-simulated by GDFE, its parameter
fitted so that the RMS deviation of the rigidly aligned scan is least. Besides one region's
contraction ratio (fitted in :mod:`gdfe.diagnosis.shape`), this module fits

* **film anisotropy**: the free faces shrink ``rho`` times less along one in-plane axis than
  along the other, the mean of the two shrinks kept at the design's (the design's contraction
  stands for the film's calibrated shrink, whose direction relative to the film's draw is
  unknown; a change of the mean alone is what the check of a common contraction factor and the
  region forms already cover). GDFE's :attr:`~gdfe.design.Design.isotropy` only makes y the
  weaker axis (y shrinks by ``isotropy`` times x's), so there are two forms: *weaker along y*
  (``isotropy = rho``, the contraction scaled by ``(1 + isotropy_0) / (1 + rho)``) and *weaker
  along x*, the same design mirrored across the plane ``x = y`` (:func:`mirrored`: the mesh's x
  and y swapped, its hexahedra reordered to stay right-handed), simulated, and mirrored back;
  the energy of Eq. 5 is unchanged by a reflection, so the mirrored design's shape is the
  reflection of the shape of a film weaker along x. ``rho`` is a bounded 1-D search within
  ``physical_ranges.RANGES["isotropy"]``;
* **coat misregistration**: one face's coat moved by ``k`` whole pixels (cells) along x or y
  (:func:`shifted_coat`: the cells it leaves shrink on that face, those it reaches stop; coat
  that lands off the film is lost), one form per face and axis, ``k`` searched over every
  nonzero shift within ``physical_ranges.RANGES["coat_offset"]`` (one simulation each).

**Credit** (:func:`credit`, in the spirit of :mod:`gdfe.diagnosis.attribution`: a fit is not
an explanation). Let ``floor`` be the RMS distance at which the model and a part as designed
already disagree (measured by the user on a part printed as designed; 0 when not given) and
``noise`` the scan's own noise (:func:`scan_noise`). The part of a deviation ``r`` beyond the
floor is ``sqrt(max(r^2 - floor^2, 0))`` (model disagreement and an effect add in quadrature
when they are unrelated). A form is *named* only when

1. the scan's RMS deviation exceeds the floor and the noise combined in quadrature,
   ``level = sqrt(floor^2 + noise^2)`` (the floor was measured on one scan, with its noise;
   another scan of the same part differs from it by about its noise); else "no gap beyond the
   floor";
2. the part of the scan beyond that level is at least :data:`EFFECT_OVER_FLOOR` times the floor,
   ``sqrt(r^2 - level^2) >= floor``; else "within the models' disagreement". The disagreement
   is systematic, not noise: a form fitted to a scan absorbs a part of it as readily as a part of
   an effect (on the shape benchmark's null L, a part printed as designed, refitting one hinge
   takes the RMS deviation from 31.0 to 27.9 um, below the floor), so an effect smaller than the
   disagreement cannot be told from the part of the disagreement a form can fit;
3. the best form (least RMS after its fit) removes at least :data:`NAME_GAIN` of the part
   beyond the floor; else no gap is localised;
4. no *rival*, another form, comes within the noise of the best: a rival is not ruled out
   when its RMS deviation after its own fit is within :data:`RIVAL_TOL` of the best's,
   ``rms_rival <= (1 + RIVAL_TOL) rms_best``. The best's residual is the scan's own estimate of
   what no form explains: its noise and the models' disagreement (the floor). The noise alone
   would separate far closer fits (hundreds of points are compared point by point), but the
   disagreement is not noise: it is the same on every scan of the part and may favour one form
   or another by a part of itself. Otherwise the diagnosis credits nothing and names the
   forms it could not rule out.

Lengths in mm, offsets in pixels (the design's cells).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gdfe.material import Material
from gdfe.mesh import HexMesh
from gdfe.physical_ranges import RANGES

__all__ = ["FormFit", "Credit", "NAME_GAIN", "RIVAL_TOL", "EFFECT_OVER_FLOOR", "mirrored", "anisotropic_design", "shifted_coat",
           "fit_anisotropy", "fit_offset", "fit_film_forms", "scan_noise", "beyond", "level_of", "credit"]

#: A form is named when it removes at least this share of the deviation beyond the floor.
NAME_GAIN = 0.2
#: A form is credited only when the scan's deviation beyond the floor and the noise is at least this
#: many times the floor (the effect at least as large as the models' own disagreement).
EFFECT_OVER_FLOOR = 1.0
#: A rival form is not ruled out when its RMS deviation after its fit is within this share of
#: the best form's.
RIVAL_TOL = 0.1
#: The faces a coat is printed on, and the materials that carry a coat on each.
FACES = {"top": (Material.RIGID, Material.CONTRACT_BOTTOM), "bottom": (Material.RIGID, Material.CONTRACT_TOP)}
AXES = ("x", "y")
#: Hexahedron corners (VTK order) of a cell mirrored across x = y, in right-handed VTK order again.
_MIRROR = [0, 3, 2, 1, 4, 7, 6, 5]
#: The corners of a cell in VTK order, in units of its size.
_HEX_CORNERS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)


@dataclasses.dataclass
class FormFit:
    """One form fitted to a scan.

    Attributes
    ----------
    name : str
        ``"contraction of hinge_a"``, ``"film anisotropy (weaker along y)"``,
        ``"top coat offset along x"``.
    kind : str
        ``"region"``, ``"anisotropy"`` or ``"offset"``.
    params : dict
        The fitted parameters (``region``, ``R_design``, ``R``; ``weak_axis``, ``ratio``; ``face``,
        ``axis``, ``pixels``).
    rms_after : float [mm]
        RMS deviation of the scan from the form's shape at the fitted parameters.
    n_simulations : int
    points : (n, 3) float array [mm] or None
        The simulated shape at the fitted parameters (not in :meth:`as_dict`).
    """

    name: str
    kind: str
    params: dict
    rms_after: float
    n_simulations: int = 0
    points: np.ndarray | None = None

    def as_dict(self) -> dict:
        return {"form": self.name, "kind": self.kind, "params": dict(self.params), "rms_after": float(self.rms_after),
                "n_simulations": int(self.n_simulations)}


@dataclasses.dataclass
class Credit:
    """What a shape diagnosis credits (:func:`credit`).

    Attributes
    ----------
    outcome : str
        ``"credited"``, ``"cannot_tell"`` (rivals fit as well), ``"no_form"`` (no form removes
        :data:`NAME_GAIN` of the part beyond the floor), ``"within_disagreement"`` (the scan is
        beyond the floor and the noise by less than :data:`EFFECT_OVER_FLOOR` times the floor) or
        ``"within_floor"`` (the scan is no further from the design than the floor and the noise).
    credited : FormFit or None
    not_ruled_out : list of str
        The forms within :data:`RIVAL_TOL` of the best (the best first) when the outcome is
        ``"cannot_tell"``.
    level : float [mm]
        ``sqrt(floor^2 + noise^2)``.
    gain : float
        Share of the part beyond the floor that the best form removes.
    """

    outcome: str
    credited: FormFit | None
    not_ruled_out: list
    level: float
    gain: float


def mirrored(design):
    """The design mirrored across the plane ``x = y``: the same cells, vertices and materials,
    their x and y swapped (hexahedra reordered to stay right-handed)."""
    m = design.mesh
    mesh = HexMesh(points=m.points[:, [1, 0, 2]].copy(), cells=m.cells[:, _MIRROR].copy(),
                   cell_ij=m.cell_ij[:, ::-1].copy(), cell_k=m.cell_k.copy(), spacing=m.spacing[[1, 0, 2]].copy())
    return dataclasses.replace(design, mesh=mesh)


def anisotropic_design(design, ratio, weak_axis):
    """The design on a film that shrinks ``ratio`` times less along ``weak_axis`` (0: x, 1: y)
    than along the other axis, the mean of the two shrinks kept; mirrored across ``x = y`` when
    the weaker axis is x (mirror the simulated shape back: swap its x and y).

    Returns
    -------
    Design
    """
    top, bottom = design.face_contraction()
    scale = (1.0 + design.isotropy) / (1.0 + float(ratio))
    c = np.clip(np.column_stack([top, bottom]) * scale, 0.0, 0.99)
    des = dataclasses.replace(design, contraction=c, isotropy=float(ratio), model=None)
    return mirrored(des) if weak_axis == 0 else des


def _grid(design, values):
    ij = design.mesh.cell_ij
    g = np.zeros(tuple(ij.max(0) + 1), bool)
    g[ij[:, 0], ij[:, 1]] = values
    return g


def shifted_coat(design, face, axis, pixels):
    """The design with one face's coat printed ``pixels`` cells (signed) along ``axis`` (0: x,
    1: y) off its mask; None when that changes no cell.

    The cells the coat leaves shrink on that face, those it reaches stop; coat that lands off
    the film is lost. A cell that starts to shrink keeps its own contraction ratio, or takes the
    median of the design's shrinking cells where it had none (``R = 1``). Every layer of a
    column shares its material.
    """
    ij = design.mesh.cell_ij
    film = _grid(design, True)
    coats = {f: _grid(design, np.isin(design.material, [int(c) for c in codes])) for f, codes in FACES.items()}
    moved, k = coats[face], int(pixels)
    out = np.zeros_like(moved)
    src, dst = [slice(None)] * 2, [slice(None)] * 2
    n = moved.shape[axis]
    if abs(k) >= n:
        return None
    src[axis] = slice(0, n - k) if k >= 0 else slice(-k, None)
    dst[axis] = slice(k, None) if k >= 0 else slice(0, n + k)
    out[tuple(dst)] = moved[tuple(src)]
    coats = dict(coats, **{face: out & film})
    top, bottom = coats["top"][ij[:, 0], ij[:, 1]], coats["bottom"][ij[:, 0], ij[:, 1]]
    mat = np.select([top & bottom, top, bottom], [int(Material.RIGID), int(Material.CONTRACT_BOTTOM),
                                                  int(Material.CONTRACT_TOP)], int(Material.FREE_SHRINK))
    if np.array_equal(mat, design.material):
        return None
    R = design.R.copy()
    shrinking = design.material != Material.RIGID
    starts = (mat != Material.RIGID) & (R >= 1.0)
    if starts.any() and shrinking.any():
        R[starts] = float(np.median(design.R[shrinking]))
    return dataclasses.replace(design, material=mat.astype(np.int8), R=R, contraction=None, model=None)


def _rms(dev):
    return float(np.sqrt(np.mean(dev**2)))


def fit_anisotropy(comp, weak_axis):
    """The film-anisotropy form weaker along ``weak_axis`` (0: x, 1: y): ``rho`` by a bounded
    1-D search within ``RANGES["isotropy"]``. ``comp`` simulates and compares (see
    :func:`fit_film_forms`)."""
    from scipy.optimize import minimize_scalar

    lo, hi = RANGES["isotropy"].lo, RANGES["isotropy"].hi
    best = {"rms": math.inf}
    n0 = comp.n_sims
    base = comp.design.with_R(comp.design.R)  # per-cell ratios, as every other form's shape

    def f(rho):
        pts = comp.simulate_design(anisotropic_design(base, rho, weak_axis), mirror=weak_axis == 0)
        r = _rms(comp.compare(pts)[0])
        if r < best["rms"]:
            best.update(rms=r, rho=float(rho), points=pts)
        return r

    minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 0.005})
    return FormFit(f"film anisotropy (weaker along {AXES[weak_axis]})", "anisotropy",
                   {"weak_axis": AXES[weak_axis], "ratio": best["rho"], "isotropy_design": float(comp.design.isotropy)},
                   best["rms"], comp.n_sims - n0, best["points"])


def fit_offset(comp, face, axis):
    """The coat-offset form of ``face`` along ``axis`` (0: x, 1: y): every nonzero whole-pixel
    shift within ``RANGES["coat_offset"]``; None when no shift changes the design."""
    reach = int(RANGES["coat_offset"].hi)
    best = None
    n0 = comp.n_sims
    for k in [s * p for p in range(1, reach + 1) for s in (1, -1)]:
        des = shifted_coat(comp.design, face, axis, k)
        if des is None:
            continue
        pts = comp.simulate_design(des)
        r = _rms(comp.compare(pts)[0])
        if best is None or r < best[0]:
            best = (r, k, pts)
    if best is None:
        return None
    return FormFit(f"{face} coat offset along {AXES[axis]}", "offset",
                   {"face": face, "axis": AXES[axis], "pixels": int(best[1])}, best[0], comp.n_sims - n0, best[2])


def fit_film_forms(comp):
    """Every form of this module fitted to the scan: the two anisotropies, and the offset of each
    face's coat along x and along y.

    Parameters
    ----------
    comp : object
        What compares shapes with the scan: ``design`` (the design as designed), ``n_sims``,
        ``simulate_design(design, mirror=False) -> (n, 3) points`` (GDFE's shape, mirrored back
        across ``x = y`` when asked) and ``compare(points) -> (deviations, owners)`` (after rigid
        alignment).

    Returns
    -------
    list of FormFit
    """
    forms = [fit_anisotropy(comp, axis) for axis in (1, 0)]
    for face in FACES:
        for axis in (0, 1):
            fit = fit_offset(comp, face, axis)
            if fit is not None:
                forms.append(fit)
    return forms


def scan_noise(design, measured, sim, owner=None, faces=None):
    """The scan's noise [mm]: the spread of its deviations from the simulated shape about a
    smooth (affine, or planar) field over each cell (a smooth deviation varies little within a
    cell beyond that; noise does not).

    Parameters
    ----------
    design : Design
    measured : (k, 3) float array [mm]
        The scan, rigidly aligned to ``sim``.
    sim : (n, 3) float array [mm]
        The simulated shape.
    owner : (k,) int array or None
        None: ``measured`` are the design's vertices (correspondences); the deviation vectors of
        each cell's 8 corners less the affine field that fits them best (4 degrees of freedom
        left per coordinate) give the noise of a vertex's distance (all three coordinates).
        Otherwise each point's signed distance along
        its closest surface point's cell normal, about a plane fitted to the points of the same
        cell on the same side of the film (groups of more than 3 points, 3 degrees of freedom
        each): the noise of a distance to the surface.
    faces : optional
        The design's boundary faces (:func:`gdfe.io.surface_faces`).

    Returns
    -------
    float
        An upper bound where the deviation varies within cells.
    """
    cells = design.mesh.cells
    if owner is None:
        # the part of each cell's deviation vectors that no affine field over the cell holds: the
        # corners' bilinear and trilinear modes, 4 of the 8 degrees of freedom per coordinate
        corners = 2.0 * _HEX_CORNERS - 1.0
        A = np.column_stack([np.ones(8), corners])
        M = np.eye(8) - A @ np.linalg.solve(A.T @ A, A.T)
        r = np.einsum("ab,mbc->mac", M, (measured - sim)[cells])
        return float(np.sqrt(np.sum(r**2) / (4 * len(cells))))
    from gdfe.diagnosis.surface import Surface

    C, _, own = Surface(sim, design, faces=faces).closest(measured)
    P = sim[cells]
    normal = np.cross(P[:, 6] - P[:, 4], P[:, 7] - P[:, 5])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    D = measured - C
    s = np.einsum("ij,ij->i", D, normal[own])
    # points off the film's faces (closest to its edges or walls: not along the cell's normal) say
    # nothing of a distance along it
    face = np.abs(s) >= 0.9 * np.linalg.norm(D, axis=1)
    s, C, own = s[face], C[face], own[face]
    # one group per cell and side of the film (the two faces may sit apart by a thickness change),
    # a plane a + b u + c v fitted to each group's signed distances (u, v along the cell's face)
    centre = P[own].mean(axis=1)
    side = np.einsum("ij,ij->i", C - centre, normal[own]) > 0
    group = 2 * own + side
    e1 = (P[:, 1] - P[:, 0]) + (P[:, 2] - P[:, 3])
    e1 /= np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-300)
    e2 = np.cross(normal, e1)
    basis = np.column_stack([np.ones(len(s)), np.einsum("ij,ij->i", C - centre, e1[own]),
                             np.einsum("ij,ij->i", C - centre, e2[own])])  # (k, 3)
    m = 2 * len(cells)
    cnt = np.bincount(group, minlength=m)
    A = np.zeros((m, 3, 3))
    np.add.at(A, group, basis[:, :, None] * basis[:, None, :])
    rhs = np.zeros((m, 3))
    np.add.at(rhs, group, basis * s[:, None])
    used = cnt[group] > 3
    coef = np.einsum("gij,gj->gi", np.linalg.pinv(A), rhs)
    res = s - np.einsum("ij,ij->i", basis, coef[group])
    dof = int(np.sum(cnt[cnt > 3] - 3))
    if dof <= 0:
        return float("nan")
    return float(np.sqrt(np.sum(res[used] ** 2) / dof))


def beyond(rms, floor):
    """The part of an RMS deviation [mm] beyond the floor [mm]: ``sqrt(max(rms^2 - floor^2, 0))``."""
    return float(math.sqrt(max(rms * rms - floor * floor, 0.0)))


def level_of(floor, noise):
    """The RMS deviation [mm] a scan must exceed for a gap: ``sqrt(floor^2 + noise^2)`` (a floor of
    None and a noise that could not be estimated, NaN, count as 0)."""
    floor = 0.0 if floor is None else float(floor)
    noise = float(noise) if np.isfinite(noise) else 0.0
    return math.hypot(floor, noise)


def credit(forms, rms0, floor=None, noise=0.0):
    """What the fitted forms let a diagnosis credit (see the module docstring).

    Parameters
    ----------
    forms : list of FormFit
    rms0 : float [mm]
        RMS deviation of the scan from the design's shape.
    floor : float [mm] or None
        The model floor (None: 0).
    noise : float [mm]
        The scan's noise (NaN: 0).

    Returns
    -------
    Credit
    """
    floor = 0.0 if floor is None else float(floor)
    level = level_of(floor, noise)
    ranked = sorted(forms, key=lambda f: f.rms_after)
    if not ranked:
        return Credit("no_form", None, [], level, 0.0)
    best = ranked[0]
    e0 = beyond(rms0, floor)
    gain = 1.0 - beyond(best.rms_after, floor) / e0 if e0 > 0 else 0.0
    if rms0 <= level:
        return Credit("within_floor", None, [], level, gain)
    if beyond(rms0, level) < EFFECT_OVER_FLOOR * floor:
        return Credit("within_disagreement", None, [], level, gain)
    if gain < NAME_GAIN:
        return Credit("no_form", None, [], level, gain)
    rivals = [f.name for f in ranked[1:] if f.rms_after <= (1.0 + RIVAL_TOL) * best.rms_after]
    if rivals:
        return Credit("cannot_tell", None, [best.name] + rivals, level, gain)
    return Credit("credited", best, [], level, gain)
