"""Measurements of simulated (or scanned) shapes: fold angles, curvature, shape distance."""

from __future__ import annotations

import numpy as np

from gdfe._validation import GdfeError, GdfeTypeError, check_array, check_number, describe

__all__ = ["fold_angle", "curvature_profile", "rigid_align", "shape_distance", "column_frames", "panel_angles"]


def rigid_align(source, target, weights=None):
    """Best rotation and translation taking ``source`` onto ``target`` (Kabsch).

    Parameters
    ----------
    source, target : (n, 3) float arrays [mm]
        Corresponding points.
    weights : (n,) float array, optional

    Returns
    -------
    Q : (3, 3) float array
        Rotation (det +1).
    t : (3,) float array [mm]
        Translation: ``source @ Q.T + t`` is aligned with ``target``.
    """
    source = check_array("source", source, shape=(-1, 3), min_size=1)
    target = check_array("target", target, shape=(-1, 3), min_size=1)
    if source.shape != target.shape:
        raise GdfeError(f"source, target: expected two (n, 3) arrays of the same shape, "
                         f"got {source.shape} and {target.shape}")
    if weights is None:
        w = np.ones(len(source))
    else:
        w = check_array("weights", weights, shape=(len(source),))
        if (w < 0).any() or not w.sum() > 0:
            raise GdfeError(f"weights: expected non-negative weights with a positive sum, got {describe(w)}")
    w = w / w.sum()
    cs, ct = w @ source, w @ target
    H = ((source - cs) * w[:, None]).T @ (target - ct)
    U, _, Vt = np.linalg.svd(H)
    dd = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    Q = Vt.T @ np.diag([1.0, 1.0, dd]) @ U.T
    return Q, ct - cs @ Q.T


def shape_distance(a, b):
    """Distance between two shapes with corresponding points after rigid alignment.

    Returns
    -------
    dict
        ``rms`` and ``max`` vertex distance [mm], and ``aligned`` (``b`` moved onto ``a``).
    """
    a = check_array("a", a, shape=(-1, 3), min_size=1)
    b = check_array("b", b, shape=(-1, 3), min_size=1)
    if a.shape != b.shape:
        raise GdfeError(f"a, b: expected two (n, 3) arrays of the same shape, got {a.shape} and {b.shape}")
    Q, t = rigid_align(b, a)
    bb = b @ Q.T + t
    d = np.linalg.norm(bb - np.asarray(a, float), axis=1)
    return {"rms": float(np.sqrt((d**2).mean())), "max": float(d.max()), "aligned": bb}


def column_frames(points, design, cells=None):
    """Rotation of every column of cells (fixed x index) relative to the flat print.

    Parameters
    ----------
    points : (n, 3) float array [mm]
    design : Design
    cells : (k,) int array, optional
        Restrict to these cells.

    Returns
    -------
    cols : (c,) int array
        Column indices i (along x), ascending.
    Q : (c, 3, 3) float array
        Rotation of each column.
    centre : (c, 3) float array [mm]
        Centroid of each column's vertices.
    """
    mesh = design.mesh
    sel = np.arange(mesh.n_cells) if cells is None else np.asarray(cells)
    ci = mesh.cell_ij[sel, 0]
    cols = np.unique(ci)
    Qs, cs = [], []
    for c in cols:
        vid = np.unique(mesh.cells[sel[ci == c]])
        Q, _ = rigid_align(mesh.points[vid], points[vid])
        Qs.append(Q)
        cs.append(points[vid].mean(axis=0))
    return cols, np.array(Qs), np.array(cs)


def _rotvec(Q):
    """Rotation vectors (axis * angle) of rotations ``(k, 3, 3)``."""
    c = np.clip((np.trace(Q, axis1=1, axis2=2) - 1) / 2, -1, 1)
    th = np.arccos(c)
    ax = np.stack([Q[:, 2, 1] - Q[:, 1, 2], Q[:, 0, 2] - Q[:, 2, 0], Q[:, 1, 0] - Q[:, 0, 1]], 1)
    s = np.sin(th)
    small = s < 1e-9
    ax = ax / np.where(small, 1.0, 2 * s)[:, None]
    ax[small] = 0.5 * ax[small]  # near identity: vee(Q - Q^T)/2 ~ theta * axis
    return np.where(small[:, None], ax, ax * th[:, None])


