"""Diagnosis of shapes: a scanned part against the GDFE simulation of its design.

:func:`diagnose_shape`

1. refuses a **degenerate** cloud at once (fewer than 4 distinct points, or points that
   span less than a line's worth of the part: identical or collinear points);
2. simulates the design and **aligns** the measured shape to it rigidly: with
   correspondences (Kabsch) when the measurement is a mesh of the design (same vertices and
   cells, e.g. a VTU written by ``gdfe simulate``), else by iterative closest points from a
   correspondence-free start (:func:`~gdfe.diagnosis.align.align_icp`), measuring each
   point's exact distance to the simulated surface (:class:`~gdfe.diagnosis.surface.Surface`).
   A cloud with exactly the design's vertex count and no cells is aligned both ways and by
   correspondences when they fit at least as well (an exact copy of the vertices);
3. checks that **the scan is the part** (:func:`_match`): the RMS distance of the measured
   points to the simulated surface must stay within :data:`MATCH_RESIDUAL` of the part's
   size (its RMS radius), and the points must cover the part: the in-plane cells of the
   design that own a measured point's closest surface point must be at least
   :data:`MATCH_COVERAGE` of those that as many points spread evenly would reach. When the
   nominal simulation fails this, but not by far (:data:`CLEAR_MISMATCH`), the contraction
   ``1 - R`` of every contracting cell is scaled by one common factor (a bounded 1-D search
   within :data:`FACTORS`, at most 9 simulations) in case the whole part folded more or less
   than designed; if it still fails, the verdict is :data:`NO_MATCH`, with its residual,
   coverage and scale, and no region is named. Another part, a random cloud or a scale error
   (mm against cm or inches) end there, most before any search.

   The cases the thresholds were set on (scans of the three-hinge test strip, the Figure 6
   hinge and the tube example with regions changed, and scans of one of these parts against
   another's design), with their residuals and coverages before and after the common
   factor, are computed by the blind-diagnosis study (:func:`studies.blind_diagnosis.scan_checks`,
   its output's "Is the scan the part?" table);
4. reports the **deviation** per element and per region of the design
   (:func:`~gdfe.diagnosis.regions.design_regions`), both after the global alignment and
   after aligning each region alone (its own shape error, which a global alignment spreads
   over the whole part). The deviation of a set of points is the RMS distance
   ``sqrt(mean_i d_i^2)``; of an element, over its 8 vertices (correspondences) or over the
   measured points whose closest surface point lies on its faces (ICP);
5. **localises** the gap by fitting *forms* (:mod:`gdfe.diagnosis.shape_forms`): each
   contracting region's contraction ratio alone (a bounded 1-D search with a GDFE
   re-simulation per evaluation), the film's anisotropy (weaker along y, or along x) and each
   face's coat printed a few pixels off its mask along x or y. A form is credited only when
   the scan is further from the design than the model floor (``floor``, given by the user)
   and its noise combined, the form removes at least :data:`NAME_GAIN` of the deviation
   beyond the floor, and no rival form fits within :data:`RIVAL_TOL` of it; with rivals, the
   diagnosis credits nothing and names them. A credited region is joined by further regions
   while each removes at least :data:`NAME_GAIN` of what is left beyond the floor (refitted
   together); the deviation before and after is reported, and every form's fit.

A measured shape must be a scan of the surface: an exact copy of the simulated *vertices*
of a design with two or more cell layers through the film (``nz >= 2``) includes the vertices
inside the film, up to ``h / 2`` from any surface, which ICP can only split between the faces:
that, not the alignment, was the floor of tens of micrometres an exact copy kept. The copy's
surface vertices align by ICP to round-off, and a whole copy (the design's vertex count, no
cells) now takes the correspondence alignment when it fits at least as well; the numbers are
in the blind-diagnosis study's output.

Measured shapes are read by :func:`~gdfe.diagnosis.scan.load_measured`. Lengths in mm.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_array, check_choice, check_number, check_positive
from gdfe.diagnosis.align import align_icp
from gdfe.diagnosis.regions import design_regions
from gdfe.diagnosis.scan import check_points, load_measured
from gdfe.diagnosis.shape_forms import (EFFECT_OVER_FLOOR, NAME_GAIN, RIVAL_TOL, Credit, FormFit, beyond, credit,
                                        fit_film_forms, level_of, scan_noise)
from gdfe.diagnosis.surface import Surface

__all__ = ["ShapeDiagnosis", "diagnose_shape", "NAME_GAIN", "RIVAL_TOL", "ALIGNMENTS", "MATCH_RESIDUAL",
           "MATCH_COVERAGE", "NO_MATCH", "NO_GAP", "NO_GAP_BEYOND_FLOOR", "GAP_WITHIN_DISAGREEMENT"]

#: Largest RMS distance of the measured points to the simulated surface, over the part's RMS
#: radius, of a scan of the part (see the module docstring for the cases it was set on).
MATCH_RESIDUAL = 0.1
#: Smallest share of the design's in-plane cells the measured points reach, over the share
#: as many points spread evenly would reach.
MATCH_COVERAGE = 0.8
#: Beyond these (relative residual, coverage) of the nominal shape a scan does not match
#: without trying a common contraction factor.
CLEAR_MISMATCH = (0.5, 0.5)
#: Range of the common contraction factor tried.
FACTORS = (0.5, 2.0)
#: The verdict of a scan that is not the part.
NO_MATCH = "the scan does not match the design"
#: The ``align`` choices of :func:`diagnose_shape`.
ALIGNMENTS = ("auto", "correspondence", "icp")
#: The verdict when no form removes :data:`NAME_GAIN` of the deviation (beyond the floor, when
#: one is given): there may be a gap, but no form of the diagnosis localises it.
NO_GAP = "no gap localised"
#: The verdict, with a floor given, of a scan no further from the design than the floor and the noise.
NO_GAP_BEYOND_FLOOR = "no gap beyond the floor"
#: The verdict of a scan beyond the floor by less than the floor itself
#: (:data:`~gdfe.diagnosis.shape_forms.EFFECT_OVER_FLOOR`): what a form fits could be the models'
#: own disagreement.
GAP_WITHIN_DISAGREEMENT = "a gap no larger than the models' own disagreement: nothing credited"


@dataclasses.dataclass
class ShapeDiagnosis:
    """Result of :func:`diagnose_shape`.

    Attributes
    ----------
    verdict : str
        :data:`NO_MATCH`, ``"no gap localised"`` or ``"the gap lies in ..."`` (first in the
        text and the JSON).
    matches : bool
        Whether the scan is the part (see :func:`_match`); when not, no region is named.
    match : dict
        ``residual`` [mm] (RMS distance of the aligned points to the simulated surface),
        ``size`` [mm] (RMS radius of the simulated part), ``relative_residual``,
        ``coverage`` (share of the design's in-plane cells reached, over the share as many
        evenly spread points reach), ``scale`` (RMS radius of the cloud over the part's),
        ``factor`` (the common contraction factor the check settled on, 1 for the design),
        ``reasons`` (what failed), ``seconds``.
    method : str
        ``"correspondence"`` or ``"icp"``.
    rms_before, rms_after : float [mm]
        RMS deviation of the measurement from the simulated design, and after the correction.
    element_deviation : (m,) float array [mm]
        RMS deviation per element (NaN where no measured point fell).
    regions : list of dict
        Per region: ``name``, ``n_cells``, ``rms`` (global alignment), ``local_rms`` (region
        aligned alone), ``R_design``, ``single_fit`` R and ``single_fit_rms`` (overall RMS
        with only this region corrected), ``R_fit`` and ``rms_after`` (after the correction).
        Empty when the scan does not match.
    named : list of str
        Regions where the gap lies.
    corrected_R : dict of str -> float
        Contraction ratios fitted to the named regions.
    converged : bool
        Every GDFE solve converged.
    forms : list of dict
        Every form fitted (:class:`~gdfe.diagnosis.shape_forms.FormFit`: ``form``, ``kind``,
        ``params``, ``rms_after``): each region's contraction, the film's anisotropy weaker along
        y and along x, each face's coat offset along x and along y.
    outcome : str
        What the forms allow (:func:`~gdfe.diagnosis.shape_forms.credit`): ``"credited"``,
        ``"cannot_tell"``, ``"no_form"``, ``"within_disagreement"``, ``"within_floor"``, or
        ``"not_fitted"``.
    credited : dict or None
        The form credited (as in ``forms``).
    not_ruled_out : list of str
        With ``"cannot_tell"``: the forms that fit within
        :data:`~gdfe.diagnosis.shape_forms.RIVAL_TOL` of the best, the best first.
    floor : float [mm] or None
        The model floor given.
    noise : float [mm]
        The scan's noise (:func:`~gdfe.diagnosis.shape_forms.scan_noise`).
    level : float [mm]
        ``sqrt(floor^2 + noise^2)``: the RMS deviation a scan must exceed for a gap.
    gain : float
        Share of the deviation beyond the floor that the best form removes.
    """

    design_path: str
    measured_path: str
    method: str
    n_measured: int
    rms_before: float
    rms_after: float
    element_deviation: np.ndarray
    regions: list
    named: list
    corrected_R: dict
    converged: bool
    n_simulations: int
    transform: dict
    matches: bool = True
    match: dict = dataclasses.field(default_factory=dict)
    forms: list = dataclasses.field(default_factory=list)
    outcome: str = "not_fitted"
    credited: dict | None = None
    not_ruled_out: list = dataclasses.field(default_factory=list)
    floor: float | None = None
    noise: float = float("nan")
    level: float = float("nan")
    gain: float = 0.0

    @property
    def verdict(self) -> str:
        if not self.matches:
            return NO_MATCH
        if self.outcome == "cannot_tell":
            return "cannot tell which form: " + ", ".join(self.not_ruled_out)
        if self.outcome == "credited" and self.credited["kind"] != "region":
            return _form_words(self.credited)
        if not self.named:
            if self.outcome == "within_disagreement":
                return GAP_WITHIN_DISAGREEMENT
            return NO_GAP_BEYOND_FLOOR if (self.outcome == "within_floor" and self.floor is not None) else NO_GAP
        return "the gap lies in " + ", ".join(self.named)

    def as_dict(self) -> dict:
        return {"verdict": self.verdict, "matches": self.matches, "match": self.match,
                "design": self.design_path, "measured": self.measured_path, "alignment": self.method,
                "n_measured_points": self.n_measured, "rms_before": self.rms_before,
                "rms_after": self.rms_after,
                "shrink": 1.0 - self.rms_after / self.rms_before if self.rms_before > 0 else 0.0,
                "named": self.named, "corrected_R": self.corrected_R, "regions": self.regions,
                "element_deviation": [None if not np.isfinite(v) else float(v) for v in self.element_deviation],
                "converged": self.converged, "n_simulations": self.n_simulations,
                "transform": self.transform, "name_gain": NAME_GAIN, "rival_tolerance": RIVAL_TOL,
                "outcome": self.outcome, "credited": self.credited, "not_ruled_out": self.not_ruled_out,
                "forms": self.forms, "floor_mm": self.floor, "noise_mm": _finite(self.noise),
                "level_mm": _finite(self.level), "gain_beyond_floor": float(self.gain)}

    def text(self) -> str:
        m = self.match
        if not self.matches:
            lines = [f"{NO_MATCH}: {'; '.join(m['reasons'])}",
                     f"{self.measured_path} against {self.design_path}: {self.n_measured} points"
                     + (f", aligned by {self.method}" if self.method else "")]
            if m.get("residual") is not None:
                lines.append(f"RMS distance to the simulated surface {m['residual']:.4g} mm "
                             f"({100 * m['relative_residual']:.0f} % of the part's RMS radius "
                             f"{m['size']:.4g} mm; at most {100 * MATCH_RESIDUAL:.0f} %), coverage "
                             f"{m['coverage']:.2f} (at least {MATCH_COVERAGE:g}), scale {m['scale']:.3g}"
                             + (f", best common contraction factor {m['factor']:.3g}" if m.get("factor") != 1.0
                                else ""))
            lines.append("no region is named: the scan is not this part (another part, degenerate or random "
                         "points, or a scale error)")
            return "\n".join(lines)
        lines = [f"{self.verdict}",
                 f"{self.measured_path} against {self.design_path}: {self.n_measured} points, "
                 f"aligned by {self.method}; matches the design (RMS distance {m['residual']:.3g} mm, "
                 f"{100 * m['relative_residual']:.0f} % of its size; coverage {m['coverage']:.2f})",
                 f"RMS deviation {self.rms_before:.4g} mm"
                 + (f" -> {self.rms_after:.4g} mm after correcting {', '.join(self.named)}" if self.named else ""),
                 f"{'region':12s} {'cells':>6s} {'RMS':>9s} {'local RMS':>10s} {'R design':>9s} "
                 f"{'R alone':>8s} {'RMS if alone':>12s}"]
        for r in self.regions:
            sf = r.get("single_fit")
            lines.append(f"{r['name']:12s} {r['n_cells']:6d} {r['rms']:9.4g} {r['local_rms']:10.4g} "
                         + (f"{r['R_design']:9.4f} {sf:8.4f} {r['single_fit_rms']:12.4g}" if sf is not None
                            else f"{'-':>9s} {'-':>8s} {'-':>12s}"))
        lines += self._form_lines()
        if self.named:
            lines.append("the gap lies in " + ", ".join(
                f"{n} (R {self.regions_by_name()[n]['R_design']:.4f} -> {self.corrected_R[n]:.4f})"
                for n in self.named))
        else:
            lines.append(self._why_nothing())
        return "\n".join(lines)

    def _form_lines(self):
        if not self.forms:
            return []
        lines = [f"scan noise {self.noise:.3g} mm; floor "
                 + ("not given" if self.floor is None else f"{self.floor:.4g} mm")
                 + f"; a gap needs an RMS deviation above {self.level:.4g} mm (floor and noise in quadrature)",
                 f"{'form':36s} {'RMS after':>10s}  parameters"]
        for f in sorted(self.forms, key=lambda f: f["rms_after"]):
            par = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in f["params"].items())
            lines.append(f"{f['form']:36s} {f['rms_after']:10.4g}  {par}")
        return lines

    def _why_nothing(self):
        if self.outcome == "credited":
            return (f"credited: {self.verdict}; every other form leaves an RMS deviation more than "
                    f"{100 * RIVAL_TOL:.0f} % above its")
        if self.outcome == "cannot_tell":
            return (f"nothing is credited: {len(self.not_ruled_out)} forms leave RMS deviations within "
                    f"{100 * RIVAL_TOL:.0f} % of the best's; not ruled out: {', '.join(self.not_ruled_out)}")
        if self.outcome == "within_floor":
            return (f"the RMS deviation {self.rms_before:.4g} mm is within the floor and the noise "
                    f"({self.level:.4g} mm): {self.verdict}")
        if self.outcome == "within_disagreement":
            return (f"the RMS deviation {self.rms_before:.4g} mm exceeds the floor and the noise "
                    f"({self.level:.4g} mm) by less than {EFFECT_OVER_FLOOR:g} x the floor: a form's fit could be "
                    f"the models' own disagreement; {self.verdict}")
        return (f"no form removes {100 * NAME_GAIN:.0f} % of the deviation"
                + (" beyond the floor" if self.floor is not None else "") + f" (best {100 * self.gain:.0f} %): "
                + self.verdict)

    def regions_by_name(self):
        return {r["name"]: r for r in self.regions}


def _finite(v):
    return float(v) if v is not None and np.isfinite(v) else None


def _form_words(form):
    """The verdict of a credited form other than a region's contraction."""
    p = form["params"]
    if form["kind"] == "anisotropy":
        return (f"the film is anisotropic: it shrinks {p['ratio']:.3g} times as much along {p['weak_axis']} "
                f"as across it")
    return f"the {p['face']} coat is printed {p['pixels']:+d} pixels off its mask along {p['axis']}"


class _Comparer:
    """Deviation of the measurement from simulated shapes of one design (the alignment kept
    from one call to the next)."""

    def __init__(self, design, measured, cells, align, options, from_file):
        self.design = design
        self.measured = measured
        self.options = options
        self.n_sims = 0
        self.converged = True
        n = design.mesh.n_points
        # a mesh of the design: its vertices with the design's hexahedra (a file), or exactly
        # the design's vertices (an array passed in)
        same = measured.shape[0] == n and (
            (cells is not None and cells.shape == design.mesh.cells.shape
             and np.array_equal(cells, design.mesh.cells)) or (cells is None and not from_file))
        if align == "correspondence" and measured.shape[0] != n:
            raise GdfeError(f"measured: expected the design's {n} vertices in its order for correspondence "
                            f"alignment, got {measured.shape[0]} points")
        self.method = "correspondence" if (align == "correspondence" or (align == "auto" and same)) else "icp"
        # the design's vertex count without cells to prove it: try correspondences too
        self.maybe_vertices = align == "auto" and self.method == "icp" and measured.shape[0] == n
        self.Q, self.t = np.eye(3), np.zeros(3)
        self._first = None
        from gdfe.io import surface_faces

        self.faces = surface_faces(design)

    def simulate(self, R):
        return self.simulate_design(self.design.with_R(R))

    def simulate_design(self, design, mirror=False):
        """GDFE's shape of ``design`` (a changed copy of the design); x and y swapped back when
        ``mirror`` (a design mirrored across ``x = y``)."""
        import gdfe

        res = gdfe.simulate(design, **self.options)
        self.n_sims += 1
        self.converged &= bool(res.converged)
        return res.points[:, [1, 0, 2]] if mirror else res.points

    def compare(self, sim, restart=False):
        """Per-point deviations [mm] and the cell of each point (None: per vertex), after
        rigid alignment; ICP restarts from every axis flip when ``restart``."""
        from gdfe.measure import rigid_align

        if self.maybe_vertices:  # decided once, on the first shape compared
            self.maybe_vertices = False
            dev_i, owner_i = self.compare(sim, restart=True)
            Qi, ti = self.Q, self.t
            Q, t = rigid_align(self.measured, sim)
            dev_c = np.linalg.norm(self.measured @ Q.T + t - sim, axis=1)
            if np.sqrt(np.mean(dev_c**2)) <= np.sqrt(np.mean(dev_i**2)):
                self.method, self.Q, self.t = "correspondence", Q, t
                return dev_c, None
            self.Q, self.t = Qi, ti
            return dev_i, owner_i
        if self.method == "correspondence":
            Q, t = rigid_align(self.measured, sim)
            dev = np.linalg.norm(self.measured @ Q.T + t - sim, axis=1)
            self.Q, self.t = Q, t
            return dev, None
        surf = Surface(sim, self.design, faces=self.faces)
        if restart or self._first is None:
            Q, t, _ = align_icp(self.measured, surf)
            self._first = (Q, t)
        else:  # from the first alignment and from the last: the objective stays a function of R
            runs = [align_icp(self.measured, surf, start=s) for s in (self._first, (self.Q, self.t))]
            Q, t, _ = min(runs, key=lambda r: r[2])
        self.Q, self.t = Q, t
        _, dev, owner = surf.closest(self.measured @ Q.T + t)
        return dev, owner

    def rms(self, R):
        dev, _ = self.compare(self.simulate(R))
        return float(np.sqrt(np.mean(dev**2)))


def _rms_radius(P):
    """RMS distance of points to their centroid [mm]."""
    P = np.asarray(P, float)
    return float(np.sqrt(np.mean(np.sum((P - P.mean(0)) ** 2, axis=1))))


def _degenerate(measured, design):
    """Why a cloud cannot be a scan of the design (None when it can): too few distinct
    points, or points that span no more than a line (identical or collinear points)."""
    flat = design.mesh.points
    size = float(np.linalg.svd(flat - flat.mean(0), compute_uv=False)[0] / np.sqrt(len(flat)))
    distinct = np.unique(np.round(measured / (1e-9 * size)), axis=0).shape[0]
    if distinct < 4:
        return (f"the {len(measured)} points are only {distinct} distinct point(s): a degenerate cloud, "
                f"not a scan of a surface")
    sv = np.linalg.svd(measured - measured.mean(0), compute_uv=False) / np.sqrt(len(measured))
    if sv[1] < 1e-3 * size:
        return (f"the points span a line at most (spread {sv[0]:.3g} mm and {sv[1]:.2g} mm along their "
                f"principal axes, against {size:.3g} mm of the flat design): a degenerate cloud")
    return None


def _match(comp, sim, dev, owner):
    """Whether the aligned measurement is a scan of the simulated part (see the module docstring)."""
    design = comp.design
    n = len(comp.measured)
    if comp.method == "correspondence":
        size, coverage = _rms_radius(sim), 1.0
    else:
        size = _rms_radius(Surface(sim, design, faces=comp.faces).samples)
        cols = design.mesh.cell_ij
        key = cols[:, 0] * (int(cols[:, 1].max()) + 1) + cols[:, 1]
        m = np.unique(key).size
        hit = np.unique(key[owner]).size
        coverage = hit / (m * (1.0 - (1.0 - 1.0 / m) ** n))
    residual = float(np.sqrt(np.mean(dev**2)))
    rel = residual / size
    scale = _rms_radius(comp.measured) / size
    reasons = []
    if rel > MATCH_RESIDUAL:
        reasons.append(f"the points lie {residual:.3g} mm (RMS) from the simulated surface, "
                       f"{100 * rel:.0f} % of the part's size (at most {100 * MATCH_RESIDUAL:.0f} %)")
    if coverage < MATCH_COVERAGE:
        reasons.append(f"the points reach {100 * coverage:.0f} % of the part's cells that as many evenly spread "
                       f"points would reach (at least {100 * MATCH_COVERAGE:.0f} %)")
    if reasons and not 0.5 <= scale <= 2.0:
        reasons.append(f"the cloud is {scale:.3g} times the part's size: a unit error (mm against cm or "
                       f"inches) or another part?")
    return {"residual": residual, "size": size, "relative_residual": rel, "coverage": float(coverage),
            "scale": float(scale), "factor": 1.0, "reasons": reasons, "ok": not reasons}


def _check_match(comp, R0, sim0, dev, owner):
    """:func:`_match` of the design; when it fails, of the common factor of every contracting
    cell's contraction ``1 - R`` (within :data:`FACTORS`) that brings the points closest to the
    surface; not tried beyond :data:`CLEAR_MISMATCH`."""
    from scipy.optimize import minimize_scalar

    m = _match(comp, sim0, dev, owner)
    if m["ok"] or m["relative_residual"] > CLEAR_MISMATCH[0] or m["coverage"] < CLEAR_MISMATCH[1]:
        return m
    contracting = R0 < 1.0
    best = {"m": m}

    def trial(f):
        R = R0.copy()
        R[contracting] = np.clip(1.0 - f * (1.0 - R0[contracting]), 0.02, 1.0)
        sim = comp.simulate(R)
        d, o = comp.compare(sim, restart=True)
        mm = dict(_match(comp, sim, d, o), factor=float(f))
        if mm["relative_residual"] < best["m"]["relative_residual"]:
            best["m"] = mm
        return mm["relative_residual"]

    if contracting.any():
        minimize_scalar(trial, bounds=FACTORS, method="bounded", options={"xatol": 0.02, "maxiter": 8})
    return best["m"]


def _per_cell(design, dev, owner):
    """RMS deviation per cell: over its 8 vertices (``owner`` None), or over the measured
    points whose closest surface point it owns (NaN where none)."""
    m = design.mesh.n_cells
    if owner is None:
        return np.sqrt(np.mean(dev[design.mesh.cells] ** 2, axis=1))
    ss = np.bincount(owner, weights=dev**2, minlength=m)
    cnt = np.bincount(owner, minlength=m)
    return np.where(cnt > 0, np.sqrt(ss / np.maximum(cnt, 1)), np.nan)


def _region_rms(design, cells, dev, owner):
    if owner is None:
        vid = np.unique(design.mesh.cells[cells])
        return float(np.sqrt(np.mean(dev[vid] ** 2)))
    sel = np.isin(owner, cells)
    return float(np.sqrt(np.mean(dev[sel] ** 2))) if sel.any() else float("nan")


def _local_rms(comp, sim, cells, owner_all):
    """RMS deviation of a region aligned alone to its simulated counterpart."""
    from gdfe.measure import shape_distance

    design = comp.design
    if comp.method == "correspondence":
        vid = np.unique(design.mesh.cells[cells])
        return shape_distance(sim[vid], comp.measured[vid])["rms"]
    pts = comp.measured[np.isin(owner_all, cells)]
    if len(pts) < 4:
        return float("nan")
    return align_icp(pts, Surface(sim, design, cells=cells, faces=comp.faces), start=(comp.Q, comp.t))[2]


def diagnose_shape(design, measured, *, align="auto", correct=True, options=None, regions=None,
                   r_span=0.5, floor=None):
    """Where a measured shape deviates from the simulation of its design, and which region's
    contraction explains it.

    Parameters
    ----------
    design : Design or str or Path
        The design, or a TOML design file (its ``[simulate]`` options are used).
    measured : (k, 3) float array or str or Path
        The measured shape: points [mm] (k >= 4), or a ``.ply``, ``.vtu``, ``.obj`` or ``.csv``
        file (:func:`~gdfe.diagnosis.scan.load_measured`).
    align : {"auto", "correspondence", "icp"}
        ``"auto"``: correspondences when the measurement is a mesh of the design (a file with
        the design's vertices and hexahedra, e.g. a VTU of ``gdfe simulate``, or an array of
        exactly the design's vertices), else ICP.
    correct : bool
        Fit the per-region correction (GDFE re-simulations); else only report deviations.
    options : dict, optional
        Keyword arguments of :func:`gdfe.simulate`.
    regions : dict of str -> cell indices, optional
        Default :func:`design_regions`.
    r_span : float
        Each region's contraction ratio is searched within ``R +- r_span`` (clipped to
        (0.02, 1]).
    floor : float [mm], optional
        The model floor: the RMS deviation of a scan of a part printed as designed from its
        simulation (measured by the user). A gap is localised only when the scan's RMS deviation
        exceeds the floor and the scan's noise in quadrature (else :data:`NO_GAP_BEYOND_FLOOR`),
        by at least the floor itself (else :data:`GAP_WITHIN_DISAGREEMENT`), and the credited form
        removes at least :data:`NAME_GAIN` of the deviation beyond the floor (else
        :data:`NO_GAP`; :mod:`gdfe.diagnosis.shape_forms`). None: 0.

    Returns
    -------
    ShapeDiagnosis

    Raises
    ------
    GdfeError
        A measured shape that is not an array of at least 4 points or a readable file, an
        unknown ``align``, correspondences asked of a measurement that is not a mesh of
        the design, or a ``floor`` that is negative or not finite.
    """
    import gdfe

    align = check_choice("align", align, ALIGNMENTS)
    r_span = check_positive("r_span", r_span)
    if floor is not None:
        floor = check_number("floor", floor, minimum=0.0,
                             what="a finite RMS distance >= 0 in mm (a scan of a part printed as designed against "
                                  "its simulation)")
    design_path = measured_path = "<array>"
    opts = {}
    if not isinstance(design, gdfe.Design):
        design_path = str(design)
        design, opts = gdfe.load_design(design)
    opts.update(options or {})
    cells = None
    if isinstance(measured, (str, Path)):
        measured_path = str(measured)
        measured, cells = load_measured(measured, name="measured")
    measured = check_points("measured", measured)
    import time

    t0 = time.perf_counter()
    if align == "correspondence" and measured.shape[0] != design.mesh.n_points:
        raise GdfeError(f"measured: expected the design's {design.mesh.n_points} vertices in its order for "
                        f"correspondence alignment, got {measured.shape[0]} points")
    why = _degenerate(measured, design)
    if why is not None:
        return ShapeDiagnosis(
            design_path=design_path, measured_path=measured_path, method="", n_measured=int(len(measured)),
            rms_before=float("nan"), rms_after=float("nan"), element_deviation=np.full(design.n_cells, np.nan),
            regions=[], named=[], corrected_R={}, converged=True, n_simulations=0, transform={},
            matches=False, match={"residual": None, "size": None, "relative_residual": None, "coverage": None,
                                  "scale": None, "factor": None, "reasons": [why],
                                  "seconds": time.perf_counter() - t0})
    regions = design_regions(design) if regions is None else regions
    comp = _Comparer(design, measured, cells, align, opts, from_file=measured_path != "<array>")
    R0 = design.R.copy()
    sim0 = comp.simulate(R0)
    dev, owner = comp.compare(sim0, restart=True)
    match = _check_match(comp, R0, sim0, dev, owner)
    match["seconds"] = time.perf_counter() - t0
    match.pop("ok")
    rms0 = float(np.sqrt(np.mean(dev**2)))
    if match["reasons"]:
        return ShapeDiagnosis(
            design_path=design_path, measured_path=measured_path, method=comp.method,
            n_measured=int(len(measured)), rms_before=rms0, rms_after=rms0,
            element_deviation=_per_cell(design, dev, owner), regions=[], named=[], corrected_R={},
            converged=comp.converged, n_simulations=comp.n_sims,
            transform={"Q": comp.Q.tolist(), "t": comp.t.tolist()}, matches=False, match=match)
    if match["factor"] != 1.0:  # the alignment to the nominal shape again
        dev, owner = comp.compare(sim0, restart=True)
    elem = _per_cell(design, dev, owner)
    table = _region_table(comp, regions, R0, sim0, dev, owner)
    transform = {"Q": comp.Q.tolist(), "t": comp.t.tolist()}
    noise = scan_noise(design, comp.measured @ comp.Q.T + comp.t, sim0, owner, faces=comp.faces)
    fit = _Correction(named=[], fitted={}, rms_after=rms0, forms=[],
                      credit=Credit("not_fitted", None, [], level_of(floor, noise), 0.0))
    if correct:
        fit = _correct(comp, regions, table, R0, rms0, r_span, floor, noise)
    c = fit.credit
    return ShapeDiagnosis(
        design_path=design_path, measured_path=measured_path, method=comp.method,
        n_measured=int(len(measured)), rms_before=rms0, rms_after=fit.rms_after, element_deviation=elem,
        regions=table, named=fit.named, corrected_R=fit.fitted, converged=comp.converged,
        n_simulations=comp.n_sims, transform=transform, matches=True, match=match,
        forms=[f.as_dict() for f in fit.forms], outcome=c.outcome,
        credited=c.credited.as_dict() if c.credited is not None else None, not_ruled_out=c.not_ruled_out,
        floor=floor, noise=noise, level=c.level, gain=c.gain)


def _region_table(comp, regions, R0, sim0, dev, owner):
    """Per region: its deviation after the global alignment and aligned alone, and the design's
    contraction ratio (None for a region that does not contract)."""
    from gdfe.material import Material

    design, table = comp.design, []
    for name, rc in regions.items():
        contracting = bool(np.any(design.material[rc] != Material.RIGID))
        table.append({"name": name, "n_cells": int(len(rc)), "rms": _region_rms(design, rc, dev, owner),
                      "local_rms": _local_rms(comp, sim0, rc, owner),
                      "R_design": float(np.mean(R0[rc])) if contracting else None,
                      "single_fit": None, "single_fit_rms": None})
    return table


@dataclasses.dataclass
class _Correction:
    """What the forms fitted to a scan say (:func:`_correct`)."""

    named: list
    fitted: dict
    rms_after: float
    forms: list
    credit: Credit


def _correct(comp, regions, table, R0, rms0, r_span, floor, noise):
    """Fit every form (each region's contraction, the film's anisotropy, the coats' offsets),
    credit one or none (:func:`~gdfe.diagnosis.shape_forms.credit`), extend a credited region's
    contraction to further regions while each removes :data:`NAME_GAIN` of what is left beyond
    the floor, and report each region's deviation after the correction."""
    single = _single_fits(comp, regions, table, R0, r_span)
    forms = [FormFit(f"contraction of {n}", "region",
                     {"region": n, "R_design": float(np.mean(R0[regions[n]])), "R": v}, rms, k)
             for n, (v, rms, k) in single.items()]
    forms += fit_film_forms(comp)
    c = credit(forms, rms0, floor, noise)
    named, fitted, rms_after, points = [], {}, rms0, None
    if c.credited is not None and c.credited.kind == "region":
        named, fitted, rms_after = _extend(comp, regions, R0, single, c.credited.params["region"], r_span, floor)
        R = R0.copy()
        for n, v in fitted.items():
            R[regions[n]] = v
        points = comp.simulate(R)
    elif c.credited is not None:
        rms_after, points = c.credited.rms_after, c.credited.points
    if points is not None:
        dev1, owner1 = comp.compare(points)
        for row in table:
            row["R_fit"] = fitted.get(row["name"], row["R_design"])
            row["rms_after"] = _region_rms(comp.design, regions[row["name"]], dev1, owner1)
    return _Correction(named=named, fitted=fitted, rms_after=rms_after, forms=forms, credit=c)


def _fit_regions(comp, regions, names, R0, start, r_span, sweeps=2):
    """Coordinate-wise bounded 1-D searches of the contraction ratios of ``names``."""
    from scipy.optimize import minimize_scalar

    R = R0.copy()
    vals = dict(start)
    for n in names:
        R[regions[n]] = vals.get(n, float(np.mean(R0[regions[n]])))
    rms = None
    for _ in range(sweeps if len(names) > 1 else 1):
        for n in names:
            r0 = float(np.mean(R0[regions[n]]))
            lo, hi = max(0.02, r0 - r_span), min(1.0, r0 + r_span)

            def f(r, n=n):
                R[regions[n]] = r
                return comp.rms(R)

            res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3})
            vals[n] = float(res.x)
            R[regions[n]] = vals[n]
            rms = float(res.fun)
    return vals, rms


