"""Property-based tests (Hypothesis) of the surfaces added since ``tests/test_properties.py``.

Process-variable strings (``--process``), SVG documents, FOLD documents, target meshes, model
files and diagnose's extra columns: every input gives a :class:`gdfe.GdfeError` of one line, or
a result that passes its checks (what was given is recorded, what the design holds is finite and
in range, an accepted mesh is one manifold disc by an independent count). Each property has a
deadline per example (:data:`DEADLINE`) besides the hang guard, and runs 25 examples in the
default profile, 400 in the long one (``tests/conftest.py``; ``GDFE_HYPOTHESIS_PROFILE=long``).
"""

from __future__ import annotations

import argparse
import json
import math
import warnings
from datetime import timedelta

import numpy as np
import pytest
from hypothesis import event, given, note, settings
from hypothesis import strategies as st

import gdfe
from bad_input_catalogue import SVG, _fold, _grid_mesh, deadline  # a module of tests/

#: The longest one example may take (Hypothesis's deadline); a run past HANG_SECONDS is a hang.
DEADLINE = timedelta(seconds=20)
HANG_SECONDS = 60


def _refused(exc):
    text = str(exc).strip()
    assert text and "\n" not in text, repr(text)
    note(f"refused: {text}")
    event("refused")


# -- process variables --------------------------------------------------------------------------------
NAMES = st.sampled_from(["T_C", "T_K", "t_s", "t_min", "lot", "x", "", " ", "T_C ", "a=b", "_C"])
VALUES = st.one_of(st.sampled_from(["150", "1e6", "-300", "nan", "inf", "", " ", "B", "-1", "0", "1e308", "500",
                                    "-273.15", "-273.2"]),
                   st.floats(allow_nan=True, allow_infinity=True).map(repr), st.text(max_size=4))


@settings(deadline=DEADLINE)
@given(st.lists(st.tuples(NAMES, VALUES, st.sampled_from(["=", "", "=="])), max_size=4))
def test_process_strings(items):
    """``--process`` text: refused by the parser or by the design, or recorded whole with each unit in range."""
    from gdfe.cli._common import _process
    from gdfe.design import PROCESS_UNIT_RANGES

    text = ",".join(f"{n}{eq}{v}" for n, v, eq in items)
    note(text)
    with deadline(HANG_SECONDS):
        try:
            proc = _process(text)
        except argparse.ArgumentTypeError as exc:
            _refused(exc)
            return
        try:
            des = gdfe.hinge(1.0, d=0.33, cell_size=0.25, panel_length=0.5, process=proc)
        except gdfe.GdfeError as exc:
            _refused(exc)
            return
    event("accepted")
    assert des.meta.get("process", {}) == (proc or {})
    assert des.meta.get("process_unused", []) == list(proc)  # the paper's model reads none of them
    for k, v in proc.items():
        assert isinstance(v, str) and v.strip() or math.isfinite(v)
        unit = next((u for u in PROCESS_UNIT_RANGES if k.endswith(u) and len(k) > len(u)), None)
        if unit and not isinstance(v, str):
            lo, hi, _ = PROCESS_UNIT_RANGES[unit]
            assert lo <= v <= hi


# -- SVG documents ----------------------------------------------------------------------------------
NUMBER = st.one_of(st.sampled_from(["0", "1", "2", "-1", "nan", "NaN", "inf", "-inf", "1e9", "1e-9", "", "x",
                                    "0.05", "3mm"]),
                   st.floats(-10, 10, allow_nan=False).map(lambda x: f"{x:.3g}"))


