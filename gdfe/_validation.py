"""The input checks of the whole project: one toolkit, one message style, one exception.

Every check names the argument (or file, key, column) and says what it expected and what
came, as ``"NAME: expected ..., got ..."``, and raises :class:`GdfeError` (a
``ValueError``), or one of its subclasses that are also a ``TypeError`` (a value of the
wrong kind) or a ``FileNotFoundError`` (a missing file). The command line turns a
:class:`GdfeError` into one line and a non-zero exit status; any other exception is a bug
and keeps its traceback.

Modelled on PyVista's ``core/_validation`` (``validate_array(x, must_have_shape=...,
must_be_finite=True, name=...)``).
"""

from __future__ import annotations

import math
import numbers
from pathlib import Path

import numpy as np

__all__ = [
    "GdfeError", "GdfeTypeError", "GdfeFileNotFoundError",
    "check_number", "check_positive", "check_ratio", "check_poisson", "check_int", "check_bool", "check_choice",
    "check_array", "check_file", "check_instance", "check_keys", "check_length", "read_text", "describe",
    "LENGTH_RANGE", "degenerate_tests", "check_surface_mesh",
]

#: Lengths a design may have [mm]: a film between a nanometre and a kilometre. Outside this
#: range the solver's sums of squared lengths (mm^5 energies) lose their digits or overflow.
LENGTH_RANGE = (1e-6, 1e6)


class GdfeError(ValueError):
    """An error in what the user gave: a value, a file, a key or a column."""


class GdfeTypeError(GdfeError, TypeError):
    """A user error where a value is of the wrong kind (a string for a number, ...)."""


class GdfeFileNotFoundError(GdfeError, FileNotFoundError):
    """A user error naming a file that is not there."""


def describe(value) -> str:
    """A short text of ``value`` for a message: numbers with ``%g``, others by ``repr``."""
    if isinstance(value, (bool, np.bool_)) or value is None or isinstance(value, (str, bytes)):
        return repr(value)
    if isinstance(value, numbers.Real):
        return f"{float(value):g}"
    if isinstance(value, np.ndarray):
        if value.ndim == 0:
            return describe(value.item())
        return f"an array of shape {value.shape}"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _float_array(name, value, kind="a number"):
    """``value`` as a float array; strings, booleans and None are not numbers."""
    if value is None or isinstance(value, (str, bytes, bool, np.bool_)):
        raise GdfeTypeError(f"{name}: expected {kind}, got {describe(value)}")
    try:
        arr = np.asarray(value)
    except ValueError:  # a ragged nesting of sequences
        raise GdfeTypeError(f"{name}: expected {kind}, got a ragged sequence {describe(value)}") from None
    if arr.dtype == bool or arr.dtype.kind in "OUSV":
        if arr.dtype.kind == "O":
            try:
                return np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                pass
        raise GdfeTypeError(f"{name}: expected {kind}, got {describe(value)}")
    try:
        return np.asarray(arr, dtype=float)
    except (TypeError, ValueError):
        raise GdfeTypeError(f"{name}: expected {kind}, got {describe(value)}") from None


def _first_bad(arr, bad):
    """The message's ``got`` part for the entries of ``arr`` flagged in ``bad``."""
    if arr.ndim == 0:
        return f"{float(arr):g}"
    values = arr[bad]
    return f"an array containing {values.flat[0]:g}" if values.size else "an array"


