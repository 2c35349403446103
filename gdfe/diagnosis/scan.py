"""Scans: reading a measured shape from a file.

A measured shape is a point cloud [mm]: a ``.csv`` of columns x, y, z (with or without a
header line), or a ``.ply``, ``.obj`` or ``.vtu`` mesh read with meshio (a VTU may carry the
hexahedra of a volume mesh, e.g. one written by ``gdfe simulate``). Every problem with the
file, including what meshio raises (or the ``SystemExit`` it ends with on a corrupt file), is
reported as a :class:`gdfe._validation.GdfeError` naming the file.

Lengths in mm.
"""

from __future__ import annotations

import io
import logging

import numpy as np

from gdfe._validation import LENGTH_RANGE, GdfeError, check_array, check_file, data_float, read_text

__all__ = ["load_measured", "check_points", "MEASURED_SUFFIXES"]

log = logging.getLogger(__name__)

#: The file suffixes :func:`load_measured` reads.
MEASURED_SUFFIXES = (".ply", ".vtu", ".obj", ".csv")


def load_measured(path, *, name="path"):
    """Read a measured shape.

    Parameters
    ----------
    path : str or Path
        ``.csv`` (columns x, y, z, with or without a header), or ``.ply``, ``.obj``, ``.vtu``
        (read with meshio).
    name : str
        The argument's name in error messages.

    Returns
    -------
    points : (k, 3) float array [mm]
    cells : (m, 8) int array or None
        Hexahedra of a volume mesh, if any.

    Raises
    ------
    GdfeFileNotFoundError
        No such file.
    GdfeError
        Another suffix, or a file that cannot be read (naming it, and the line for a CSV).
    """
    path = check_file(name, path, suffixes=MEASURED_SUFFIXES, what="measured shape")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return _guarded(path, _read_csv(path)), None
    mesh = _read_mesh(path)
    pts = np.asarray(mesh.points, float)
    if pts.ndim != 2 or pts.shape[0] == 0:
        raise GdfeError(f"{path.name}: expected points, got none")
    if pts.shape[1] not in (2, 3):
        raise GdfeError(f"{path.name}: expected points with 2 or 3 coordinates, got {pts.shape[1]}")
    if not np.isfinite(pts).all():
        raise GdfeError(f"{path.name}: expected finite coordinates, got NaN or inf")
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    hexes = [c.data for c in mesh.cells if c.type == "hexahedron"]
    return (_guarded(path, check_points(path.name, pts[:, :3], min_size=1)),
            np.concatenate(hexes) if hexes else None)


#: The cost of a shape diagnosis per scanned point, for the guard after a scan is read: peak memory
#: over a base, and seconds at 2·10^4 points growing as a power of the count (``gdfe diagnose-shape``
#: of a 1 200-cell drawing, 2 cores: 2·10^4 points 29 s and 286 MB, 6·10^4 points 105 s and 664 MB).
SCAN_BASE_BYTES, SCAN_BYTES_PER_POINT = 100 * 2**20, 9_500
SCAN_SECONDS_AT, SCAN_TIME_EXPONENT = (2e4, 29.0), 1.17


def _guarded(path, points):
    """The scan's points, after the guard: refused when diagnosing them would not fit in memory, the
    estimate said when it takes long."""
    from gdfe.resources import check_work, machine_memory

    n = len(points)
    n0, t0 = SCAN_SECONDS_AT
    need = SCAN_BASE_BYTES + SCAN_BYTES_PER_POINT * float(n)
    every = max(2, int(np.ceil(2 * need / (machine_memory() or need))))  # to half the machine's memory
    check_work(path.name, need, f"a scan of {n:,} points", f"subsample the scan (keep every {every}th point, "
               f"for instance)", seconds=t0 * (n / n0) ** SCAN_TIME_EXPONENT, logger=log)
    return points


def check_points(name, points, min_size=4):
    """A measured shape's points: a ``(k, 3)`` array of at least ``min_size`` finite points
    whose coordinates lie within the lengths a design may have (:data:`LENGTH_RANGE`, mm).

    Coordinates beyond it (1e300) are no scan in mm: a unit or a file error, and the
    alignment's distances would overflow.
    """
    pts = check_array(name, points, shape=(-1, 3), min_size=min_size)
    far = np.abs(pts) > LENGTH_RANGE[1]
    if far.any():
        raise GdfeError(f"{name}: expected coordinates within +-{LENGTH_RANGE[1]:g} mm, got "
                        f"{pts[far].flat[0]:g} (point {int(np.argwhere(far)[0][0])})")
    return pts


def _read_mesh(path):
    """:func:`gdfe.io.read_mesh` of a scan, a PLY's header checked first."""
    from gdfe.io import read_mesh

    if path.suffix.lower() == ".ply":
        _check_ply_header(path)
    return read_mesh(path)


#: How far into a PLY file its header must end [bytes].
PLY_HEADER_MAX = 1 << 20


def _check_ply_header(path):
    """A PLY file must open with ``ply`` and close its header with ``end_header``: meshio's reader
    loops for ever on a header that never ends (it reads past the end of the file line by line)."""
    with open(path, "rb") as f:
        head = f.read(PLY_HEADER_MAX)
    if not head.startswith(b"ply"):
        raise GdfeError(f"{path.name}: expected a readable PLY file, got one meshio cannot read (it does not "
                        f"start with 'ply': {head[:16]!r})")
    if b"end_header" not in head:
        raise GdfeError(f"{path.name}: expected a readable PLY file, got one meshio cannot read (no "
                        f"'end_header' in its first {PLY_HEADER_MAX // 1024} KiB: a truncated or corrupt header)")


def _read_csv(path):
    """Points of a CSV file: columns x, y, z (by a header's names, else the first three)."""
    import csv

    text = read_text(path, "text file of comma-separated x, y, z")
    try:
        rows = [r for r in csv.reader(io.StringIO(text, newline="")) if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        raise GdfeError(f"{path.name}: expected a text file of comma-separated x, y, z, got "
                        f"{type(exc).__name__}: {exc}") from None
    if not rows:
        raise GdfeError(f"{path.name}: expected points, got none")
    header = None
    try:
        [data_float(c) for c in rows[0][:3]]
    except ValueError:
        header = [c.strip().lower() for c in rows[0]]
        rows = rows[1:]
    cols = [0, 1, 2]
    if header is not None:
        if not all(a in header for a in ("x", "y", "z")):
            raise GdfeError(f"{path.name}: expected columns x, y, z, got {', '.join(header)}")
        cols = [header.index(a) for a in ("x", "y", "z")]
    pts = np.empty((len(rows), 3))
    for i, r in enumerate(rows):
        line = i + (2 if header is not None else 1)
        try:
            pts[i] = [data_float(r[c]) for c in cols]
        except (ValueError, IndexError):
            raise GdfeError(f"{path.name}: line {line}: expected three numbers x, y, z, got {r}") from None
        if not np.all(np.isfinite(pts[i])):
            raise GdfeError(f"{path.name}: line {line}: expected finite coordinates, got {r}")
    if len(pts) < 4:
        raise GdfeError(f"{path.name}: expected at least 4 points, got {len(pts)}")
    return check_points(path.name, pts)