@st.composite
def svg_documents(draw):
    fine = st.floats(0, 6, allow_nan=False).map(lambda x: f"{x:.3g}")
    shapes = [f'<g id="bottom"><rect x="{draw(fine)}" y="0" width="{draw(fine)}" height="2" fill="black"/></g>']
    for _ in range(draw(st.integers(0, 3))):
        face = draw(st.sampled_from(["top", "bottom", "both", "film", "nowhere"]))
        x, y, w, h = (draw(NUMBER) for _ in range(4))
        rect = f'<rect x="{x}" y="{y}" width="{w}" height="{h}" fill="black"/>'
        shapes.append(rect if face == "nowhere" else f'<g id="{face}">{rect}</g>')
    page = draw(st.sampled_from(['width="6mm" height="2mm" viewBox="0 0 6 2"'] * 6 + ['width="6mm" height="2mm"',
                                 'viewBox="0 0 6 2"', 'width="nanmm" height="2mm"', 'width="1e9mm" height="1mm"',
                                 'width="6mm" height="2mm" viewBox="0 0 nan 2"']))
    return f'<svg xmlns="http://www.w3.org/2000/svg" {page}>' + "".join(shapes) + "</svg>"


@settings(deadline=DEADLINE)
@given(svg_documents())
def test_svg_documents(tmp_path_factory, text):
    """A drawing: refused in one line, or a design whose every coordinate is finite and whose coat is on the film."""
    from gdfe.fabrication import svg_masks

    path = tmp_path_factory.mktemp("svg") / "d.svg"
    path.write_text(text)
    note(text)
    with deadline(HANG_SECONDS), warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # a NaN reaching numpy is a finding
        try:
            m = svg_masks(path, 0.1)
        except gdfe.GdfeError as exc:
            _refused(exc)
            return
    event("accepted")
    assert m.film.any() and (m.top | m.bottom).any()
    assert not ((m.top | m.bottom) & ~m.film).any()
    assert np.isfinite(m.origin).all() and m.top.shape == m.film.shape == m.bottom.shape


# -- FOLD documents ---------------------------------------------------------------------------------
COORD = st.one_of(st.sampled_from([0.0, 2.0, 4.0, 1e9, -1.0, float("nan"), float("inf")]),
                  st.floats(-5, 5, allow_nan=False))


@st.composite
def fold_documents(draw):
    doc = json.loads(_fold())
    for _ in range(draw(st.integers(0, 3))):
        what = draw(st.sampled_from(["vertex", "edge", "unit", "width", "angle", "assignment", "pixel", "face"]))
        if what == "vertex":
            k = draw(st.integers(0, 5))
            doc["vertices_coords"][k] = [draw(COORD), draw(COORD)]
        elif what == "edge":
            k = draw(st.integers(0, 6))
            doc["edges_vertices"][k] = [draw(st.integers(-1, 7)), draw(st.integers(-1, 7))]
        elif what == "unit":
            doc["frame_unit"] = draw(st.sampled_from(["mm", "m", "cm", "unit", "um", "furlong"]))
        elif what == "width":
            doc["gdfe:hinge_width"] = draw(st.sampled_from([0.6, 0.0, -1.0, 1e-6, 100.0, "x"]))
        elif what == "angle":
            doc["edges_foldAngle"] = [None] * 6 + [draw(st.sampled_from([90, -90, 0, 1e9, None]))]
        elif what == "assignment":
            doc["edges_assignment"][6] = draw(st.sampled_from(["V", "M", "F", "U", "C", "Q"]))
        elif what == "pixel":
            doc["gdfe:pixel"] = draw(st.sampled_from([0.1, 1e-7, 0.0, 5.0]))
        else:
            doc["faces_vertices"] = [[0, 1, 4, 5], [1, 2, 3, 4]] if draw(st.booleans()) else [[0, 1]]
    return json.dumps(doc)


@settings(deadline=DEADLINE)
@given(fold_documents())
def test_fold_documents(tmp_path_factory, text):
    """A crease pattern: refused in one line (no numpy warning before), or a design whose hinges cover pixels."""
    path = tmp_path_factory.mktemp("fold") / "d.fold"
    path.write_text(text)
    note(text)
    with deadline(HANG_SECONDS), warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        try:
            des, _ = gdfe.load_design(path)
        except gdfe.GdfeError as exc:
            _refused(exc)
            return
    event("accepted")
    assert np.isfinite(des.mesh.points).all() and des.n_cells > 0
    assert all(h["pixels"] > 0 and h["width_mm"] > 0 for h in des.meta["hinges"])


