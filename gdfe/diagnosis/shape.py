"""Diagnosis of shapes: a scanned part against the GDFE simulation of its design.

:func:`diagnose_shape`

1. simulates the design and **aligns** the measured shape to it rigidly: with
   correspondences (Kabsch) when the measurement is a mesh of the design (same vertices and
   cells, e.g. a VTU written by ``gdfe simulate``), else by iterative closest points from a
   correspondence-free start (centroids and principal axes, every proper axis flip tried),
   measuring each point's exact distance to the simulated surface (:class:`Surface`);
2. reports the **deviation** per element and per region of the design (regions: the
   design's own, e.g. ``panel_a``/``hinge``/``panel_b``, else the connected areas of each
   material: ``hinge_1``, ``panel_1``, ...), both after the global alignment and after
   aligning each region alone (its own shape error, which a global alignment spreads over
   the whole part);
3. **localises** the gap by refitting each contracting region's contraction ratio alone
   (a bounded 1-D search with a GDFE re-simulation per evaluation) and naming the region
   whose correction removes the most deviation; further regions are named while each
   lowers the remaining RMS deviation by at least :data:`NAME_GAIN`; the named regions are
   then refitted together, and the deviation before and after is reported.

Lengths in mm.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np

__all__ = ["ShapeDiagnosis", "Surface", "diagnose_shape", "load_measured", "design_regions", "align_icp"]

log = logging.getLogger(__name__)

#: A further region is named when correcting it lowers the RMS deviation by this fraction.
NAME_GAIN = 0.2
_SUFFIXES = (".ply", ".vtu", ".obj", ".csv")


# -- input ---------------------------------------------------------------------------------
def load_measured(path):
    """Read a measured shape.

    Parameters
    ----------
    path : str or Path
        ``.csv`` (columns x, y, z, with or without a header), or ``.ply``, ``.obj``, ``.vtu``
        (read with meshio).

    Returns
    -------
    points : (k, 3) float array [mm]
    cells : (m, 8) int array or None
        Hexahedra of a volume mesh, if any.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"measured shape not found: {path}")
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise ValueError(f"{path.name}: expected a .ply, .vtu, .obj or .csv file, got {suffix or 'no suffix'}")
    if suffix == ".csv":
        return _read_csv(path), None
    import meshio

    try:
        mesh = meshio.read(path)
    except Exception as exc:  # meshio raises many kinds
        raise ValueError(f"{path.name}: could not read it as {suffix[1:].upper()}: {exc}") from None
    pts = np.asarray(mesh.points, float)
    if pts.ndim != 2 or pts.shape[0] == 0:
        raise ValueError(f"{path.name}: no points")
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    hexes = [c.data for c in mesh.cells if c.type == "hexahedron"]
    return pts[:, :3], (np.concatenate(hexes) if hexes else None)


def _read_csv(path):
    import csv

    with path.open(newline="") as f:
        rows = [r for r in csv.reader(f) if r and any(c.strip() for c in r)]
    if not rows:
        raise ValueError(f"{path.name}: no points")
    header = None
    try:
        [float(c) for c in rows[0][:3]]
    except ValueError:
        header = [c.strip().lower() for c in rows[0]]
        rows = rows[1:]
    cols = [0, 1, 2]
    if header is not None:
        if not all(a in header for a in ("x", "y", "z")):
            raise ValueError(f"{path.name}: expected columns x, y, z, got {', '.join(header)}")
        cols = [header.index(a) for a in ("x", "y", "z")]
    pts = np.empty((len(rows), 3))
    for i, r in enumerate(rows):
        line = i + (2 if header is not None else 1)
        try:
            pts[i] = [float(r[c]) for c in cols]
        except (ValueError, IndexError):
            raise ValueError(f"{path.name}: line {line}: expected three numbers x, y, z, got {r}") from None
        if not np.all(np.isfinite(pts[i])):
            raise ValueError(f"{path.name}: line {line}: expected finite coordinates, got {r}")
    if len(pts) < 4:
        raise ValueError(f"{path.name}: need at least 4 points, got {len(pts)}")
    return pts


# -- regions -------------------------------------------------------------------------------
def design_regions(design):
    """Named regions of a design: its own, else the connected areas of each material.

    Automatic names: ``hinge_k`` (cells contracting on one face), ``shrink_k`` (free shrink),
    ``panel_k`` (rigid), numbered along x then y.

    Returns
    -------
    dict of str -> (k,) int array
        Cell indices (through the thickness).
    """
    if design.regions:
        return {k: np.asarray(v) for k, v in design.regions.items()}
    from scipy import ndimage

    from gdfe.design import Material

    ij = design.mesh.cell_ij
    nx, ny = ij.max(0) + 1
    grid = np.full((nx, ny), -1)
    grid[ij[:, 0], ij[:, 1]] = design.material
    kinds = {"hinge": (Material.CONTRACT_TOP, Material.CONTRACT_BOTTOM),
             "shrink": (Material.FREE_SHRINK,), "panel": (Material.RIGID,)}
    regions = {}
    for word, codes in kinds.items():
        comps = []
        for code in codes:
            lab, n = ndimage.label(grid == int(code))
            for k in range(1, n + 1):
                cells = np.nonzero(lab[ij[:, 0], ij[:, 1]] == k)[0]
                c = ij[cells].mean(0)
                comps.append((c[0], c[1], cells))
        for k, (_, _, cells) in enumerate(sorted(comps, key=lambda t: (t[0], t[1])), start=1):
            regions[f"{word}_{k}"] = cells
    return regions


