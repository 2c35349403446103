"""Pictures of shapes (gdfe.io.render_png): the coat's colours fill their share of the picture,
cells' edges are drawn on small designs only, the picture holds its legend and title.

The shares are measured on a flat 10^5-cell sheet seen from above (``view="top"``, an
orthographic camera): each pixel of the sheet then shows the top face of one cell, so the share
of each material's colour among the sheet's pixels is the share of its cells, up to the pixels
along the boundaries between materials (tolerance 0.01).
"""

from __future__ import annotations

import numpy as np
import pytest

import gdfe
from gdfe.io import EDGE_CELLS, MATERIAL_COLOURS, outline_edges, render_png

BACKENDS = ["matplotlib", "pyvista"]


def _image(path):
    from PIL import Image

    with Image.open(path) as img:
        return np.asarray(img.convert("RGB"), float)


def _backend(name, tmp_path):
    """Skip the PyVista cases where PyVista is missing or cannot render off-screen here."""
    if name == "pyvista":
        pv = pytest.importorskip("pyvista")
        try:
            pl = pv.Plotter(off_screen=True, window_size=[32, 32])
            pl.add_mesh(pv.Sphere())
            pl.screenshot(str(tmp_path / "probe.png"))
            pl.close()
        except Exception as exc:  # no OpenGL context
            pytest.skip(f"pyvista cannot render off-screen here: {exc}")
    return name


def _classify(rgb, codes):
    """The material of each clearly coloured pixel (by chromaticity; -1 elsewhere): grey text,
    outlines and the white background stay unclassified."""
    flat = rgb.reshape(-1, 3)
    colourful = (flat.max(1) - flat.min(1)) > 40
    chroma = flat / np.maximum(flat.sum(1, keepdims=True), 1)
    ref = MATERIAL_COLOURS[codes] / MATERIAL_COLOURS[codes].sum(1, keepdims=True)
    nearest = np.argmin(((chroma[:, None, :] - ref[None]) ** 2).sum(2), axis=1)
    return np.where(colourful, np.asarray(codes)[nearest], -1)


def _sheet(n):
    """A flat n x n sheet coated in bands: top face only, bottom face only, and uncoated."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    top = (i < 0.3 * n) & (j % 40 < 30)
    bottom = (i >= 0.6 * n) & (j % 20 < 12)
    return gdfe.from_masks(top, bottom, pixel=0.1, R=0.8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_coat_colours_fill_their_share_of_a_large_sheet(tmp_path, backend):
    backend = _backend(backend, tmp_path)
    des = _sheet(316)
    assert des.n_cells == 316 * 316 > 30 * EDGE_CELLS
    png = render_png(des.mesh.points, tmp_path / "sheet.png", design=des, view="top", backend=backend,
                     title="flat sheet")
    rgb = _image(png)
    assert rgb.shape == (700, 1000, 3)
    codes = [1, 2, 3]  # bottom coated, top coated, uncoated: no cell is rigid
    seen = _classify(rgb, codes)
    counts = np.array([np.count_nonzero(seen == c) for c in codes])
    expected = np.array([np.count_nonzero(des.material == c) for c in codes]) / des.n_cells
    share = counts / counts.sum()
    np.testing.assert_allclose(share, expected, atol=0.01, err_msg=f"{backend}: shares {share} vs {expected}")
    # the sheet fills most of the picture's height: 10^5 cells in some 600 x 600 pixels
    assert counts.sum() > 0.45 * rgb.shape[0] * rgb.shape[1]
    # nothing is clipped: the picture's border is background
    border = np.concatenate([rgb[0], rgb[-1], rgb[:, 0], rgb[:, -1]])
    assert border.min() > 250, f"{backend}: something touches the picture's border"


def _dark_share(rgb):
    """Share of the sheet's pixels (not background) that are dark: cells' edges and outline."""
    flat = rgb.reshape(-1, 3)
    sheet = flat.min(1) < 245
    dark = flat.max(1) < 90
    return np.count_nonzero(dark & sheet) / np.count_nonzero(sheet)


@pytest.mark.parametrize("backend", BACKENDS)
def test_cell_edges_only_below_the_threshold(tmp_path, backend):
    backend = _backend(backend, tmp_path)
    small, large = _sheet(40), _sheet(80)  # 1 600 and 6 400 cells about EDGE_CELLS = 3 000
    assert small.n_cells <= EDGE_CELLS < large.n_cells
    shares = {}
    for name, des in (("small", small), ("large", large)):
        png = render_png(des.mesh.points, tmp_path / f"{name}.png", design=des, view="top", backend=backend,
                         title=name)
        shares[name] = _dark_share(_image(png))
    # 40 cells across some 600 pixels: an edge line every 15 pixels darkens several per cent
    assert shares["small"] > 0.04, shares
    # without edges only the rim and the words are dark
    assert shares["large"] < 0.02, shares


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_bent_shape_renders_with_its_title(tmp_path, backend):
    backend = _backend(backend, tmp_path)
    res = gdfe.simulate(gdfe.hinge(1.0, R=0.8)).check()
    png = render_png(res, tmp_path / "h.png", title=f"fold angle {gdfe.fold_angle(res):.3f} rad", backend=backend,
                     window_size=(640, 400))
    rgb = _image(png)
    assert rgb.shape == (400, 640, 3)
    # the contracting cells' colour shows (the rigid cells' grey has no hue to tell it by), and the
    # cells' edges are drawn: 384 cells, below EDGE_CELLS
    assert np.count_nonzero(_classify(rgb, [0, 1]) == 1) > 1000
    assert _dark_share(rgb) > 0.04


def test_render_checks_its_arguments(tmp_path):
    des = _sheet(4)
    with pytest.raises(ValueError, match="view: expected one of 'iso', 'top', 'front'"):
        render_png(des.mesh.points, tmp_path / "x.png", design=des, view="side")
    with pytest.raises(ValueError, match="backend: expected one of"):
        render_png(des.mesh.points, tmp_path / "x.png", design=des, backend="opengl")
    with pytest.raises(TypeError, match="design: needed"):
        render_png(des.mesh.points, tmp_path / "x.png")


def test_outline_of_one_cell_is_its_twelve_edges():
    des = gdfe.from_masks(np.ones((1, 1), bool), np.zeros((1, 1), bool), pixel=1.0, R=0.8)
    from gdfe.io import surface_faces

    faces, _ = surface_faces(des)
    edges, owners = outline_edges(des.mesh.points, faces)
    assert len(edges) == 12 and (owners >= 0).all()
    # a flat 3 x 3 sheet: no edge inside the top or bottom face is on the outline
    des = gdfe.from_masks(np.ones((3, 3), bool), np.zeros((3, 3), bool), pixel=1.0, R=0.8)
    faces, _ = surface_faces(des)
    edges, _ = outline_edges(des.mesh.points, faces)
    assert len(edges) == 4 * 3 * 2 + 4  # the rim at the top and at the bottom, and the four corners