def check_number(name, value, *, minimum=None, maximum=None, include_minimum=True, include_maximum=True,
                 what=None, allow_array=False):
    """A finite real number (or array of them, with ``allow_array``) within optional bounds.

    Parameters
    ----------
    name : str
        The argument's name, first word of the message.
    value : float or array
    minimum, maximum : float, optional
        Bounds; ``include_*`` says whether the bound itself is allowed.
    what : str, optional
        Words for what is expected (default: built from the bounds).
    allow_array : bool
        Accept arrays (every entry is checked); else only a scalar.

    Returns
    -------
    float, or float array when ``allow_array`` and ``value`` is an array.
    """
    if what is None:
        what = "a finite number"
        parts = []
        if minimum is not None:
            parts.append(f"{'>=' if include_minimum else '>'} {minimum:g}")
        if maximum is not None:
            parts.append(f"{'<=' if include_maximum else '<'} {maximum:g}")
        if parts:
            what += " " + " and ".join(parts)
    arr = _float_array(name, value, what)
    if arr.ndim and not allow_array:
        raise GdfeTypeError(f"{name}: expected {what}, got {describe(value)}")
    bad = ~np.isfinite(arr)
    with np.errstate(invalid="ignore"):
        if minimum is not None:
            bad |= (arr < minimum) if include_minimum else (arr <= minimum)
        if maximum is not None:
            bad |= (arr > maximum) if include_maximum else (arr >= maximum)
    if np.any(bad):
        raise GdfeError(f"{name}: expected {what}, got {_first_bad(arr, bad)}")
    return arr if arr.ndim else float(arr)


def check_positive(name, value):
    """A positive finite number, or an array of them; returned as float (array)."""
    return check_number(name, value, minimum=0.0, include_minimum=False,
                        what="a positive finite number", allow_array=True)


def check_length(name, value, allow_array=True):
    """A length of a design [mm]: positive, finite and within :data:`LENGTH_RANGE` (arrays too,
    unless ``allow_array`` is False)."""
    if not allow_array:
        arr = check_number(name, value, minimum=0.0, include_minimum=False, what="a positive finite number")
    else:
        arr = check_positive(name, value)
    lo, hi = LENGTH_RANGE
    bad = (np.asarray(arr) < lo) | (np.asarray(arr) > hi)
    if np.any(bad):
        raise GdfeError(f"{name}: expected a length between {lo:g} and {hi:g} mm, got {_first_bad(np.asarray(arr), bad)}")
    return arr


#: The smallest contraction ratio a design may have: a film shrunk to 1 % of its length is far
#: beyond any shrink film, and much below it the folded part's geometry degenerates (at
#: R = 1e-9 its cells are 1e-10 mm across and the contact solve's collision detection does
#: not return).
R_MIN = 0.01
RATIO_WHAT = f"a contraction ratio in [{R_MIN:g}, 1]"


def check_ratio(name, value):
    """A contraction ratio (or array of them): finite and in [:data:`R_MIN`, 1]."""
    return check_number(name, value, minimum=R_MIN, maximum=1.0, what=RATIO_WHAT, allow_array=True)


def check_poisson(name, value):
    """A Poisson's ratio: -1 < value < 0.5."""
    return check_number(name, value, minimum=-1.0, maximum=0.5, include_minimum=False, include_maximum=False,
                        what="a Poisson's ratio in (-1, 0.5)")


def data_float(text):
    """The number a data file's cell ``text`` writes, by :class:`float`; :class:`ValueError` where only Python
    reads it as one: with a digit separator (``1_50`` is 150 to Python, a typo or a pasted thousands
    separator to a spreadsheet) or with digits of other scripts."""
    t = str(text).strip()
    if "_" in t or not t.isascii():
        raise ValueError(f"not a plain decimal number: {text!r}")
    return float(t)


def check_int(name, value, minimum=1, maximum=None):
    """An integer (not a boolean, not a float) ``>= minimum`` (and ``<= maximum``)."""
    what = f"an integer >= {minimum}" + (f" and <= {maximum}" if maximum is not None else "")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise GdfeTypeError(f"{name}: expected {what}, got {describe(value)}")
    if value < minimum or (maximum is not None and value > maximum):
        raise GdfeError(f"{name}: expected {what}, got {int(value)}")
    return int(value)


def check_bool(name, value):
    """A boolean (``True``/``False``; numbers and strings are not booleans)."""
    if not isinstance(value, (bool, np.bool_)):
        raise GdfeTypeError(f"{name}: expected true or false, got {describe(value)}")
    return bool(value)