# -- alignment -----------------------------------------------------------------------------
class Surface:
    """The boundary of a simulated shape, for exact closest-point queries.

    Each boundary quadrilateral of the hex mesh is split into four triangles around its
    centre (within about 1e-3 of the cell size of the bilinear face); a query finds the
    faces of the ``k`` nearest of a few interior samples per face and the exact closest
    point on their triangles (inside, or on one of the three edges).

    Parameters
    ----------
    points : (n, 3) float array [mm]
        Vertices of the shape.
    design : Design
    cells : (c,) int array, optional
        Only the boundary faces of these cells.
    faces : ((f, 4) int array, (f,) int array), optional
        The design's boundary faces and their cells (:func:`gdfe.io.surface_faces`), if known.
    """

    def __init__(self, points, design, cells=None, per_edge=3, faces=None):
        from scipy.spatial import cKDTree

        from gdfe.io import surface_faces

        faces, owner = surface_faces(design) if faces is None else faces
        if cells is not None:
            keep = np.isin(owner, cells)
            faces, owner = faces[keep], owner[keep]
        self.P = np.asarray(points, float)[faces]  # (f, 4, 3)
        self.owner = owner
        u = (np.arange(per_edge) + 0.5) / per_edge
        uu, vv = [a.ravel() for a in np.meshgrid(u, u)]
        w = np.stack([(1 - uu) * (1 - vv), uu * (1 - vv), uu * vv, (1 - uu) * vv], 1)
        samples = np.einsum("sk,fkc->fsc", w, self.P).reshape(-1, 3)
        self.sample_face = np.repeat(np.arange(len(self.P)), len(uu))
        self.tree = cKDTree(samples)
        self.samples = samples

        # four triangles per face, fanned around its centre, (4f, 3) each, with what a query needs
        c = self.P.mean(axis=1, keepdims=True)
        tri = np.concatenate([np.concatenate([self.P[:, [i, (i + 1) % 4]], c], axis=1) for i in range(4)])
        self._a = tri[:, 0]
        self._ab = tri[:, 1] - tri[:, 0]
        self._ac = tri[:, 2] - tri[:, 0]
        self._bc = tri[:, 2] - tri[:, 1]
        d00 = np.einsum("ij,ij->i", self._ab, self._ab)
        d01 = np.einsum("ij,ij->i", self._ab, self._ac)
        d11 = np.einsum("ij,ij->i", self._ac, self._ac)
        self._d = np.stack([d00, d01, d11, np.einsum("ij,ij->i", self._bc, self._bc)], 1)
        den = d00 * d11 - d01**2
        self._den = np.where(den > 0, den, np.inf)  # degenerate triangles: edges only
        self._nf = len(self.P)

    def closest(self, X, k=4):
        """Closest surface points of ``X`` ``(q, 3)``: points ``(q, 3)``, distances ``(q,)``
        [mm] and the cell owning each."""
        k = min(k, len(self.samples))
        _, nn = self.tree.query(X, k=k)
        F = self.sample_face[nn.reshape(len(X), -1)]
        T = np.concatenate([F + i * self._nf for i in range(4)], axis=1)  # (q, 4k) candidates
        p = X[:, None, :]
        a, ab, ac, bc = self._a[T], self._ab[T], self._ac[T], self._bc[T]
        d00, d01, d11, dbc = (self._d[T, i] for i in range(4))
        ap = p - a
        d20 = np.einsum("qkc,qkc->qk", ap, ab)
        d21 = np.einsum("qkc,qkc->qk", ap, ac)
        den = self._den[T]
        v = (d11 * d20 - d01 * d21) / den
        w = (d00 * d21 - d01 * d20) / den
        inside = (v >= 0) & (w >= 0) & (v + w <= 1)
        # clamped projections onto the three edges
        tab = np.clip(d20 / np.where(d00 > 0, d00, 1.0), 0, 1)
        tac = np.clip(d21 / np.where(d11 > 0, d11, 1.0), 0, 1)
        tbc = np.clip(np.einsum("qkc,qkc->qk", ap - ab, bc) / np.where(dbc > 0, dbc, 1.0), 0, 1)
        cands = np.stack([a + v[..., None] * ab + w[..., None] * ac, a + tab[..., None] * ab,
                          a + tac[..., None] * ac, a + ab + tbc[..., None] * bc])  # (4, q, 4k, 3)
        diff = cands - p
        dist2 = np.einsum("sqkc,sqkc->sqk", diff, diff)
        dist2[0] = np.where(inside, dist2[0], np.inf)
        s_best = np.argmin(dist2, axis=0)  # (q, 4k)
        d2 = np.take_along_axis(dist2, s_best[None], 0)[0]
        j = np.argmin(d2, axis=1)
        rows = np.arange(len(X))
        C = cands[s_best[rows, j], rows, j]
        face = T[rows, j] % self._nf
        return C, np.sqrt(d2[rows, j]), self.owner[face]


