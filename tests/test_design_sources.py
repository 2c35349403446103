"""One way in for designs: every reader registered with :func:`gdfe.load_design` gets the same arguments.

Also what a design records of how its contraction was made (process variables, the model file and
its sha256), the checks of target meshes, and the cost of the refusals in front of large inputs.
"""

import ast
import json
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

import gdfe
from gdfe.design import DESIGN_KEYS, DESIGN_KINDS, DESIGN_READERS, DesignSource, register_design_reader
from bad_input_catalogue import SVG, _bad_meshes, _fold, _grid_mesh  # a module of tests/

ROOT = Path(__file__).resolve().parents[1]


def test_the_design_loader_imports_nothing_of_fabrication():
    """gdfe.design knows SVG, FOLD and packages only through the readers registered with it."""
    tree = ast.parse((ROOT / "gdfe" / "design.py").read_text())
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert not [m for m in names if m.startswith("gdfe.fabrication")]
    assert {"hinge", "layout", "masks", "svg", "fold", "package"} <= set(DESIGN_READERS)
    assert DESIGN_KINDS == ["hinge", "layout", "masks", "svg", "fold"]
    assert list(DESIGN_KEYS) == ["film", "hinge", "layout", "masks", "svg", "fold", "process", "simulate"]


@pytest.fixture
def model_file(tmp_path):
    from gdfe.cli import main

    path = tmp_path / "m.toml"
    assert main(["calibrate", str(gdfe.TABLE1), "--boot", "0", "--model-out", str(path), "-q"]) == 0
    return path


def test_every_reader_gets_the_same_arguments(tmp_path, model_file, monkeypatch):
    seen = []

    def read(source):
        seen.append(source)
        return source.masks_design(np.ones((4, 2), bool), np.zeros((4, 2), bool), 0.25)

    monkeypatch.setitem(DESIGN_READERS, "probe", None)
    register_design_reader("probe", read, suffixes=(".probe",))
    try:
        (tmp_path / "a.probe").write_text("")
        des, options = gdfe.load_design(tmp_path / "a.probe", model=model_file, process={"T_C": 150})
    finally:
        DESIGN_READERS.pop("probe")
    src = seen[0]
    assert isinstance(src, DesignSource) and src.table is None and src.path.name == "a.probe"
    assert src.film.model.name == "calibration eq1" and src.film.process == {"T_C": 150}
    assert des.model is src.film.model and des.meta["process"] == {"T_C": 150} and options == {}
    assert des.meta["model_file"]["sha256"] == __import__("hashlib").sha256(model_file.read_bytes()).hexdigest()


def test_a_bare_drawing_keeps_the_model_and_the_process_of_a_design_file(tmp_path, model_file):
    svg = tmp_path / "d.svg"
    svg.write_text(SVG)
    alone, _ = gdfe.load_design(svg, model=model_file, process={"lot": "B"})
    (tmp_path / "d.toml").write_text(f'[film]\nd = {gdfe.paper.FIG6_D}\nh = {gdfe.paper.H}\nnz = 1\n'
                                     f'model = "{model_file}"\n[svg]\nfile = "d.svg"\npixel = 0.1\n'
                                     f'[process]\nlot = "B"\n')
    table, _ = gdfe.load_design(tmp_path / "d.toml")
    assert np.array_equal(alone.R, table.R) and alone.n_cells == table.n_cells
    for des in (alone, table):
        assert des.meta["process"] == {"lot": "B"} and des.meta["process_unused"] == ["lot"]
        assert des.meta["contraction_source"] == "model 'calibration eq1'"


def test_a_print_package_reads_as_a_design(tmp_path):
    from gdfe.fabrication import write_print_package

    des = gdfe.from_rows(["RTTR", "RTTR"], R=0.7, pixel=0.25)
    pkg = write_print_package(tmp_path / "p.zip", {"part": des})
    back, options = gdfe.load_design(pkg)
    assert back.n_cells == des.n_cells and np.allclose(back.R, des.R) and options == {}
    two = write_print_package(tmp_path / "two.zip", {"a": des, "b": des})
    with pytest.raises(gdfe.GdfeError, match=r"two\.zip: expected a package of one part .* got 2 parts \(a, b\)"):
        gdfe.load_design(two)


