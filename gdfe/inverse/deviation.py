"""Deviation of a simulated strip from its target curve, overall and per printed segment.

The strip's mid-line (:func:`gdfe.inverse.strip_midline`) is aligned with the target by the
best rigid motion of the plane (:func:`gdfe.inverse.compare_curves`): for a target given by
couples, starting from corresponding arc lengths couple by couple (a hinge maps onto the
joint it replaces); for a sketch, by normalised arc length. Overall, ``max`` is the
symmetric Hausdorff distance between the two polylines and ``rms`` the root mean square of
the mid-line points' distances to the target. Per printed segment (couple or hinge),
``rms_mm`` and ``max_to_target_mm`` are over the mid-line points of that segment, and for a
couple ``max_from_target_mm`` is the largest distance from the target points of that couple
to the aligned mid-line; ``max_mm`` is the larger of the two.

All lengths in millimetres.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError

__all__ = ["Deviation", "strip_deviation", "plot_deviation"]


@dataclasses.dataclass
class Deviation:
    """A simulated mid-line measured against its target.

    Attributes
    ----------
    max : float [mm]
        Symmetric Hausdorff distance between the aligned mid-line and the target.
    rms : float [mm]
        Root mean square of the mid-line points' distances to the target.
    max_to_target, max_from_target : float [mm]
        The two one-sided distances.
    end_gap : float [mm]
        Distance between the aligned mid-line's ends minus the target's.
    off_plane : float [mm]
        Largest spread of the mid-line across the plane it should curl in.
    s : (k,) float array [mm]
        Arc length of each mid-line point along the flat print.
    midline : (k, 2) float array [mm]
        The simulated mid-line as it came out of the solver (the strip's x-z plane).
    aligned : (k, 2) float array [mm]
        The mid-line, moved onto the target.
    target : (m, 2) float array [mm]
        The target's points.
    point_segment : (k,) int array
        Printed segment of each mid-line point.
    segments : list of dict
        Per printed segment: ``index``, ``kind`` ("couple" or "hinge"), ``target_couple``
        (None for a hinge), ``L_mm``, ``r_mm``, ``points``, ``rms_mm``, ``max_to_target_mm``,
        ``max_from_target_mm`` (None for a hinge), ``max_mm``.
    """

    max: float
    rms: float
    max_to_target: float
    max_from_target: float
    end_gap: float
    off_plane: float
    s: np.ndarray
    midline: np.ndarray
    aligned: np.ndarray
    target: np.ndarray
    point_segment: np.ndarray
    segments: list

    def summary(self) -> dict:
        return {"max_mm": self.max, "rms_mm": self.rms, "max_to_target_mm": self.max_to_target,
                "max_from_target_mm": self.max_from_target, "end_gap_mm": self.end_gap,
                "off_plane_mm": self.off_plane, "segments": self.segments}


def strip_deviation(plan, result):
    """Measure a simulated strip's mid-line against the plan's target.

    Parameters
    ----------
    plan : gdfe.inverse.StripPlan
    result : gdfe.Result
        The simulated strip (its design's columns along x are the plan's pattern).

    Returns
    -------
    Deviation

    Raises
    ------
    GdfeError
        If ``result`` did not converge: its shape is not measured.
    """
    from gdfe.inverse.curves import _closest_on_polyline, compare_curves
    from gdfe.inverse.strips import strip_midline

    if not result.converged:
        raise GdfeError(f"result: the solver did not converge (residual {result.residual:.3g}); "
                        "its shape is not measured")
    target = plan.target
    s, uv, off = strip_midline(result)
    if target.s_curve is not None:
        ends_p, ends_t = plan.printed_ends(), plan.target_ends()
        cmp = compare_curves(uv, target.curve, s=np.interp(s, ends_p, ends_t), s_target=target.s_curve)
    else:
        cmp = compare_curves(uv, target.curve)
    A = cmp["aligned"]
    pat = plan.pattern
    col = np.clip(np.floor(s / pat.cell).astype(int), 0, pat.material.size - 1)
    seg = pat.segment[col]
    d_to, _ = _closest_on_polyline(A, target.curve)
    d_from, _ = _closest_on_polyline(target.curve, A)
    rows = []
    for k, c in enumerate(plan.printed):
        j = int(plan.source[k])
        mine = seg == k
        n = int(mine.sum())
        rms = float(np.sqrt((d_to[mine] ** 2).mean())) if n else None
        mto = float(d_to[mine].max()) if n else None
        mfrom = None
        if j >= 0 and np.any(target.curve_segment == j):
            mfrom = float(d_from[target.curve_segment == j].max())
        worst = max([v for v in (mto, mfrom) if v is not None], default=None)
        rows.append({"index": k, "kind": "hinge" if j < 0 else "couple", "target_couple": None if j < 0 else j,
                     "L_mm": c.L, "r_mm": c.r, "points": n, "rms_mm": rms, "max_to_target_mm": mto,
                     "max_from_target_mm": mfrom, "max_mm": worst})
    return Deviation(max=cmp["max"], rms=cmp["rms"], max_to_target=cmp["max_to_target"],
                     max_from_target=cmp["max_from_target"], end_gap=cmp["end_gap_mm"], off_plane=off,
                     s=s, midline=uv, aligned=A, target=target.curve, point_segment=seg, segments=rows)


def plot_deviation(deviation, path, title=None):
    """A PNG overlay of the target (grey) and the aligned simulated mid-line, coloured by segment.

    Each segment is labelled ``index: largest deviation [mm]``. The pair of points at the
    largest deviation, :attr:`Deviation.max` (the symmetric Hausdorff distance, the number the
    default title quotes), is joined by a red line: a mid-line point and its closest point on
    the target, or a target point and its closest point on the mid-line, whichever is farther.
    The legend sits beside the axes, inside the picture.

    Returns
    -------
    Path
    """
    from gdfe._plotting import pyplot
    from gdfe.inverse.curves import _closest_on_polyline
    from gdfe.io import save_figure

    plt = pyplot()
    dev = deviation
    fig, ax = plt.subplots(figsize=(9, 6), layout="constrained")
    T, A = dev.target, dev.aligned
    ax.plot(T[:, 0], T[:, 1], "-", color="0.65", lw=6, solid_capstyle="round", label="target")
    cmap = plt.get_cmap("tab10")
    for row in dev.segments:
        k = row["index"]
        idx = np.nonzero(dev.point_segment == k)[0]
        if idx.size == 0:
            continue
        # join each segment to the next one's first point so the curve has no gaps
        idx = np.append(idx, min(idx[-1] + 1, len(A) - 1))
        colour = "k" if row["kind"] == "hinge" else cmap(k % 10)
        ax.plot(A[idx, 0], A[idx, 1], "-", color=colour, lw=1.6)
        m = idx[len(idx) // 2]
        if row["max_mm"] is not None:
            ax.annotate(f"{k}: {row['max_mm']:.2f}", A[m], fontsize=7, xytext=(4, 4), textcoords="offset points")
    # the two one-sided distances; the larger is dev.max
    d_to, close_to = _closest_on_polyline(A, T)
    d_from, close_from = _closest_on_polyline(T, A)
    i, j = int(np.argmax(d_to)), int(np.argmax(d_from))
    if d_to[i] >= d_from[j]:
        a, b, where = A[i], close_to[i], "mid-line point farthest from the target"
    else:
        a, b, where = T[j], close_from[j], "target point farthest from the mid-line"
    ax.plot([a[0], b[0]], [a[1], b[1]], "r-", lw=1)
    ax.plot(a[0], a[1], "ro", ms=4, label=f"largest deviation, max {dev.max:.3f} mm\n({where})")
    ax.plot([], [], "-", color=cmap(0), label="GDFE mid-line\n(colour: segment, black: hinge)")
    ax.set_aspect("equal")
    ax.set(xlabel="mm", ylabel="mm",
           title=title or f"deviation: max {dev.max:.3f} mm (Hausdorff), RMS {dev.rms:.3f} mm")
    fig.legend(fontsize=8, loc="outside right upper")
    return save_figure(fig, Path(path), dpi=110)