# -- target meshes ----------------------------------------------------------------------------------
@st.composite
def meshes(draw):
    V, T = _grid_mesh(5)
    V, T = V.copy(), [list(t) for t in T]
    for _ in range(draw(st.integers(0, 3))):
        what = draw(st.sampled_from(["drop", "flip", "fin", "far", "copy", "lift"]))
        k = draw(st.integers(0, len(T) - 1)) if T else 0
        if what == "drop" and len(T) > 1:
            T.pop(k)
        elif what == "flip" and T:
            T[k] = T[k][::-1]
        elif what == "fin" and T:
            V = np.vstack([V, [[draw(st.floats(0, 4)), draw(st.floats(0, 4)), draw(st.floats(-2, 2))]]])
            T.append([T[k][0], T[k][1], len(V) - 1])
        elif what == "far":
            V = np.vstack([V, [[10, 10, 0], [11, 10, 0], [10, 11, 0]]])
            T.append([len(V) - 3, len(V) - 2, len(V) - 1])
        elif what == "copy" and T:
            T.append(list(T[k]))
        elif what == "lift":
            V[draw(st.integers(0, len(V) - 1)), 2] += draw(st.floats(-3, 3))
    return V, np.array(T, np.int64)


def _independent_disc(V, T):
    """The properties of one oriented manifold disc, counted the plain way (dicts of edges)."""
    uses, directed = {}, set()
    for t in T:
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            uses[frozenset((a, b))] = uses.get(frozenset((a, b)), 0) + 1
            assert (a, b) not in directed, "an edge walked twice the same way"
            directed.add((a, b))
    assert max(uses.values()) <= 2
    boundary = [e for e, c in uses.items() if c == 1]
    assert boundary
    used = {int(v) for t in T for v in t}
    euler = len(used) - len(uses) + len(T)
    assert euler == 1, f"Euler characteristic {euler}: not a disc"


@settings(deadline=DEADLINE)
@given(meshes())
def test_target_meshes(data):
    """A mesh is refused in one line, or it is one oriented manifold disc (independent count)."""
    from gdfe._validation import check_surface_mesh

    V, T = data
    with deadline(HANG_SECONDS):
        try:
            check_surface_mesh("t.obj", V, T)
        except gdfe.GdfeError as exc:
            _refused(exc)
            return
    event("accepted")
    _independent_disc(V, T)


# -- model files ------------------------------------------------------------------------------------
MODEL_VALUES = st.one_of(st.sampled_from([float("nan"), float("inf"), -1.0, 0.0, 1e308, "x", "", True, [1], {}]),
                         st.floats(allow_nan=False, allow_infinity=False), st.integers(-3, 3), st.text(max_size=3))


@pytest.fixture(scope="module")
def model_doc(tmp_path_factory):
    import tomllib

    from gdfe.cli import main

    tmp = tmp_path_factory.mktemp("model")
    assert main(["calibrate", str(gdfe.TABLE1), "--boot", "0", "--model", "power", "--model-out",
                 str(tmp / "m.toml"), "-q"]) == 0
    return tomllib.loads((tmp / "m.toml").read_text())


def _paths(doc, prefix=()):
    for k, v in doc.items():
        yield prefix + (k,)
        if isinstance(v, dict):
            yield from _paths(v, prefix + (k,))