def test_unused_process_variables_are_said_once_and_recorded(caplog):
    with caplog.at_level("WARNING"):
        des = gdfe.hinge(1.0, d=0.33, process={"T_C": 150.0, "lot": "B"})
    said = [r.getMessage() for r in caplog.records if "not used" in r.getMessage()]
    assert len(said) == 1 and "T_C, lot not used" in said[0] and "model 'paper'" in said[0]
    assert des.meta["process"] == {"T_C": 150.0, "lot": "B"} and des.meta["process_used"] == []
    with pytest.raises(gdfe.GdfeError, match=r"process: T_C: expected a temperature in degrees Celsius"):
        gdfe.hinge(1.0, d=0.33, process={"T_C": 1e6})


def test_the_hinge_command_records_the_process_and_the_model_file(tmp_path, model_file, capsys):
    from gdfe.cli import main

    assert main(["hinge", "-L", "1", "--d", "0.33", "--model", str(model_file), "--process", "T_C=150",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["process"] == {"T_C": 150.0} and out["process_unused"] == ["T_C"]
    assert out["contraction_source"] == "model 'calibration eq1'" and len(out["model_file"]["sha256"]) == 64


@pytest.mark.parametrize("label", list(_bad_meshes()))
def test_bad_target_meshes_are_named(label):
    from gdfe._validation import check_surface_mesh

    (V, T), names = _bad_meshes()[label]
    with pytest.raises(gdfe.GdfeError, match=names):
        check_surface_mesh("t.obj", V, T)


def test_a_good_disc_and_its_hole():
    from gdfe._validation import check_surface_mesh

    V, T = _grid_mesh(6)
    check_surface_mesh("t.obj", V, T)
    inner = [k for k, t in enumerate(T) if all(1 <= v // 6 <= 4 and 1 <= v % 6 <= 4 for v in t)]
    with pytest.raises(gdfe.GdfeError, match=r"2 boundary loops and Euler characteristic 0"):
        check_surface_mesh("t.obj", V, np.delete(T, inner[:1], axis=0))


def _cost(fn):
    """Seconds and peak traced memory [bytes] of ``fn()``, which must refuse."""
    tracemalloc.start()
    t0 = time.perf_counter()
    with pytest.raises(gdfe.GdfeError) as info:
        fn()
    seconds = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return seconds, peak, str(info.value)


def test_refusals_of_the_largest_inputs_are_cheap(tmp_path):
    """A refusal in front of a huge input costs at most 1 s and 100 MiB (it is decided before any grid is made)."""
    from gdfe.cli.bench import _sizes  # noqa: F401  (the bench's sizes are refused by argparse, cheaper still)
    from gdfe.diagnosis.scan import _guarded

    (tmp_path / "m.fold").write_text(_fold(frame_unit="m", vertices_coords=[[0, 0], [10, 0], [20, 0], [20, 10],
                                                                            [10, 10], [0, 10]]))
    (tmp_path / "km.svg").write_text(SVG.replace('width="6mm" height="2mm"', 'width="1e7mm" height="1e7mm"'))

    class Points:
        def __len__(self):
            return 10**10

    cases = {"FOLD in metres": lambda: gdfe.load_design(tmp_path / "m.fold"),
             "SVG 10 km wide": lambda: gdfe.load_design(tmp_path / "km.svg"),
             "10^12-cell layout": lambda: gdfe.from_masks(np.ones((10**6, 10**6), bool)[:0] if False else
                                                          np.broadcast_to(True, (10**6, 10**6)),
                                                          np.broadcast_to(False, (10**6, 10**6)), 0.1, R=0.7),
             "10^10-point scan": lambda: _guarded(Path("scan.csv"), Points())}
    for label, fn in cases.items():
        seconds, peak, text = _cost(fn)
        assert seconds <= 1.0 and peak <= 100 * 2**20, f"{label}: {seconds:.3g} s, {peak / 2**20:.3g} MiB: {text}"
        assert "memory" in text, text
