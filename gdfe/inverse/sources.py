"""The files a 1-D design starts from: couples (TOML), and sketches (CSV of points, or an SVG stroke).

**Couples** (``.toml``)::

    name = "hook"               # optional (default: the file's stem)
    heading = 1.5707963         # tangent direction at the start [rad] (default 0)
    start = [0.0, 0.0]          # first point [mm] (default the origin)
    couples = [[6.0, 0.0], [9.42477796, 3.0]]   # (L [mm], r [mm]); r = 0 straight, r > 0 anticlockwise
    turns = [0.0, 0.0]          # optional sharp turns before each couple [rad]

    [film]                      # optional: h, d or R, K (as in a design file)
    [print]                     # optional: pixel, w_min, width [mm]

**Sketches** (``.csv``): one point per line, ``x, y`` in mm (commas, semicolons or blanks
between them); a first line that is not numeric is a header; ``#`` starts a comment.
An ``.svg`` sketch is one stroke (:func:`gdfe.fabrication.svg_polyline`).

Errors name the file and the line (CSV, TOML syntax) or the key and entry (TOML content).
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_file, check_keys, read_text

__all__ = ["CouplesFile", "read_couples_toml", "read_sketch_csv", "read_sketch", "FILM_KEYS", "PRINT_KEYS"]

#: Keys of the optional tables of a couples file.
FILM_KEYS = ("h", "d", "R", "K")
PRINT_KEYS = ("pixel", "w_min", "width")


@dataclasses.dataclass
class CouplesFile:
    """A couples file: its target, and the film and print settings it gives (possibly none).

    Attributes
    ----------
    target : gdfe.inverse.TargetCurve
    film : dict
        Entries of ``[film]`` (``h``, ``d``, ``R``, ``K``).
    print : dict
        Entries of ``[print]`` (``pixel``, ``w_min``, ``width``).
    """

    target: object
    film: dict
    print: dict


def _table(doc, key, known, name):
    t = doc.get(key, {})
    if not isinstance(t, dict):
        raise GdfeError(f"{name}: {key}: expected a table [{key}], got {type(t).__name__}")
    check_keys(f"{name}: [{key}]", t, known)
    for k, v in t.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise GdfeError(f"{name}: [{key}] {k}: expected a number, got {v!r}")
    return {k: float(v) for k, v in t.items()}


def read_couples_toml(path):
    """Read a couples file (module docstring).

    Returns
    -------
    CouplesFile
    """
    from gdfe.fabrication._film import load_toml
    from gdfe.inverse.pipeline import target_from_couples

    path = check_file("couples", path, suffixes=(".toml",), what="couples file")
    name = path.name
    doc = load_toml(path)
    check_keys(name, doc, ("name", "heading", "start", "couples", "turns", "film", "print"))
    if "couples" not in doc:
        raise GdfeError(f"{name}: missing 'couples' (a list of [L, r] pairs in mm)")
    couples = doc["couples"]
    if not isinstance(couples, list):
        raise GdfeError(f"{name}: couples: expected a list of [L, r] pairs, got {type(couples).__name__}")
    for i, c in enumerate(couples):
        if (not isinstance(c, list) or len(c) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in c)):
            raise GdfeError(f"{name}: couples[{i}]: expected an [L, r] pair of numbers (mm), got {c!r}")
    film = _table(doc, "film", FILM_KEYS, name)
    prn = _table(doc, "print", PRINT_KEYS, name)
    try:
        target = target_from_couples(couples, heading=doc.get("heading", 0.0), start=doc.get("start", (0.0, 0.0)),
                                     turns=doc.get("turns"), name=str(doc.get("name", path.stem)))
    except GdfeError as exc:
        raise type(exc)(f"{name}: {exc}") from None
    return CouplesFile(target=target, film=film, print=prn)


_SPLIT = re.compile(r"[,;\s]+")


def read_sketch_csv(path):
    """Read a sketch's points from a CSV file (module docstring).

    Returns
    -------
    (n, 2) float array [mm]
    """
    path = check_file("sketch", path, suffixes=(".csv", ".txt"), what="sketch CSV")
    text = read_text(path, "sketch CSV")
    first = _first_content_line(text)
    rows = []
    for k, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = [p for p in _SPLIT.split(line) if p]
        try:
            xy = [float(p) for p in parts]
        except ValueError:
            if not rows and k == first:
                continue  # a header
            raise GdfeError(f"{path.name} line {k}: expected two numbers x, y [mm], got {raw.strip()!r}") from None
        if len(xy) != 2 or not np.all(np.isfinite(xy)):
            raise GdfeError(f"{path.name} line {k}: expected two finite numbers x, y [mm], got {raw.strip()!r}")
        rows.append(xy)
    if len(rows) < 3:
        raise GdfeError(f"{path.name}: expected a sketch of at least 3 points, got {len(rows)}")
    return np.array(rows)


def _first_content_line(text):
    for k, raw in enumerate(text.splitlines(), start=1):
        if raw.split("#", 1)[0].strip():
            return k
    return 0


def read_sketch(path, element_id=None, spacing=0.2):
    """A sketch's points [mm] from a ``.csv`` file or one stroke of an ``.svg`` drawing."""
    from gdfe.fabrication.svg import svg_polyline

    path = Path(path)
    if path.suffix.lower() == ".svg":
        return svg_polyline(path, element_id=element_id, spacing=spacing)
    return read_sketch_csv(path)
