"""Property-based tests (Hypothesis): no input is a traceback, an exit-0 absurdity or a hang.

Over design files (TOML of random sections, keys, types and values), masks (arrays of every
dtype and shape, images of every mode and bit depth), folding-test CSVs (random bytes, BOMs,
missing and extra columns, non-numbers, NaN, infinity, huge values), scans (point clouds:
empty, degenerate, NaN; files of random content) and command lines (random argument lists of
the subcommands): through the API every input gives a :class:`gdfe.GdfeError` or a result
that passes sanity checks (finite numbers, a ``converged`` flag that a fresh solve from the
result confirms); through the command line every input gives exit status 0 with a sane
result, or a non-zero status with one line on standard error and no traceback.

The default profile (``tests/conftest.py``) tries 25 examples per property, derandomized; the
test marked slow reruns every property with the "long" profile (400 examples each). Designs are
kept small by their strategies (a few cells to a few hundred) and every command line runs with
:data:`gdfe.resources.LARGE_SECONDS` lowered, so the solver's own estimate refuses any run that
would take more than a few seconds (``--large`` is never drawn); a run past
:data:`HANG_SECONDS` fails the property as a hang (``bad_input_catalogue.Hang``).
"""

from __future__ import annotations

import io
import json
import math
import os
import string
import subprocess
import sys
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np
import pytest
from hypothesis import event, given, note
from hypothesis import strategies as st

import gdfe
from gdfe.cli._main import build_parser
from gdfe.design import DESIGN_KEYS
from bad_input_catalogue import _message_lines, deadline  # a module of tests/, which pytest puts on the path

#: Seconds one example may take before it counts as a hang (far above what the strategies make).
HANG_SECONDS = 60
#: Cells of a design the properties simulate (larger ones are only loaded and checked).
SIMULATE_CELLS = 150


