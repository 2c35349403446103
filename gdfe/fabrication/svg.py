"""Designs from SVG drawings: filled regions are the passive coating of each face of the film.

**How faces are told apart.** With ``by="layer"`` (the default) every filled shape belongs
to the face named by the nearest enclosing group ``<g>`` whose ``inkscape:label`` (an
Inkscape layer's name) or ``id`` is, in any case, one of

``top``
    passive material printed on the top face (the face seen in the drawing);
``bottom``
    on the bottom face;
``both``
    on both faces (rigid panels);
``film``
    the outline of the film itself (default: the whole page).

A filled shape outside such a group is an error (hide it, ``display:none``, or delete it).
With ``by="colour"`` the fill colour says it instead: :data:`FACE_COLOURS` (red top, blue
bottom, black both, green film), or a mapping given by the caller. Shapes without a fill
(strokes, guides) are left out, with a warning naming those in a face's group (by layer) or
whose stroke has a face's colour (by colour, naming the colour and the face); where all the
film's shapes lack a fill it is an error instead (the film is not the whole page then). Fills
use the shape's ``fill-rule`` (``nonzero`` or ``evenodd``); transforms, ``<use>`` clones,
groups and units are resolved by svgelements, and so are fills and strokes set by a ``<style>``
sheet: only its rules for ``*``, a type, ``.class``, ``#id`` or ``type.class``, and only from
sheets that come before the shape (as Inkscape and Illustrator write them).

**Clipping and masking** are not applied, so a clip or mask on a face's shape, on a group
holding it or on what it clones with ``<use>`` (by colour: on any shape) is an error: release
the clip or intersect the shapes in the drawing program. They are set by the attributes
``clip-path`` and ``mask``, and by the CSS properties ``clip-path``, ``mask`` and
``mask-image`` (and their ``-webkit-`` forms) in ``style`` or in a ``<style>`` sheet; a value
``none`` sets none. A sheet's rule counts wherever the sheet stands, inside ``@media`` too, and
whatever other rules or ``style`` say (a clip that a more specific rule would release is still
an error), for selectors of type, ``*``, ``.class`` and ``#id``, compounded (``rect.c``) or in
comma-separated lists. A rule that clips or masks with any other selector (combinators,
attribute selectors, pseudo-classes) is not resolved: it is an error, naming the ``<style>``,
by colour and in a drawing with face groups by layer.

**Geometry.** Lengths come out in millimetres from the page size (``width``/``height`` with
units; user units without them are CSS pixels, 96 per inch). The drawing's y axis points
down; the design's points up, so the page's bottom edge is y = 0. Curves are flattened to
chords no longer than a tenth of a pixel, and each region is rasterised at the printer's
pixel: a pixel is coated when its centre is inside (:func:`gdfe.fabrication.raster.fill_polygons`).
The grid is cropped to the film's bounding box.

**Errors.** XML that is not well formed is reported with its line and column; a ``<path>``
whose ``d`` does not parse, text not converted to paths, clipped or masked face shapes, and
shapes outside any face are reported naming the element (tag, id, line); a style sheet's rule
that clips or masks by a selector not resolved names its ``<style>``.

svgelements is imported by the functions that read SVG.
"""

from __future__ import annotations

import dataclasses
import io
import logging
import math
import re
import xml.etree.ElementTree as ET
import xml.parsers.expat

import numpy as np

from gdfe._validation import GdfeError, check_choice, check_file, check_positive

__all__ = ["SvgMasks", "svg_masks", "svg_polyline", "FACES", "FACE_COLOURS", "MM_PER_PX"]

log = logging.getLogger(__name__)

#: The names of the face groups (``id`` or ``inkscape:label``).
FACES = ("top", "bottom", "both", "film")
#: Fill colour of each face with ``by="colour"``.
FACE_COLOURS = {"top": "#ff0000", "bottom": "#0000ff", "both": "#000000", "film": "#00ff00"}
#: Millimetres per CSS pixel (SVG user unit without a page size): 25.4 / 96.
MM_PER_PX = 25.4 / 96.0

_INKSCAPE_LABEL = "{http://www.inkscape.org/namespaces/inkscape}label"
_SHAPES = ("path", "rect", "circle", "ellipse", "line", "polyline", "polygon")
_ARITY = {"m": 2, "l": 2, "t": 2, "h": 1, "v": 1, "c": 6, "s": 4, "q": 4, "a": 7, "z": 0}
_TOKEN = re.compile(r"([MmZzLlHhVvCcSsQqTtAa])|([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)|([\s,]+)")


