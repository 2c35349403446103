"""The interactive offline 3-D page: its data, ``gdfe view``, the report's view, and a real browser where there is one."""

import base64
import re
import shutil
import subprocess

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.fabrication import read_series, view_data, viewer_page, write_viewer
from gdfe.io import write_series


@pytest.fixture(scope="module")
def folded():
    return gdfe.simulate(gdfe.hinge(1.0, d=0.33, cell_size=0.125), steps=3).check()


def _payload(page):
    import json

    text = re.search(r'<script type="application/json" class="gdfe-data">(.*?)</script>', page, re.S).group(1)
    return json.loads(text.replace("<\\/", "</"))


def test_page_carries_every_frame_and_needs_no_network(folded):
    data = view_data(folded)
    page = viewer_page(data)
    assert not re.search(r"(src|href)\s*=\s*[\"']?(https?:)?//", page)  # nothing loaded from anywhere
    assert "<canvas" in page and 'type="range"' in page and "webgl" in page
    p = _payload(page)
    frames = np.frombuffer(base64.b64decode(p["frames"]), "<f4").reshape(p["n_frames"], p["n_vertices"], 3)
    assert p["n_frames"] == 4 and p["activation"] == pytest.approx([0, 1 / 3, 2 / 3, 1])
    np.testing.assert_allclose(frames[-1], folded.points[data_point_index(folded)], atol=1e-6)
    quads = np.frombuffer(base64.b64decode(p["quads"]), "<u4").reshape(-1, 4)
    assert quads.max() < p["n_vertices"] and len(quads) == len(gdfe.io.surface_faces(folded.design)[0])


def data_point_index(res):
    from gdfe.fabrication import hex_surface

    return hex_surface(res.points, res.design.mesh.cells, res.design.material).point_index


def test_series_reads_back_and_view_command(folded, tmp_path, capsys):
    write_series(folded, tmp_path, name="hinge")
    data = read_series(tmp_path / "hinge.pvd")
    ref = view_data(folded)
    np.testing.assert_allclose(data.frames, ref.frames, atol=1e-6)
    np.testing.assert_array_equal(data.material, ref.material)
    assert main(["view", str(tmp_path), "--html"]) == 0
    assert (tmp_path / "hinge.html").is_file() and "wrote" in capsys.readouterr().out
    assert main(["view", str(tmp_path / "hinge.pvd"), "--html", str(tmp_path / "v.html")]) == 0
    write_series(folded, tmp_path, name="other")
    assert main(["view", str(tmp_path)]) == 1
    assert "expected one .pvd series" in capsys.readouterr().err
    (tmp_path / "bad.pvd").write_text("<VTKFile><Collection><DataSet timestep='x' file='a.vtu'/></Collection>")
    with pytest.raises(ValueError, match="not well-formed XML at line 1"):
        read_series(tmp_path / "bad.pvd")
    (tmp_path / "bad.pvd").write_text("<VTKFile><Collection><DataSet timestep='0' file='none.vtu'/>"
                                      "</Collection></VTKFile>")
    with pytest.raises(ValueError, match=r"DataSet 0: file 'none.vtu' not found"):
        read_series(tmp_path / "bad.pvd")


def test_a_truncated_frame_is_named(folded, tmp_path, capsys):
    """meshio prints a line and exits on a truncated VTU: the command says which file, and its --json error
    object comes out, instead of a bare line and no object."""
    import json

    write_series(folded, tmp_path, name="hinge")
    frame = sorted(tmp_path.glob("hinge*.vtu"))[-1]
    frame.write_bytes(frame.read_bytes()[: frame.stat().st_size // 2])
    with pytest.raises(ValueError, match=rf"{frame.name}: expected a VTU frame gdfe wrote, got one meshio cannot read"):
        read_series(tmp_path / "hinge.pvd")
    assert main(["view", str(tmp_path), "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["error"]["type"] == "GdfeError" and frame.name in out["error"]["message"]


def test_report_has_the_interactive_view():
    from studies.validation_report import interactive_view

    fragment, rec = interactive_view()
    assert rec["converged"] and 'id="hinge-view"' in fragment
    assert rec["fold_angle_rad"] == pytest.approx(float(gdfe.Calibration().alpha(2.6, 0.33)), abs=0.03)  # Fig. 6


def _browser():
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        if shutil.which(name):
            return shutil.which(name)
    return None


@pytest.mark.skipif(_browser() is None, reason="no Chromium or Chrome installed")
def test_page_renders_in_a_headless_browser(folded, tmp_path):
    page = write_viewer(tmp_path / "view.html", folded)
    cmd = [_browser(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=5000", "--dump-dom", page.as_uri()]
    dom = subprocess.run(cmd, capture_output=True, text=True, timeout=120).stdout
    assert re.search(r'data-rendered="(webgl|canvas2d)"', dom), dom[-2000:]
    assert "data-error" not in dom
    n = 2 * len(gdfe.io.surface_faces(folded.design)[0])
    assert f"{n} triangles" in dom
