"""Designs from FOLD crease patterns: every crease becomes a hinge, the faces rigid panels.

FOLD (the origami community's JSON format, https://github.com/edemaine/fold) gives the
crease pattern as ``vertices_coords`` (flat: z absent or 0), ``edges_vertices`` and
``edges_assignment`` (``B`` boundary, ``M`` mountain, ``V`` valley, ``F`` flat, ``U``
unassigned), optionally ``edges_foldAngle`` (degrees, positive for valleys) and
``faces_vertices``. Lengths are in ``frame_unit`` (``mm``, ``cm``, ``m``, ``in``, ``pt``,
``um``, ``nm``); a unit-less file (``unit``, the FOLD default) needs a scale in mm per unit
(the ``gdfe:scale`` key or the ``scale`` argument).

The design, on the printer's pixel grid:

- the **film** is the union of the faces (without ``faces_vertices``: the loops of the
  boundary edges);
- every **crease** (``M`` or ``V``) is a hinge: the pixels whose centres lie within half its
  width of the crease, across it (a band as long as the crease); where bands overlap, the
  nearest crease wins;
- a hinge is coated on one face only: a **valley** fold (folding towards the viewer, +z)
  has its top face free (``CONTRACT_TOP``: coated on the bottom), a **mountain** fold the
  bottom face free (coated on top); ``edges_gdfe:coated`` (``"top"`` or ``"bottom"``, per
  edge, null for the default) overrides it;
- everything else is coated on both faces (``RIGID``).

:func:`fold_masks` gives the printer masks; :func:`gdfe.fabrication.fold_design` the design.

The hinge width, per crease, is the first of: ``edges_gdfe:width`` [frame units]; from
``edges_foldAngle`` by Eq. 2, ``L = |alpha| h / (1 - R)``, the width that folds a
fully contracting hinge by that angle; ``gdfe:hinge_width`` [mm] of the file; the
``hinge_width`` argument [mm]. ``gdfe:pixel`` [mm] gives the file's printer pixel.

Errors name the key and the index of the entry (``edges_vertices[3]``); JSON that does
not parse is reported with its line and column. Fold angles must lie in [-180, 180] degrees
(FOLD's range); each face must be a simple polygon, and the faces must not overlap (where
there are boundary edges, their areas must add up to the area the boundary encloses).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math

import numpy as np

from gdfe._validation import GdfeError, check_file, check_positive, describe, is_finite_number, read_text
from gdfe.resources import check_grid

__all__ = ["CreasePattern", "FoldMasks", "read_fold", "fold_masks", "crease_faces", "UNITS_MM", "ASSIGNMENTS"]

log = logging.getLogger(__name__)

#: Millimetres per FOLD ``frame_unit``.
UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "pt": 25.4 / 72.0, "um": 1e-3, "nm": 1e-6}
#: The edge assignments read (FOLD 1.1; cuts ``C`` and joins ``J`` are refused).
ASSIGNMENTS = ("B", "M", "V", "F", "U")


@dataclasses.dataclass
class CreasePattern:
    """A flat crease pattern read from a FOLD file, in millimetres.

    Attributes
    ----------
    name : str
    vertices : (v, 2) float array [mm]
    edges : (e, 2) int array
    assignment : (e,) str array
        ``B``, ``M``, ``V``, ``F`` or ``U``.
    fold_angle : (e,) float array [rad]
        Target fold angle (NaN where not given); positive for valleys.
    width : (e,) float array [mm]
        Hinge width from ``edges_gdfe:width`` (NaN where not given).
    coated : (e,) object array
        ``"top"``, ``"bottom"`` or None (from the assignment).
    faces : list of (k,) int arrays, or None
    keys : dict
        The file's ``gdfe:`` keys (``gdfe:hinge_width`` [mm], ``gdfe:pixel`` [mm], ...).
    """

    name: str
    vertices: np.ndarray
    edges: np.ndarray
    assignment: np.ndarray
    fold_angle: np.ndarray
    width: np.ndarray
    coated: np.ndarray
    faces: list | None
    keys: dict

    @property
    def creases(self):
        """Indices of the mountain and valley edges."""
        return np.nonzero(np.isin(self.assignment, ("M", "V")))[0]


@dataclasses.dataclass
class FoldMasks:
    """A crease pattern on the printer's pixel grid.

    Attributes
    ----------
    top, bottom, film : (nx, ny) bool arrays
        Passive material on each face, and where the film is (``[i, j]``: column i along x).
    pixel : float [mm]
    origin : (2,) float array [mm]
        Position of the grid's corner in the crease pattern's frame.
    hinges : list of dict
        Per crease: ``edge``, ``assignment``, ``coated``, ``width_mm``, ``width_from``,
        ``length_mm``, ``pixels``, ``faces`` (the two faces it joins, when the file has
        faces) and ``angle_rad``, the fold that Eq. 2 gives a fully contracting hinge of
        that width (positive towards +z).
    owner : (nx, ny) int array
        Crease of each hinge pixel (-1: none).
    faces : dict of int -> (nx, ny) bool array
        The panel pixels of each face (``faces_vertices`` order), hinges left out.
    """

    top: np.ndarray
    bottom: np.ndarray
    film: np.ndarray
    pixel: float
    origin: np.ndarray
    hinges: list
    owner: np.ndarray
    faces: dict


def _list(doc, key, name, n=None, required=True):
    """The list under ``key`` (``n`` entries, one per edge, if given); None if optional and absent."""
    v = doc.get(key)
    if v is None:
        if required:
            raise GdfeError(f"{name}: missing {key!r}")
        return None
    if not isinstance(v, list):
        raise GdfeError(f"{name}: {key}: expected a list, got {type(v).__name__}")
    if n is not None and len(v) != n:
        raise GdfeError(f"{name}: {key}: expected {n} entries (one per edge), got {len(v)}")
    return v


def _number(v, where):
    """``v`` as a float, refused unless a finite number."""
    if not is_finite_number(v):
        raise GdfeError(f"{where}: expected a finite number, got {v!r}")
    return float(v)


def read_fold(path, scale=None, scale_name="scale"):
    """Read a flat crease pattern from a FOLD file.

    Parameters
    ----------
    path : str or Path
        The ``.fold`` file.
    scale : float [mm per unit], optional
        For a unit-less file (overrides ``gdfe:scale``).
    scale_name : str or None
        What gives ``scale`` where the caller reads it (an option, a key), for the message asking
        for it; None where there is no such way (only the file's ``gdfe:scale``).

    Returns
    -------
    CreasePattern
    """
    path = check_file("fold", path, suffixes=(".fold",), what="FOLD file")
    name = path.name
    doc = _json_object(path)
    mm = _mm_per_unit(doc, name, scale, scale_name)
    V = _vertices(doc, name)
    E = _edges(doc, name, V)
    assignment = _assignments(doc, name, len(E))
    angle = _fold_angles(doc, name, assignment)
    width = _widths(doc, name, len(E), mm)
    coated = _coated(doc, name, assignment)
    faces = _faces(doc, name, len(V))
    keys = _gdfe_keys(doc, name)
    cp = CreasePattern(name=name, vertices=V * mm, edges=E, assignment=assignment, fold_angle=angle, width=width,
                       coated=coated, faces=faces, keys=keys)
    if faces:  # an empty list: the film from the boundary loops, as without faces_vertices
        _check_faces(cp)
    return cp


def _json_object(path):
    """The FOLD file's top-level JSON object (a parse error named by its line and column)."""
    name = path.name
    try:
        doc = json.loads(read_text(path, "FOLD (JSON) file"))
    except json.JSONDecodeError as exc:
        raise GdfeError(f"{name}: not valid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}") from None
    if not isinstance(doc, dict):
        raise GdfeError(f"{name}: expected a JSON object at the top, got {type(doc).__name__}")
    return doc


def _mm_per_unit(doc, name, scale, scale_name):
    """Millimetres per length unit of the file's frame (``frame_unit``, or the scale of a unit-less file)."""
    unit = doc.get("frame_unit", "unit")
    if not isinstance(unit, str):  # a list or an object cannot name a unit (it was an unhashable-type TypeError)
        raise GdfeError(f"{name}: frame_unit: expected one of unit, {', '.join(UNITS_MM)}, got {unit!r}")
    if unit in UNITS_MM:
        if scale is not None:
            log.info("%s: frame_unit %s: scale ignored", name, unit)
        return UNITS_MM[unit]
    if unit != "unit":
        raise GdfeError(f"{name}: frame_unit: expected one of unit, {', '.join(UNITS_MM)}, got {unit!r}")
    if scale is not None:
        return float(check_positive(scale_name or "scale", scale))
    s = doc.get("gdfe:scale")
    if s is None:
        how = "the file's 'gdfe:scale' key" + (f", or {scale_name}" if scale_name else "")
        raise GdfeError(f"{name}: frame_unit is 'unit' (no length unit): give the scale in mm per unit "
                        f"({how}), or a frame_unit of {', '.join(UNITS_MM)}")
    mm = _number(s, f"{name}: gdfe:scale")
    if mm <= 0:
        raise GdfeError(f"{name}: gdfe:scale: expected a positive number of mm per unit, got {mm:g}")
    return mm


def _vertices(doc, name):
    """The (v, 2) vertex positions [frame units] of ``vertices_coords``, which must lie in z = 0."""
    vc = _list(doc, "vertices_coords", name)
    V = np.zeros((len(vc), 2))
    for k, c in enumerate(vc):
        where = f"{name}: vertices_coords[{k}]"
        if not isinstance(c, list) or len(c) not in (2, 3):
            raise GdfeError(f"{where}: expected [x, y] (or [x, y, 0]), got {c!r}")
        xyz = [_number(x, where) for x in c]
        if len(xyz) == 3 and abs(xyz[2]) > 1e-9 * max(1.0, abs(xyz[0]), abs(xyz[1])):
            raise GdfeError(f"{where}: expected a flat crease pattern (z = 0), got z = {xyz[2]:g}")
        V[k] = xyz[:2]
    return V


def _edges(doc, name, V):
    """The (e, 2) vertex indices of ``edges_vertices``: two different vertices of ``V``, at different points."""
    ev = _list(doc, "edges_vertices", name)
    E = np.zeros((len(ev), 2), int)
    for k, e in enumerate(ev):
        if (not isinstance(e, list) or len(e) != 2 or not all(isinstance(i, int) and not isinstance(i, bool)
                                                                  for i in e)):
            raise GdfeError(f"{name}: edges_vertices[{k}]: expected two vertex indices, got {e!r}")
        if not all(0 <= i < len(V) for i in e) or e[0] == e[1]:
            raise GdfeError(f"{name}: edges_vertices[{k}]: expected two different vertices in 0..{len(V) - 1}, "
                            f"got {e!r}")
        E[k] = e
        if np.array_equal(V[e[0]], V[e[1]]):
            raise GdfeError(f"{name}: edges_vertices[{k}]: an edge of zero length (vertices {e[0]} and {e[1]} are "
                            f"both at {describe(V[e[0]].tolist())}); expected two vertices at different points")
    return E


def _assignments(doc, name, ne):
    """The (e,) ``edges_assignment`` letters (all ``U`` when absent); cuts and joins refused."""
    ea = _list(doc, "edges_assignment", name, ne, required=False) or ["U"] * ne
    for k, a in enumerate(ea):
        if a in ("C", "J"):
            raise GdfeError(f"{name}: edges_assignment[{k}]: {a!r} ({'cut' if a == 'C' else 'join'}) is not "
                            f"supported; expected one of {', '.join(ASSIGNMENTS)}")
        if a not in ASSIGNMENTS:
            raise GdfeError(f"{name}: edges_assignment[{k}]: expected one of {', '.join(ASSIGNMENTS)}, got {a!r}")
    return np.array(ea, dtype="<U1")


def _fold_angles(doc, name, assignment):
    """The (e,) ``edges_foldAngle`` [rad] (NaN where not given), of the sign the mountain or valley needs."""
    fa = _list(doc, "edges_foldAngle", name, len(assignment), required=False)
    angle = np.full(len(assignment), np.nan)
    for k, a in enumerate(fa or []):
        if a is not None:
            deg = _number(a, f"{name}: edges_foldAngle[{k}]")
            if not -180.0 <= deg <= 180.0:  # FOLD's fold angles are in [-180, 180] (720 made an 11.9 mm hinge)
                raise GdfeError(f"{name}: edges_foldAngle[{k}]: expected degrees in [-180, 180], got {a!r}")
            angle[k] = math.radians(deg)
            mv = assignment[k]
            if mv == "M" and angle[k] > 0 or mv == "V" and angle[k] < 0:
                raise GdfeError(f"{name}: edges_foldAngle[{k}]: a {'mountain' if mv == 'M' else 'valley'} "
                                f"fold needs a {'negative' if mv == 'M' else 'positive'} angle, got {a!r}")
    return angle


def _widths(doc, name, ne, mm):
    """The (e,) hinge widths [mm] of ``edges_gdfe:width`` (NaN where not given)."""
    ew = _list(doc, "edges_gdfe:width", name, ne, required=False)
    width = np.full(ne, np.nan)
    for k, w in enumerate(ew or []):
        if w is not None:
            width[k] = _number(w, f"{name}: edges_gdfe:width[{k}]") * mm
            if width[k] <= 0:
                raise GdfeError(f"{name}: edges_gdfe:width[{k}]: expected a positive width, got {w!r}")
    return width


def _coated(doc, name, assignment):
    """The (e,) coated face of each edge: ``edges_gdfe:coated``, else the one its fold leaves coated."""
    ec = _list(doc, "edges_gdfe:coated", name, len(assignment), required=False)
    coated = np.full(len(assignment), None, dtype=object)
    coated[assignment == "V"] = "bottom"  # a valley folds towards +z: its top face is the free one
    coated[assignment == "M"] = "top"
    for k, c in enumerate(ec or []):
        if c is not None:
            if c not in ("top", "bottom"):
                raise GdfeError(f"{name}: edges_gdfe:coated[{k}]: expected 'top', 'bottom' or null, got {c!r}")
            coated[k] = c
    return coated


def _faces(doc, name, nv):
    """The ``faces_vertices``, each a (k,) int array of at least 3 of the ``nv`` vertices; None when absent."""
    fv = _list(doc, "faces_vertices", name, required=False)
    if fv is None:
        return None
    faces = []
    for k, f in enumerate(fv):
        if (not isinstance(f, list) or len(f) < 3
                or not all(isinstance(i, int) and not isinstance(i, bool) and 0 <= i < nv for i in f)):
            raise GdfeError(f"{name}: faces_vertices[{k}]: expected at least 3 vertex indices in "
                            f"0..{nv - 1}, got {f!r}")
        faces.append(np.array(f, int))
    return faces


def _gdfe_keys(doc, name):
    """The file's ``gdfe:hinge_width`` and ``gdfe:pixel`` [mm] that it gives, each positive."""
    keys = {}
    for key in ("gdfe:hinge_width", "gdfe:pixel"):
        if key in doc:
            v = _number(doc[key], f"{name}: {key}")
            if v <= 0:
                raise GdfeError(f"{name}: {key}: expected a positive length in mm, got {v:g}")
            keys[key] = v
    return keys


def _boundary_loops(cp):
    """Closed loops of the boundary edges (for a file without faces)."""
    b = [tuple(e) for e, a in zip(cp.edges.tolist(), cp.assignment) if a == "B"]
    if not b:
        raise GdfeError(f"{cp.name}: no faces_vertices and no boundary (B) edges: the film's outline is unknown")
    nbr = {}
    for u, v in b:
        nbr.setdefault(u, []).append(v)
        nbr.setdefault(v, []).append(u)
    odd = [u for u, n in nbr.items() if len(n) != 2]
    if odd:
        raise GdfeError(f"{cp.name}: the boundary edges do not form closed loops (vertex {odd[0]} has "
                        f"{len(nbr[odd[0]])} boundary edges)")
    loops, seen = [], set()
    for start in nbr:
        if start in seen:
            continue
        loop, prev, cur = [start], None, start
        seen.add(start)
        while True:
            nxt = nbr[cur][0] if nbr[cur][0] != prev else nbr[cur][1]
            if nxt == start:
                break
            loop.append(nxt)
            seen.add(nxt)
            prev, cur = cur, nxt
        loops.append(np.array(loop))
    return loops


def _cross(o, a, b):
    """z of ``(a - o) x (b - o)``, over the leading axes of (..., 2) arrays."""
    return (a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1]) - (a[..., 1] - o[..., 1]) * (b[..., 0] - o[..., 0])