@dataclasses.dataclass
class SvgMasks:
    """The faces of an SVG drawing on the printer's pixel grid.

    Attributes
    ----------
    top, bottom, film : (nx, ny) bool arrays
        Passive material on each face (``both`` counted on each), and where the film is;
        ``[i, j]``: column i along x, row j along y.
    pixel : float [mm]
    origin : (2,) float array [mm]
        Position of the grid's corner (column 0, row 0) on the page, y up from the page's bottom.
    shapes : dict
        Number of filled shapes read per face.
    """

    top: np.ndarray
    bottom: np.ndarray
    film: np.ndarray
    pixel: float
    origin: np.ndarray
    shapes: dict


def _describe(el, line):
    ident = el.get("id")
    return f"element <{el.tag.rsplit('}', 1)[-1]}{f' id={ident!r}' if ident else ''}> (line {line})"


def _read_tree(path):
    """The SVG's element tree and the line of every element; errors name the line."""
    data = path.read_bytes()
    lines = []
    parser = xml.parsers.expat.ParserCreate()
    parser.StartElementHandler = lambda *_: lines.append(parser.CurrentLineNumber)
    try:
        parser.Parse(data, True)
        root = ET.fromstring(data)
    except (xml.parsers.expat.ExpatError, ET.ParseError) as exc:
        line, col = getattr(exc, "position", (getattr(exc, "lineno", "?"), getattr(exc, "offset", "?")))
        raise GdfeError(f"{path.name}: not well-formed XML at line {line}, column {col}: "
                        f"{xml.parsers.expat.ErrorString(exc.code) if hasattr(exc, 'code') else exc}") from None
    elements = list(root.iter())
    if root.tag.rsplit("}", 1)[-1] != "svg":
        raise GdfeError(f"{path.name}: expected an <svg> document, got <{root.tag.rsplit('}', 1)[-1]}> at line 1")
    return root, dict(zip(map(id, elements), lines))


def _check_path_data(d, where):
    """Raise naming ``where`` if a path's ``d`` is not SVG path data."""
    pos, cmd, count, first = 0, None, 0, True
    d = d.strip()

    def close_command():
        if cmd is None:
            return
        n = _ARITY[cmd.lower()]
        if cmd.lower() == "a":  # arc flags may be written without separators: only ask for some numbers
            ok = count > 0
        else:
            ok = count == 0 if n == 0 else (count > 0 and count % n == 0)
        if not ok:
            raise GdfeError(f"{where}: path data: command {cmd!r} takes "
                            f"{'no numbers' if n == 0 else f'numbers in groups of {n}'}, got {count}")

    while pos < len(d):
        m = _TOKEN.match(d, pos)
        if not m:
            raise GdfeError(f"{where}: path data: unexpected {d[pos:pos + 10]!r} at character {pos + 1}")
        if m.group(1):
            close_command()
            cmd, count = m.group(1), 0
            if first and cmd not in "Mm":
                raise GdfeError(f"{where}: path data: expected it to start with M or m, got {cmd!r}")
            first = False
        elif m.group(2):
            if cmd is None:
                raise GdfeError(f"{where}: path data: expected it to start with M or m, got a number")
            count += 1
        pos = m.end()
    close_command()


#: The attributes that place a shape: a NaN or infinite value in one is an error (svgelements reads it as 0).
_GEOMETRY = ("x", "y", "width", "height", "cx", "cy", "r", "rx", "ry", "x1", "y1", "x2", "y2", "points", "d",
             "transform", "viewBox")
_NOT_FINITE = re.compile(r"(?i)(?<![a-z])(nan|inf(inity)?)(?![a-z])")


