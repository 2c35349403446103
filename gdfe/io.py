"""Output: VTU time series for ParaView, a PNG picture, JSON of the numbers.

meshio, pyvista and matplotlib are imported inside the functions that use them.
Every file is written to a temporary name and renamed when complete, so a failed
write leaves nothing half-written behind.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, GdfeTypeError, describe

__all__ = ["read_mesh", "write_vtu", "write_series", "render_png", "write_json", "write_text", "check_creatable",
           "surface_faces", "boundary_quads", "atomic_path", "json_default", "save_figure", "OutputFolder",
           "MATERIAL_CODES", "MANIFEST", "MARKER", "folder_state", "hex_meshio", "material_field_data",
           "outline_edges", "EDGE_CELLS", "MATERIAL_LABELS", "VIEWS"]

log = logging.getLogger(__name__)

#: Colours of the materials in pictures (RGB 0-1): rigid grey, contracting orange/blue, shrink green.
MATERIAL_COLOURS = np.array([[0.62, 0.62, 0.66], [0.95, 0.55, 0.15], [0.2, 0.5, 0.9], [0.3, 0.75, 0.4]])



def read_mesh(path, what=None):
    """``meshio.read(path)``, its failures (and what it prints) turned into one :class:`GdfeError`.

    meshio raises many kinds of error on a damaged file, and on some (a truncated VTU) prints a
    line and exits; either way the error names the file and says what it was expected to be
    (``what``, default the file's format, e.g. "a readable PLY file"). What meshio prints on a
    file it reads is logged as a warning.
    """
    import io

    import meshio

    path = Path(path)
    what = what or f"a readable {path.suffix[1:].upper()} file"
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            mesh = meshio.read(path)
    except (Exception, SystemExit) as exc:  # meshio raises many kinds, and exits on a corrupt file
        detail = " ".join(line.strip() for line in said.getvalue().splitlines() if line.strip())
        if not isinstance(exc, SystemExit):
            detail = " ".join(f"{detail} {type(exc).__name__}: {exc}".split())  # one line (meshio's span several)
        raise GdfeError(f"{path.name}: expected {what}, got one meshio cannot read"
                        + (f" ({detail})" if detail else "")) from None
    if said.getvalue().strip():
        log.warning("%s: meshio: %s", path.name, said.getvalue().strip())
    return mesh

def _not_a_file_name(path):
    """Why no file could be renamed onto ``path`` (``"an empty name"``, ``"a folder"``), or ``""``."""
    if not str(path).strip():
        return "an empty name"
    if str(path).strip() == "." or str(path).endswith(("/", os.sep)) or Path(path).is_dir():
        return "a folder"
    return ""


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; rename it to ``path`` only on success.

    Raises
    ------
    GdfeError
        ``path`` is empty or names a folder (no file could be renamed onto it).
    """
    if not isinstance(path, (str, os.PathLike)):
        raise GdfeTypeError(f"path: expected the name of a file to write, got {describe(path)}")
    problem = _not_a_file_name(path)
    if problem:
        raise GdfeError(f"{str(path) or repr('')}: expected the name of a file to write, got {problem}")
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent)
    except OSError as exc:  # a parent that is a file, no permission, a full disk
        raise GdfeError(f"{path}: cannot write there ({exc.strerror or exc})") from None
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


#: The ``material`` codes of the VTU files and what each means (written into every VTU as field data).
MATERIAL_CODES = {0: "rigid (both faces coated)", 1: "contract_top (bottom face coated, top free)",
                  2: "contract_bottom (top face coated, bottom free)", 3: "free_shrink (no coat)"}


def material_field_data():
    """The legend of the ``material`` codes as meshio ``field_data``: ``material_NAME`` -> ``[code]``.

    Returns
    -------
    dict
        ``{"material_rigid": array([0]), "material_contract_top": array([1]), ...}`` (int32 arrays).
    """
    from gdfe.material import Material

    return {f"material_{m.name.lower()}": np.array([int(m)], np.int32) for m in Material}


def _cell_data(design):
    return {"material": design.material.astype(np.int32), "R": design.R.astype(float),
            "layer": design.mesh.cell_k.astype(np.int32)}