def _segments_meet(a, b, c, d, tol):
    """Whether the closed segments a-b and c-d meet (cross, touch or overlap), over the leading axes.

    Points within ``tol`` [length] of a segment's line count as on it, so collinear and
    touching segments are found whatever the round-off.
    """
    def side(p, q, r):  # -1, 0 or 1: r right of, on or left of the line p-q (within tol)
        o = _cross(p, q, r)
        return np.where(np.abs(o) <= tol * np.hypot(*(q - p).T).T, 0, np.sign(o))

    def within(p, q, r):  # r, on the line p-q, lies between p and q
        return np.all((np.minimum(p, q) - tol <= r) & (r <= np.maximum(p, q) + tol), axis=-1)

    s1, s2, s3, s4 = side(c, d, a), side(c, d, b), side(a, b, c), side(a, b, d)
    cross = (s1 * s2 < 0) & (s3 * s4 < 0)
    touch = ((s1 == 0) & within(c, d, a)) | ((s2 == 0) & within(c, d, b)) | ((s3 == 0) & within(a, b, c)) \
        | ((s4 == 0) & within(a, b, d))
    return cross | touch


def _areas(P):
    """Signed (shoelace) areas of the closed polygons ``P`` (m, n, 2), positive anticlockwise."""
    Q = np.roll(P, -1, axis=-2)
    return 0.5 * np.sum(P[..., 0] * Q[..., 1] - Q[..., 0] * P[..., 1], axis=-1)