#: Presentation attributes that clip or mask what an element draws: svgelements does not apply them.
_CLIPPING = ("clip-path", "mask")
#: CSS properties (in ``style`` or a style sheet) that clip or mask what an element draws.
_CLIPPING_CSS = (*_CLIPPING, "mask-image", "-webkit-clip-path", "-webkit-mask", "-webkit-mask-image")
#: Elements whose content is not drawn where it stands (only where referenced, e.g. by ``<use>``).
_UNDRAWN = ("defs", "clipPath", "mask", "symbol", "pattern", "marker")
_XLINK_HREF = "{http://www.w3.org/1999/xlink}href"
_CSS_COMMENT = re.compile(r"/\*.*?\*/", re.S)
#: A rule without nested blocks (the inner rules of ``@media`` and the like are read as if unconditional).
_CSS_RULE = re.compile(r"([^{}]*)\{([^{}]*)\}")
#: A compound selector this module resolves: a type or ``*``, then any ``.class`` and ``#id``.
_CSS_COMPOUND = re.compile(r"(\*|[A-Za-z_][\w-]*)?((?:[.#][\w-]+)*)")


def _clip_value(key, value):
    """``'key=value'`` when ``value`` clips or masks; None when it is empty or ``none``."""
    value = (value or "").replace("!important", "").strip()
    return f"{key}={value!r}" if value and value.lower() != "none" else None


def _css_clip(declarations):
    """The first clip or mask among CSS declarations (``'name: value; ...'``) as ``'name=value'``, or None."""
    for decl in declarations.split(";"):
        key, sep, value = decl.partition(":")
        key = key.strip().lower()
        ref = _clip_value(key, value) if sep and key in _CLIPPING_CSS else None
        if ref:
            return ref
    return None


def _compound(selector):
    """``(type or None, classes, ids)`` of a compound selector this module resolves, or None."""
    m = _CSS_COMPOUND.fullmatch(selector)
    if not m or not selector:
        return None
    parts = re.findall(r"([.#])([\w-]+)", m.group(2))
    tag = None if m.group(1) in (None, "*") else m.group(1)
    return tag, {v for k, v in parts if k == "."}, {v for k, v in parts if k == "#"}


def _selects(compound, el):
    """Whether a compound selector (:func:`_compound`) selects the element."""
    tag, classes, ids = compound
    return ((tag is None or el.tag.rsplit("}", 1)[-1] == tag) and classes <= set((el.get("class") or "").split())
            and ids <= {el.get("id")})


def _sheet_clips(root):
    """The style sheets' rules that clip or mask: ``[(selector, compound or None, 'name=value', <style>), ...]``,
    one per selector of a comma-separated list; compound None where the selector is not resolved (combinators,
    attribute selectors, pseudo-classes, namespaces)."""
    rules = []
    for style in root.iter():
        if style.tag.rsplit("}", 1)[-1] != "style":
            continue
        for selectors, declarations in _CSS_RULE.findall(_CSS_COMMENT.sub("", "".join(style.itertext()))):
            ref = _css_clip(declarations)
            for selector in (selectors.split(",") if ref else ()):
                rules.append((selector.strip(), _compound(selector.strip()), ref, style))
    return rules


def _clip_of(el, sheet=()):
    """The element's first clip-path or mask reference (attribute, ``style``, or a rule of the style sheet
    ``sheet`` (:func:`_sheet_clips`) that selects it) as ``'name=value'``, or None; ``none`` is no reference."""
    for key in _CLIPPING:
        ref = _clip_value(key, el.get(key))
        if ref:
            return ref
    ref = _css_clip(el.get("style") or "")
    if ref:
        return ref
    for selector, compound, ref, _ in sheet:
        if compound is not None and _selects(compound, el):
            return f"{ref} set by the style sheet's rule {selector!r}"
    return None


def _use_target(el, ids):
    """The element a ``<use>`` clones (``href`` or ``xlink:href`` = ``#id``), or None."""
    ref = (el.get("href") or el.get(_XLINK_HREF) or "").strip()
    return ids.get(ref[1:]) if ref.startswith("#") else None


def _clip_in(el, ids, seen, sheet):
    """``(element, reference)`` of the first clip-path or mask on ``el`` (by ``sheet`` too, :func:`_clip_of`), its
    content or what its ``<use>`` elements clone, or None."""
    if id(el) in seen:
        return None
    seen.add(id(el))
    ref = _clip_of(el, sheet)
    if ref:
        return el, ref
    if el.tag.rsplit("}", 1)[-1] in ("clipPath", "mask"):
        return None
    target = _use_target(el, ids) if el.tag.rsplit("}", 1)[-1] == "use" else None
    for child in [*el, *([target] if target is not None else [])]:
        found = _clip_in(child, ids, seen, sheet)
        if found:
            return found
    return None


def _face_of(el):
    for key in (_INKSCAPE_LABEL, "id"):
        v = (el.get(key) or "").strip().lower()
        if v in FACES:
            return v
    return None