@settings(deadline=DEADLINE)
@given(st.data(), st.booleans())
def test_model_files(tmp_path_factory, model_doc, data, bom):
    """A model file with a value replaced (or a key dropped): refused in one line, or a model whose
    parameters are finite and whose closed-form fold of the paper's hinge is a number."""
    import copy

    import tomli_w

    doc = copy.deepcopy(model_doc)
    paths = sorted(_paths(doc))
    for _ in range(data.draw(st.integers(1, 3))):
        path = data.draw(st.sampled_from(paths))
        node = doc
        for k in path[:-1]:
            node = node.get(k) if isinstance(node, dict) else None
        if not isinstance(node, dict) or path[-1] not in node:
            continue
        if data.draw(st.booleans()):
            node[path[-1]] = data.draw(MODEL_VALUES)
        else:
            del node[path[-1]]
    try:
        text = tomli_w.dumps(doc)
    except (TypeError, ValueError):  # a value TOML cannot hold (NaN is fine; None is not)
        return
    at = data.draw(st.integers(0, len(text))) if bom else 0
    if bom:
        text = text[:at] + "\ufeff" + text[at:]
    path = tmp_path_factory.mktemp("m") / "m.toml"
    path.write_text(text)
    note(text)
    with deadline(HANG_SECONDS):
        try:
            model = gdfe.load_model(path)
            alpha = model.hinge_angle(1.0, 0.33, 0.29)
        except gdfe.GdfeError as exc:
            _refused(exc)
            if bom and at > 0:
                assert "BOM" in str(exc) or "line" in str(exc)
            return
    event("accepted")
    assert all(math.isfinite(p.value) for p in model.params.values())
    assert math.isfinite(alpha)


# -- diagnose's extra columns -----------------------------------------------------------------------
CELLS = st.one_of(st.sampled_from(["", "nan", "NaN", "inf", "-inf", "A", "B", "150", "1e308", " ", "x"]),
                  st.floats(100, 200, allow_nan=False).map(lambda x: f"{x:.4g}"))


@settings(deadline=DEADLINE)
@given(st.lists(CELLS, min_size=6, max_size=6), st.sampled_from(["T_C", "lot", "group", "sigma_rad"]))
def test_diagnose_columns(tmp_path_factory, cells, name):
    """An extra column: refused in one line naming the column, or sorted so that every numeric process
    column is finite (a NaN never turns a numeric column into labels)."""
    from gdfe.diagnosis.angles import read_columns

    rows = ["1.5,0.33,0.29,1.0", "2.6,0.33,0.29,1.7", "1.2,0.24,0.29,0.9", "3.4,0.24,0.29,1.44",
            "1.8,0.40,0.29,0.7", "3.1,0.15,0.29,2.2"]
    text = f"L_mm,d_mm,h_mm,alpha_rad,{name}\n" + "".join(f"{r},{c}\n" for r, c in zip(rows, cells))
    path = tmp_path_factory.mktemp("c") / "t.csv"
    path.write_text(text)
    note(text)
    with deadline(HANG_SECONDS):
        try:
            cols = read_columns(gdfe.load_folding_tests(path))
        except gdfe.GdfeError as exc:
            _refused(exc)
            return
    event("accepted")
    for k, x in cols.process.items():
        assert np.isfinite(x).all()
    numbers = []
    for c in cells:
        try:
            numbers.append(float(c))
        except ValueError:
            numbers.append(None)
    if name != "group" and name != "sigma_rad" and all(v is not None for v in numbers) and not all(
            math.isfinite(v) for v in numbers):
        pytest.fail(f"a numeric column with a non-finite value was accepted: {cells}")


@pytest.mark.slow
def test_every_property_with_the_long_profile():
    """Rerun this module's properties with 400 examples each (``GDFE_HYPOTHESIS_PROFILE=long``)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = {**os.environ, "GDFE_HYPOTHESIS_PROFILE": "long"}
    p = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", __file__,
                        "-k", "not long_profile"], env=env, capture_output=True, text=True,
                       cwd=Path(__file__).resolve().parents[1])
    assert p.returncode == 0, p.stdout[-4000:] + p.stderr[-2000:]