def _area(P):
    """Signed (shoelace) area of the closed polygon ``P``, positive anticlockwise."""
    return float(_areas(P[None])[0])


def _inside(P, pts, tol):
    """Which of the points ``pts`` (m, 2) lie inside the closed polygon ``P`` by more than ``tol``.

    Even-odd rule (a ray along +x); a point within ``tol`` of an edge is not inside.
    """
    a, b = P[None, :, :], np.roll(P, -1, axis=0)[None, :, :]
    p = np.asarray(pts, float)[:, None, :]
    d = b - a
    L2 = np.maximum(np.sum(d * d, axis=-1), np.finfo(float).tiny)
    t = np.clip(np.sum((p - a) * d, axis=-1) / L2, 0.0, 1.0)
    near = np.hypot(*(a + t[..., None] * d - p).transpose(2, 0, 1)).min(axis=1) <= tol
    straddle = (a[..., 1] > p[..., 1]) != (b[..., 1] > p[..., 1])
    dy = np.where(straddle, d[..., 1], 1.0)
    x = a[..., 0] + (p[..., 1] - a[..., 1]) * d[..., 0] / dy
    odd = np.sum(straddle & (x > p[..., 0]), axis=1) % 2 == 1
    return odd & ~near


def _blocks(m, cost, budget=1 << 22):
    """Slices of ``range(m)`` of at most ``budget / cost`` entries (at least one): rows of ``cost`` numbers."""
    step = max(1, budget // max(int(cost), 1))
    return [slice(s, min(s + step, m)) for s in range(0, m, step)]


def _simple_faults(f, P, tol):
    """How the faces ``f`` (m, n) [vertex indices], at ``P`` (m, n, 2), fail to be simple polygons.

    Returns
    -------
    twice : (m, n, n) bool array
        ``[k, p, q]``: entries p and q < p are the same vertex.
    close : (m, n, n) bool array
        ``[k, p, q]``: entries p < q are different vertices within ``tol`` of each other.
    back : (m, n) bool array
        ``[k, p]``: the edges into and out of entry p double back over each other.
    meet : (m, e) bool array
        Per pair of non-adjacent edges (:func:`_edge_pairs`): they meet.
    """
    n = f.shape[1]
    twice = np.tril(f[:, :, None] == f[:, None, :], -1)
    close = np.triu(np.hypot(*(P[:, :, None, :] - P[:, None, :, :]).transpose(3, 0, 1, 2)) <= tol, 1)
    prev, nxt = np.roll(P, 1, axis=1), np.roll(P, -1, axis=1)
    u, w = prev - P, nxt - P
    back = (np.abs(_cross(P, prev, nxt)) <= tol * np.hypot(u[..., 0], u[..., 1])) & (np.sum(u * w, axis=-1) > 0)
    i, j = _edge_pairs(n)
    meet = _segments_meet(P[:, i], nxt[:, i], P[:, j], nxt[:, j], tol)
    return twice, close, back, meet


def _edge_pairs(n):
    """The pairs (i, j), i < j, of non-adjacent edges of a polygon of ``n`` vertices (edge i: vertex i to i + 1)."""
    i, j = np.triu_indices(n, 2)
    keep = ~((i == 0) & (j == n - 1))  # the last edge and the first are adjacent
    return i[keep], j[keep]


def _check_simple(name, k, f, P, tol):
    """Refuse face ``k`` (vertex indices ``f``, positions ``P``) unless a simple polygon.

    Its vertices are different points, two adjacent edges do not double back over each other,
    and two non-adjacent edges do not meet (adjacent ones meet only at their shared vertex).
    """
    where = f"{name}: faces_vertices[{k}]: expected a simple polygon (edges meeting only at their shared corners)"
    twice, close, back, meet = (x[0] for x in _simple_faults(f[None], P[None], tol))
    n = len(f)
    if twice.any():
        raise GdfeError(f"{where}, got {f.tolist()}: it has vertex {f[np.nonzero(twice)[0][0]]} twice")
    if close.any():
        i, j = (int(x[0]) for x in np.nonzero(close))
        raise GdfeError(f"{where}, got {f.tolist()}: its vertices {f[i]} and {f[j]} are both at "
                        f"{describe(P[i].tolist())}")
    if back.any():
        m = int(np.argmax(back))
        raise GdfeError(f"{where}, got {f.tolist()}: its edges {f[m - 1]}-{f[m]} and {f[m]}-{f[(m + 1) % n]} "
                        f"double back over each other")
    if meet.any():
        i, j = _edge_pairs(n)
        a, b = int(i[np.argmax(meet)]), int(j[np.argmax(meet)])
        raise GdfeError(f"{where}, got {f.tolist()}: its edge {f[a]}-{f[(a + 1) % n]} crosses its edge "
                        f"{f[b]}-{f[(b + 1) % n]}")


def _face_groups(faces, V):
    """The faces grouped by their number of vertices: a list of (rows, f, P), ``rows`` the faces'
    indices, ``f`` (m, n) their vertex indices and ``P`` (m, n, 2) their positions."""
    sizes = np.array([len(f) for f in faces])
    flat = np.concatenate(faces)
    start = np.cumsum(sizes) - sizes
    groups = []
    for n in np.unique(sizes).tolist():
        rows = np.nonzero(sizes == n)[0]
        f = flat[start[rows][:, None] + np.arange(n)]
        groups.append((rows, f, V[f]))
    return groups


def _check_simple_faces(name, faces, V, groups, tol):
    """Refuse the first face (in file order) that is not a simple polygon, as :func:`_check_simple` does;
    the faces are tested together, those of each number of vertices (``groups``, :func:`_face_groups`) as one."""
    bad = [np.zeros(0, int)]
    for rows, f, P in groups:
        n = f.shape[1]
        for s in _blocks(len(rows), 16 * n * n):
            faults = _simple_faults(f[s], P[s], tol)
            bad.append(rows[s][np.any([x.reshape(len(x), -1).any(axis=1) for x in faults], axis=0)])
    for k in np.sort(np.concatenate(bad)).tolist():
        _check_simple(name, k, faces[k], V[faces[k]], tol)


def _convex(P, tol):
    """Which of the simple polygons ``P`` (m, n, 2) are convex (vertices on a straight edge allowed)."""
    prev = np.roll(P, 1, axis=1)
    turn = _cross(prev, P, np.roll(P, -1, axis=1)) * np.sign(_areas(P))[:, None]
    return np.all(turn >= -tol * np.hypot(*(P - prev).transpose(2, 0, 1)), axis=1)


def _overlap_convex(A, B, tol):
    """Which pairs of convex polygons ``A`` (m, na, 2) and ``B`` (m, nb, 2) overlap inside (separating axes).

    Two convex polygons' insides are apart where the projections on the normal of one of
    their edges overlap by ``tol`` or less (touching along an edge or at a corner: apart).
    """
    d = np.concatenate([np.roll(A, -1, axis=1) - A, np.roll(B, -1, axis=1) - B], axis=1)
    axes = np.stack([-d[..., 1], d[..., 0]], axis=-1) / np.hypot(d[..., 0], d[..., 1])[..., None]
    pa = A[:, :, None, 0] * axes[:, None, :, 0] + A[:, :, None, 1] * axes[:, None, :, 1]
    pb = B[:, :, None, 0] * axes[:, None, :, 0] + B[:, :, None, 1] * axes[:, None, :, 1]
    gap = np.minimum(pa.max(axis=1), pb.max(axis=1)) - np.maximum(pa.min(axis=1), pb.min(axis=1))
    return np.all(gap > tol, axis=1)


def _triangles(P, tol):
    """Triangles tiling the simple polygons ``P`` (m, n, 2), by ear clipping (all the polygons at once).

    Each polygon is walked anticlockwise, and loses one vertex a step: a vertex within ``tol``
    of the line through its two neighbours lies on a straight edge, and is dropped without a
    triangle; otherwise an ear (:func:`_ears`) is cut off as a triangle. The three vertices
    left make the last triangle.

    Returns
    -------
    triangles : (t, 3, 2) float array
        Anticlockwise.
    owner : (t,) int array
        The polygon (row of ``P``) of each.
    """
    m = len(P)
    Q = np.where((_areas(P) > 0)[:, None, None], P, P[:, ::-1])
    rows = np.arange(m)
    out, owner = [np.zeros((0, 3, 2))], [np.zeros(0, int)]
    while True:
        prev, nxt = np.roll(Q, 1, axis=1), np.roll(Q, -1, axis=1)
        base = np.hypot(*(nxt - prev).transpose(2, 0, 1))
        turn = _cross(prev, Q, nxt)
        if Q.shape[1] == 3:
            keep = turn[:, 1] > tol * base[:, 1]  # not three points on a line
            out.append(Q[keep])
            owner.append(rows[keep])
            break
        straight = np.abs(turn) <= tol * base
        v = np.where(straight.any(axis=1), np.argmax(straight, axis=1), _ears(Q, turn, base, tol))
        cut = ~straight[rows, v]
        out.append(np.stack([prev[rows, v], Q[rows, v], nxt[rows, v]], axis=1)[cut])
        owner.append(rows[cut])
        keep = np.ones(Q.shape[:2], bool)
        keep[rows, v] = False
        Q = Q[keep].reshape(m, -1, 2)
    return np.concatenate(out), np.concatenate(owner)


def _ears(Q, turn, base, tol, block=16):
    """An ear of each anticlockwise simple polygon ``Q`` (m, n, 2): the first vertex turning left (by
    more than ``tol``) whose triangle with its two neighbours holds no other vertex, nor has one within
    ``tol`` of it; ``block`` candidates of each polygon are tried at a time.

    Where round-off leaves none, the first whose triangle holds no vertex by more than ``tol``;
    where none either, the vertex turning left the most.
    """
    m, n = turn.shape
    convex = turn > tol * base
    order = np.argsort(~convex, axis=1, kind="stable")  # the vertices turning left first, in order
    found = np.full(m, -1)
    for margin in (-tol, tol):
        for s in range(0, n, block):
            todo = np.nonzero(found < 0)[0]
            c = order[todo, s:s + block]
            valid = convex[todo[:, None], c]
            if not valid.any():
                break
            corners = [Q[todo[:, None], (c + off) % n] for off in (-1, 0, 1)]
            held = np.ones(c.shape + (n,), bool)
            for a, b in zip(corners, corners[1:] + corners[:1]):  # distance left of each side, over margin
                held &= _cross(a[:, :, None], b[:, :, None], Q[todo, None]) > \
                    margin * np.hypot(*(b - a).transpose(2, 0, 1))[..., None]
            for off in (-1, 0, 1):
                np.put_along_axis(held, ((c + off) % n)[..., None], False, axis=2)
            ear = valid & ~held.any(axis=2)
            has = ear.any(axis=1)
            found[todo[has]] = c[has, np.argmax(ear[has], axis=1)]
    return np.where(found >= 0, found, np.argmax(turn, axis=1))


def _box_pairs(lo, hi, tol, budget=1 << 20):
    """The pairs ``(i, j)``, i < j, of the boxes ``[lo, hi]`` (f, 2) that overlap by more than ``tol`` on both axes.

    Sort and sweep, in strips: the plane is cut into strips along y (:func:`_strips`), each box
    put in every strip it reaches; in each strip the boxes are sorted by their lower x, and the
    candidates of each are the boxes after it that start before it ends along x (found by
    bisection). A pair is kept in one strip only, that of the higher of the two boxes' lower
    y, and where the boxes overlap by more than ``tol`` along x and along y. Done a block of
    about ``budget`` candidates at a time.

    Returns
    -------
    i, j : (p,) int arrays
    """
    f = len(lo)
    first_strip, box, strip = _strips(lo[:, 1], hi[:, 1])
    by_x = np.argsort(lo[:, 0], kind="stable")
    rank = np.empty(f, int)
    rank[by_x] = np.arange(f)
    reach = np.searchsorted(lo[by_x, 0], hi[:, 0], side="right")  # the ranks of the boxes starting by its end
    key = strip * (f + 1) + rank[box]  # the entries by strip, then by lower x
    order = np.argsort(key)
    box, strip = box[order], strip[order]
    count = np.searchsorted(key[order], strip * (f + 1) + reach[box]) - np.arange(len(box)) - 1
    count = np.maximum(count, 0)
    end = np.cumsum(count)
    first = end - count  # where each entry's candidates start in the list of all of them
    pairs = [np.zeros((2, 0), int)]
    p = 0
    while p < len(box):
        q = max(p + 1, int(np.searchsorted(end, first[p] + budget, side="right")))
        a = np.repeat(np.arange(p, q), count[p:q])
        b = a + 1 + np.arange(len(a)) - (first[a] - first[p])
        i, j = box[a], box[b]
        keep = np.all(np.minimum(hi[i], hi[j]) - np.maximum(lo[i], lo[j]) > tol, axis=1)
        keep &= strip[a] == np.maximum(first_strip[i], first_strip[j])
        pairs.append(np.sort([i[keep], j[keep]], axis=0))
        p = q
    i, j = np.concatenate(pairs, axis=1)
    return i, j


def _strips(lo, hi):
    """Strips for :func:`_box_pairs`: the intervals ``[lo, hi]`` (f,) cut at multiples of a height,
    twice the median interval's (doubled while the intervals would reach more than 4 f strips in all).

    Returns
    -------
    first : (f,) int array
        The strip each interval starts in.
    box, strip : (e,) int arrays
        Every interval (``box``) in every strip it reaches, in order.
    """
    f = len(lo)
    h = max(2.0 * float(np.median(hi - lo)), float(hi.max() - lo.min()) / f, np.finfo(float).tiny)
    while True:
        first = np.floor((lo - lo.min()) / h).astype(int)
        span = np.floor((hi - lo.min()) / h).astype(int) - first + 1
        if span.sum() <= 4 * f:
            break
        h *= 2.0
    box = np.repeat(np.arange(f), span)
    strip = first[box] + np.arange(len(box)) - (np.cumsum(span) - span)[box]
    return first, box, strip


def _pieces(groups, convex, needed, tol):
    """Convex pieces of the ``needed`` faces: a convex face whole, any other in triangles (:func:`_triangles`).

    Returns
    -------
    owner : (p,) int array
        Face of each piece, in increasing order.
    size, row : (p,) int arrays
        Its number of vertices, and its row in ``stacks[size]``.
    lo, hi : (p, 2) float arrays
        Its bounding box.
    stacks : dict of int -> (m, size, 2) float array
    """
    owners, stacks = {}, {}
    for rows, f, P in groups:
        take = convex[rows] & needed[rows]
        owners.setdefault(f.shape[1], []).append(rows[take])
        stacks.setdefault(f.shape[1], []).append(P[take])
        cut = np.nonzero(~convex[rows] & needed[rows])[0]
        for s in _blocks(len(cut), 64 * f.shape[1]):
            T, r = _triangles(P[cut[s]], tol)
            owners.setdefault(3, []).append(rows[cut[s]][r])
            stacks.setdefault(3, []).append(T)
    stacks = {n: np.concatenate(s) for n, s in stacks.items()}
    owner = np.concatenate([np.concatenate(owners[n]) for n in stacks])
    size = np.concatenate([np.full(len(stacks[n]), n) for n in stacks])
    row = np.concatenate([np.arange(len(stacks[n])) for n in stacks])
    lo = np.concatenate([stacks[n].min(axis=1) for n in stacks])
    hi = np.concatenate([stacks[n].max(axis=1) for n in stacks])
    order = np.argsort(owner, kind="stable")
    return owner[order], size[order], row[order], lo[order], hi[order], stacks


def _faces_overlap(groups, convex, i, j, tol):
    """Which pairs of faces ``(i, j)`` overlap inside: any of their convex pieces (:func:`_pieces`) do
    (tested where the pieces' bounding boxes overlap by more than ``tol``)."""
    if not len(i):
        return np.zeros(0, bool)
    needed = np.zeros(len(convex), bool)
    needed[i] = needed[j] = True
    owner, size, row, lo, hi, stacks = _pieces(groups, convex, needed, tol)
    count = np.bincount(owner, minlength=len(convex))
    start = np.cumsum(count) - count
    n = count[i] * count[j]  # piece pairs per face pair
    pair = np.repeat(np.arange(len(i)), n)
    k = np.arange(len(pair)) - (np.cumsum(n) - n)[pair]
    a = start[i][pair] + k // count[j][pair]
    b = start[j][pair] + k % count[j][pair]
    near = np.all(np.minimum(hi[a], hi[b]) - np.maximum(lo[a], lo[b]) > tol, axis=1)  # their boxes overlap
    pair, a, b = pair[near], a[near], b[near]
    hit = np.zeros(len(pair), bool)
    kind = size[a] * (int(size.max(initial=0)) + 1) + size[b]
    for key in np.unique(kind).tolist():
        sel = np.nonzero(kind == key)[0]
        na, nb = size[a[sel[0]]], size[b[sel[0]]]
        for s in _blocks(len(sel), (na + nb) * max(na, nb) * 4):
            t = sel[s]
            hit[t] = _overlap_convex(stacks[na][row[a[t]]], stacks[nb][row[b[t]]], tol)
    overlap = np.zeros(len(i), bool)
    overlap[pair[hit]] = True
    return overlap


def _check_tiling(cp, V, areas, tol, span):
    """Refuse faces whose areas do not add up to the area the boundary (B) edges' loops enclose."""
    name = cp.name
    try:
        loops = [V[p] for p in _boundary_loops(cp)]
    except GdfeError as exc:
        log.info("%s: faces not checked against the boundary: %s", name, exc)
        return
    enclosed = 0.0
    for i, L in enumerate(loops):
        depth = sum(bool(_inside(M, L, tol).any()) for j, M in enumerate(loops) if j != i)
        enclosed += (-1.0) ** depth * abs(_area(L))  # a loop inside an odd number of loops: a hole
    total = float(areas.sum())
    if abs(total - enclosed) > 1e-6 * max(total, enclosed) + 1e-9 * span ** 2:
        how = "overlap (or reach outside the outline)" if total > enclosed else "leave out part of the outline"
        raise GdfeError(f"{name}: faces_vertices: the faces' areas add up to {total:.6g} mm2 but the "
                        f"boundary (B) edges enclose {enclosed:.6g} mm2; expected faces that tile the "
                        f"outline, got faces that {how}")


def _check_faces(cp):
    """Refuse faces that cross themselves, overlap one another or do not tile the boundary's outline.

    Each face must be a simple polygon (:func:`_check_simple`). Where the file has boundary
    (``B``) edges in closed loops, the faces' areas must add up to the area the loops enclose
    (a loop inside another one is a hole). Then no two faces may overlap inside, exactly for
    any simple polygons: the pairs whose bounding boxes overlap (:func:`_box_pairs`) are
    tested piece by piece, a convex face whole and any other in triangles, by separating axes
    (:func:`_overlap_convex`). Faces that share an edge or a corner, or touch along an edge,
    do not overlap; round-off is allowed for by a tolerance of 1e-9 of the pattern's size.
    The faces are checked together, those of each number of vertices as one array.
    """
    name = cp.name
    V = cp.vertices - cp.vertices.min(0)  # round-off as of the pattern's size, not its position
    span = float(max(np.ptp(cp.vertices, axis=0).max(), np.finfo(float).tiny))
    tol = 1e-9 * span
    groups = _face_groups(cp.faces, V)
    _check_simple_faces(name, cp.faces, V, groups, tol)
    areas, convex = np.zeros(len(cp.faces)), np.zeros(len(cp.faces), bool)
    lo, hi = np.zeros((len(cp.faces), 2)), np.zeros((len(cp.faces), 2))
    for rows, f, P in groups:
        areas[rows], convex[rows] = np.abs(_areas(P)), _convex(P, tol)
        lo[rows], hi[rows] = P.min(axis=1), P.max(axis=1)
    if (cp.assignment == "B").any():
        _check_tiling(cp, V, areas, tol, span)
    # pairwise, exact for simple polygons: a face not convex is cut into triangles, and two faces
    # overlap where a piece of one and a piece of the other do (where there are B edges the areas
    # above already catch most overlaps, but not those a gap elsewhere makes up for)
    i, j = _box_pairs(lo, hi, tol)
    overlap = _faces_overlap(groups, convex, i, j, tol)
    if overlap.any():
        first = np.lexsort((i[overlap], j[overlap]))[0]
        i, j = int(i[overlap][first]), int(j[overlap][first])
        raise GdfeError(f"{name}: faces_vertices[{j}]: overlaps faces_vertices[{i}] (expected faces that "
                        f"meet only along their edges, got {cp.faces[j].tolist()} and {cp.faces[i].tolist()})")
    _check_creases_bound_faces(cp, V, tol)


def crease_faces(cp):
    """The faces each crease joins: ``{edge: [face, ...]}`` over :attr:`CreasePattern.creases`, the faces whose
    boundary has the crease as one of its sides (its two vertices next to each other)."""
    sides = {}
    for k, f in enumerate(cp.faces or []):
        for a, b in zip(f.tolist(), np.roll(f, -1).tolist()):
            sides.setdefault((min(a, b), max(a, b)), []).append(k)
    return {int(e): sides.get(tuple(sorted(cp.edges[e].tolist())), []) for e in cp.creases}


def _check_creases_bound_faces(cp, V, tol):
    """Warn of a crease that runs through a face (joins two of its corners that are not neighbours, inside it):
    its hinge is printed and folds, but the faces on its sides are not in the file, so its fold is not
    measured (:func:`gdfe.fabrication.crease_angles` joins a crease's two faces)."""
    holding = {}  # vertex -> the faces with that corner
    for k, f in enumerate(cp.faces):
        for v in f.tolist():
            holding.setdefault(v, set()).add(k)
    for e, faces in crease_faces(cp).items():
        a, b = cp.edges[e].tolist()
        for k in sorted((holding.get(a, set()) & holding.get(b, set())) - set(faces)):
            f = cp.faces[k]
            if _inside(V[f], V[cp.edges[e]].mean(axis=0)[None], tol)[0]:
                log.warning("%s: edges_vertices[%d] (%s) runs through faces_vertices[%d] from corner to corner: "
                            "its hinge is printed, but its fold is not measured (split the face along the crease "
                            "to measure it)", cp.name, e, cp.assignment[e], k)


#: Bytes per pixel of :func:`fold_masks`: the film, face and hinge masks, the pixels' centres, the
#: nearest crease's distance and owner, and one crease's band at a time (about ten 8-byte arrays).
FOLD_BYTES_PER_PIXEL = 80


def fold_masks(cp, pixel, R, h, hinge_width=None):
    """The printer masks of a crease pattern at a pixel size.

    Parameters
    ----------
    cp : CreasePattern
    pixel : float [mm]
    R : float
        Contraction ratio of the free faces (for widths from fold angles, Eq. 2).
    h : float [mm]
        Film thickness (likewise).
    hinge_width : float [mm], optional
        Width of creases that give none (nor a fold angle, nor ``gdfe:hinge_width``).

    Returns
    -------
    FoldMasks
    """
    from gdfe.fabrication.raster import fill_polygons

    pixel = check_positive("pixel", pixel)
    V = cp.vertices
    lo, hi = V.min(0), V.max(0)
    n = [(hi[k] - lo[k]) / pixel for k in (0, 1)]
    # before any grid is made: the film's size on the printer's grid (a file in metres read as
    # millimetres, or a pixel far too small, would ask for tens of GiB)
    check_grid(f"{cp.name}: pixel", n[0] * n[1], (hi - lo).tolist(), pixel, FOLD_BYTES_PER_PIXEL)
    nx, ny = (max(1, int(math.ceil(n[k] - 1e-9))) for k in (0, 1))
    polys = [(V[f] - lo) / pixel for f in cp.faces] if cp.faces else [(V[p] - lo) / pixel for p in _boundary_loops(cp)]
    if cp.faces:
        film = np.zeros((ny, nx), bool)
        for P in polys:
            film |= fill_polygons([P], (ny, nx))
    else:
        film = fill_polygons(polys, (ny, nx), "evenodd")
    film = film.T
    if not film.any():
        raise GdfeError(f"{cp.name}: the film covers no pixel at {pixel:g} mm")
    xc = lo[0] + (np.arange(nx) + 0.5) * pixel
    yc = lo[1] + (np.arange(ny) + 0.5) * pixel
    X, Y = np.meshgrid(xc, yc, indexing="ij")
    best = np.full((nx, ny), np.inf)
    owner = np.full((nx, ny), -1)
    default = cp.keys.get("gdfe:hinge_width", hinge_width)
    hinges = []
    unassigned = int((cp.assignment == "U").sum())
    if unassigned:
        log.warning("%s: %d unassigned (U) edges are left flat", cp.name, unassigned)
    joined = crease_faces(cp)
    for e in cp.creases:
        if not math.isnan(cp.width[e]):
            w, src = float(cp.width[e]), "edges_gdfe:width"
        elif not math.isnan(cp.fold_angle[e]):
            w, src = float(abs(cp.fold_angle[e]) * h / (1.0 - R)), "edges_foldAngle (Eq. 2)"
        elif default is not None:
            w, src = float(default), "gdfe:hinge_width" if "gdfe:hinge_width" in cp.keys else "hinge_width"
        else:
            raise GdfeError(f"{cp.name}: edges_vertices[{e}] ({cp.assignment[e]}): no hinge width: give "
                            "edges_gdfe:width, edges_foldAngle, gdfe:hinge_width or the hinge width")
        a, b = V[cp.edges[e, 0]], V[cp.edges[e, 1]]
        d = b - a
        L = float(np.hypot(*d))
        t = ((X - a[0]) * d[0] + (Y - a[1]) * d[1]) / L ** 2
        dist = np.abs((X - a[0]) * d[1] - (Y - a[1]) * d[0]) / L
        inside = (t >= 0) & (t <= 1) & (dist <= w / 2) & film
        take = inside & (dist < best)
        best[take] = dist[take]
        owner[take] = e
        adjacent = joined[int(e)]
        hinges.append({"edge": int(e), "assignment": str(cp.assignment[e]), "coated": cp.coated[e],
                       "width_mm": w, "width_from": src, "length_mm": L, "faces": adjacent,
                       "angle_rad": (1.0 if cp.coated[e] == "bottom" else -1.0) * (1.0 - R) * w / h})
    top = film.copy()
    bottom = film.copy()
    for rec in hinges:
        mine = owner == rec["edge"]
        rec["pixels"] = int(mine.sum())
        if rec["pixels"] == 0:
            raise GdfeError(f"{cp.name}: edges_vertices[{rec['edge']}]: a hinge {rec['width_mm']:g} mm wide covers "
                            f"no pixel at {pixel:g} mm; widen it or print finer")
        (top if rec["coated"] == "bottom" else bottom)[mine] = False  # the free face of the hinge
    faces = {}
    for k, P in enumerate(polys if cp.faces else []):
        faces[k] = fill_polygons([P], (ny, nx)).T & (owner < 0) & film
    return FoldMasks(top=top, bottom=bottom, film=film, pixel=pixel, origin=lo.copy(), hinges=hinges, owner=owner,
                     faces=faces)