def _refuse_unresolved(sheet, by, root, lines, name):
    """Raise naming the ``<style>`` if a rule of the style sheet whose selector is not resolved clips or masks, and
    the drawing has shapes that may not be clipped (any by colour; those in face groups by layer)."""
    unresolved = [rule for rule in sheet if rule[1] is None]
    if not unresolved or not (by == "colour" or any(e.tag.rsplit("}", 1)[-1] == "g" and _face_of(e)
                                                     for e in root.iter())):
        return
    selector, _, ref, style = unresolved[0]
    raise GdfeError(f"{name}: {_describe(style, lines.get(id(style), '?'))}: the style sheet clips or masks "
                    f"({ref} for {selector!r}) with a selector that is not resolved (only type, *, .class and #id "
                    "selectors, compounded or in comma-separated lists, are): clipping and masking are not applied; "
                    "release the clip or mask in the drawing program, or delete the rule")


def _prepare(path, by):
    """Parse, check and mark the drawing; returns svgelements' parsed document and the element lines."""
    import svgelements as se

    root, lines = _read_tree(path)
    _complete_page(root)
    ids = {el.get("id"): el for el in root.iter() if el.get("id")}
    unclipped = ("clipping and masking are not applied (the shape would be read whole); release the clip or "
                 "mask, or intersect the shapes, in the drawing program")
    sheet = _sheet_clips(root)
    _refuse_unresolved(sheet, by, root, lines, path.name)

    def walk(el, face, drawn=True):
        tag = el.tag.rsplit("}", 1)[-1]
        where = _describe(el, lines.get(id(el), "?"))
        if tag == "g" and by == "layer":
            face = _face_of(el) or face
        drawn = drawn and tag not in _UNDRAWN
        ref = _clip_of(el, sheet) if drawn else None
        if ref and (by == "colour" or face is not None):  # a face's shape, or any shape by colour
            raise GdfeError(f"{path.name}: {where}: {ref}: {unclipped}")
        if ref and any(e.tag.rsplit("}", 1)[-1] == "g" and _face_of(e) for e in el.iter()):
            raise GdfeError(f"{path.name}: {where}: {ref} on a group holding face groups: {unclipped}")
        if drawn and (by == "colour" or face is not None):
            target = _use_target(el, ids) if tag == "use" else None
            found = _clip_in(target, ids, {id(el)}, sheet) if target is not None else None
            if found:
                raise GdfeError(f"{path.name}: {where}: clones {_describe(found[0], lines.get(id(found[0]), '?'))}"
                                f" with {found[1]}: {unclipped}")
        for key in _GEOMETRY:
            value = el.get(key)
            if value is not None and _NOT_FINITE.search(value):
                raise GdfeError(f"{path.name}: {where}: {key}={value!r}: expected finite numbers, got a value that "
                                f"is not a number (NaN or infinite)")
        if tag == "path":
            _check_path_data(el.get("d", ""), f"{path.name}: {where}")
        if tag in ("text", "tspan", "flowRoot") and (el.text or "").strip():
            raise GdfeError(f"{path.name}: {where}: text is not read; convert it to paths first")
        el.set("gdfe-where", where)
        if face is not None:
            el.set("gdfe-face", face)
        for child in el:
            walk(child, face, drawn)

    walk(root, None)
    text = ET.tostring(root, encoding="unicode")
    try:
        svg = se.SVG.parse(io.StringIO(text), ppi=96.0)
    except Exception as exc:  # svgelements reports malformed attribute values with its own exceptions
        raise GdfeError(f"{path.name}: not a readable SVG drawing ({type(exc).__name__}: {exc})") from None
    return svg, root


def _subpaths(shape, step_px):
    """The closed polygons [px, y down] of a shape's subpaths, curves cut into chords <= step_px."""
    import svgelements as se

    out = []
    for sub in se.Path(shape).as_subpaths():
        pts = []
        for seg in sub:
            if isinstance(seg, se.Move):
                pts.append((seg.end.x, seg.end.y))
            elif isinstance(seg, (se.Line, se.Close)):
                if seg.end is not None:
                    pts.append((seg.end.x, seg.end.y))
            else:
                n = max(2, int(math.ceil(seg.length(error=1e-4) / step_px)) + 1)
                pts.extend(map(tuple, seg.npoint(np.linspace(0.0, 1.0, n))[1:]))
        if len(pts) >= 3:
            out.append(np.array(pts, float))
    return out