def hex_meshio(points, design, point_data=None):
    """A meshio mesh of one shape of a design: the hexahedra, cell data ``material``, ``R`` and
    ``layer``, and the legend of the material codes as ``field_data`` (:func:`material_field_data`).

    Parameters
    ----------
    points : (n, 3) float array [mm]
    design : Design
    point_data : dict of (n, ...) arrays, optional
    """
    import meshio

    return meshio.Mesh(np.asarray(points, float), [("hexahedron", design.mesh.cells)],
                       cell_data={k: [v] for k, v in _cell_data(design).items()},
                       point_data=point_data or {}, field_data=material_field_data())


def _write_field_data(path, field_data):
    """Add a mesh's ``field_data`` to the VTU file at ``path`` as its grid's ``FieldData`` (meshio's
    VTU writer leaves field data out; its reader reads them back into ``Mesh.field_data``)."""
    import xml.etree.ElementTree as ET

    tree = ET.parse(path)
    grid = tree.getroot().find("UnstructuredGrid")
    if grid is None:  # not a file meshio's VTU writer wrote: nothing to add to
        raise GdfeError(f"{path}: expected a VTU file with an UnstructuredGrid, got none")
    block = ET.Element("FieldData")
    for name, value in field_data.items():
        value = np.atleast_1d(np.asarray(value))
        kind = "Int32" if np.issubdtype(value.dtype, np.integer) else "Float64"
        array = ET.SubElement(block, "DataArray", type=kind, Name=name, NumberOfTuples=str(value.size),
                              format="ascii")
        array.text = " ".join(str(v) for v in value.ravel().tolist())
    words = "; ".join(f"{k} = {v}" for k, v in MATERIAL_CODES.items())
    comment = ET.Comment(f"cell data 'material': {words}")
    comment.tail = block.tail = block.text = "\n"
    for array in block:
        array.tail = "\n"
    grid.insert(0, block)
    grid.insert(0, comment)
    tree.write(path, xml_declaration=True, encoding="utf-8")


def write_vtu(path, points, design, point_data=None):
    """Write one shape of a design as a VTU hexahedral mesh with the material map as cell data
    and the legend of its codes as field data (:func:`hex_meshio`)."""
    import meshio

    mesh = hex_meshio(points, design, point_data)
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
        _write_field_data(tmp, mesh.field_data)
    return Path(path)


