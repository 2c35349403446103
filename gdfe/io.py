"""Output: VTU time series for ParaView, a PNG picture, JSON of the numbers.

meshio, pyvista and matplotlib are imported inside the functions that use them.
Every file is written to a temporary name and renamed when complete, so a failed
write leaves nothing half-written behind.
"""

from __future__ import annotations

import contextlib
import json
import math
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, GdfeTypeError, describe

__all__ = ["write_vtu", "write_series", "render_png", "write_json", "write_text", "surface_faces", "boundary_quads",
           "atomic_path", "json_default", "save_figure", "OutputFolder", "MATERIAL_CODES", "MANIFEST", "MARKER",
           "folder_state"]

log = logging.getLogger(__name__)

#: Colours of the materials in pictures (RGB 0-1): rigid grey, contracting orange/blue, shrink green.
MATERIAL_COLOURS = np.array([[0.62, 0.62, 0.66], [0.95, 0.55, 0.15], [0.2, 0.5, 0.9], [0.3, 0.75, 0.4]])


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
    if str(path).strip() in ("", ".") or str(path).endswith(("/", os.sep)) or Path(path).is_dir():
        raise GdfeError(f"{str(path) or repr('')}: expected the name of a file to write, got "
                        f"{'a folder' if str(path).strip() else 'an empty name'}")
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


def _material_legend():
    """The VTU ``FieldData`` block naming the ``material`` codes (meshio writes no field data to VTU)."""
    from gdfe.material import Material

    arrays = "".join(f'<DataArray type="Int32" Name="material_{m.name.lower()}" NumberOfTuples="1" '
                     f'format="ascii">{int(m)}</DataArray>\n' for m in Material)
    words = "; ".join(f"{k} = {v}" for k, v in MATERIAL_CODES.items())
    return f"<!--cell data 'material': {words}-->\n<FieldData>\n{arrays}</FieldData>\n"


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
        text = tmp.read_text()
        tmp.write_text(text.replace("<UnstructuredGrid>\n", "<UnstructuredGrid>\n" + _material_legend(), 1))
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
            parent = self.path.absolute().parent
            while not parent.exists() and parent != parent.parent:
                parent = parent.parent
            if not parent.is_dir():
                raise GdfeError(f"{self.name}: cannot create the folder {self.path}: {parent} is a file")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise GdfeError(f"{self.name}: cannot create the folder {self.path}: no permission to write in "
                                f"{parent}")
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