_LENGTH = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(mm|cm|in|px|pt|pc|q)?\s*$", re.I)
_UNIT_MM = {"mm": 1.0, "cm": 10.0, "in": 25.4, "px": 25.4 / 96.0, "pt": 25.4 / 72.0, "pc": 25.4 / 6.0,
            "q": 0.25, None: 25.4 / 96.0}


def _complete_page(root):
    """The root's missing ``width`` or ``height`` from the other and the ``viewBox``'s aspect ratio, in the
    other's unit, as SVG renderers size such a page; set on ``root`` so that svgelements reads the same page."""
    box = (root.get("viewBox") or "").replace(",", " ").split()
    try:
        bw, bh = (float(box[2]), float(box[3])) if len(box) == 4 else (0.0, 0.0)
    except ValueError:
        return  # svgelements and _page report a malformed viewBox
    given = {key: _LENGTH.match(root.get(key) or "") for key in ("width", "height")}
    if not (bw > 0 and bh > 0) or sum(root.get(key) is None for key in given) != 1:
        return
    have, missing, ratio = ("width", "height", bh / bw) if root.get("height") is None else ("height", "width", bw / bh)
    m = given[have]
    if m:
        root.set(missing, f"{float(m.group(1)) * ratio!r}{m.group(2) or ''}")


def _page(root, svg, name):
    """Page width and height [mm] from the root's ``width``/``height`` (or ``viewBox``), and the
    millimetres per unit of svgelements' parsed coordinates (which are scaled to the page)."""
    sizes = []
    box = (root.get("viewBox") or "").replace(",", " ").split()
    for k, key in enumerate(("width", "height")):
        text = root.get(key)
        m = _LENGTH.match(text) if text else None
        if m:
            unit = m.group(2).lower() if m.group(2) else None
            sizes.append(float(m.group(1)) * _UNIT_MM[unit])
        elif len(box) == 4:
            sizes.append(float(box[2 + k]) * _UNIT_MM[None])
        else:
            raise GdfeError(f"{name}: expected a page size (width and height, or a viewBox), got "
                            f"{key}={text!r}")
    W, H = sizes
    if not (W > 0 and H > 0 and svg.width and svg.height):
        raise GdfeError(f"{name}: expected a page of positive size, got {W:g} x {H:g} mm")
    return W, H, W / float(svg.width)


#: Bytes per pixel of :func:`svg_masks` besides the design: the page's face masks and one shape's
#: raster at a time (a few boolean and integer arrays of the page's size).
SVG_BYTES_PER_PIXEL = 40


def svg_masks(path, pixel, by="layer", colours=None):
    """Rasterise an SVG drawing into the masks of the two faces and of the film.

    Parameters
    ----------
    path : str or Path
        The ``.svg`` file.
    pixel : float [mm]
        Printer pixel size.
    by : {"layer", "colour"}
        How faces are told apart (module docstring).
    colours : dict of str -> str, optional
        Face -> fill colour (``#rrggbb``) for ``by="colour"`` (default :data:`FACE_COLOURS`).

    Returns
    -------
    SvgMasks
    """
    path = check_file("svg", path, suffixes=(".svg",), what="SVG drawing")
    pixel = check_positive("pixel", pixel)
    check_choice("by", by, ("layer", "colour"))
    colour_face = _colour_faces(colours) if by == "colour" else None
    svg, root = _prepare(path, by)
    W, H, mm = _page(root, svg, path.name)
    polys, counts, unfilled = _face_shapes(svg, path.name, by, colour_face, pixel / mm / 10.0, mm)
    _check_unfilled(polys, unfilled, by, path.name)
    from gdfe.resources import check_grid

    # before any grid is made: the page's size on the printer's grid
    check_grid(f"{path.name}: pixel", (H / pixel) * (W / pixel), (W, H), pixel, SVG_BYTES_PER_PIXEL)
    film, top, bottom = _face_masks(polys, (W, H), pixel, path.name)
    ii, jj = np.nonzero(film)
    sl = (slice(ii.min(), ii.max() + 1), slice(jj.min(), jj.max() + 1))
    outside = (top | bottom) & ~film
    if outside.any():
        log.info("%s: %d coated pixels lie outside the film and are left out", path.name, int(outside.sum()))
    return SvgMasks(top=(top & film)[sl], bottom=(bottom & film)[sl], film=film[sl], pixel=pixel,
                    origin=np.array([ii.min() * pixel, jj.min() * pixel]), shapes=counts)


