"""2-D inverse design: the coating of both faces whose GDFE fold matches a target surface.

The method, in four steps (each measured by ``gdfe study inverse2d``):

1. **Placement and reachability** (:func:`scale_for`). The film point ``p`` goes to the target's
   conformal coordinates ``u = sigma p`` (:mod:`gdfe.inverse2d.targets`). Isotropic shrink gives
   the mid-surface the metric factor ``lambda = 1 - c_mid`` and, through the two faces'
   difference, the bending ``c_top - c_bottom = h kappa lambda`` (the fold of a cell whose faces
   contract by ``c_top`` and ``c_bottom``: Eq. 2 per unit length). Both faces' contractions must
   lie in ``[0, c_0]``, so a target is within reach of this estimate when some ``sigma`` keeps
   ``|h kappa lambda| / 2 <= 1 - lambda <= c_0 - |h kappa lambda| / 2`` everywhere;
   ``sigma`` is chosen to maximise the smallest margin. ``kappa`` is the natural curvature a
   thin film bent by isotropic means takes: the larger principal curvature where the target's
   Gaussian curvature is >= 0, its mean curvature where it is negative.
2. **Relaxed design** (:func:`design_surface`): a coating fraction ``rho`` per cell and face,
   through the density filter of :mod:`gdfe.inverse2d.masks`, sets the contraction
   ``c = c_0 (1 - rho)`` (:class:`gdfe.inverse2d.film.Film`). Starting from step 1's estimate, SciPy's
   L-BFGS-B minimises the mean squared distance, after rigid alignment, of the fold's
   mid-surface points from the target points they are placed on (``J``, in units of ``h^2``),
   with the gradient through the GDFE equilibrium by the adjoint method
   (:mod:`gdfe.inverse2d.adjoint`: one sparse solve with the exact Hessian per evaluation). Each
   fold starts from the last one; the first from the target's shape (the flat print of a film
   that only contracts in its plane is an equilibrium, which a start from it would keep). A
   film can have several equilibria (a saddle and the same saddle turned by 90 degrees share
   their metric and mean curvature): where the design, folded from the flat print as in the
   oven, lands on another one, a second optimisation folds every evaluation from the flat print.
3. **Printable masks**: the relaxed fractions are halftoned in blocks of ``w_min``
   (:func:`gdfe.inverse2d.masks.halftone`); ``projection="threshold"`` is the topology
   optimiser's 1/2 threshold instead.
4. **Forward checks**: the relaxed design and the printed one (read from the masks by
   :func:`gdfe.from_masks`, with the model's geometric mechanisms) are folded by
   :func:`gdfe.simulate` from the flat print, as a part folds in the oven, and their
   distances to the target measured by :func:`gdfe.inverse2d.distance.surface_distance`.

A target that is out of reach gets its answer: the estimate of step 1 (by how much, and the
closest target of the same kind that is within it, :func:`closest_reachable`), and the closest
fold found, with its distance.

Lengths in mm.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import time

import numpy as np

from gdfe._validation import GdfeError, check_choice, check_instance, check_int, check_number, check_positive
from gdfe.inverse2d.adjoint import contraction_gradient, fold
from gdfe.inverse2d.distance import Distance, patch, surface_distance
from gdfe.inverse2d.film import Film
from gdfe.inverse2d.masks import PROJECTIONS, block_size, density_filter, min_feature_ok, project
from gdfe.inverse2d.targets import Target
from gdfe.measure import rigid_align
from gdfe.paper import FIG6_D
from gdfe.resources import estimate_run

__all__ = ["TOLERANCE_FRACTION", "Reachability", "SurfaceDesign", "scale_for", "closest_reachable", "reachable_sizes", "natural_curvature",
           "target_start", "initial_coating", "Objective", "design_surface", "DEFAULT_ITERATIONS", "FOLD_TOL",
           "BRANCH_RATIO", "BRANCH_FLOOR"]

log = logging.getLogger(__name__)

#: L-BFGS-B iterations of :func:`design_surface` by default.
DEFAULT_ITERATIONS = 60
#: The optimisation's folds continue from the last one (smooth, and cheap); where the design then folds
#: from the flat print more than BRANCH_RATIO times as far from the target (RMS) as on the continued
#: folds, and by more than BRANCH_FLOOR of the tolerance, the flat print takes another branch (a saddle
#: turned by 90 degrees, a dome inside out): a second optimisation folds every evaluation from the flat print.
BRANCH_RATIO = 2.0
BRANCH_FLOOR = 0.1
#: Tolerance (units of h) of the folds inside the optimisation: the adjoint gradient is as
#: accurate as the equilibrium (the gradient test checks it at this tolerance).
FOLD_TOL = 1e-8


#: The default tolerance of a design: its printed fold within this fraction of the film's size RMS.
TOLERANCE_FRACTION = 0.01


def natural_curvature(II):
    """The isotropic natural curvature [1/mm] a film needs for the second fundamental forms ``II`` ``(k, 2, 2)``.

    The larger principal curvature (with its sign) where the Gaussian curvature is >= 0 (a
    sphere's radius, a cylinder's: an isotropically bent thin film rolls into a cylinder of its
    natural radius), the mean curvature where it is negative (a saddle).
    """
    ev = np.linalg.eigvalsh(II)
    K = ev[:, 0] * ev[:, 1]
    big = np.where(np.abs(ev[:, 1]) >= np.abs(ev[:, 0]), ev[:, 1], ev[:, 0])
    return np.where(K >= 0, big, ev.mean(axis=1))


@dataclasses.dataclass(frozen=True)
class Reachability:
    """Step 1: the placement of the film on the target and whether the target is within reach.

    Attributes
    ----------
    sigma : float
        ``u = sigma p``.
    margin : float
        Smallest margin of the face contractions to ``[0, c_0]`` (>= 0: within reach of the
        estimate; < 0: the contraction the target lacks).
    reachable : bool
    mid_range : (2,) floats
        Smallest and largest mid-surface contraction the target needs.
    face_range : (2,) floats
        Smallest and largest face contraction it needs.
    c0 : float
        The film's largest contraction.
    metric_ratio : float
        Largest over smallest length ratio the target needs (isotropic shrink gives at most
        ``1 / (1 - c0)``).
    curvature_max : float [1/mm]
        Largest natural curvature it needs (a fully one-sided coat gives about ``c0 / h``).
    """

    sigma: float
    margin: float
    reachable: bool
    mid_range: tuple
    face_range: tuple
    c0: float
    metric_ratio: float
    curvature_max: float

    def text(self):
        head = (f"needs mid-surface contractions {self.mid_range[0]:.3f}..{self.mid_range[1]:.3f} and face "
                f"contractions {self.face_range[0]:.3f}..{self.face_range[1]:.3f}; the film gives 0..{self.c0:.3f}")
        if self.reachable:
            return f"within reach (margin {self.margin:.3f} in contraction): {head}"
        return (f"OUT OF REACH by {-self.margin:.3f} in contraction: {head} (length ratio {self.metric_ratio:.3f} "
                f"needed, {1 / (1 - self.c0):.3f} possible; natural curvature up to {self.curvature_max:.3g} /mm)")

    def as_dict(self):
        return {"sigma": self.sigma, "margin": self.margin, "reachable": self.reachable,
                "mid_contraction_range": list(self.mid_range), "face_contraction_range": list(self.face_range),
                "c0": self.c0, "metric_ratio_needed": self.metric_ratio,
                "metric_ratio_possible": 1.0 / (1.0 - self.c0), "natural_curvature_max_per_mm": self.curvature_max,
                "text": self.text()}


def _needs(target, p, sigma, h):
    """Mid contraction ``1 - lambda``, face difference ``h kappa lambda`` and ``lambda`` at film points ``p``."""
    lam = target.metric_factor(p, sigma)
    kappa = natural_curvature(target.second_form(p, sigma))
    return 1.0 - lam, h * kappa * lam, lam, kappa


def _margin(target, p, sigma, h, c0):
    cm, dc, _, _ = _needs(target, p, sigma, h)
    half = 0.5 * np.abs(dc)
    return float(np.min(np.minimum(cm - half, c0 - half - cm)))


def scale_for(target, film, sigma=None):
    """Step 1: the scale ``sigma`` and the :class:`Reachability` of ``target`` on ``film``.

    ``sigma`` is the target's own (a mesh), the one given, or the one that maximises the
    smallest margin of the face contractions to ``[0, c_0]`` over the film's points.
    """
    check_instance("target", target, Target)
    check_instance("film", film, Film)
    p = film.mid.flat
    h, c0 = film.h, film.c0
    if sigma is None:
        sigma = target.sigma
    if sigma is None:
        from scipy.optimize import minimize_scalar

        grid = np.linspace(0.3, 1.05, 151)
        vals = np.array([_margin(target, p, s, h, c0) for s in grid])
        k = int(np.argmax(vals))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        res = minimize_scalar(lambda s: -_margin(target, p, s, h, c0), bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-6})
        sigma = float(res.x) if -res.fun >= vals[k] else float(grid[k])
    sigma = check_positive("sigma", sigma)
    cm, dc, lam, kappa = _needs(target, p, sigma, h)
    margin = _margin(target, p, sigma, h, c0)
    faces = np.concatenate([cm + 0.5 * dc, cm - 0.5 * dc])
    return sigma, Reachability(sigma=sigma, margin=margin, reachable=margin >= 0.0,
                               mid_range=(float(cm.min()), float(cm.max())),
                               face_range=(float(faces.min()), float(faces.max())), c0=c0,
                               metric_ratio=float(lam.max() / lam.min()), curvature_max=float(np.abs(kappa).max()))


def closest_reachable(target, film, t_min=1e-3):
    """The closest target of the same kind within reach: its curvature scaled by the largest ``t`` <= 1.

    Returns ``(t, Target)``, ``(1, target)`` when the target is within reach, or ``(None, None)``
    for a target without a family (a mesh) or none within reach above ``t_min``.
    """
    if target.family is None:
        return None, None
    if scale_for(target, film)[1].reachable:
        return 1.0, target
    lo, hi = t_min, 1.0
    if not scale_for(target.family(lo), film)[1].reachable:
        return None, None
    for _ in range(30):
        mid = math.sqrt(lo * hi)
        if scale_for(target.family(mid), film)[1].reachable:
            lo = mid
        else:
            hi = mid
        if hi / lo < 1.0 + 1e-4:
            break
    return lo, target.family(lo)


def reachable_sizes(target, film):
    """For a target of fixed size (a mesh, ``target.sigma`` set): the film sizes within reach of step 1's estimate.

    The film of side ``s'`` covers the same conformal coordinates ``u = sigma p`` as this one with
    ``sigma' s' = sigma s``, so the metric factor becomes ``lambda = sigma' f(u)`` while the
    curvature (per mm of the target) stays: the margin is scanned over ``sigma'``.

    Returns
    -------
    dict
        ``size_mm`` (the film size [mm] with the largest margin, scaled from the film's largest side),
        ``margin`` there, ``sizes_mm`` (``[smallest, largest]`` within reach, or None when none is).
    """
    check_instance("target", target, Target)
    check_instance("film", film, Film)
    if target.sigma is None:
        raise GdfeError("target: expected a target of fixed size (a mesh), got an analytic one")
    p = film.mid.flat
    s0 = float(target.sigma)
    f = target.metric_factor(p, s0) / s0
    dc = film.h * np.abs(natural_curvature(target.second_form(p, s0)))

    def margin(k):
        lam = k * f
        half = 0.5 * dc * lam
        return float(np.min(np.minimum(1.0 - lam - half, film.c0 - half - (1.0 - lam))))

    grid = np.linspace(0.3, 1.05, 301)
    vals = np.array([margin(k) for k in grid])
    size = float(max(film.shape) * film.pixel)
    best = int(np.argmax(vals))
    ok = grid[vals >= 0]
    return {"size_mm": size * s0 / float(grid[best]), "margin": float(vals[best]),
            "sizes_mm": [size * s0 / float(ok.max()), size * s0 / float(ok.min())] if ok.size else None}


def initial_coating(target, film, sigma):
    """Step 1's coating fractions ``(m, 2)`` (top, bottom) at the cells, clipped to [0, 1]."""
    cm, dc, _, _ = _needs(target, film.cell_centres, sigma, film.h)
    c = np.column_stack([cm + 0.5 * dc, cm - 0.5 * dc])
    return np.clip(1.0 - c / film.c0, 0.0, 1.0)


def _normals(target, p, sigma, size):
    eps = 1e-4 * size
    ex, ey = np.array([eps, 0.0]), np.array([0.0, eps])
    Xu = target.point(p + ex, sigma) - target.point(p - ex, sigma)
    Xv = target.point(p + ey, sigma) - target.point(p - ey, sigma)
    n = np.cross(Xu, Xv)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def target_start(target, film, sigma):
    """The film's vertices ``(n, 3)`` [mm] laid on the target: mid-surface on it, faces ``h / 2`` off along its normal."""
    mid = film.mid
    T = target.point(mid.flat, sigma)
    nrm = _normals(target, mid.flat, sigma, float(np.max(film.shape) * film.pixel))
    V = np.zeros((film.base.mesh.n_points, 3))
    V[mid.bottom] = T - 0.5 * film.h * nrm
    V[mid.top] = T + 0.5 * film.h * nrm
    return V


class Objective:
    """``J(V)``: mean squared distance of the mid-surface points from their target points after the
    best rigid motion (Kabsch), in units of ``h^2``, and its gradient by the design's vertices.

    It does not change under rigid motions of ``V`` (the adjoint needs that).
    """

    def __init__(self, film, points):
        self.film = film
        self.mid = film.mid
        self.T = np.asarray(points, float)

    def __call__(self, V):
        M = self.mid.points(V)
        Q, t = rigid_align(M, self.T)
        r = M @ Q.T + t - self.T
        h2 = self.film.h ** 2
        J = float(np.mean(np.einsum("ij,ij->i", r, r))) / h2
        g = (2.0 / (len(M) * h2)) * (r @ Q)
        return J, self.mid.pull_back(g, len(V))


class _Quiet(logging.Filter):
    """Counts and holds back the solver's warnings inside the optimisation loop (reported as one number)."""

    def __init__(self):
        super().__init__()
        self.count = 0

    def filter(self, record):
        if record.levelno >= logging.WARNING:
            self.count += 1
            return False
        return True


@dataclasses.dataclass
class SurfaceDesign:
    """Outcome of :func:`design_surface`.

    Attributes
    ----------
    target : Target
    film : Film
    sigma : float
    reachability : Reachability
    closest : dict or None
        Where the target is out of reach, the closest within reach, with its ``text``: for an
        analytic target the one of the same kind (:func:`closest_reachable`: ``t``, its curvature
        over the target's, ``params`` and ``distance``, its patch from the target's after rigid
        alignment, :meth:`Distance.as_dict`); for a mesh the film sizes that reach it
        (:func:`reachable_sizes`).
    rho : (m, 2) float array
        The relaxed coating fractions (top, bottom) after the filter.
    top, bottom : (nx, ny) bool arrays
        The printable masks (True = coated).
    relaxed, printable, initial : gdfe.Result
        The forward checks (from the flat print, :func:`gdfe.simulate`) of the relaxed design,
        the printed one and the optimisation's start.
    relaxed_distance, printable_distance : Distance
    initial_distance : Distance
        The fold of step 1's estimate (the optimisation's start), for comparison.
    optimised_rms_mm : float
        The optimisation's last objective as an RMS [mm] (folds continued from the target's shape).
    history : list of dict
        Per evaluation: ``J``, ``rms_mm``, ``seconds`` (since the start), fold iterations.
    iterations : int
        L-BFGS-B iterations.
    evaluations : int
        Folds and adjoint solves.
    message : str
        L-BFGS-B's stopping message.
    seconds : dict
        Wall-clock time of each step.
    solver_warnings : int
        Solver warnings held back during the optimisation (folds drifting between near-equal states).
    unconverged_folds : int
        Folds inside the optimisation that did not converge.
    masks_ok : bool
        Whether both masks respect ``w_min`` (:func:`gdfe.inverse2d.masks.min_feature_ok`).
    tolerance_mm : float
        The RMS distance below which the target counts as reached.
    options : dict
        The choices the design was made with.
    target_surface : TriangleSurface
        The target's patch the distances are measured to.
    branch : dict or None
        The optimised design's objective as an RMS [mm] on the continued folds and folded from
        the flat print, and whether a second optimisation from the flat print followed
        (:data:`BRANCH_RATIO`); None without optimisation.
    """

    target: Target
    film: Film
    sigma: float
    reachability: Reachability
    closest: dict | None
    rho: np.ndarray
    top: np.ndarray
    bottom: np.ndarray
    relaxed: object
    printable: object
    initial: object
    relaxed_distance: Distance
    printable_distance: Distance
    initial_distance: Distance
    optimised_rms_mm: float
    history: list
    iterations: int
    evaluations: int
    message: str
    seconds: dict
    solver_warnings: int
    unconverged_folds: int
    masks_ok: bool
    tolerance_mm: float
    options: dict
    target_surface: object = None
    branch: dict | None = None

    @property
    def reached(self) -> bool:
        """Whether the printed design's fold (converged) is within :attr:`tolerance_mm` RMS of the target."""
        return bool(self.printable.converged and self.printable_distance.rms_mm <= self.tolerance_mm)

    def verdict(self) -> str:
        """One sentence: reached, or by how much and why not."""
        d = self.printable_distance
        if not self.printable.converged:
            return (f"the printed design's fold did not converge (residual {self.printable.residual:.2g}): "
                    "its distance is not an answer")
        if self.reached:
            return (f"reached: the printed fold is within {d.rms_mm:.3g} mm RMS ({d.max_mm:.3g} mm max) of the "
                    f"target, tolerance {self.tolerance_mm:.3g} mm")
        rd = self.relaxed_distance
        if self.relaxed.converged and rd.rms_mm <= self.tolerance_mm:  # the masks lost what the fractions had
            why = (f"the relaxed design (coating fractions per pixel) reaches it ({rd.rms_mm:.3g} mm RMS), but "
                   f"its {self.options['projection']} projection to printable masks in blocks of "
                   f"{self.options['w_min_mm']:g} mm loses the fold: try a smaller w_min or the other projection")
        elif not self.reachability.reachable:
            why = f"the target is {self.reachability.text()}"
        else:
            why = ("the target is within the estimate's reach, but the fold found does not get there"
                   + (f": {self.target.note}" if self.target.note else ""))
        near = ""
        if self.closest is not None:
            near = f"; the closest within reach: {self.closest['text']}"
        return (f"NOT REACHED: the closest fold found misses the target by {d.rms_mm:.3g} mm RMS ({d.max_mm:.3g} mm "
                f"max, Hausdorff {d.hausdorff_mm:.3g} mm), tolerance {self.tolerance_mm:.3g} mm; {why}{near}")

    def summary(self) -> dict:
        """The numbers for JSON.

        At the top level: the printed fold's distance (``rms_mm``, ``max_mm``, ``hausdorff_mm``,
        ``target_rms_mm``), whether it ``converged`` and ``reached`` the target, the ``verdict``,
        the L-BFGS-B ``iterations`` and ``evaluations``; ``relaxed`` and ``initial`` (the start)
        hold the same distances of the relaxed design's and the start's folds.
        """
        pd_, rd, idist = self.printable_distance, self.relaxed_distance, self.initial_distance
        return {
            **pd_.as_dict(), "converged": bool(self.printable.converged), "reached": self.reached,
            "tolerance_mm": self.tolerance_mm, "verdict": self.verdict(),
            "iterations": self.iterations, "evaluations": self.evaluations,
            "target": self.target.summary(), "sigma": self.sigma, "reachability": self.reachability.as_dict(),
            "closest_reachable": self.closest,
            "film": {"nx": self.film.shape[0], "ny": self.film.shape[1], "pixel_mm": self.film.pixel,
                     "h_mm": self.film.h, "d_mm": self.film.d, "c0": self.film.c0, "cells": self.film.n_cells,
                     "model": self.film.model.name},
            "printable": {**pd_.as_dict(), "converged": bool(self.printable.converged),
                          "iterations": int(self.printable.iterations),
                          "penetration_mm": float(self.printable.summary().get("penetration_mm", 0.0)),
                          "coated_fraction": {"top": float(self.top[self.film.mask if self.film.mask is not None
                                                                     else slice(None)].mean()),
                                              "bottom": float(self.bottom[self.film.mask if self.film.mask is not None
                                                                           else slice(None)].mean())},
                          "masks_respect_w_min": bool(self.masks_ok)},
            "relaxed": {**rd.as_dict(), "converged": bool(self.relaxed.converged),
                        "optimised_rms_mm": self.optimised_rms_mm},
            "initial": {**idist.as_dict(), "converged": bool(self.initial.converged)},
            "optimisation": {"message": self.message, "branch": self.branch,
                             "solver_warnings": self.solver_warnings, "unconverged_folds": self.unconverged_folds,
                             "history": self.history},
            "seconds": self.seconds, "options": self.options,
        }


def _target_gap(near, film, surf):
    """Distance of target ``near``'s patch (at its own scale on ``film``) from the patch ``surf``."""
    s_near, _ = scale_for(near, film)
    mid = film.mid
    return surface_distance(near.point(mid.flat, s_near), mid.triangles, surf)


def _distance(result, film, surf, designed):
    mid = film.mid
    return surface_distance(mid.points(result.points), mid.triangles, surf, designed=designed)


@dataclasses.dataclass(frozen=True)
class _Options:
    """The checked choices of a design and the lengths derived from them (:attr:`SurfaceDesign.options`).

    Attributes
    ----------
    pixel, w_min, d, h : float [mm]
    block : int
        Pixels per side of a ``w_min`` block.
    iterations : int
    projection : str
    radius : float [mm]
        Radius of the density filter.
    size : float [mm]
        The target film's larger side.
    tolerance_mm : float
    """

    pixel: float
    w_min: float
    block: int
    d: float
    h: float
    iterations: int
    projection: str
    radius: float
    size: float
    tolerance_mm: float

    def as_dict(self):
        """The choices for :attr:`SurfaceDesign.options`."""
        return {"pixel_mm": self.pixel, "w_min_mm": self.w_min, "block_pixels": self.block, "d_mm": self.d,
                "h_mm": self.h, "iterations": self.iterations, "projection": self.projection,
                "filter_radius_mm": self.radius,
                "objective": "mean squared distance of the mid-surface points from their target points after "
                             "rigid alignment, units of h^2"}


def _check_options(target, pixel, w_min, d, h, iterations, projection, filter_radius, tolerance_mm):
    """The :class:`_Options` of :func:`design_surface`'s arguments, each checked where it enters."""
    import gdfe

    check_instance("target", target, Target)
    pixel = check_positive("pixel", pixel)
    w_min = pixel if w_min is None else check_positive("w_min", w_min)
    if w_min < pixel * (1 - 1e-9):
        raise GdfeError(f"w_min: expected at least one pixel ({pixel:g} mm), got {w_min:g}")
    iterations = check_int("iterations", iterations, minimum=0)
    projection = check_choice("projection", projection, PROJECTIONS)
    h = gdfe.paper.H if h is None else check_positive("h", h)
    b = block_size(w_min, pixel)
    radius = 2.0 * b * pixel if filter_radius is None else check_number("filter_radius", filter_radius, minimum=0.0)
    size = float(np.max(target.film_size))
    tol_mm = TOLERANCE_FRACTION * size if tolerance_mm is None else check_positive("tolerance_mm", tolerance_mm)
    return _Options(pixel=pixel, w_min=w_min, block=b, d=d, h=h, iterations=iterations, projection=projection,
                    radius=radius, size=size, tolerance_mm=tol_mm)


def _whole_pixel_film(target, pixel, h, d, model):
    """The :class:`Film` of the target's film size rounded to whole pixels, cut to its outline."""
    nx, ny = (int(round(float(v) / pixel)) for v in target.film_size)
    if min(nx, ny) < 2:
        raise GdfeError(f"pixel: expected at most half the film's smaller side ({float(min(target.film_size)):g} mm), "
                        f"got {pixel:g} mm")
    est = estimate_run(nx * ny)
    if not est.fits:
        raise GdfeError(f"pixel: expected a film that fits in memory, got {nx} x {ny} pixels ({est.text()}); "
                        "use a larger pixel or a smaller film")
    mask = None
    if target.film_mask is not None:
        x = (np.arange(nx) + 0.5) * pixel - 0.5 * nx * pixel
        y = (np.arange(ny) + 0.5) * pixel - 0.5 * ny * pixel
        X, Y = np.meshgrid(x, y, indexing="ij")
        mask = np.asarray(target.film_mask(np.column_stack([X.ravel(), Y.ravel()])), bool).reshape(nx, ny)
    return Film((nx, ny), pixel, h, d, model=model, mask=mask)


@dataclasses.dataclass(frozen=True)
class _Placement:
    """Step 1 on the film: the scale, the reachability, the target's patch and, out of reach, the closest answer.

    Attributes
    ----------
    sigma : float
    reachability : Reachability
    surface : TriangleSurface
        The target's patch the distances are measured to.
    closest : dict or None
        :attr:`SurfaceDesign.closest`.
    """

    sigma: float
    reachability: Reachability
    surface: object
    closest: dict | None


def _place(target, film, sigma, opts):
    """Step 1: the :class:`_Placement` of ``target`` on ``film`` (``sigma`` forced, or None)."""
    sigma, reach = scale_for(target, film, sigma)
    rect = np.array(film.shape, float) * opts.pixel
    surf = patch(target, sigma, rect, min(opts.pixel, opts.size / 100.0), target.film_mask)
    return _Placement(sigma=sigma, reachability=reach, surface=surf, closest=_closest_answer(target, film, reach, surf))


def _closest_answer(target, film, reach, surf):
    """What is within reach where the target is not (:attr:`SurfaceDesign.closest`); None where it is, or nothing is."""
    if reach.reachable:
        return None
    if target.family is not None:
        return _closest_of_its_kind(target, film, surf)
    if target.sigma is not None:
        return _film_sizes_within_reach(target, film)
    return None


def _closest_of_its_kind(target, film, surf):
    """The closest target of the same kind within reach and its distance from ``target``'s patch ``surf``, or None."""
    t, near = closest_reachable(target, film)
    if near is None:
        return None
    gap = _target_gap(near, film, surf)
    return {"t": t, "params": near.params, "distance": gap.as_dict(),
            "text": (f"a {near.kind} with " + ", ".join(f"{k} {v:.4g}" for k, v in near.params.items())
                     + f" (curvature x {t:.3g}), {gap.rms_mm:.3g} mm RMS ({gap.max_mm:.3g} mm max) "
                       "from the target")}


def _film_sizes_within_reach(target, film):
    """For a target of fixed size (a mesh): the film sizes that bring it within reach (:func:`reachable_sizes`)."""
    sizes = reachable_sizes(target, film)
    text = (f"this {target.kind} on a film of {sizes['size_mm']:.3g} mm (films of {sizes['sizes_mm'][0]:.3g} to "
            f"{sizes['sizes_mm'][1]:.3g} mm are within reach)" if sizes["sizes_mm"] is not None else
            f"none: no film size brings this {target.kind} within reach (best margin {sizes['margin']:.3f} at "
            f"{sizes['size_mm']:.3g} mm)")
    return {**sizes, "text": text}


@dataclasses.dataclass
class _Optimisation:
    """Step 2's objective and gradient in the design variables, and what carries from one evaluation to the next.

    The design variables ``x`` ``(m, 2)`` (top, bottom) are the coating fractions before the
    density filter ``F``. L-BFGS-B calls :meth:`evaluate`; each fold starts from the last
    converged one (:attr:`V`), or from the flat print once :attr:`flat` is set.

    Attributes
    ----------
    film : Film
    objective : Objective
    F : (m, m) sparse matrix
        The density filter.
    h : float [mm]
        The film thickness ``J`` is measured in.
    started : float
        ``time.perf_counter()`` at the start of step 2, for the records' ``seconds``.
    callback : callable or None
        ``callback(record)`` after every evaluation.
    V : (n, 3) float array [mm]
        The last converged fold, where the next one starts.
    best : (float, (m, 2) float array)
        ``J`` and ``x`` of the best converged evaluation so far.
    flat : bool
        Whether every evaluation folds from the flat print.
    n, bad : int
        Evaluations, and those whose fold did not converge.
    history : list of dict
        :attr:`SurfaceDesign.history`.
    """

    film: Film
    objective: Objective
    F: object
    h: float
    started: float
    callback: object
    V: np.ndarray
    best: tuple
    flat: bool = False
    n: int = 0
    bad: int = 0
    history: list = dataclasses.field(default_factory=list)

    def fractions(self, x):
        """The filtered coating fractions ``rho`` ``(m, 2)`` of the design variables ``x``."""
        return np.column_stack([self.F @ x[:, 0], self.F @ x[:, 1]])

    def evaluate(self, xflat):
        """``J`` and its gradient by the flattened design variables, through the fold's adjoint; recorded."""
        film = self.film
        x = xflat.reshape(-1, 2)
        f = fold(film.relaxed(self.fractions(x)), start=None if self.flat else self.V, tol=FOLD_TOL)
        self.n += 1
        if not f.converged:
            self.bad += 1
        else:
            self.V = f.points
        J, dJdV = self.objective(f.points)
        grad_c, _ = contraction_gradient(f, dJdV)
        grad_x = -film.c0 * np.column_stack([self.F.T @ grad_c[:, 0], self.F.T @ grad_c[:, 1]])
        if J < self.best[0] and f.converged:
            self.best = (J, x.copy())
        rec = {"evaluation": self.n, "J": J, "rms_mm": self.h * math.sqrt(J), "fold_iterations": f.iterations,
               "converged": f.converged, "seconds": time.perf_counter() - self.started,
               "folds_from": "flat print" if self.flat else "last fold"}
        self.history.append(rec)
        if self.callback is not None:
            self.callback(rec)
        return J, grad_x.ravel()

    def phase(self, x_start, iterations):
        """One L-BFGS-B run from ``x_start``: its iterations and stopping message."""
        from scipy.optimize import minimize

        res = minimize(self.evaluate, x_start.ravel(), jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * x_start.size,
                       options={"maxiter": iterations, "ftol": 1e-12, "gtol": 1e-10, "maxcor": 20})
        return int(res.nit), str(res.message)

    def flat_print_objective(self, x):
        """``J`` of the design ``x`` folded from the flat print, as in the oven (inf where the fold fails)."""
        f = fold(self.film.relaxed(self.fractions(x)), tol=FOLD_TOL)
        return self.objective(f.points)[0] if f.converged else np.inf


#: The solver's loggers whose warnings the optimisation holds back.
_SOLVER_LOGGERS = ("gdfe.solver", "gdfe.solver.newton", "gdfe.solver.simulation")


@contextlib.contextmanager
def _solver_warnings_held_back():
    """Holds back and counts (the :class:`_Quiet` it yields) the solver's warnings for the ``with`` block."""
    quiet = _Quiet()
    loggers = [logging.getLogger(name) for name in _SOLVER_LOGGERS]
    for logger in loggers:
        logger.addFilter(quiet)
    try:
        yield quiet
    finally:
        for logger in loggers:
            logger.removeFilter(quiet)


@dataclasses.dataclass(frozen=True)
class _Phases:
    """What step 2's optimisation reports: L-BFGS-B ``iterations`` and ``message``, and the ``branch`` check."""

    iterations: int
    message: str
    branch: dict | None


def _optimise(opt, x0, iterations, tolerance_mm):
    """Step 2: L-BFGS-B from ``x0`` on continued folds, then from the flat print where it folds onto another branch."""
    opt.evaluate(x0.ravel())
    if iterations == 0:
        return _Phases(iterations=0, message="no optimisation (iterations=0)", branch=None)
    nit, message = opt.phase(x0, iterations)
    # the oven folds the print from flat: is that the branch the folds continued on?
    J_cont, x_cont = opt.best
    J_flat = opt.flat_print_objective(x_cont)
    rms_cont, rms_flat = opt.h * math.sqrt(J_cont), opt.h * math.sqrt(J_flat)
    switch = rms_flat > BRANCH_RATIO * rms_cont and rms_flat > BRANCH_FLOOR * tolerance_mm
    branch = {"continued_rms_mm": rms_cont, "flat_print_rms_mm": rms_flat, "second_phase": bool(switch)}
    if switch:
        log.info("inverse2d: from the flat print the design folds %.3g mm RMS from the target against %.3g "
                 "mm on the folds continued from the target's shape: a second optimisation, every fold "
                 "from the flat print", rms_flat, rms_cont)
        opt.flat = True
        opt.best = (J_flat, x_cont)
        nit2, message2 = opt.phase(x_cont, iterations)
        nit += nit2
        message = f"{message}; folds from the flat print: {message2}"
        branch["flat_print_best_rms_mm"] = opt.h * math.sqrt(opt.best[0])
    return _Phases(iterations=nit, message=message, branch=branch)


def design_surface(target, *, pixel=0.125, w_min=None, d=FIG6_D, h=None, model=None, iterations=DEFAULT_ITERATIONS,
                   projection="halftone", filter_radius=None, sigma=None, tolerance_mm=None, callback=None):
    """Design the coating of both faces of a film so that its GDFE fold matches ``target``.

    Parameters
    ----------
    target : Target
        From :func:`gdfe.inverse2d.make_target` (its ``film_size`` is the film's).
    pixel : float [mm]
        Printer pixel = cell size.
    w_min : float [mm], optional
        Narrowest printed feature, coated or free (default one pixel).
    d : float [mm]
        Passive thickness of the coat on both faces.
    h : float [mm], optional
        Film thickness (default the paper's 0.29 mm).
    model : DeformationModel or path, optional
        Default the paper's Eq. 3.
    iterations : int
        L-BFGS-B iterations (0: step 1's estimate only), of each phase: the folds continue from the
        last one, and where the flat print folds onto another branch a second phase folds every
        evaluation from the flat print (:data:`BRANCH_RATIO`).
    projection : {"halftone", "nested", "threshold"}
        :func:`gdfe.inverse2d.masks.project`.
    filter_radius : float [mm], optional
        Radius of the density filter on the design variables; default two blocks of ``w_min``
        (the scale a halftone reproduces), 0 for none.
    sigma : float, optional
        Force the scale of step 1.
    tolerance_mm : float, optional
        RMS distance below which the target counts as reached (default 1 % of the film's size).
    callback : callable, optional
        ``callback(record)`` after every evaluation (a progress bar).

    Returns
    -------
    SurfaceDesign
    """
    import gdfe

    opts = _check_options(target, pixel, w_min, d, h, iterations, projection, filter_radius, tolerance_mm)
    seconds = {}
    t0 = time.perf_counter()
    film = _whole_pixel_film(target, opts.pixel, opts.h, d, model)
    place = _place(target, film, sigma, opts)
    surf = place.surface
    seconds["placement"] = time.perf_counter() - t0
    log.info("inverse2d: %s on %d x %d pixels (%d cells); %s", target.name, film.shape[0], film.shape[1],
             film.n_cells, place.reachability.text())

    t1 = time.perf_counter()
    T = target.point(film.mid.flat, place.sigma)
    objective = Objective(film, T)
    F = density_filter(film.cell_centres, opts.radius)
    # step 1's estimate is smooth: the filter leaves it almost as it is
    x0 = initial_coating(target, film, place.sigma)
    opt = _Optimisation(film=film, objective=objective, F=F, h=opts.h, started=t1, callback=callback,
                        V=target_start(target, film, place.sigma), best=(np.inf, x0))
    with _solver_warnings_held_back() as quiet:
        phases = _optimise(opt, x0, opts.iterations, opts.tolerance_mm)
    J_best, x_best = opt.best
    rho = opt.fractions(x_best)
    seconds["optimisation"] = time.perf_counter() - t1

    t2 = time.perf_counter()
    relaxed = gdfe.simulate(film.relaxed(rho))
    rd = _distance(relaxed, film, surf, T)
    initial = gdfe.simulate(film.relaxed(opt.fractions(x0)))
    idist = _distance(initial, film, surf, T)
    seconds["relaxed_check"] = time.perf_counter() - t2

    t3 = time.perf_counter()
    top, bottom = project(film.grid(rho[:, 0]), film.grid(rho[:, 1]), opts.block, present=film.mask,
                          method=opts.projection)
    ok = all(min_feature_ok(m, opts.block, film.mask) for m in (top, bottom))
    printable = gdfe.simulate(film.printable(top, bottom))
    pd_ = _distance(printable, film, surf, T)
    seconds["printable_check"] = time.perf_counter() - t3
    seconds["total"] = time.perf_counter() - t0
    return SurfaceDesign(target=target, film=film, sigma=place.sigma, reachability=place.reachability,
                         closest=place.closest, rho=rho, top=top, bottom=bottom, relaxed=relaxed, printable=printable,
                         initial=initial, relaxed_distance=rd, printable_distance=pd_, initial_distance=idist,
                         optimised_rms_mm=opts.h * math.sqrt(J_best), history=opt.history,
                         iterations=phases.iterations, evaluations=opt.n, message=phases.message, seconds=seconds,
                         solver_warnings=quiet.count, unconverged_folds=opt.bad, masks_ok=ok,
                         tolerance_mm=opts.tolerance_mm, options=opts.as_dict(), target_surface=surf,
                         branch=phases.branch)
