"""Output: VTU time series for ParaView, a PNG picture, JSON of the numbers.

meshio, pyvista and matplotlib are imported inside the functions that use them.
Every file is written to a temporary name and renamed when complete, so a failed
write leaves nothing half-written behind.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeTypeError

__all__ = ["write_vtu", "write_series", "render_png", "write_json", "write_text", "surface_faces", "boundary_quads",
           "atomic_path",
           "json_default", "save_figure"]

log = logging.getLogger(__name__)

#: Colours of the materials in pictures (RGB 0-1): rigid grey, contracting orange/blue, shrink green.
MATERIAL_COLOURS = np.array([[0.62, 0.62, 0.66], [0.95, 0.55, 0.15], [0.2, 0.5, 0.9], [0.3, 0.75, 0.4]])


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; rename it to ``path`` only on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes files private; outputs are not
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def _cell_data(design):
    return {"material": design.material.astype(np.int32), "R": design.R.astype(float),
            "layer": design.mesh.cell_k.astype(np.int32)}


def write_vtu(path, points, design, point_data=None):
    """Write one shape of a design as a VTU hexahedral mesh with the material map as cell data."""
    import meshio

    mesh = meshio.Mesh(np.asarray(points, float), [("hexahedron", design.mesh.cells)],
                       cell_data={k: [v] for k, v in _cell_data(design).items()},
                       point_data=point_data or {})
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    return Path(path)


def write_series(result, out_dir, name="shape"):
    """Write every frame of a result as ``NAME_###.vtu`` plus ``NAME.pvd``, which ParaView plays.

    The time of each frame is its activation, 0 (flat print) to 1 (fully contracted).
    Point data ``displacement`` [mm] is relative to the flat print.

    Returns
    -------
    Path
        The ``.pvd`` collection file.
    """
    out_dir = Path(out_dir)
    design = result.design
    entries = []
    for k, (pts, act) in enumerate(zip(result.frames, result.activation)):
        fname = f"{name}_{k:03d}.vtu"
        write_vtu(out_dir / fname, pts, design, {"displacement": pts - design.mesh.points})
        entries.append(f'    <DataSet timestep="{act:.6g}" group="" part="0" file="{fname}"/>')
    pvd = "\n".join(['<?xml version="1.0"?>',
                     '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                     "  <Collection>", *entries, "  </Collection>", "</VTKFile>", ""])
    return write_text(out_dir / f"{name}.pvd", pvd)


def surface_faces(design):
    """Boundary quadrilaterals of the hex mesh and the cell each belongs to.

    Returns
    -------
    faces : (f, 4) int array
    owner : (f,) int array
    """
    return boundary_quads(design.mesh.cells)


def boundary_quads(cells):
    """Boundary quadrilaterals of a hexahedral mesh (VTK vertex order), oriented outwards.

    Parameters
    ----------
    cells : (m, 8) int array

    Returns
    -------
    faces : (f, 4) int array
    owner : (f,) int array
        The cell each face belongs to.
    """
    local = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
    cells = np.asarray(cells)
    faces = cells[:, local].reshape(-1, 4)
    # a face is on the boundary when no other cell has the same four vertices: sort the
    # faces by their sorted vertices (two int64 keys) and drop those equal to a neighbour
    key = np.sort(faces, axis=1).astype(np.int64)
    n = int(cells.max()) + 1 if cells.size else 1
    k1, k2 = key[:, 0] * n + key[:, 1], key[:, 2] * n + key[:, 3]
    order = np.lexsort((k2, k1))
    a1, a2 = k1[order], k2[order]
    same = (a1[1:] == a1[:-1]) & (a2[1:] == a2[:-1])
    shared = np.zeros(order.size, bool)
    shared[1:] |= same
    shared[:-1] |= same
    boundary = np.empty(order.size, bool)
    boundary[order] = ~shared
    owner = np.repeat(np.arange(cells.shape[0]), 6)
    return faces[boundary], owner[boundary]


def render_png(result_or_points, path, design=None, title=None, window_size=(1000, 700)):
    """Render a shape to a PNG, coloured by material, without a display.

    Uses PyVista off-screen; if PyVista or its OpenGL context is not available, falls
    back to matplotlib's 3-D axes.
    """
    if hasattr(result_or_points, "design"):
        points, design = result_or_points.points, result_or_points.design
    else:
        points = np.asarray(result_or_points, float)
        if design is None:
            raise GdfeTypeError("design: needed when rendering an array of points")
    faces, owner = surface_faces(design)
    colours = (MATERIAL_COLOURS[design.material[owner]] * 255).astype(np.uint8)
    path = Path(path)
    try:
        _render_pyvista(points, faces, colours, path, title, window_size)
    except Exception as exc:  # no OpenGL context: draw with matplotlib instead
        log.info("pyvista rendering unavailable (%s); using matplotlib", exc)
        _render_matplotlib(points, faces, colours, path, title, window_size)
    return path


def _render_pyvista(points, faces, colours, path, title, window_size):
    import pyvista as pv

    with contextlib.suppress(Exception):  # VTK warns on stderr when there is no X display
        import vtk

        vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)
    cells = np.hstack([np.full((len(faces), 1), 4), faces]).ravel()
    surf = pv.PolyData(points, cells)
    surf.cell_data["colour"] = colours
    pl = pv.Plotter(off_screen=True, window_size=list(window_size))
    pl.set_background("white")
    pl.add_mesh(surf, scalars="colour", rgb=True, show_edges=True, edge_color=(0.3, 0.3, 0.3),
                line_width=0.5)
    if title:
        pl.add_text(title, font_size=10, color="black")
    pl.view_isometric()
    pl.camera.elevation = -10
    pl.reset_camera()
    with atomic_path(path) as tmp:
        pl.screenshot(str(tmp))
    pl.close()


def _render_matplotlib(points, faces, colours, path, title, window_size):
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from gdfe._plotting import pyplot

    plt = pyplot()

    fig = plt.figure(figsize=(window_size[0] / 100, window_size[1] / 100), dpi=100)
    ax = fig.add_subplot(projection="3d")
    ax.add_collection3d(Poly3DCollection(points[faces], facecolors=colours / 255.0,
                                         edgecolors=(0.3, 0.3, 0.3, 0.3), linewidths=0.2))
    lo, hi = points.min(0), points.max(0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set(xlim=(c[0] - r, c[0] + r), ylim=(c[1] - r, c[1] + r), zlim=(c[2] - r, c[2] + r),
           xlabel="x [mm]", ylabel="y [mm]", zlabel="z [mm]")
    if title:
        ax.set_title(title)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)


def save_figure(fig, path, **kwargs):
    """Save a matplotlib figure to ``path`` (renamed into place when complete) and close it."""
    from gdfe._plotting import pyplot

    path = Path(path)
    fmt = kwargs.pop("format", path.suffix.lstrip(".") or "png")
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, **kwargs)
    finally:
        pyplot().close(fig)
    return path


def write_text(path, text):
    """Write ``text`` to ``path`` (renamed into place when complete)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def json_default(o):
    """``json.dumps``'s ``default``: numpy scalars and arrays as Python numbers and lists."""
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def write_json(path, obj):
    """Write ``obj`` as indented JSON (numpy scalars and arrays converted)."""
    return write_text(path, json.dumps(obj, indent=2, default=json_default) + "\n")