def check_choice(name, value, options):
    """``value`` if it is one of ``options`` (listed in the message otherwise)."""
    options = tuple(sorted(options)) if isinstance(options, (set, frozenset)) else tuple(options)
    try:
        ok = value in options
    except TypeError:  # unhashable value against a set-like
        ok = False
    if not ok:
        listed = ", ".join(repr(o) for o in options)
        raise GdfeError(f"{name}: expected one of {listed}, got {describe(value)}")
    return value


def check_keys(where, mapping, known, what="key"):
    """Every key of ``mapping`` is one of ``known``; else a :class:`GdfeError` with a "did you mean".

    ``where`` starts the message (a file and table, e.g. ``"d.toml: [hinge]"``); ``what``
    names the kind of key (``"key"``, ``"section"``); sections are shown in brackets.
    """
    import difflib

    known = tuple(known)
    show = (lambda k: f"[{k}]") if what == "section" else repr
    for key in mapping:
        if key not in known:
            near = difflib.get_close_matches(str(key), [str(k) for k in known], n=1, cutoff=0.6)
            hint = f" (did you mean {show(near[0])}?)" if near else ""
            listed = ", ".join(show(k) for k in known) if what == "section" else ", ".join(known)
            raise GdfeError(f"{where}: unknown {what} {show(key)}{hint}; expected some of {listed}")
    return mapping