def _check_unfilled(polys, unfilled, by, name):
    """An error if the film's shapes all lack a fill (else the whole page would silently be the film), and a
    warning naming the faces' shapes without a fill (:func:`_face_shapes`)."""
    if not polys["film"] and unfilled["film"]:
        n = len(unfilled["film"])
        whose = f"the film group's {n} shape(s)" if by == "layer" else f"{n} shape(s) in the film's colour"
        raise GdfeError(f"{name}: {whose} have no fill ({', '.join(unfilled['film'][:3])}{', ...' if n > 3 else ''}): "
                        "an outline drawn as a stroke is not read; fill the film's shape")
    left = [where for face in FACES for where in unfilled[face]]
    if left:
        log.warning("%s: %d shape(s) %s have no fill and are left out (an outline drawn as a stroke is not read; "
                    "fill it to coat it): %s%s", name, len(left),
                    "in face groups" if by == "layer" else "stroked in a face's colour", ", ".join(left[:3]),
                    ", ..." if len(left) > 3 else "")


def _colour_faces(colours):
    """Fill colour (``#rrggbb``, lower case) -> face, from ``colours`` (face -> colour; default
    :data:`FACE_COLOURS`)."""
    import svgelements as se

    table = dict(FACE_COLOURS if colours is None else colours)
    for face in table:
        check_choice("colours", face, FACES)
    return {str(se.Color(v).hex)[:7].lower(): f for f, v in table.items()}


def _face_shapes(svg, name, by, colour_face, step, mm):
    """The drawing's filled shapes by face: face -> ``[(polygons [mm, y down], fill rule, where), ...]``,
    how many shapes each face has, and face -> the ``where`` of each shape without a fill in that face's
    group (by layer) or whose stroke has that face's colour (by colour, then with the colour). A filled shape
    of no face is an error naming it."""
    import svgelements as se

    polys = {f: [] for f in FACES}
    counts = dict.fromkeys(FACES, 0)
    unfilled = {f: [] for f in FACES}
    for el in svg.elements():
        if isinstance(el, se.Text):
            continue  # non-empty text was refused in _prepare
        if not isinstance(el, se.Shape):
            continue
        fill = el.fill
        where = el.values.get("gdfe-where", type(el).__name__)
        # a <line> encloses no area: its fill (black by default) paints nothing
        if fill is None or fill.value is None or fill.alpha == 0 or isinstance(el, se.SimpleLine):
            face, where = _unfilled_face(el, where, by, colour_face)
            if face is not None:
                unfilled[face].append(where)
            continue
        if by == "layer":
            face = el.values.get("gdfe-face")
            if face is None:
                raise GdfeError(f"{name}: {where}: a filled shape outside any group named "
                                f"{', '.join(FACES)} (by id or Inkscape layer name); hide or delete it, "
                                "or tell faces apart by colour")
        else:
            key = str(fill.hex)[:7].lower()
            face = colour_face.get(key)
            if face is None:
                raise GdfeError(f"{name}: {where}: fill colour {key} is none of the face colours "
                                + ", ".join(f"{f} {c}" for c, f in colour_face.items()))
        rule = str(el.values.get("fill-rule", "nonzero")).strip().lower()
        rule = rule if rule in ("nonzero", "evenodd") else "nonzero"
        sub = [P * mm for P in _subpaths(el, step)]
        if any(not np.isfinite(P).all() for P in sub):
            raise GdfeError(f"{name}: {where}: expected finite coordinates, got a shape whose points are not "
                            f"numbers (NaN or infinite: check its x, y, width, height, points, d or transform)")
        if sub:
            polys[face].append((sub, rule, where))
            counts[face] += 1
    return polys, counts, unfilled


def _unfilled_face(el, where, by, colour_face):
    """The face of a shape without a fill (its group's by layer, its stroke colour's by colour; None if none)
    and its ``where``, which by colour names the stroke's colour and face."""
    if by == "layer":
        return el.values.get("gdfe-face"), where
    stroke = el.stroke
    if stroke is None or stroke.value is None or stroke.alpha == 0:
        return None, where
    key = str(stroke.hex)[:7].lower()
    face = colour_face.get(key)
    return face, f"{where}: stroke {key}, the {face} face's colour"