def fold_angle(result, design=None, a="panel_a", b="panel_b", axis=(0.0, -1.0, 0.0), panel_fraction=None):
    """Fold angle [rad] between two regions of a strip: the turn of the strip from ``a`` to ``b``.

    The angle is accumulated column by column along x (the relative rotation of each
    column of cells to the next, projected on the fold ``axis`` in the flat print), so
    folds beyond pi are measured, and the sign says the direction: positive for a strip
    that curls towards +z (top face inside).

    Parameters
    ----------
    result : Result or (n, 3) float array
        A :func:`gdfe.simulate` result, or vertex positions (then ``design`` is needed).
    design : Design, optional
    a, b : str
        Region names of the two panels (default: those of :func:`gdfe.hinge`).
    axis : (3,) float
        Fold axis in the flat print.
    panel_fraction : float in (0, 1], optional
        Measure each panel's direction on the outer ``panel_fraction`` of its columns (away
        from the hinge), as one rigid frame, as :func:`reference_fem.fold_angle` does with
        its mid-line chords. Default: the panels' columns next to the hinge. With in-plane
        isotropic shrink those columns warp with the hinge (the hinge also shrinks across
        the strip, the panel does not), which adds an error of first order in the cell
        size; the outer frames converge faster (measured by ``gdfe bench``'s FEM
        comparison, docs/bench/bench.txt).
    """
    points, design = _points_design(result, design)
    cells_a, cells_b = design.region_cells(a), design.region_cells(b)
    ia = design.mesh.cell_ij[cells_a, 0]
    ib = design.mesh.cell_ij[cells_b, 0]
    forward = ia.max() < ib.min()
    lo, hi = (ia.max(), ib.min()) if forward else (ib.max(), ia.min())
    ci = design.mesh.cell_ij[:, 0]
    if panel_fraction is None:
        span = np.nonzero((ci >= lo) & (ci <= hi))[0]
        _, Q, _ = column_frames(points, design, span)
        total = _accumulated_turn(Q, axis)
        return total if forward else -total
    panel_fraction = check_number("panel_fraction", panel_fraction, minimum=0.0, maximum=1.0,
                                  include_minimum=False, what="a number in (0, 1]")
    left, right = (cells_a, cells_b) if forward else (cells_b, cells_a)
    il, ir = design.mesh.cell_ij[left, 0], design.mesh.cell_ij[right, 0]
    nl = max(1, int(round(panel_fraction * (il.max() - il.min() + 1))))
    nr = max(1, int(round(panel_fraction * (ir.max() - ir.min() + 1))))
    outer_l, outer_r = left[il <= il.min() + nl - 1], right[ir >= ir.max() - nr + 1]
    # the outer parts' frames, joined by the columns between them (each turn small: unwrapped)
    c0, c1 = il.min() + nl - 1, ir.max() - nr + 1
    span = np.nonzero((ci >= c0) & (ci <= c1))[0]
    _, Qc, _ = column_frames(points, design, span)
    Q = np.concatenate([_region_frame(points, design, outer_l)[None], Qc,
                        _region_frame(points, design, outer_r)[None]])
    total = _accumulated_turn(Q, axis)
    return total if forward else -total


def _region_frame(points, design, cells):
    """Rotation of a group of cells as one rigid body, relative to the flat print."""
    vid = np.unique(design.mesh.cells[cells])
    Q, _ = rigid_align(design.mesh.points[vid], points[vid])
    return Q


def _accumulated_turn(Q, axis):
    rel = np.einsum("kji,kjl->kil", Q[:-1], Q[1:])  # Q_k^T Q_{k+1}: turn in the frame of column k
    return float((_rotvec(rel) @ np.asarray(axis, float)).sum())