def read_text(path, what="text file"):
    """The text of a UTF-8 file (a byte-order mark dropped); binary or other encodings refused.

    Raises
    ------
    GdfeError
        Naming the file: a binary file (NUL bytes), bytes that are not UTF-8 (with the line),
        or a file that cannot be read.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise GdfeError(f"{path.name}: cannot read the {what}: {exc.strerror or exc}") from None
    if b"\x00" in data:
        raise GdfeError(f"{path.name}: not a text file: expected a {what}, got binary data (NUL bytes)")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise GdfeError(f"{path.name}: not a UTF-8 text file: expected a {what}, got byte 0x{data[exc.start]:02x} "
                        f"at line {line} (save the file as UTF-8)") from None
    if "\ufeff" in text:  # one at the very start is dropped above; one inside is where files were joined
        line = text[:text.index("\ufeff")].count("\n") + 1
        raise GdfeError(f"{path.name}: line {line}: a UTF-8 byte-order mark (BOM, U+FEFF) inside the {what}, where "
                        f"files were joined; expected one only at the very start (remove it, or save the file as "
                        f"UTF-8 without BOM)")
    return text


def check_instance(name, value, cls, what=None):
    """``value`` if it is an instance of ``cls``; else a :class:`GdfeTypeError`."""
    if not isinstance(value, cls):
        if what is None:
            classes = cls if isinstance(cls, tuple) else (cls,)
            what = " or ".join(f"a {c.__module__.split('.')[0]}.{c.__name__}" for c in classes)
        raise GdfeTypeError(f"{name}: expected {what}, got {type(value).__name__}")
    return value


def check_array(name, value, *, shape=None, ndim=None, dtype=float, finite=True, min_size=None):
    """An array of a given shape (``-1`` for any length along an axis), finite by default.

    Parameters
    ----------
    name : str
    value : array-like
    shape : tuple of int, optional
        Expected shape; ``-1`` matches any length.
    ndim : int, optional
        Expected number of dimensions (when ``shape`` is not given).
    dtype : numpy dtype
        The array is returned with this dtype (``float``: strings and booleans refused).
    finite : bool
        Every entry must be finite (float arrays).
    min_size : int, optional
        Fewest entries along the first axis.
    """
    if dtype is float:
        arr = _float_array(name, value, "an array of numbers")
    else:
        try:
            arr = np.asarray(value, dtype=dtype)
        except (TypeError, ValueError):
            raise GdfeTypeError(f"{name}: expected an array of {np.dtype(dtype).name}, "
                                f"got {describe(value)}") from None
    if shape is not None:
        shape = tuple(shape)
        text = "(" + ", ".join("n" if s == -1 else str(s) for s in shape) + (",)" if len(shape) == 1 else ")")
        if arr.ndim != len(shape) or any(s not in (-1, a) for s, a in zip(shape, arr.shape)):
            raise GdfeError(f"{name}: expected an array of shape {text}, got shape {arr.shape}")
    elif ndim is not None and arr.ndim != ndim:
        raise GdfeError(f"{name}: expected a {ndim}-D array, got shape {arr.shape}")
    if min_size is not None and (arr.ndim == 0 or arr.shape[0] < min_size):
        got = arr.shape[0] if arr.ndim else 0
        raise GdfeError(f"{name}: expected at least {min_size} entries, got {got}")
    if finite and arr.dtype.kind == "f" and not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))[0]
        where = ", ".join(map(str, bad))
        raise GdfeError(f"{name}: expected finite numbers, got {arr[tuple(bad)]} at [{where}]")
    return arr


def check_file(name, path, suffixes=None, what="file"):
    """The path of an existing file (with one of ``suffixes``, if given)."""
    if isinstance(path, (bytes, bool)) or not isinstance(path, (str, Path)) or str(path) == "":
        raise GdfeTypeError(f"{name}: expected the path of a {what}, got {describe(path)}")
    path = Path(path)
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise GdfeError(f"{name}: expected a {' or '.join(suffixes)} {what}, got {path.name!r}")
    if not path.is_file():
        state = "a directory" if path.is_dir() else "not found"
        raise GdfeFileNotFoundError(f"{name}: {what} {state}: {path}")
    return path


def is_finite_number(value) -> bool:
    """Whether ``value`` is a real, finite number (not a boolean)."""
    return (isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
            and math.isfinite(float(value)))


def degenerate_tests(name, L, d, h, alpha, single_point_is_error=False, same_angles=True):
    """Folding tests that cannot say what they seem to: an error for what no fit can use, sentences for the rest.

    Parameters
    ----------
    name : str
        The file (or argument) the tests came from, first word of every message.
    L, d, h, alpha : (n,) float arrays
        Hinge widths, passive and film thicknesses [mm], fold angles [rad].
    single_point_is_error : bool
        Whether tests of one design point (the same L, d, h in every row) are refused (a diagnosis,
        which compares how the angle changes with them) or only named (a fit of K).
    same_angles : bool
        Whether to name every angle being the same (a caller whose result says so itself does not).

    Returns
    -------
    list of str
        Sentences naming what is degenerate but usable (every angle the same, one design point).

    Raises
    ------
    GdfeError
        Every fold angle 0 (nothing folded); every row the same test (copies: no scatter, so an
        interval of zero width and a held-out error of 0); one design point, where asked.
    """
    L, d, h, alpha = (np.asarray(v, float) for v in (L, d, h, alpha))
    n = alpha.size
    if n == 0:
        return []
    if np.all(alpha == 0):
        raise GdfeError(f"{name}: alpha_rad: expected fold angles, got 0 in all {n} rows: nothing folded, so there is "
                        f"no fold for a model to explain (check the alpha_rad column, or the activation)")
    rows = np.column_stack([L, d, h, alpha])
    if n >= 2 and np.all(rows == rows[0]):
        raise GdfeError(f"{name}: expected distinct folding tests, got the same row (L = {L[0]:g}, d = {d[0]:g}, "
                        f"h = {h[0]:g} mm, alpha = {alpha[0]:g} rad) {n} times: copies carry no scatter, so a fit "
                        f"would claim an interval of zero width and a held-out error of 0")
    notes = []
    if n >= 2 and np.all(rows[:, :3] == rows[0, :3]):
        text = (f"{name}: every row is one design point (L = {L[0]:g}, d = {d[0]:g}, h = {h[0]:g} mm): the tests "
                f"say how well it repeats, not how the angle changes with L, d or h")
        if single_point_is_error:
            raise GdfeError(text + "; expected tests that vary them")
        notes.append(text)
    if same_angles and n >= 2 and np.all(alpha == alpha[0]):
        notes.append(f"{name}: every fold angle is the same ({alpha[0]:g} rad in all {n} rows): there is no spread "
                     f"to explain")
    return notes


def check_surface_mesh(name, V, T):
    """A triangle mesh that is one disc-like surface: refuse what a target surface cannot be.

    Checks, in order: one piece; every edge shared by at most two triangles (no fin, an edge-manifold);
    every vertex's triangles one fan (no bow-tie); triangles oriented alike; an open surface (a
    boundary to flatten from: no closed shell); and no two triangles that share no vertex crossing
    each other (self-intersection: an edge of one through the other; coplanar overlaps are not seen).

    Parameters
    ----------
    name : str
        The file, first word of the message.
    V : (n, 3) float array [mm]
    T : (t, 3) int array

    Raises
    ------
    GdfeError
        Naming the first problem found and where (an edge's or a vertex's index, two triangles).
    """
    from scipy import sparse
    from scipy.sparse.csgraph import connected_components

    V = np.asarray(V, float)
    T = np.asarray(T, np.int64)
    t = len(T)
    if t == 0:
        raise GdfeError(f"{name}: expected a surface of triangles, got none")
    E = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    tri = np.tile(np.arange(t), 3)
    key = np.sort(E, axis=1)
    edges, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    if counts.max() > 2:
        k = int(np.argmax(counts))
        raise GdfeError(f"{name}: expected a surface (every edge shared by at most two triangles), got the edge "
                        f"between vertices {edges[k, 0]} and {edges[k, 1]} shared by {counts[k]} triangles: a "
                        f"non-manifold mesh (a fin or a T-junction); repair it (e.g. in MeshLab) first")
    shared = counts[inv] == 2
    pairs = np.zeros((len(edges), 2), np.int64)
    order = np.argsort(inv, kind="stable")
    ordered = inv[order]
    firsts = np.r_[True, ordered[1:] != ordered[:-1]]
    pairs[ordered[firsts], 0] = tri[order[firsts]]
    pairs[ordered[~firsts], 1] = tri[order[~firsts]]
    inner = counts == 2
    adj = sparse.coo_matrix((np.ones(int(inner.sum())), (pairs[inner, 0], pairs[inner, 1])), shape=(t, t))
    n_parts, part = connected_components(adj, directed=False)
    if n_parts > 1:
        sizes = np.bincount(part)
        raise GdfeError(f"{name}: expected one piece of surface, got {n_parts} pieces (of "
                        f"{', '.join(str(s) for s in sorted(sizes, reverse=True)[:4])}{', ...' if n_parts > 4 else ''} "
                        f"triangles) joined by no edge")
    # orientation: an edge shared by two triangles is walked once each way
    same_way = np.zeros(len(edges), int)
    np.add.at(same_way, inv, np.where(E[:, 0] < E[:, 1], 1, -1))
    flipped = inner & (same_way != 0)
    if flipped.any():
        k = int(np.nonzero(flipped)[0][0])
        raise GdfeError(f"{name}: expected triangles oriented alike, got the two triangles {pairs[k, 0]} and "
                        f"{pairs[k, 1]} on either side of the edge {edges[k, 0]}-{edges[k, 1]} facing opposite ways "
                        f"(a flipped triangle, or a one-sided surface)")
    boundary = edges[counts == 1]
    if not len(boundary):
        raise GdfeError(f"{name}: expected an open surface (a disc with one boundary), got a closed one "
                        f"(every edge shared by two triangles): cut it open where the film's outline should be")
    n = len(V)
    at = np.bincount(boundary.ravel(), minlength=n)
    fan = np.bincount(T.ravel(), minlength=n) - np.bincount(edges[inner].ravel(), minlength=n)
    bad = np.nonzero((at > 2) | (fan > 1))[0]
    if bad.size:
        v = int(bad[0])
        raise GdfeError(f"{name}: expected every vertex's triangles to form one fan, got vertex {v} where "
                        f"{max(int(fan[v]), at[v] // 2)} fans meet (a bow-tie: the surface touches itself in a point)")
    used = np.unique(T)
    euler = len(used) - len(edges) + t
    if euler != 1:
        loops = _count_loops(boundary)
        raise GdfeError(f"{name}: expected a disc (one piece with one boundary, no hole or handle), got a surface "
                        f"with {loops} boundary loop{'s' if loops != 1 else ''} and Euler characteristic {euler} "
                        f"(a disc has 1): fill its holes, or cut it into a disc")
    pair = _crossing_triangles(V, T)
    if pair is not None:
        raise GdfeError(f"{name}: expected a surface that does not pass through itself, got triangles {pair[0]} and "
                        f"{pair[1]} crossing each other (a self-intersecting mesh)")


def _count_loops(boundary):
    """The closed loops that the boundary edges ``(b, 2)`` form (their connected pieces)."""
    from scipy import sparse
    from scipy.sparse.csgraph import connected_components

    verts, idx = np.unique(boundary, return_inverse=True)
    idx = idx.reshape(-1, 2)
    g = sparse.coo_matrix((np.ones(len(idx)), (idx[:, 0], idx[:, 1])), shape=(len(verts), len(verts)))
    return int(connected_components(g, directed=False)[0])


def _crossing_triangles(V, T, chunk=200_000):
    """Two triangles that share no vertex and cross (an edge of one through the other), or None.

    The candidates are the pairs whose bounding boxes overlap (a k-d tree of the triangles' centres,
    within the sum of their circumradii' bound); each is tested with the segment-triangle test of
    Moeller and Trumbore on the six edges.
    """
    from scipy.spatial import cKDTree

    P = V[T]  # (t, 3, 3)
    centre = P.mean(axis=1)
    reach = np.linalg.norm(P - centre[:, None], axis=2).max(axis=1)
    tree = cKDTree(centre)
    pairs = tree.query_pairs(2.0 * float(reach.max()), output_type="ndarray")
    if not len(pairs):
        return None
    a, b = pairs[:, 0], pairs[:, 1]
    close = np.linalg.norm(centre[a] - centre[b], axis=1) <= reach[a] + reach[b]
    a, b = a[close], b[close]
    share = (T[a][:, :, None] == T[b][:, None, :]).any(axis=(1, 2))
    a, b = a[~share], b[~share]
    for lo in range(0, len(a), chunk):
        aa, bb = a[lo:lo + chunk], b[lo:lo + chunk]
        hit = _edges_cross(P[aa], P[bb]) | _edges_cross(P[bb], P[aa])
        if hit.any():
            k = int(np.argmax(hit))
            return int(aa[k]), int(bb[k])
    return None


def _edges_cross(A, B):
    """Whether an edge of triangle ``A[k]`` passes through the inside of triangle ``B[k]`` (``(m, 3, 3)`` each)."""
    hit = np.zeros(len(A), bool)
    e1, e2 = B[:, 1] - B[:, 0], B[:, 2] - B[:, 0]
    scale = np.maximum(np.linalg.norm(e1, axis=1), np.linalg.norm(e2, axis=1))
    for i, j in ((0, 1), (1, 2), (2, 0)):
        o, d = A[:, i], A[:, j] - A[:, i]
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-12 * scale ** 2 * np.linalg.norm(d, axis=1)
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o - B[:, 0]
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("ij,ij->i", d, q) * inv
        w = np.einsum("ij,ij->i", e2, q) * inv
        eps = 1e-9
        hit |= ok & (u > eps) & (v > eps) & (u + v < 1 - eps) & (w > eps) & (w < 1 - eps)
    return hit