def _face_masks(polys, page, pixel, name):
    """The film's and the faces' masks on the page's grid of ``pixel`` (``both`` coats top and bottom),
    in the grid's order (j up); an error where the film or the coat covers no pixel, a warning for
    each shape that covers none."""
    from gdfe.fabrication.raster import fill_polygons

    W, H = page
    rows, cols = int(math.ceil(H / pixel - 1e-6)), int(math.ceil(W / pixel - 1e-6))  # page sizes carry round-off
    empty = []

    def raster(face):
        img = np.zeros((rows, cols), bool)
        for sub, rule, where in polys[face]:
            one = fill_polygons([P / pixel for P in sub], (rows, cols), rule)
            if not one.any():
                empty.append(where)
            img |= one
        return img[::-1].T  # image rows run down from the page's top; the grid's j runs up

    film = raster("film") if polys["film"] else np.ones((cols, rows), bool)
    both = raster("both")
    top, bottom = raster("top") | both, raster("bottom") | both
    if not film.any():
        raise GdfeError(f"{name}: the film group covers no pixel at {pixel:g} mm")
    if not (top | bottom).any():
        raise GdfeError(f"{name}: no filled shape in a top, bottom or both group covers a pixel at "
                        f"{pixel:g} mm: nothing is coated")
    if empty:
        log.warning("%s: %d filled shape(s) cover no pixel at %g mm and are left out (%s%s)", name, len(empty),
                    pixel, ", ".join(empty[:3]), ", ..." if len(empty) > 3 else "")
    if not ((top | bottom) & film).any():
        raise GdfeError(f"{name}: no coated pixel lies on the film (the film group covers none of the top, "
                        f"bottom or both shapes at {pixel:g} mm): nothing on the film is coated")
    return film, top, bottom


def svg_polyline(path, element_id=None, spacing=0.2):
    """The vertices [mm, y up] of one stroke of an SVG drawing: a sketch for the 1-D design.

    Parameters
    ----------
    path : str or Path
    element_id : str, optional
        ``id`` of the ``<path>`` (or line, polyline, ...) to read; default the drawing's only one.
    spacing : float [mm]
        Curved segments are sampled at about this spacing; straight ones keep their two
        end points (a polyline's own vertices are the sketch's).

    Returns
    -------
    (n, 2) float array [mm]
    """
    import svgelements as se

    path = check_file("sketch", path, suffixes=(".svg",), what="SVG sketch")
    spacing = check_positive("spacing", spacing)
    svg, root = _prepare(path, "layer")
    mm = _page(root, svg, path.name)[2]
    shapes = [e for e in svg.elements() if isinstance(e, se.Shape) and len(se.Path(e)) > 0]
    if element_id is not None:
        shapes = [e for e in shapes if e.id == element_id]
        if not shapes:
            raise GdfeError(f"{path.name}: no path with id {element_id!r}")
    if len(shapes) != 1:
        ids = [e.values.get("gdfe-where") for e in shapes]
        raise GdfeError(f"{path.name}: expected one stroke to read (or give its id), got {len(shapes)}: "
                        + "; ".join(map(str, ids)))
    shape = shapes[0]
    where = shape.values.get("gdfe-where")
    subs = list(se.Path(shape).as_subpaths())
    if len(subs) != 1:
        raise GdfeError(f"{path.name}: {where}: expected one stroke, got {len(subs)} subpaths (a strip folds "
                        "into one stroke)")
    pts = []
    step = spacing / mm
    for seg in subs[0]:
        if isinstance(seg, se.Move):
            pts.append((seg.end.x, seg.end.y))
        elif isinstance(seg, (se.Line, se.Close)):
            if seg.end is not None and (seg.end.x, seg.end.y) != pts[-1]:
                pts.append((seg.end.x, seg.end.y))
        else:
            n = max(2, int(math.ceil(seg.length(error=1e-4) / step)) + 1)
            pts.extend(map(tuple, seg.npoint(np.linspace(0.0, 1.0, n))[1:]))
    P = np.array(pts, float) * mm
    if len(P) < 3:
        raise GdfeError(f"{path.name}: {where}: expected a stroke of at least 3 points, got {len(P)}")
    P[:, 1] = -P[:, 1]  # y up
    return P
