"""Files other tools read: the PLY surface, the VTU series and a result's meshio/PyVista meshes,
each read back with meshio and PyVista, the material of every face or cell included."""

from __future__ import annotations

import numpy as np
import pytest

import gdfe
from gdfe.io import MATERIAL_COLOURS, material_field_data

meshio = pytest.importorskip("meshio")

LEGEND = {"material_rigid": 0, "material_contract_top": 1, "material_contract_bottom": 2, "material_free_shrink": 3}


@pytest.fixture(scope="module")
def result():
    """Every material in a small strip, simulated in two frames."""
    return gdfe.simulate(gdfe.from_rows(["RTBS", "RTBS"], R=0.8), steps=2).check()


def test_ply_reads_back_with_meshio_and_pyvista(tmp_path, result):
    from gdfe.fabrication import film_surface, write_shape

    surf = film_surface(result.design, result.points)
    path = write_shape(tmp_path / "s.ply", result.design, result.points)
    m = meshio.read(path)
    assert [c.type for c in m.cells] == ["triangle"]
    np.testing.assert_array_equal(m.cells[0].data, surf.triangles)
    np.testing.assert_allclose(m.points, surf.vertices, atol=1e-6)
    np.testing.assert_array_equal(m.cell_data["material"][0], surf.triangle_material)
    assert set(m.cell_data["material"][0].tolist()) == {0, 1, 2, 3}

    pv = pytest.importorskip("pyvista")
    g = pv.read(path)
    assert g.n_points == len(surf.vertices) and g.n_cells == len(surf.triangles)
    np.testing.assert_array_equal(g.faces.reshape(-1, 4)[:, 1:], surf.triangles)
    # PyVista (VTK's PLY reader) keeps the faces' colours: each is one material's
    palette = np.round(MATERIAL_COLOURS * 255).astype(int)
    rgb = np.asarray(g.cell_data["RGB"], int)
    material = np.argmin(np.abs(rgb[:, None, :] - palette[None]).sum(2), axis=1)
    np.testing.assert_array_equal(material, surf.triangle_material)


def test_ply_reads_back_with_trimesh(tmp_path, result):
    trimesh = pytest.importorskip("trimesh")
    from gdfe.fabrication import film_surface, write_shape

    surf = film_surface(result.design, result.points)
    mesh = trimesh.load(write_shape(tmp_path / "s.ply", result.design, result.points), process=False)
    assert len(mesh.vertices) == len(surf.vertices) and len(mesh.faces) == len(surf.triangles)
    assert mesh.is_watertight


def test_result_to_meshio(result):
    m = result.to_meshio()
    des = result.design
    np.testing.assert_array_equal(m.points, result.points)
    np.testing.assert_array_equal(m.cells_dict["hexahedron"], des.mesh.cells)
    np.testing.assert_array_equal(m.cell_data["material"][0], des.material)
    np.testing.assert_allclose(m.point_data["displacement"], result.points - des.mesh.points)
    assert {k: int(v[0]) for k, v in m.field_data.items()} == LEGEND
    flat = result.to_meshio(frame=0)
    np.testing.assert_array_equal(flat.points, des.mesh.points)
    with pytest.raises(ValueError, match=r"frame: expected an integer in \[-3, 2\]"):
        result.to_meshio(frame=3)


def test_result_to_pyvista(result):
    pv = pytest.importorskip("pyvista")
    g = result.to_pyvista()
    assert isinstance(g, pv.UnstructuredGrid)
    assert g.n_cells == result.design.n_cells and g.n_points == result.design.mesh.n_points
    np.testing.assert_allclose(g.points, result.points)
    np.testing.assert_array_equal(g.cell_data["material"], result.design.material)
    assert {k: int(g.field_data[k][0]) for k in g.field_data.keys()} == LEGEND
    assert set(np.asarray(g.celltypes).tolist()) == {pv.CellType.HEXAHEDRON}


def test_vtu_legend_is_field_data(tmp_path, result):
    from gdfe.fabrication import read_series
    from gdfe.io import write_series

    assert {k: int(v[0]) for k, v in material_field_data().items()} == LEGEND
    pvd = write_series(result, tmp_path, "s")
    m = meshio.read(tmp_path / "s_002.vtu")
    assert {k: int(v[0]) for k, v in m.field_data.items()} == LEGEND
    np.testing.assert_array_equal(m.cell_data["material"][0], result.design.material)
    np.testing.assert_allclose(m.points, result.points)
    # the legend's words stay in the file for a human reader
    assert "0 = rigid (both faces coated)" in (tmp_path / "s_002.vtu").read_text()
    pv = pytest.importorskip("pyvista")
    g = pv.read(tmp_path / "s_002.vtu")
    assert {k: int(g.field_data[k][0]) for k in g.field_data.keys()} == LEGEND
    # and the series reads back as the viewer's frames, the material of every face with it
    from gdfe.fabrication import film_surface

    series = read_series(pvd)
    surf = film_surface(result.design, result.points)
    assert len(series.frames) == 3
    np.testing.assert_allclose(series.frames[-1], result.points[surf.point_index])
    np.testing.assert_array_equal(series.material, surf.material)