def _api(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, or the :class:`gdfe.GdfeError` it raised (any other exception fails)."""
    with deadline(HANG_SECONDS):
        try:
            return fn(*args, **kwargs)
        except gdfe.GdfeError as exc:
            note(f"refused: {exc}")
            event(f"{getattr(fn, '__name__', 'call')}: refused")
            assert str(exc).strip() and "\n" not in str(exc).strip(), repr(str(exc))
            return exc


# -- values -------------------------------------------------------------------------------------------
SANE = st.sampled_from([0.05, 0.1, 0.125, 0.2, 0.25, 0.29, 0.33, 0.5, 0.7, 1.0, 1.6, 2.6])
BAD_FLOATS = st.sampled_from([0.0, -0.0, -1.0, -0.33, math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, 1e-300,
                              1e-7, 1e7, 1e12, 1.0 + 1e-12, 0.9999999])
FLOATS = st.one_of(SANE, BAD_FLOATS, st.floats(min_value=0.05, max_value=3.0),
                   st.floats(allow_nan=True, allow_infinity=True))
INTS = st.one_of(st.integers(-3, 6), st.sampled_from([0, -1, 10**6, 2**63 - 1, -(2**63)]))
TEXT = st.one_of(st.sampled_from(["", "0.7", "0.29", "1e3", "nan", "true", "RRTT", "top", "bottom", "on", "off",
                                  "newton", "plain", "warn", "stop", "auto", "x.png", "m.toml", "../d.toml"]),
                 st.text(max_size=8))
ROWS = st.lists(st.text(alphabet="RTBS.", min_size=1, max_size=6), min_size=1, max_size=5)
SCALARS = st.one_of(FLOATS, INTS, st.booleans(), TEXT)
VALUES = st.one_of(SCALARS, ROWS, st.lists(SCALARS, max_size=3),
                   st.dictionaries(st.sampled_from(["a", "h", "R"]), SCALARS, max_size=2))


# -- design files -------------------------------------------------------------------------------------
def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, str):
        return json.dumps(v)  # a TOML basic string: JSON's escapes are TOML's
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)  # pragma: no cover


def _toml(doc, top=()):
    """TOML text of ``doc`` (a dict of tables), with ``top`` key/value pairs before any table."""
    lines = [f"{json.dumps(k)} = {_toml_value(v)}" for k, v in top]
    for name, table in doc.items():
        lines.append(f"[{json.dumps(name) if not name.isidentifier() else name}]")
        lines += [f"{json.dumps(k)} = {_toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


#: Values a valid design file may give each key (small designs: a few to a few hundred cells).
GOOD = {
    "h": st.sampled_from([0.2, 0.29, 0.4]), "R": st.sampled_from([0.3, 0.5, 0.7, 0.9, 1.0]),
    "d": st.sampled_from([0.15, 0.2, 0.33, 0.5]), "K": st.sampled_from([0.2, 0.3706]), "nz": st.sampled_from([1, 2]),
    "isotropy": st.sampled_from([0.0, 0.5, 1.0]), "length": st.sampled_from([0.5, 1.0, 1.6, 2.6]),
    "width": st.sampled_from([0.5, 1.0]), "panel_length": st.sampled_from([0.5, 1.0]),
    "cell_size": st.sampled_from([0.1, 0.2, 0.25]), "face": st.sampled_from(["top", "bottom"]),
    "pixel": st.sampled_from([0.1, 0.2, 0.25]), "rows": st.integers(1, 6).flatmap(
        lambda n: st.lists(st.text(alphabet="RTBS.", min_size=n, max_size=n), min_size=1, max_size=5)),
    "steps": st.sampled_from([1, 2, 3]), "tol": st.sampled_from([1e-5, 1e-6, 1e-4]),
    "max_iter": st.sampled_from([1, 5, 50]),
    "method": st.sampled_from(["newton", "newton-cg", "plain", "anderson", "auto"]),
    "contact": st.sampled_from(["auto", "off"]), "on_drift": st.sampled_from(["warn", "stop"]),
    "T_C": st.sampled_from([120, 150.5]), "lot": st.sampled_from(["A", "B"]),
}
#: Mutations of a valid design file (its tables as a dict) that a careless user makes.
MUTATIONS = ("value", "drop_key", "unknown_key", "drop_section", "unknown_section", "second_kind", "top_level",
             "string_number", "boolean")


@st.composite
def valid_design(draw):
    """The tables of a valid small design file: a film, a hinge or a layout, maybe [simulate] and [process]."""
    film = {"h": draw(GOOD["h"])}
    if draw(st.booleans()):
        film["R"] = draw(GOOD["R"])
    else:
        film["d"] = draw(GOOD["d"])
        if draw(st.booleans()):
            film["K"] = draw(GOOD["K"])
    for key in draw(st.lists(st.sampled_from(["nz", "isotropy"]), unique=True, max_size=2)):
        film[key] = draw(GOOD[key])
    doc = {"film": film}
    if draw(st.booleans()):
        doc["hinge"] = {k: draw(GOOD[k]) for k in ["length"] + draw(st.lists(st.sampled_from(
            ["width", "panel_length", "cell_size", "face"]), unique=True, max_size=4))}
    else:
        doc["layout"] = {"pixel": draw(GOOD["pixel"]), "rows": draw(GOOD["rows"])}
    if draw(st.booleans()):
        doc["simulate"] = {k: draw(GOOD[k]) for k in draw(st.lists(st.sampled_from(DESIGN_KEYS["simulate"]),
                                                                     unique=True, max_size=3))}
    if draw(st.integers(0, 3)) == 0:
        doc["process"] = {k: draw(GOOD[k]) for k in draw(st.lists(st.sampled_from(["T_C", "lot"]), unique=True))}
    return doc


@st.composite
def design_files(draw):
    """TOML text of a design file: a valid small one with 0 to 3 random mutations."""
    doc = draw(valid_design())
    top = []
    for what in draw(st.lists(st.sampled_from(MUTATIONS), max_size=3)):
        name = draw(st.sampled_from(sorted(doc)))
        table = doc[name]
        if what == "value" and table:
            table[draw(st.sampled_from(sorted(table)))] = draw(VALUES)
        elif what == "drop_key" and table:
            del table[draw(st.sampled_from(sorted(table)))]
        elif what == "unknown_key":
            table[draw(st.sampled_from(["widht", "pixle", "lenght", "hh", "r", "steps_", "x", "H", "Length"]))] = \
                draw(SCALARS)
        elif what == "drop_section" and len(doc) > 1:
            del doc[name]
        elif what == "unknown_section":
            doc[draw(st.sampled_from(["simulte", "Film", "hinges", "x", "masks", "svg", "fold"]))] = {}
        elif what == "second_kind":
            doc["layout" if "hinge" in doc else "hinge"] = {"length": 1.0, "pixel": 0.2, "rows": ["RT"]}
        elif what == "top_level":
            top.append((draw(st.sampled_from(["R", "h", "steps", "title"])), draw(SCALARS)))
        elif what == "string_number" and table:
            key = draw(st.sampled_from(sorted(table)))
            table[key] = str(table[key])
        elif what == "boolean" and table:
            table[draw(st.sampled_from(sorted(table)))] = draw(st.booleans())
    return _toml(doc, top)


def _check_design(design):
    """A loaded design's sanity: cells, finite points, ratios in (0, 1], codes known."""
    assert isinstance(design, gdfe.Design)
    assert design.n_cells >= 1
    assert np.isfinite(design.mesh.points).all()
    assert np.all((design.R > 0) & (design.R <= 1))
    assert set(np.unique(design.material)) <= {int(m) for m in gdfe.Material}
    assert 1e-6 <= design.h <= 1e6


def _check_result(design, res):
    """A simulated result's sanity: finite numbers, and a ``converged`` that a fresh solve confirms."""
    assert isinstance(res, gdfe.Result)
    assert np.isfinite(res.points).all() and all(np.isfinite(f).all() for f in res.frames)
    assert math.isfinite(res.energy) and res.energy >= 0
    assert res.iterations == sum(res.frame_iterations)
    if res.converged and res.tol <= 1e-4 and not res.penetrates:  # a penetrating result is flagged (exit 4)
        # an equilibrium stays where it is: a tight Newton solve from it moves it by a small
        # part of the film's size (the default stopping test asks 1e-6 of it; measured at most
        # 7.1e-7 over 300 design-file examples; 10x the tolerance leaves room for the estimate's
        # factor 2-3). A design file may loosen the tolerance (tol = 1e-5 moved a 0.574 mm film
        # by 1.19e-5 mm, 2.1 x tol of its size): the bound scales with the tolerance asked for
        again = gdfe.simulate(design, init=res.points, method="newton", tol=1e-7,
                              contact="on" if res.contact.used else "off")
        size = float(np.linalg.norm(np.ptp(design.mesh.points, axis=0)))
        moved = gdfe.shape_distance(again.points, res.points)["max"]
        bound = 10.0 * max(res.tol, 1e-6) * size
        if again.converged:
            assert moved <= bound, (f"converged result moved {moved:.3g} mm by a tight re-solve (size {size:.3g} mm, "
                                    f"tol {res.tol:g})")
        else:
            # the tight solve drifts along a near-zero-energy mode (a cell held by one edge of its
            # neighbour turns freely: measured 8.8e-3 mm moved for a 5.8e-8 relative energy change):
            # the equilibrium is not unique, and the converged result is one of its states
            assert again.energy >= res.energy * (1 - 1e-6), (
                f"a tight re-solve found an energy {1 - again.energy / res.energy:.2g} of itself lower than the "
                f"converged result's")
    if not res.converged:
        assert res.summary()["converged"] is False


def _simulate_small(design, options):
    from gdfe.resources import estimate_run

    if design.n_cells > SIMULATE_CELLS or estimate_run(design.n_cells, options.get("steps", 1)).seconds > 5:
        return
    res = _api(gdfe.simulate, design, **options)
    if not isinstance(res, gdfe.GdfeError):
        event(f"simulated: {'converged' if res.converged else 'not converged'}")
        _check_result(design, res)


@given(text=design_files())
def test_design_files(tmp_path, text):
    path = tmp_path / "d.toml"
    path.write_text(text)
    note(text)
    out = _api(gdfe.load_design, path)
    if isinstance(out, gdfe.GdfeError):
        assert str(out).startswith("d.toml"), str(out)  # every message names the file
        return
    design, options = out
    _check_design(design)
    assert set(options) <= set(DESIGN_KEYS["simulate"])
    _simulate_small(design, options)


@given(data=st.binary(max_size=200) | st.text(max_size=200).map(str.encode),
       bom=st.sampled_from([b"", b"\xef\xbb\xbf", b"\xff\xfe"]))
def test_design_files_of_random_bytes(tmp_path, data, bom):
    path = tmp_path / "d.toml"
    path.write_bytes(bom + data)
    out = _api(gdfe.load_design, path)
    assert isinstance(out, gdfe.GdfeError) and str(out).startswith("d.toml")


# -- masks ------------------------------------------------------------------------------------------
DTYPES = st.sampled_from([bool, np.uint8, np.uint16, np.int8, np.int32, np.int64, np.uint32, np.float16,
                          np.float32, np.float64, np.complex128, object, "U3"])


@st.composite
def junk_arrays(draw):
    """An array of any dtype and shape (0-D to 4-D, empty ones too) with any values."""
    dtype = draw(DTYPES)
    shape = draw(st.lists(st.integers(0, 4), min_size=0, max_size=4).map(tuple))
    size = int(np.prod(shape)) if shape else 1
    raw = draw(st.lists(st.one_of(st.integers(0, 70000), st.floats(allow_nan=True, allow_infinity=True),
                                  st.sampled_from([0, 1, 255, 65535, 0.5])), min_size=size, max_size=size))
    with np.errstate(all="ignore"):
        try:
            arr = np.array(raw, dtype=object).astype(dtype).reshape(shape)
        except (ValueError, TypeError, OverflowError):
            arr = np.zeros(shape, dtype=dtype)
    return arr


@st.composite
def pixel_arrays(draw, shape):
    """A valid mask of ``shape``: booleans, 8- or 16-bit pixels or floats in [0, 1], grey or with channels."""
    kind = draw(st.sampled_from(["bool", "uint8", "uint16", "float", "rgba"]))
    size = int(np.prod(shape))
    if kind == "bool":
        return np.array(draw(st.lists(st.booleans(), min_size=size, max_size=size)), bool).reshape(shape)
    if kind == "float":
        return np.array(draw(st.lists(st.floats(0, 1), min_size=size, max_size=size))).reshape(shape)
    if kind == "rgba":
        return np.array(draw(st.lists(st.integers(0, 255), min_size=4 * size, max_size=4 * size)),
                        np.uint8).reshape(*shape, 4)
    top = 255 if kind == "uint8" else 65535
    return np.array(draw(st.lists(st.integers(0, top), min_size=size, max_size=size)), kind).reshape(shape)


@st.composite
def mask_pairs(draw):
    """Top and bottom masks: valid and of one shape, or (a third of the time) one of them junk."""
    shape = draw(st.tuples(st.integers(1, 6), st.integers(1, 6)))
    top, bottom = draw(pixel_arrays(shape)), draw(pixel_arrays(shape))
    damage = draw(st.integers(0, 5))
    if damage == 0:
        top = draw(junk_arrays())
    elif damage == 1:
        bottom = draw(junk_arrays())
    elif damage == 2:
        bottom = draw(pixel_arrays(draw(st.tuples(st.integers(1, 6), st.integers(1, 6)))))
    return top, bottom


def _check_mask_design(des, shape):
    _check_design(des)
    i, j = des.mesh.cell_ij.T
    assert i.max() < shape[0] and j.max() < shape[1]


@given(masks=mask_pairs(), R=st.one_of(st.sampled_from([0.5, 0.7, 0.9]), FLOATS),
       pixel=st.one_of(st.sampled_from([0.1, 0.2]), FLOATS))
def test_mask_arrays(masks, R, pixel):
    top, bottom = masks
    note(f"top {top.dtype} {top.shape}, bottom {bottom.dtype} {bottom.shape}")
    out = _api(gdfe.from_masks, top, bottom, pixel, R=R)
    if not isinstance(out, gdfe.GdfeError):
        event("from_masks: accepted")
        _check_mask_design(out, np.shape(top))
        assert 0.01 <= R <= 1
        _simulate_small(out, {})


#: Pillow modes a greyscale picture is saved in, and how its 8-bit values become that mode's pixels.
MODES = ("L", "LA", "RGB", "RGBA", "P", "I;16", "I", "F", "CMYK", "1")


def _save_as(grey, mode, path):
    """Save the 8-bit greyscale picture ``grey`` (rows, cols) in ``mode``; the same picture to the eye."""
    from PIL import Image

    img = Image.fromarray(grey)
    if mode == "I;16":
        img = Image.fromarray(grey.astype(np.uint16) * 257)
    elif mode == "I":
        img = Image.fromarray(grey.astype(np.int32) * 257)
        path = path.with_suffix(".tif")
    elif mode == "F":
        img = Image.fromarray(grey.astype(np.float32) / 255)
        path = path.with_suffix(".tif")
    elif mode == "1":
        img = img.point(lambda v: 255 if v >= 128 else 0).convert("1")
    elif mode == "CMYK":
        path = path.with_suffix(".tif")
        img = img.convert("CMYK")
    else:
        img = img.convert(mode)
    img.save(path)
    assert Image.open(path).mode == mode, (Image.open(path).mode, mode)
    return path


@given(grey=st.integers(1, 5).flatmap(lambda r: st.integers(1, 5).flatmap(lambda c: st.lists(
    st.integers(0, 255) | st.sampled_from([127, 128]), min_size=r * c, max_size=r * c).map(
    lambda v: np.array(v, np.uint8).reshape(r, c)))), mode=st.sampled_from(MODES))
def test_mask_images_of_every_mode_read_alike(tmp_path, grey, mode):
    """One picture, saved in any mode or bit depth, is one mask; the array of its pixels is the same mask."""
    from gdfe._images import mask_from_array, read_mask_image

    path = _save_as(grey, mode, tmp_path / f"m_{mode.replace(';', '')}.png")
    expected = (grey < 128)[::-1].T  # dark = set; grid [i (x), j (y)], picture row 0 at the top
    if mode == "CMYK":  # CMYK -> RGB in Pillow is not exact: compare where the grey is clear of the threshold
        clear = (np.abs(grey.astype(int) - 128) > 3)[::-1].T
        got, _ = read_mask_image("m", path)
        np.testing.assert_array_equal(got[clear], expected[clear])
        return
    got, _ = read_mask_image("m", path)
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(mask_from_array("m", grey[::-1].T), expected)  # the array of its pixels


@given(data=st.binary(max_size=300), suffix=st.sampled_from([".png", ".tif", ".bmp", ".jpg", ".gif"]),
       prefix=st.sampled_from([b"", b"\x89PNG\r\n\x1a\n", b"GIF89a", b"BM", b"II*\x00"]))
def test_mask_files_of_random_bytes(tmp_path, data, suffix, prefix):
    path = tmp_path / f"top{suffix}"
    path.write_bytes(prefix + data)
    out = _api(gdfe.from_masks, path, np.zeros((2, 2), bool), 0.1, R=0.7)
    if not isinstance(out, gdfe.GdfeError):  # random bytes that happen to be an image
        _check_design(out)
    else:
        assert str(out).startswith("top"), str(out)


# -- folding-test CSVs -------------------------------------------------------------------------------
COLUMNS = ["L_mm", "d_mm", "h_mm", "alpha_rad"]
CELLS = st.one_of(
    st.sampled_from(["1", "1.6", "2.6", "0.33", "0.29", "0.15", "1.2", "2.0", "0", "-1", "nan", "inf", "-inf", "1e308",
                     "1e-300", "", " ", "abc", "1,5", "1.5.2", "0x10", "1e", "TRUE", "\"2\"", "+3", "1_000", "٣"]),
    st.floats(min_value=0.1, max_value=4).map(lambda v: f"{v:.4g}"),
    st.text(max_size=4))


@st.composite
def csv_texts(draw):
    """A folding-test CSV: valid rows (of plausible hinges) with 0 to 3 mutations of its columns, cells,
    separators, line ends, byte-order mark and encoding."""
    header = list(COLUMNS)
    n = draw(st.integers(1, 10))
    rows = [[f"{draw(st.floats(0.8, 5.5)):.3g}", f"{draw(st.floats(0.11, 0.5)):.3g}",
             draw(st.sampled_from(["0.29", "0.29", "0.2"])), f"{draw(st.floats(0.4, 3.0)):.3g}"] for _ in range(n)]
    sep, end, bom, enc = ",", "\n", b"", "utf-8"
    for what in draw(st.lists(st.sampled_from(["permute", "extra", "drop", "cell", "row", "sep", "end", "bom",
                                               "enc", "blank", "same"]), max_size=3)):
        if what == "permute":
            order = draw(st.permutations(range(len(header))))
            header = [header[k] for k in order]
            rows = [[r[k] if k < len(r) else "" for k in order] for r in rows]
        elif what == "extra":
            header.append(draw(st.sampled_from(["sigma_rad", "group", "T_C", "L_mm", "l_mm", "alpha", " d_mm ", ""])))
            rows = [r + [draw(st.one_of(CELLS, st.sampled_from(["A", "B", "0.05", "150"])))] for r in rows]
        elif what == "drop" and header:
            k = draw(st.integers(0, len(header) - 1))
            header.pop(k)
            rows = [r[:k] + r[k + 1:] for r in rows]
        elif what == "cell" and rows:
            r = draw(st.integers(0, len(rows) - 1))
            if rows[r]:
                rows[r][draw(st.integers(0, len(rows[r]) - 1))] = draw(CELLS)
        elif what == "row" and rows:
            r = draw(st.integers(0, len(rows) - 1))
            rows[r] = rows[r][:-1] if draw(st.booleans()) else rows[r] + [draw(CELLS)]
        elif what == "sep":
            sep = draw(st.sampled_from([";", "\t", " ", ", "]))
        elif what == "end":
            end = draw(st.sampled_from(["\r\n", "\r"]))
        elif what == "bom":
            bom = b"\xef\xbb\xbf"
        elif what == "enc":
            enc = draw(st.sampled_from(["latin-1", "utf-16", "cp1252"]))
        elif what == "blank":
            rows.insert(draw(st.integers(0, len(rows))), [])
        elif what == "same" and rows:
            rows = [list(rows[0]) for _ in rows]
    text = end.join(sep.join(r) for r in [header] + rows) + draw(st.sampled_from(["", end, end + end]))
    try:
        return bom + text.encode(enc)
    except UnicodeEncodeError:
        return bom + text.encode("utf-8")


def _check_tests(tests):
    assert len(tests) >= 1
    for name in ("L", "d", "h"):
        v = getattr(tests, name)
        assert np.isfinite(v).all() and (v > 0).all(), name
    assert np.isfinite(tests.alpha).all()


@given(data=csv_texts() | st.binary(max_size=200))
def test_folding_test_csvs(tmp_path, data):
    path = tmp_path / "t.csv"
    path.write_bytes(data)
    note(repr(data))
    tests = _api(gdfe.load_folding_tests, path)
    if isinstance(tests, gdfe.GdfeError):
        assert str(tests).startswith("t.csv"), str(tests)
        return
    _check_tests(tests)
    event("load_folding_tests: read")
    for model in gdfe.READINGS:
        fit = _api(gdfe.fit_reading, tests, model, n_boot=100)
        if not isinstance(fit, gdfe.GdfeError):
            assert math.isfinite(fit.K) and math.isfinite(fit.p) and math.isfinite(fit.rmse), fit
            lo, hi = fit.K_ci
            assert lo <= hi  # an interval, which may exclude K only with a warning (few, skewed tests)
            if math.isnan(fit.r2):
                assert np.ptp(tests.alpha) == 0  # undefined only where every angle is the same


@given(data=csv_texts(), args=st.sampled_from([[], ["--json"], ["--boot", "0"], ["--model", "all", "--boot", "0"],
                                                ["--d", "0.33", "--boot", "0", "--json"]]))
def test_calibrate_command_on_csvs(tmp_path, capsys, data, args):
    path = tmp_path / "t.csv"
    path.write_bytes(data)
    rc, out, err = _cli(capsys, ["calibrate", str(path), "--boot", "0", *args])
    if rc == 0 and "--json" in args:
        _check_json(out)


# -- scans ------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_hinge():
    return gdfe.hinge(1.0, d=0.33, cell_size=0.25, width=0.5, panel_length=0.5)


@st.composite
def clouds(draw):
    kind = draw(st.sampled_from(["random", "same", "line", "plane", "nan", "empty", "huge"] + ["shape"] * 4))
    n = draw(st.integers(0, 40))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    if kind == "random":
        return rng.normal(size=(n, 3))
    if kind == "same":
        return np.ones((n, 3)) * draw(st.floats(-10, 10))
    if kind == "line":
        return np.outer(rng.normal(size=n), [1.0, 2.0, 0.5])
    if kind == "plane":
        p = rng.normal(size=(n, 3))
        p[:, 2] = 0
        return p
    if kind == "nan":
        p = rng.normal(size=(max(n, 5), 3))
        p[draw(st.integers(0, len(p) - 1)), draw(st.integers(0, 2))] = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
        return p
    if kind == "empty":
        return np.zeros(draw(st.sampled_from([(0,), (0, 3), (3, 0), (5,), (4, 2), (4, 4), (2, 2, 3)])))
    if kind == "huge":
        return rng.normal(size=(max(n, 4), 3)) * 1e300
    # the simulated hinge itself: moved, noisy, a part of it, or scaled (a unit error)
    return ("shape", draw(st.sampled_from(["moved", "noise", "part", "scaled", "flat"])), int(rng.integers(2**16)))


@given(cloud=clouds(), align=st.sampled_from(["auto", "icp", "correspondence"]))
def test_scans_as_arrays(small_hinge, cloud, align):
    from gdfe.diagnosis.shape import diagnose_shape

    if isinstance(cloud, tuple):
        _, how, seed = cloud
        rng = np.random.default_rng(seed)
        pts = small_hinge.mesh.points.copy() if how == "flat" else gdfe.simulate(small_hinge).points
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        pts = pts @ (Q * np.linalg.det(Q)).T + rng.normal(size=3)
        if how == "noise":
            pts = pts + rng.normal(scale=0.01, size=pts.shape)
        elif how == "part":
            pts = pts[rng.random(len(pts)) < 0.5]
        elif how == "scaled":
            pts = pts * 10.0
        cloud = pts
    out = _api(diagnose_shape, small_hinge, cloud, align=align, correct=False)
    if not isinstance(out, gdfe.GdfeError):
        event(f"diagnose_shape: {'matches' if out.matches else 'no match'}")
        assert out.n_measured >= 4
        if out.matches:
            assert math.isfinite(out.rms_before) and out.rms_before >= 0
        else:
            assert out.match["reasons"]


def _scan_text(points, fmt):
    """A valid scan file's bytes: ``points`` as CSV (with a header), ASCII PLY or OBJ."""
    rows = [" ".join(f"{v:.6g}" for v in p) for p in points]
    if fmt == ".csv":
        return ("x,y,z\n" + "\n".join(r.replace(" ", ",") for r in rows) + "\n").encode()
    if fmt == ".ply":
        return (f"ply\nformat ascii 1.0\nelement vertex {len(rows)}\nproperty float x\nproperty float y\n"
                f"property float z\nend_header\n" + "\n".join(rows) + "\n").encode()
    return ("\n".join(f"v {r}" for r in rows) + "\n").encode()


@st.composite
def scan_files(draw):
    """``(suffix, bytes)``: a valid CSV/PLY/OBJ scan with 0 to 2 mutations, or random bytes and text."""
    if draw(st.integers(0, 3)) == 0:
        data = draw(st.binary(max_size=300) | st.lists(st.lists(CELLS, max_size=4), max_size=12).map(
            lambda rows: "\n".join(",".join(r) for r in rows).encode()))
        prefix = draw(st.sampled_from([b"", b"x,y,z\n", b"ply\nformat ascii 1.0\n", b'<?xml version="1.0"?>\n<VTKFile ',
                                       b"v "]))
        return draw(st.sampled_from([".csv", ".ply", ".obj", ".vtu", ".stl", ""])), prefix + data
    fmt = draw(st.sampled_from([".csv", ".ply", ".obj"]))
    n = draw(st.integers(1, 30))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    points = rng.normal(size=(n, 3)) * draw(st.sampled_from([1.0, 1e-3, 1e3]))
    data = _scan_text(points, fmt)
    for what in draw(st.lists(st.sampled_from(["truncate", "junk", "nan", "huge", "dup"]), max_size=2)):
        if what == "truncate":
            data = data[:draw(st.integers(0, len(data)))]
        elif what == "junk":
            k = draw(st.integers(0, len(data)))
            data = data[:k] + draw(st.binary(min_size=1, max_size=8)) + data[k:]
        elif what in ("nan", "huge"):
            data = data.replace(data.split(b"\n")[-2].split(b" ")[-1].split(b",")[-1], b"nan" if what == "nan"
                                else b"1e300", 1) if data.count(b"\n") >= 2 else data
        elif what == "dup":
            data = data + data
    return fmt, data


@given(scan=scan_files())
def test_scan_files(tmp_path, scan):
    from gdfe.diagnosis.scan import load_measured

    suffix, data = scan
    path = tmp_path / f"scan{suffix}"
    path.write_bytes(data)
    out = _api(load_measured, path)
    if not isinstance(out, gdfe.GdfeError):
        event("load_measured: read")
        pts, cells = out
        assert pts.ndim == 2 and pts.shape[1] == 3 and len(pts) >= 1 and np.isfinite(pts).all()
        assert np.abs(pts).max() <= 1e6
    else:
        assert "scan" in str(out) or "path" in str(out), str(out)


# -- command lines ----------------------------------------------------------------------------------
def _cli(capsys, argv):
    """``gdfe.cli.main(argv)`` under the CLI's rules: (status, stdout, stderr); a bad outcome fails."""
    from gdfe.cli import main

    note(f"argv: {argv}")
    with deadline(HANG_SECONDS):
        try:
            try:
                rc = main(argv)
            except SystemExit as exc:  # argparse: --help, --version, or a mistake in the arguments
                rc = exc.code
        finally:
            cap = capsys.readouterr()  # emptied even when main raised, so the next example starts clean
    event(f"{argv[0] if argv else ''}: exit {rc}")
    assert "Traceback" not in cap.err and "internal error" not in cap.err, cap.err
    assert isinstance(rc, int), rc
    if rc != 0:
        lines = _message_lines(cap.err)
        assert rc in (1, 2, 3, 4, 130), (rc, cap.err)
        assert lines, f"exit {rc} with nothing on standard error"
        assert len(lines) == 1 or rc in (3, 4), cap.err  # one line; 3/4 print a result, then one line
        assert "error" in lines[-1], cap.err
    return rc, cap.out, cap.err


def _check_json(out):
    def walk(x):
        if isinstance(x, float):
            assert math.isfinite(x)
        elif isinstance(x, dict):
            [walk(v) for v in x.values()]
        elif isinstance(x, list):
            [walk(v) for v in x]
    walk(json.loads(out))


@pytest.fixture
def cheap_runs(monkeypatch):
    """Runs the estimate calls longer than a few seconds need --large, which is never drawn."""
    import gdfe.resources

    monkeypatch.setattr(gdfe.resources, "LARGE_SECONDS", 3.0)


NUMBERS = st.sampled_from(["1", "0", "-1", "0.33", "2.6", "nan", "inf", "-inf", "1e308", "1e-9", "abc", "", "3",
                           "16", "1000000", "0.1", "1e5", "2", "1.5", "true"])
#: Options of each subcommand the fuzzer draws from, with the values they take.
OPTIONS = {
    "hinge": ["--length", "-L", "--d", "--h", "--K", "--R", "--width", "--panel-length", "--cells", "--nz",
              "--isotropy", "--steps", "--tol", "--max-iter", "--method", "--on-drift", "--model", "--process",
              "--out", "--json", "--no-contact", "--allow-penetration", "-v", "-q"],
    "simulate": ["--out", "--steps", "--tol", "--max-iter", "--method", "--model", "--export", "--export-frame",
                 "--json", "--process", "-v"],
    "calibrate": ["--model", "--boot", "--d", "--model-out", "--json"],
    "view": ["--html", "--title", "--json"],
    "diagnose": ["--sigma", "--process", "--json", "--group", "--no-pairs", "--check", "--effect"],
    "diagnose-shape": ["--align", "--no-correct", "--json"],
    "design": ["--text", "--pixel", "--w-min", "--d", "--R", "--K", "--h", "--width", "--rounding", "--clamp",
               "--json"],
}


@st.composite
def command_lines(draw, files):
    cmd = draw(st.sampled_from(sorted(OPTIONS)))
    words = {"--method": st.sampled_from(["newton", "plain", "bogus", ""]), "--on-drift": st.sampled_from(["warn", "x"]),
             "--model": st.sampled_from(["eq1", "all", "power", files["model"], files["csv"], "missing.toml"]),
             "--check": st.sampled_from(["none", "coarse", "x"]), "--align": st.sampled_from(["auto", "icp", "x"]),
             "--export": st.sampled_from(["stl", "x", ",", "obj,stl"]),
             "--process": st.sampled_from(["T_C=150", "=", "a=", "lot=B,T_C=1"]),
             "--out": st.sampled_from([files["out"], files["csv"], "", files["tmp"] + "/o2"]),
             "--json": st.sampled_from(["-", files["tmp"] + "/r.json", files["csv"]]),
             "--html": st.sampled_from([files["tmp"] + "/v.html", ""]), "--model-out": st.sampled_from(
                 [files["tmp"] + "/m.toml", files["csv"], ""]),
             "--group": st.sampled_from(["group", "L_mm", "nope"]), "--effect": st.sampled_from(["saturation", "x"]),
             "--title": st.text(max_size=5), "--text": st.sampled_from(["C", "S", "CS", "Q", "", "c"]),
             "--rounding": st.sampled_from(["nearest", "carry", "x"])}
    flags = {"--no-contact", "--allow-penetration", "-v", "-q", "--no-pairs", "--no-correct", "--clamp"}
    positional = {"simulate": [files["design"]], "calibrate": [files["csv"]], "diagnose": [files["csv"]],
                  "view": [files["out"]], "diagnose-shape": [files["design"], files["scan"]]}.get(cmd, [])
    argv = [cmd]
    if draw(st.integers(0, 4)):
        argv += positional
    else:
        argv += draw(st.lists(st.sampled_from(list(files.values()) + ["", "-", "x.toml"]), max_size=2))
    if cmd == "hinge" and draw(st.integers(0, 3)):
        argv += ["-L", draw(st.sampled_from(["1", "1.6", "0.5"])), "--d", draw(st.sampled_from(["0.33", "0.2"]))]
    for opt in draw(st.lists(st.sampled_from(OPTIONS[cmd]), max_size=4)):
        if opt in flags:
            argv.append(opt)
        elif opt == "--json" and draw(st.booleans()):
            argv.append(opt)
        else:
            argv += [opt, draw(words.get(opt, NUMBERS))]
    if cmd == "design":  # the 1-D pipeline into a fresh folder, without its simulated check (minutes)
        argv += ["--no-check", "--out", draw(st.sampled_from([files["tmp"] + "/des", files["csv"], ""]))]
        if draw(st.integers(0, 2)):
            argv += ["--text", draw(st.sampled_from(["C", "S"]))]
    if draw(st.integers(0, 9)) == 0:
        argv.insert(draw(st.integers(0, len(argv))), draw(st.sampled_from(["--bogus", "-x", "--", "-"])))
    return argv


@pytest.fixture(scope="module")
def cli_files(tmp_path_factory):
    """Files the fuzzed command lines name: a small design, Table 1, a model, a result folder, a scan."""
    from gdfe.cli import main

    import shutil

    tmp = tmp_path_factory.mktemp("cli")
    shutil.copy(gdfe.TABLE1, tmp / "table1.csv")  # a copy: no drawn option may write over the package's data
    design = tmp / "d.toml"
    design.write_text('[film]\nd = 0.33\n[layout]\npixel = 0.25\nrows = ["RRTTRR", "RRTTRR"]\n')
    model = tmp / "m.toml"
    assert main(["calibrate", str(tmp / "table1.csv"), "--boot", "0", "--model-out", str(model), "-q"]) == 0
    out = tmp / "out"
    assert main(["simulate", str(design), "--out", str(out), "-q"]) == 0
    scan = tmp / "scan.csv"
    res = gdfe.simulate(gdfe.load_design(design)[0])
    scan.write_text("x,y,z\n" + "\n".join(",".join(f"{v:.6g}" for v in p) for p in res.points))
    return {"design": str(design), "csv": str(tmp / "table1.csv"), "model": str(model), "out": str(out), "scan": str(scan),
            "tmp": str(tmp)}


@given(data=st.data())
def test_command_lines(cli_files, cheap_runs, capsys, data):
    argv = data.draw(command_lines(cli_files))
    rc, out, err = _cli(capsys, argv)
    if rc == 0 and getattr(build_parser().parse_args(argv), "json", None) == "-":
        _check_json(out)
    if rc == 0 and argv[0] == "hinge" and "--json" not in argv:
        assert "converged in" in out  # a result with exit 0 is a converged one


def test_the_command_line_in_a_process_is_one_line_and_no_traceback(tmp_path):
    """``python -m gdfe`` itself (the console entry, not ``main``): a bad argument, a bad file, Ctrl-C elsewhere."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    bad = tmp_path / "bad.toml"
    bad.write_text("[film]\nh = 0.29\nR = 0.7\n[hinge]\nlenght = 1\n")
    for argv, rc, match in ((["hinge", "-L", "abc"], 2, "gdfe hinge: error: argument --length/-L: invalid float "
                                                          "value: 'abc' (options: gdfe hinge --help)"),
                            (["simulate", str(bad), "--out", str(tmp_path / "o")], 1,
                             "gdfe simulate: error: bad.toml: [hinge]: unknown key 'lenght' (did you mean "
                             "'length'?); expected some of length, width, panel_length, cell_size, face"),
                            (["--version"], 0, None)):
        p = subprocess.run([sys.executable, "-m", "gdfe", *argv], capture_output=True, text=True, env=env, timeout=120)
        assert p.returncode == rc, p.stderr
        if match is not None:
            assert p.stderr.splitlines() == [match]
        else:
            assert p.stdout.strip() == f"gdfe {gdfe.__version__}"


# -- the long profile -------------------------------------------------------------------------------
@pytest.mark.slow
def test_every_property_with_the_long_profile():
    """Rerun this module's properties with 400 examples each (``GDFE_HYPOTHESIS_PROFILE=long``)."""
    env = {**os.environ, "GDFE_HYPOTHESIS_PROFILE": "long"}
    p = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", __file__,
                        "-k", "not long_profile and not in_a_process"], env=env, capture_output=True, text=True,
                       cwd=Path(__file__).resolve().parents[1])
    assert p.returncode == 0, p.stdout[-4000:] + p.stderr[-2000:]