def _single_fits(comp, regions, table, R0, r_span):
    """Each contracting region's contraction ratio fitted alone: ``{name: (R, rms, simulations)}``
    (also written into ``table``)."""
    rows = {r["name"]: r for r in table}
    single = {}
    for n in (r["name"] for r in table if r["R_design"] is not None):
        k = comp.n_sims
        vals, rms = _fit_regions(comp, regions, [n], R0, {}, r_span)
        single[n] = (vals[n], rms, comp.n_sims - k)
        rows[n]["single_fit"], rows[n]["single_fit_rms"] = vals[n], rms
    return single


def _extend(comp, regions, R0, single, first, r_span, floor):
    """The credited region ``first``, and further regions (best single fit first) refitted together
    while each removes at least :data:`NAME_GAIN` of the deviation left beyond the floor."""
    floor = floor or 0.0
    named, fitted, current = [first], {first: single[first][0]}, single[first][1]
    for n in sorted((n for n in single if n != first), key=lambda n: single[n][1]):
        if beyond(current, floor) <= 0.0:  # nothing left beyond the floor
            break
        vals, rms = _fit_regions(comp, regions, named + [n], R0, {**fitted, n: single[n][0]}, r_span)
        if beyond(rms, floor) > (1.0 - NAME_GAIN) * beyond(current, floor):
            break
        named, fitted, current = named + [n], vals, rms
    return named, fitted, current