def write_series(result, out_dir, name="shape", progress=False):
    """Write every frame of a result as ``NAME_###.vtu`` plus ``NAME.pvd``, which ParaView plays.

    The time of each frame is its activation, 0 (flat print) to 1 (fully contracted).
    Point data ``displacement`` [mm] is relative to the flat print; cell data ``material``
    (codes named in :data:`MATERIAL_CODES` and in each file's field data), ``R`` and ``layer``.
    ``progress``: a tqdm bar over the frames (True; None: only on a terminal).

    Returns
    -------
    Path
        The ``.pvd`` collection file.
    """
    out_dir = Path(out_dir)
    design = result.design
    entries = []
    frames = list(zip(result.frames, result.activation))
    if progress is not False and len(frames) > 1:
        from tqdm.auto import tqdm

        frames = tqdm(frames, desc=f"writing {name}", unit="frame", disable=None if progress is None else False,
                      leave=False)
    for k, (pts, act) in enumerate(frames):
        fname = f"{name}_{k:03d}.vtu"
        write_vtu(out_dir / fname, pts, design, {"displacement": pts - design.mesh.points})
        entries.append(f'    <DataSet timestep="{act:.6g}" group="" part="0" file="{fname}"/>')
    words = "; ".join(f"{k} = {v}" for k, v in MATERIAL_CODES.items())
    pvd = "\n".join(['<?xml version="1.0"?>', f"<!--cell data 'material': {words}-->",
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


#: Above this many cells a picture draws no cell edges: the cells are then a few pixels wide and
#: their edges would cover them in a dark moiré. Only the film's outline is drawn (its rim and its
#: creases, where the surface turns by more than :data:`FEATURE_ANGLE`).
EDGE_CELLS = 3000
#: Angle between two faces' normals above which their common edge is drawn as an outline [rad].
FEATURE_ANGLE = math.radians(30.0)
#: The legend of each material's colour in pictures (:data:`MATERIAL_COLOURS`).
MATERIAL_LABELS = {0: "both faces coated (rigid)", 1: "bottom face coated (bends up)",
                   2: "top face coated (bends down)", 3: "uncoated (shrinks in-plane)"}
#: Views of :func:`render_png`: azimuth and elevation of the direction towards the viewer [rad].
VIEWS = {"iso": (math.radians(-60.0), math.radians(30.0)), "top": (0.0, math.pi / 2), "front": (-math.pi / 2, 0.0)}
_EDGE_COLOUR = (0.2, 0.2, 0.22)


@dataclasses.dataclass(frozen=True)
class _Camera:
    """An orthographic camera: screen axes ``right``, ``up`` and ``back`` (towards the viewer),
    and the picture's window on the screen plane, ``(u0, u1, v0, v1)`` [mm]."""

    right: np.ndarray
    up: np.ndarray
    back: np.ndarray
    window: tuple

    @property
    def axes(self):
        """(3, 3) array whose columns are right, up, back: ``points @ axes`` are screen coordinates [mm]."""
        return np.column_stack([self.right, self.up, self.back])


def _camera(points, view, aspect, margin=0.04):
    """The camera of ``view`` framing ``points`` in a picture of width/height ``aspect``."""
    az, el = VIEWS[view]
    back = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    if abs(back[2]) > 0.999:  # looking along z: +y up the picture
        right, up = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
        back = np.array([0.0, 0.0, 1.0])
    else:
        right = np.cross([0.0, 0.0, 1.0], back)
        right /= np.linalg.norm(right)
        up = np.cross(back, right)
    uv = points @ np.column_stack([right, up])
    lo, hi = uv.min(0), uv.max(0)
    centre, size = (lo + hi) / 2, np.maximum(hi - lo, 1e-9) * (1 + 2 * margin)
    width = max(size[0], size[1] * aspect)
    height = width / aspect
    window = (centre[0] - width / 2, centre[0] + width / 2, centre[1] - height / 2, centre[1] + height / 2)
    return _Camera(right, up, back, tuple(float(w) for w in window))


def _nice_length(length):
    """The largest of 1, 2, 5 x 10^k not above ``length`` [mm]."""
    k = math.floor(math.log10(length))
    return max(m * 10.0 ** k for m in (1, 2, 5) if m * 10.0 ** k <= length * (1 + 1e-9))


def _quad_normals(points, faces):
    """Unit normals of quadrilaterals from their diagonals, (f, 3)."""
    q = points[faces]
    n = np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def outline_edges(points, faces, angle=FEATURE_ANGLE):
    """The outline of a surface of quadrilaterals: edges of one face only, and edges whose two
    faces' normals differ by more than ``angle``.

    Parameters
    ----------
    points : (n, 3) float array [mm]
    faces : (f, 4) int array
    angle : float [rad]

    Returns
    -------
    edges : (e, 2) int array
        Vertex indices of each outline edge.
    owners : (e, 2) int array
        The faces on either side (``-1`` where there is only one).
    """
    faces = np.asarray(faces)
    e = faces[:, [0, 1, 1, 2, 2, 3, 3, 0]].reshape(-1, 2)
    owner = np.repeat(np.arange(len(faces)), 4)
    key = np.sort(e, axis=1).astype(np.int64)
    code = key[:, 0] * (int(faces.max()) + 1 if faces.size else 1) + key[:, 1]
    order = np.argsort(code, kind="stable")
    code, key, owner = code[order], key[order], owner[order]
    first = np.ones(len(code), bool)
    first[1:] = code[1:] != code[:-1]
    start = np.nonzero(first)[0]
    count = np.diff(np.append(start, len(code)))
    other = np.where(count >= 2, owner[np.minimum(start + 1, len(code) - 1)], -1)
    a = owner[start]
    normals = _quad_normals(points, faces)
    cos = np.einsum("ij,ij->i", normals[a], normals[np.maximum(other, 0)])
    keep = (count != 2) | (cos < math.cos(angle))
    return key[start][keep], np.column_stack([a, other])[keep]


def render_png(result_or_points, path, design=None, title=None, window_size=(1000, 700), *, view="iso",
               edges=None, backend="auto"):
    """Render a shape to a PNG without a display: its faces coloured by material, with a legend
    of the materials shown, a scale bar [mm] and ``title``.

    The projection is orthographic, so the scale bar holds for lengths parallel to the picture.
    Designs of up to :data:`EDGE_CELLS` cells show their cells' edges; larger ones only their
    outline (:func:`outline_edges`), shaded smoothly.

    Parameters
    ----------
    result_or_points : Result or (n, 3) float array [mm]
    path : str or Path
    design : Design, optional
        Needed with an array of points.
    title : str, optional
        The headline, e.g. the fold angle; default the shape's bounding box [mm].
    window_size : (2,) int
        Width and height of the picture [pixels].
    view : {"iso", "top", "front"}
        Direction of view (:data:`VIEWS`); ``top`` looks down the z axis.
    edges : bool, optional
        Draw the cells' edges (default: when the design has at most :data:`EDGE_CELLS` cells).
    backend : {"auto", "pyvista", "matplotlib"}
        ``auto``: PyVista off-screen, or matplotlib when PyVista or its OpenGL context is missing.

    Returns
    -------
    Path
    """
    from gdfe._validation import check_choice

    view = check_choice("view", view, tuple(VIEWS))
    backend = check_choice("backend", backend, ("auto", "pyvista", "matplotlib"))
    if hasattr(result_or_points, "design"):
        points, design = result_or_points.points, result_or_points.design
    else:
        points = np.asarray(result_or_points, float)
        if design is None:
            raise GdfeTypeError("design: needed when rendering an array of points")
    faces, owner = surface_faces(design)
    material = design.material[owner]
    colours = (MATERIAL_COLOURS[material] * 255).astype(np.uint8)
    legend = [(MATERIAL_LABELS[int(m)], tuple(MATERIAL_COLOURS[int(m)])) for m in np.unique(design.material)]
    if edges is None:
        edges = design.n_cells <= EDGE_CELLS
    if title is None:
        size = points.max(0) - points.min(0)
        title = f"{design.n_cells} cells, bounding box {size[0]:.3g} x {size[1]:.3g} x {size[2]:.3g} mm"
    opts = {"legend": legend, "edges": bool(edges), "view": view}
    path = Path(path)
    if backend in ("auto", "pyvista"):
        try:
            _render_pyvista(points, faces, colours, path, title, window_size, **opts)
            log.info("%s: rendered with pyvista", path)
            return path
        except Exception as exc:  # no pyvista or no OpenGL context: draw with matplotlib instead
            if backend == "pyvista":
                raise
            log.info("pyvista rendering unavailable (%s); using matplotlib", exc)
    _render_matplotlib(points, faces, colours, path, title, window_size, **opts)
    log.info("%s: rendered with matplotlib", path)
    return path


def _render_pyvista(points, faces, colours, path, title, window_size, **opts):
    """The picture of :func:`render_png` with the film drawn by PyVista (VTK) off-screen."""
    import pyvista  # noqa: F401  (fail here, before any figure, when PyVista is missing)

    _picture(points, faces, colours, path, title, window_size, scene=_pyvista_scene, **opts)


def _render_matplotlib(points, faces, colours, path, title, window_size, **opts):
    """The picture of :func:`render_png` with the film drawn by matplotlib (painter's algorithm)."""
    _picture(points, faces, colours, path, title, window_size, scene=_matplotlib_scene, **opts)


def _picture(points, faces, colours, path, title, window_size, *, scene, legend=(), edges=False, view="iso"):
    """Lay out title, film, scale bar and legend in one figure; ``scene`` draws the film into its axes."""
    import textwrap

    from matplotlib.patches import Patch
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    from gdfe._plotting import pyplot

    plt = pyplot()
    points = np.asarray(points, float)
    faces = np.asarray(faces)
    colours = np.asarray(colours)
    w, h = (int(v) for v in window_size)
    fig = plt.figure(figsize=(w / 100, h / 100), dpi=100, layout="constrained")
    try:
        ax = fig.add_subplot()
        ax.set_axis_off()
        if title:
            fig.suptitle("\n".join(textwrap.wrap(str(title), max(30, w // 9))), fontsize=12)
        if legend:
            fig.legend(handles=[Patch(facecolor=c, edgecolor="0.3", label=t) for t, c in legend],
                       loc="outside right center", fontsize=9, frameon=False, title="material")
        # the scale bar: about a fifth of the film's extent across the picture
        u0, u1, v0, v1 = _camera(points, view, w / h).window
        ax.set(xlim=(u0, u1), ylim=(v0, v1))
        uv = points @ _camera(points, view, 1.0).axes[:, :2]
        bar = _nice_length(max(float(np.ptp(uv[:, 0])), float(np.ptp(uv[:, 1])), 1e-6) / 5)
        ax.add_artist(AnchoredSizeBar(ax.transData, bar, f"{bar:g} mm", loc="upper left", bbox_to_anchor=(0, 0),
                                      bbox_transform=ax.transAxes, frameon=False, size_vertical=0, pad=0.2,
                                      sep=4, fontproperties={"size": 10}))
        fig.canvas.draw()  # settle the layout, then draw the film at the axes' final size in pixels
        fig.set_layout_engine("none")
        box = ax.get_window_extent()
        px = (max(int(round(box.width)), 16), max(int(round(box.height)), 16))
        cam = _camera(points, view, px[0] / px[1])
        scene(ax, points, faces, colours, cam, px, edges)
        u0, u1, v0, v1 = cam.window
        ax.set(xlim=(u0, u1), ylim=(v0, v1), aspect="equal")
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png", dpi=100)
    finally:
        plt.close(fig)
    return Path(path)


def _pyvista_scene(ax, points, faces, colours, cam, px, edges):
    """Render the film with PyVista at ``px`` pixels through ``cam`` and show it in ``ax``."""
    import pyvista as pv

    with contextlib.suppress(Exception):  # VTK warns on stderr when there is no X display
        import vtk

        vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)
    surf = pv.PolyData(points, np.hstack([np.full((len(faces), 1), 4), faces]).ravel())
    surf.cell_data["colour"] = colours
    pl = pv.Plotter(off_screen=True, window_size=list(px))
    try:
        pl.set_background("white")
        if edges:
            pl.add_mesh(surf, scalars="colour", rgb=True, show_edges=True, edge_color=_EDGE_COLOUR, line_width=0.5)
        else:
            pl.add_mesh(surf, scalars="colour", rgb=True, smooth_shading=True, split_sharp_edges=True,
                        feature_angle=math.degrees(FEATURE_ANGLE))
            lines, _ = outline_edges(points, faces)
            if len(lines):
                # lifted towards the viewer by a hair, so that the faces along them do not hide them
                lift = 1e-3 * float(np.ptp(points, axis=0).max()) * cam.back
                outline = pv.PolyData(points + lift, lines=np.hstack([np.full((len(lines), 1), 2), lines]).ravel())
                pl.add_mesh(outline, color=_EDGE_COLOUR, line_width=1.0)
        u0, u1, v0, v1 = cam.window
        depth = points @ cam.back
        span = float(np.ptp(depth)) + (u1 - u0) + (v1 - v0)
        focal = (u0 + u1) / 2 * cam.right + (v0 + v1) / 2 * cam.up + float(depth.mean()) * cam.back
        pl.camera.focal_point = tuple(focal)
        pl.camera.position = tuple(focal + 2 * span * cam.back)
        pl.camera.up = tuple(cam.up)
        pl.enable_parallel_projection()
        pl.camera.parallel_scale = (v1 - v0) / 2
        pl.reset_camera_clipping_range()
        image = pl.screenshot(return_img=True)
    finally:
        pl.close()
    ax.imshow(image, extent=cam.window, interpolation="none", origin="upper")


def _matplotlib_scene(ax, points, faces, colours, cam, px, edges, slabs=16):
    """Draw the film into ``ax`` in screen coordinates [mm]: the faces turned towards the viewer,
    farthest first, shaded by a light over the viewer's shoulder; the outline (or every edge)
    drawn in depth slabs between them so that nearer faces hide it."""
    from matplotlib.collections import LineCollection, PolyCollection

    screen = points @ cam.axes
    normals = _quad_normals(points, faces)
    front = normals @ cam.back > 1e-9
    light = cam.back + 0.5 * cam.up + 0.3 * cam.right
    light /= np.linalg.norm(light)
    shade = 0.45 + 0.55 * np.clip(normals @ light, 0.0, 1.0)
    rgb = np.clip(np.asarray(colours, float) / 255.0 * shade[:, None], 0, 1)
    if edges:
        lines = faces[front][:, [0, 1, 1, 2, 2, 3, 3, 0]].reshape(-1, 2)
    else:
        lines, owners = outline_edges(points, faces)
        seen = front[owners[:, 0]] | ((owners[:, 1] >= 0) & front[np.maximum(owners[:, 1], 0)])
        lines = lines[seen]
    ids = np.nonzero(front)[0]
    depth = screen[faces[ids], 2].mean(1)
    ids = ids[np.argsort(depth, kind="stable")]
    depth = np.sort(depth)
    line_depth = screen[lines, 2].max(1) if len(lines) else np.zeros(0)
    lo, hi = (float(depth.min()), float(depth.max())) if len(depth) else (0.0, 1.0)
    bounds = np.linspace(lo, hi, slabs + 1)[1:-1]
    face_slab = np.searchsorted(bounds, depth, side="right")
    line_slab = np.searchsorted(bounds, line_depth, side="right")
    for k in range(slabs):
        sel = ids[face_slab == k]
        if len(sel):
            # each face's edge in its own colour closes the hairline seams antialiasing leaves
            ax.add_collection(PolyCollection(screen[faces[sel], :2], facecolors=rgb[sel],
                                             edgecolors=rgb[sel], linewidths=0.3, zorder=2 * k))
        seg = lines[line_slab == k]
        if len(seg):
            ax.add_collection(LineCollection(screen[seg, :2], colors=[_EDGE_COLOUR],
                                             linewidths=0.4 if edges else 0.9, zorder=2 * k + 1))


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


def check_creatable(path, name, what="folder"):
    """Refuse now a ``path`` that could not be written later (:class:`GdfeError` naming ``name``, the option
    or argument): its nearest existing folder is a file, or one this process may not write in; with
    ``what="file"``, also a path no file could be renamed onto (:func:`atomic_path`'s test)."""
    problem = _not_a_file_name(path) if what == "file" else ""
    if problem:
        raise GdfeError(f"{name}: expected the name of a file to write, got {problem} ({str(path)!r})")
    parent = Path(path).absolute().parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise GdfeError(f"{name}: cannot create the {what} {path}: {parent} is a file")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise GdfeError(f"{name}: cannot create the {what} {path}: no permission to write in {parent}")
    return Path(path)


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


def finite_json(obj):
    """``obj`` made JSON-ready: numpy scalars and arrays converted, non-finite floats as None
    (JSON has no NaN or infinity)."""
    obj = json.loads(json.dumps(obj, default=json_default))
    return _finite(obj)


def _finite(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite(v) for v in obj]
    return obj


def write_json(path, obj):
    """Write ``obj`` as indented JSON (:func:`finite_json`: numpy converted, NaN and infinity as null)."""
    return write_text(path, json.dumps(finite_json(obj), indent=2) + "\n")


#: The file an :class:`OutputFolder` writes last, listing every file of a complete output.
MANIFEST = "gdfe-manifest.json"
#: The file an :class:`OutputFolder` writes first and removes when complete: its presence marks
#: the folder as incomplete (a run still writing it, stopped or killed).
MARKER = "INCOMPLETE.txt"


def folder_state(path):
    """``"missing"``, ``"empty"``, ``"complete"`` (a manifest), ``"incomplete"`` (the marker) or ``"foreign"``."""
    path = Path(path)
    if not path.exists():
        return "missing"
    if not path.is_dir():
        return "file"
    if (path / MARKER).exists():
        return "incomplete"
    if (path / MANIFEST).exists():
        return "complete"
    return "empty" if not any(path.iterdir()) else "foreign"


def _alive(pid):
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True
    return True


class OutputFolder:
    """A folder of results that is either complete or marked incomplete, and replaced as a whole.

    ``with OutputFolder(path, command="gdfe hinge ...") as out:`` checks ``path`` before any
    work (it must not be a file, and an existing folder must be empty or one that gdfe wrote:
    with a :data:`MANIFEST` or a :data:`MARKER`), empties a previous output there (a rerun
    replaces, never mixes), and writes the marker :data:`MARKER` naming the command. Leaving
    the block normally writes the manifest last (every file with its size and SHA-256, and
    :attr:`status`) and removes the marker. On an error, Ctrl-C or a kill the marker stays
    (saying how the run ended where it can): a folder with ``INCOMPLETE.txt`` is incomplete.

    Parameters
    ----------
    path : str or Path
    command : str, optional
        The command line that writes it (recorded in the marker and the manifest).
    name : str
        The option's name in messages (``--out``).

    Attributes
    ----------
    status : dict
        Entries added to the manifest (e.g. ``converged``).
    left : str or None
        After a failure: what the folder holds, in words (``path``: N files, marked incomplete).
    """

    def __init__(self, path, command=None, name="--out"):
        if path is None or isinstance(path, bool) or not isinstance(path, (str, Path)) or str(path).strip() == "":
            raise GdfeTypeError(f"{name}: expected the name of a folder, got {path!r}")
        self.path = Path(path)
        self.command = command
        self.name = name
        self.status = {}
        self.left = None
        self.check()

    def check(self):
        """Refuse a path that is a file, or a folder with files gdfe did not write, or one being written."""
        state = folder_state(self.path)
        if state == "file":
            raise GdfeError(f"{self.name}: expected a folder, got the file {self.path}")
        if state == "missing":  # made when the command writes: its nearest existing folder must allow it
            check_creatable(self.path, self.name)
        if state == "foreign":
            raise GdfeError(f"{self.name}: {self.path} is a folder with files that gdfe did not write (no {MANIFEST}); "
                            f"gdfe replaces only its own output folders: give a new or empty folder")
        if state == "incomplete":
            info = _read_marker(self.path / MARKER)
            if info.get("host") == _host() and info.get("pid") not in (None, os.getpid()) and _alive(info["pid"]):
                raise GdfeError(f"{self.name}: {self.path} is being written by another gdfe run (process "
                                f"{info['pid']}: {info.get('command', '?')})")
        return state

    def __enter__(self):
        import shutil

        state = self.check()
        if state in ("complete", "incomplete"):  # a previous output of gdfe: replaced as a whole
            for child in self.path.iterdir():
                if child.is_dir() and not child.is_symlink():
                    shutil.rmtree(child)
                else:
                    child.unlink()
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            self._write_marker("running")
        except OSError as exc:
            raise GdfeError(f"{self.name}: cannot create the folder {self.path}: {exc.strerror or exc}") from None
        return self

    def _write_marker(self, how, detail=""):
        import datetime

        lines = [f"This folder is incomplete: {how}.", "",
                 f"command: {self.command or '?'}", f"pid: {os.getpid()}", f"host: {_host()}",
                 f"time: {datetime.datetime.now().isoformat(timespec='seconds')}"]
        if detail:
            lines += ["", detail]
        write_text(self.path / MARKER, "\n".join(lines) + "\n")

    def files(self):
        """The files written so far, relative to the folder (the marker and manifest left out)."""
        return sorted(str(p.relative_to(self.path)) for p in self.path.rglob("*")
                      if p.is_file() and p.name not in (MARKER, MANIFEST) and not p.name.startswith("."))

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self._finish()
            return False
        files = self.files()
        how = ("stopped by Ctrl-C" if issubclass(exc_type, KeyboardInterrupt)
               else f"stopped by an error ({exc_type.__name__}: {exc})")
        try:
            if not files:  # nothing written: leave no folder behind
                (self.path / MARKER).unlink()
                if not any(self.path.iterdir()):
                    self.path.rmdir()
                self.left = f"nothing was written to {self.path}"
            else:
                self._write_marker(how, f"{len(files)} files were written before it stopped.")
                self.left = (f"{self.path} holds the {len(files)} files written so far and is marked incomplete "
                             f"({MARKER}); rerun to replace it")
        except OSError:  # pragma: no cover - the folder went away under us
            self.left = f"{self.path} may be incomplete"
        return False

    def _finish(self):
        import datetime
        import hashlib

        from gdfe._version import __version__

        entries = {}
        for rel in self.files():
            h = hashlib.sha256()
            with open(self.path / rel, "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):
                    h.update(block)
            entries[rel] = {"bytes": (self.path / rel).stat().st_size, "sha256": h.hexdigest()}
        manifest = {"complete": True, "gdfe": __version__, "command": self.command,
                    "time": datetime.datetime.now().isoformat(timespec="seconds"), **self.status, "files": entries}
        write_json(self.path / MANIFEST, manifest)
        (self.path / MARKER).unlink()


def _host():
    import socket

    return socket.gethostname()


def _read_marker(path):
    info = {}
    try:
        for line in Path(path).read_text(errors="replace").splitlines():
            key, sep, value = line.partition(": ")
            if sep and key in ("command", "pid", "host", "time"):
                info[key] = int(value) if key == "pid" and value.strip().isdigit() else value
    except OSError:
        pass
    return info
