"""Diagnosis of shapes: a scanned part against the GDFE simulation of its design.

:func:`diagnose_shape`

1. simulates the design and **aligns** the measured shape to it rigidly: with
   correspondences (Kabsch) when the measurement is a mesh of the design (same vertices and
   cells, e.g. a VTU written by ``gdfe simulate``), else by iterative closest points from a
   correspondence-free start (:func:`~gdfe.diagnosis.align.align_icp`), measuring each
   point's exact distance to the simulated surface (:class:`~gdfe.diagnosis.surface.Surface`);
2. reports the **deviation** per element and per region of the design
   (:func:`~gdfe.diagnosis.regions.design_regions`), both after the global alignment and
   after aligning each region alone (its own shape error, which a global alignment spreads
   over the whole part). The deviation of a set of points is the RMS distance
   ``sqrt(mean_i d_i^2)``; of an element, over its 8 vertices (correspondences) or over the
   measured points whose closest surface point lies on its faces (ICP);
3. **localises** the gap by refitting each contracting region's contraction ratio alone
   (a bounded 1-D search with a GDFE re-simulation per evaluation) and naming the region
   whose correction removes the most deviation; further regions are named while each
   lowers the remaining RMS deviation by at least :data:`NAME_GAIN`, i.e. while
   ``rms_new <= (1 - NAME_GAIN) rms``; the named regions are then refitted together, and
   the deviation before and after is reported.

Measured shapes are read by :func:`~gdfe.diagnosis.scan.load_measured`. Lengths in mm.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_array, check_choice, check_positive
from gdfe.diagnosis.align import align_icp
from gdfe.diagnosis.regions import design_regions
from gdfe.diagnosis.scan import load_measured
from gdfe.diagnosis.surface import Surface

__all__ = ["ShapeDiagnosis", "diagnose_shape", "NAME_GAIN", "ALIGNMENTS"]

#: A further region is named when correcting it lowers the RMS deviation by this fraction.
NAME_GAIN = 0.2
#: The ``align`` choices of :func:`diagnose_shape`.
ALIGNMENTS = ("auto", "correspondence", "icp")


@dataclasses.dataclass
class ShapeDiagnosis:
    """Result of :func:`diagnose_shape`.

    Attributes
    ----------
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
    named : list of str
        Regions where the gap lies.
    corrected_R : dict of str -> float
        Contraction ratios fitted to the named regions.
    converged : bool
        Every GDFE solve converged.
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

    def as_dict(self) -> dict:
        return {"design": self.design_path, "measured": self.measured_path, "alignment": self.method,
                "n_measured_points": self.n_measured, "rms_before": self.rms_before,
                "rms_after": self.rms_after,
                "shrink": 1.0 - self.rms_after / self.rms_before if self.rms_before > 0 else 0.0,
                "named": self.named, "corrected_R": self.corrected_R, "regions": self.regions,
                "element_deviation": [None if not np.isfinite(v) else float(v) for v in self.element_deviation],
                "converged": self.converged, "n_simulations": self.n_simulations,
                "transform": self.transform, "name_gain": NAME_GAIN}

    def text(self) -> str:
        lines = [f"{self.measured_path} against {self.design_path}: {self.n_measured} points, "
                 f"aligned by {self.method}",
                 f"RMS deviation {self.rms_before:.4g} mm"
                 + (f" -> {self.rms_after:.4g} mm after correcting {', '.join(self.named)}" if self.named else ""),
                 f"{'region':12s} {'cells':>6s} {'RMS':>9s} {'local RMS':>10s} {'R design':>9s} "
                 f"{'R alone':>8s} {'RMS if alone':>12s}"]
        for r in self.regions:
            sf = r.get("single_fit")
            lines.append(f"{r['name']:12s} {r['n_cells']:6d} {r['rms']:9.4g} {r['local_rms']:10.4g} "
                         + (f"{r['R_design']:9.4f} {sf:8.4f} {r['single_fit_rms']:12.4g}" if sf is not None
                            else f"{'-':>9s} {'-':>8s} {'-':>12s}"))
        if self.named:
            lines.append("the gap lies in " + ", ".join(
                f"{n} (R {self.regions_by_name()[n]['R_design']:.4f} -> {self.corrected_R[n]:.4f})"
                for n in self.named))
        else:
            lines.append("no region's correction lowers the deviation by "
                         f"{100 * NAME_GAIN:.0f} %: no gap localised")
        return "\n".join(lines)

    def regions_by_name(self):
        return {r["name"]: r for r in self.regions}


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
        self.Q, self.t = np.eye(3), np.zeros(3)
        self._first = None
        if self.method == "icp":
            from gdfe.io import surface_faces

            self.faces = surface_faces(design)

    def simulate(self, R):
        import gdfe

        res = gdfe.simulate(self.design.with_R(R), **self.options)
        self.n_sims += 1
        self.converged &= bool(res.converged)
        return res.points

    def compare(self, sim, restart=False):
        """Per-point deviations [mm] and the cell of each point (None: per vertex), after
        rigid alignment; ICP restarts from every axis flip when ``restart``."""
        from gdfe.measure import rigid_align

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
                   r_span=0.5):
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

    Returns
    -------
    ShapeDiagnosis

    Raises
    ------
    GdfeError
        A measured shape that is not an array of at least 4 points or a readable file, an
        unknown ``align``, or correspondences asked of a measurement that is not a mesh of
        the design.
    """
    import gdfe

    align = check_choice("align", align, ALIGNMENTS)
    r_span = check_positive("r_span", r_span)
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
    measured = check_array("measured", measured, shape=(-1, 3), min_size=4)
    regions = design_regions(design) if regions is None else regions
    comp = _Comparer(design, measured, cells, align, opts, from_file=measured_path != "<array>")
    R0 = design.R.copy()
    sim0 = comp.simulate(R0)
    dev, owner = comp.compare(sim0, restart=True)
    rms0 = float(np.sqrt(np.mean(dev**2)))
    elem = _per_cell(design, dev, owner)
    table = []
    for name, rc in regions.items():
        contracting = bool(np.any(design.material[rc] != gdfe.Material.RIGID))
        table.append({"name": name, "n_cells": int(len(rc)), "rms": _region_rms(design, rc, dev, owner),
                      "local_rms": _local_rms(comp, sim0, rc, owner),
                      "R_design": float(np.mean(R0[rc])) if contracting else None,
                      "single_fit": None, "single_fit_rms": None})
    transform = {"Q": comp.Q.tolist(), "t": comp.t.tolist()}
    named, fitted, rms_after = [], {}, rms0
    if correct:
        named, fitted, rms_after = _localise(comp, regions, table, R0, rms0, r_span)
        R = R0.copy()
        for n, v in fitted.items():
            R[regions[n]] = v
        dev1, owner1 = comp.compare(comp.simulate(R))
        for row in table:
            row["R_fit"] = fitted.get(row["name"], row["R_design"])
            row["rms_after"] = _region_rms(design, regions[row["name"]], dev1, owner1)
    return ShapeDiagnosis(
        design_path=design_path, measured_path=measured_path, method=comp.method,
        n_measured=int(len(measured)), rms_before=rms0, rms_after=rms_after, element_deviation=elem,
        regions=table, named=named, corrected_R=fitted, converged=comp.converged,
        n_simulations=comp.n_sims, transform=transform)


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


def _localise(comp, regions, table, R0, rms0, r_span):
    rows = {r["name"]: r for r in table}
    movable = [r["name"] for r in table if r["R_design"] is not None]
    single = {}
    for n in movable:
        vals, rms = _fit_regions(comp, regions, [n], R0, {}, r_span)
        single[n] = (vals[n], rms)
        rows[n]["single_fit"], rows[n]["single_fit_rms"] = vals[n], rms
    named, fitted, current = [], {}, rms0
    remaining = sorted(movable, key=lambda n: single[n][1])
    while remaining:
        n = remaining[0]
        trial = named + [n]
        if named:
            vals, rms = _fit_regions(comp, regions, trial, R0, {**fitted, n: single[n][0]}, r_span)
        else:
            vals, rms = {n: single[n][0]}, single[n][1]
        if rms > (1.0 - NAME_GAIN) * current:
            break
        named, fitted, current = trial, vals, rms
        remaining = remaining[1:]
    return named, fitted, current