def _proper_flips():
    """The four sign flips of three axes that are rotations."""
    out = []
    for sx in (1, -1):
        for sy in (1, -1):
            sz = sx * sy  # det +1
            out.append(np.diag([sx, sy, sz]).astype(float))
    return out


def align_icp(measured, surface, start=None, max_iter=50, tol=1e-8):
    """Rigid alignment of a point cloud to a surface by iterative closest points.

    Without ``start``, every proper flip of the principal axes (centroids matched) is tried
    and the best kept. Each run alternates exact closest points on the surface with rigid
    motions: Kabsch steps first, Gauss-Newton steps on the distances last.

    Parameters
    ----------
    measured : (k, 3) float array [mm]
    surface : Surface
    start : ((3, 3), (3,)) tuple, optional
        A rotation and translation to start from instead.

    Returns
    -------
    Q : (3, 3) float array
    t : (3,) float array [mm]
        ``measured @ Q.T + t`` is aligned.
    rms : float [mm]
        RMS distance of the aligned points to the surface.
    """
    if start is not None:
        return _icp(measured, surface, *start, max_iter, tol, coarse=False)
    cm, ct = measured.mean(0), surface.samples.mean(0)
    _, _, Vm = np.linalg.svd(measured - cm, full_matrices=False)
    _, _, Vt = np.linalg.svd(surface.samples - ct, full_matrices=False)
    best = None
    for D in _proper_flips():
        Q = Vt.T @ D @ Vm
        if np.linalg.det(Q) < 0:
            Q = Vt.T @ D @ np.diag([1.0, 1.0, -1.0]) @ Vm
        run = _icp(measured, surface, Q, ct - cm @ Q.T, max_iter, tol)
        if best is None or run[2] < best[2]:
            best = run
    return best


def _icp(measured, surface, Q, t, max_iter, tol, coarse=True):
    """Closest-point iterations from ``(Q, t)``: Kabsch steps until they stall (relative
    decrease below 1e-3; skipped when not ``coarse``, i.e. from a start already close), then
    Gauss-Newton steps on the point-to-surface distances (each linearised in the direction to
    its closest point, the point-to-plane step of Chen and Medioni), kept only while the mean
    squared distance falls."""
    from gdfe.measure import rigid_align

    def state(Q, t):
        moved = measured @ Q.T + t
        C, d, _ = surface.closest(moved)
        return moved, C, d, float(np.mean(d**2))

    moved, C, d, err = state(Q, t)
    for _ in range(max_iter if coarse else 0):  # point to point
        Qn, tn = rigid_align(measured, C)
        mn, Cn, dn, en = state(Qn, tn)
        if en >= err:
            break
        gain = (err - en) / max(err, 1e-300)
        Q, t, moved, C, d, err = Qn, tn, mn, Cn, dn, en
        if gain < 1e-3:
            break
    scale = float(np.sqrt(np.mean(np.sum((measured - measured.mean(0)) ** 2, 1)))) or 1.0
    for _ in range(max_iter):  # Gauss-Newton, point to plane
        diff = moved - C
        n = diff / np.maximum(d, 1e-300)[:, None]
        c0 = moved.mean(0)
        A = np.column_stack([np.cross(moved - c0, n) / scale, n])
        x = np.linalg.lstsq(A, -d, rcond=None)[0]
        w, tau = x[:3] / scale, x[3:]
        th = float(np.linalg.norm(w))
        K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / (th if th > 0 else 1.0)
        dR = np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K
        Qn, tn = dR @ Q, dR @ (t - c0) + c0 + tau
        mn, Cn, dn, en = state(Qn, tn)
        if en >= err:
            break
        small = (err - en) <= tol * err
        Q, t, moved, C, d, err = Qn, tn, mn, Cn, dn, en
        if small:
            break
    return Q, t, float(np.sqrt(err))


# -- the diagnosis ----------------------------------------------------------------------------
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
            raise ValueError(f"measured: correspondence alignment needs the design's {n} vertices "
                             f"in its order, got {measured.shape[0]} points")
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
        The measured shape: points [mm], or a ``.ply``, ``.vtu``, ``.obj`` or ``.csv`` file.
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
    """
    import gdfe

    design_path = measured_path = "<array>"
    opts = {}
    if not isinstance(design, gdfe.Design):
        design_path = str(design)
        design, opts = gdfe.load_design(design)
    opts.update(options or {})
    cells = None
    if not isinstance(measured, np.ndarray):
        measured_path = str(measured)
        measured, cells = load_measured(measured)
    measured = np.asarray(measured, float)
    if measured.ndim != 2 or measured.shape[1] != 3 or len(measured) < 4:
        raise ValueError(f"measured: expected an (k, 3) array of at least 4 points, got shape {measured.shape}")
    if align not in ("auto", "correspondence", "icp"):
        raise ValueError(f"align: expected 'auto', 'correspondence' or 'icp', got {align!r}")
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