def curvature_profile(result, design=None, cells=None, axis=(0.0, -1.0, 0.0)):
    """Curvature along a strip (x direction), column by column.

    Returns
    -------
    dict
        ``s`` (c-1,) arc length at mid-column pairs [mm], ``kappa`` (c-1,) signed curvature
        [1/mm] (turn between neighbouring columns over their centroid distance),
        ``radius`` [mm] (inf where flat), ``turn`` total turning angle [rad].
    """
    points, design = _points_design(result, design)
    _, Q, centre = column_frames(points, design, cells)
    rel = np.einsum("kji,kjl->kil", Q[:-1], Q[1:])
    dth = _rotvec(rel) @ np.asarray(axis, float)
    ds = np.linalg.norm(np.diff(centre, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    kappa = dth / ds
    with np.errstate(divide="ignore"):
        radius = np.where(np.abs(kappa) > 1e-12, 1.0 / np.abs(kappa), np.inf)
    return {"s": 0.5 * (s[1:] + s[:-1]), "kappa": kappa, "radius": radius, "turn": float(dth.sum())}


def _points_design(result, design):
    if hasattr(result, "points") and hasattr(result, "design"):
        return result.points, result.design
    pts = check_array("result", result, shape=(-1, 3))  # not a Result: points, which need their design
    if design is None:
        raise GdfeTypeError("design: needed when result is an array of points")
    if pts.shape != design.mesh.points.shape:
        raise GdfeError(f"result: expected points of shape {design.mesh.points.shape}, got {pts.shape}")
    return pts, design


def panel_angles(result, design=None, min_cells=2):
    """The fold between every two rigid panels that one run of contracting cells joins.

    Panels are the connected groups (side by side in the plane) of rigid cells, at least
    ``min_cells`` columns each; hinges the connected groups of the other cells. Where a hinge
    touches two panels ``a`` and ``b``, its fold is the angle of the rotation between the
    panels' best rotations from the flat print (:func:`rigid_align` of their vertices), signed
    as :func:`fold_angle` signs a strip's: positive where the part curls towards +z (the top
    face inside) about the axis ``d x z``, ``d`` the flat direction from ``a``'s cells at the
    hinge to ``b``'s. A fold beyond pi is unwrapped as :func:`fold_angle` unwraps a strip's: the
    hinge's cells between the two panels, in slices one cell across ``d``, are a chain of frames
    whose small turns about that axis add up to the fold; of the angles equal to the panels'
    rotation (2 pi apart) the one nearest that sum is taken. (Where the chain's turns are not
    small, or the hinge joins more than two panels, the angle is the one in (-pi, pi].)

    Parameters
    ----------
    result : gdfe.Result or (n, 3) float array [mm]
    design : Design, optional
        Needed when ``result`` is an array.
    min_cells : int
        Smallest panel (cell columns) measured.

    Returns
    -------
    list of dict
        ``panels`` (two panel numbers, 1-based, ordered by their first cell), ``hinge_cells``
        (columns of the hinge joining them) and ``angle_rad``; sorted by the panels.
    """
    from scipy import ndimage

    from gdfe.material import Material

    if design is None:
        design, points = result.design, np.asarray(result.points, float)
    else:
        points = np.asarray(result, float)
    mesh = design.mesh
    if points.shape != mesh.points.shape:
        raise GdfeError(f"points: expected shape {mesh.points.shape}, got {points.shape}")
    i, j = mesh.cell_ij.T
    nx, ny = int(i.max()) + 1, int(j.max()) + 1
    rigid = np.zeros((nx, ny), bool)
    other = np.zeros((nx, ny), bool)
    is_rigid = design.material == Material.RIGID
    rigid[i[is_rigid], j[is_rigid]] = True
    other[i[~is_rigid], j[~is_rigid]] = True
    panels, n_panels = ndimage.label(rigid)
    sizes = np.bincount(panels.ravel(), minlength=n_panels + 1)
    hinges, n_hinges = ndimage.label(other & ~rigid)
    frames = _PanelFrames(points, design, _cells_by_label(panels[i, j], n_panels))
    hinge_cells = _cells_by_label(hinges[i, j], n_hinges)

    found = {}
    cross = ndimage.generate_binary_structure(2, 1)
    for h, box in enumerate(ndimage.find_objects(hinges), start=1):
        box = tuple(slice(max(0, b.start - 1), b.stop + 1) for b in box)  # the hinge and its neighbours
        region = hinges[box] == h
        near = ndimage.binary_dilation(region, cross) & rigid[box]
        touching = np.unique(panels[box][near])
        touching = [int(t) for t in touching if t and sizes[t] >= min_cells]
        for a_idx, a in enumerate(touching):
            for b in touching[a_idx + 1:]:
                at = _at_hinge(panels[box], near, a, box)
                bt = _at_hinge(panels[box], near, b, box)
                angle = frames.fold(a, b, at, bt, hinge_cells[h], unwrap=len(touching) == 2)
                key = (a, b)
                found.setdefault(key, {"panels": [a, b], "hinge_cells": 0, "angle_rad": angle})
                found[key]["hinge_cells"] += int(region.sum())
    return [found[k] for k in sorted(found)]


def _cells_by_label(labels, n):
    """The cells of each label 0..n: a list whose entry ``k`` holds the indices of the cells labelled ``k``
    (one sort, not a pass over the cells per label)."""
    order = np.argsort(labels, kind="stable")
    return np.split(order, np.cumsum(np.bincount(labels, minlength=n + 1))[:-1])


def _at_hinge(labels, near, panel, box):
    """Grid indices ``(k, 2)`` of panel ``panel``'s cells next to a hinge (``near`` within ``box``)."""
    ii, jj = np.nonzero(near & (labels == panel))
    return np.column_stack([ii + box[0].start, jj + box[1].start])


class _PanelFrames:
    """Rigid frames of panels and of a hinge's slices, and the signed, unwrapped fold between two panels."""

    def __init__(self, points, design, panel_cells):
        self.points, self.design, self.panel_cells = points, design, panel_cells
        self.spacing = np.asarray(design.mesh.spacing[:2], float)
        self.rot = {}

    def _centre(self, ij):
        """Centres ``(k, 2)`` [mm] in the flat print of the cells at grid indices ``ij``, from the grid's corner."""
        return (np.asarray(ij, float) + 0.5) * self.spacing

    def _frame(self, cells):
        vid = np.unique(self.design.mesh.cells[cells])
        return rigid_align(self.design.mesh.points[vid], self.points[vid])[0]

    def panel(self, label):
        if label not in self.rot:
            self.rot[label] = self._frame(self.panel_cells[label])
        return self.rot[label]

    def fold(self, a, b, at_a, at_b, hinge_cells, unwrap=True):
        """The fold [rad] from panel ``a`` to ``b``: ``at_a``, ``at_b`` their cells (grid indices) next to the
        hinge whose cells are ``hinge_cells``."""
        d = self._centre(at_b).mean(axis=0) - self._centre(at_a).mean(axis=0)
        norm = float(np.hypot(*d))
        Qa, Qb = self.panel(a), self.panel(b)
        rel = Qa.T @ Qb
        theta = float(np.arccos(np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0)))
        if norm == 0.0:
            return theta
        d = d / norm
        axis = np.array([d[1], -d[0], 0.0])  # d x z
        direct = theta if float(_rotvec(rel[None])[0] @ axis) >= 0.0 else -theta
        if not unwrap:
            return direct
        chain = self._chain(d, at_a, at_b, hinge_cells)
        if chain is None:
            return direct
        Q = np.concatenate([Qa[None], chain, Qb[None]])
        steps = _rotvec(np.einsum("kji,kjl->kil", Q[:-1], Q[1:]))
        if np.abs(steps @ axis).max() > 0.5 * np.pi or np.linalg.norm(steps, axis=1).max() > 0.5 * np.pi:
            return direct
        turn = float((steps @ axis).sum())
        return direct + 2.0 * np.pi * round((turn - direct) / (2.0 * np.pi))

    def _chain(self, d, at_a, at_b, hinge_cells):
        """Frames of the hinge's cells between the two panels' cells at it, in slices one cell across ``d``
        (ordered from ``a`` to ``b``), or None where there are none."""
        c = self._centre(self.design.mesh.cell_ij[hinge_cells, :2])
        ends = self._centre(np.concatenate([at_a, at_b]))
        e = np.array([-d[1], d[0]])  # across d, in the plane
        t, band = c @ e, ends @ e
        half = 0.5 * float(np.abs(self.spacing * e).sum())
        keep = (t >= band.min() - half) & (t <= band.max() + half)
        if not keep.any():
            return None
        width = float(np.abs(self.spacing * d).sum())  # a cell's extent along d
        s = (c[keep] - ends[:len(at_a)].mean(axis=0)) @ d
        slices = np.floor(s / width).astype(int)
        cells = hinge_cells[keep]
        return np.array([self._frame(cells[slices == k]) for k in np.unique(slices)])
