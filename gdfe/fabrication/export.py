"""Shapes out: the film's surface of any frame as STL, OBJ, PLY, and every frame as a FOLD file.

The surface is the boundary of the hexahedral film (:func:`gdfe.io.surface_faces`: top,
bottom and side faces), each quadrilateral split into two triangles along its 0-2
diagonal, oriented outwards, with only the vertices it uses. For a film whose cells touch
at least along a whole face this is a closed surface (every edge shared by exactly two
triangles); cells that meet only along an edge or at a corner make a non-manifold edge there.

- **STL** (binary, through meshio): triangles only; the format has no standard face
  attribute, so the material is not in it.
- **PLY** (ASCII, written here: meshio's PLY writer leaves face data out, and its reader
  misreads face properties after the vertex list of a binary file): per face the ``material``
  code (:class:`gdfe.Material`) and its colour (``red green blue``,
  :data:`gdfe.io.MATERIAL_COLOURS`). meshio reads both (``cell_data["material"]``); PyVista
  and other VTK readers keep the colours (cell data ``RGB``).
- **OBJ** (text) with a material library ``NAME.mtl`` beside it: faces grouped by
  ``usemtl rigid|contract_top|contract_bottom|free_shrink``, each with its colour.
- **FOLD** (JSON, the origami format): the surface's quadrilaterals with
  ``faces_gdfe:material``, every frame of the contraction ramp (frame 0 the flat print, then
  ``file_frames``), each frame's activation in ``frame_gdfe:activation``.

Every file is written to a temporary name and renamed when complete.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_choice
from gdfe.fabrication.surface import FilmSurface, film_surface, hex_surface

__all__ = ["FilmSurface", "film_surface", "hex_surface", "write_stl", "write_ply", "write_obj", "write_fold_frames",
           "write_shape", "export_result", "EXPORT_FORMATS"]

#: Formats of :func:`export_result` and ``gdfe simulate --export`` (html: :mod:`gdfe.fabrication.viewer`;
#: zip: the design's print package, :mod:`gdfe.fabrication.package`).
EXPORT_FORMATS = ("stl", "obj", "ply", "fold", "html", "zip")


def write_stl(path, surface):
    """Binary STL of the surface's triangles (through meshio)."""
    import meshio

    from gdfe.io import atomic_path

    mesh = meshio.Mesh(surface.vertices, [("triangle", surface.triangles)])
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="stl", binary=True)
    return Path(path)


def _colours(material):
    from gdfe.io import MATERIAL_COLOURS

    return np.round(MATERIAL_COLOURS[material] * 255).astype(np.uint8)


def write_ply(path, surface):
    """ASCII PLY: vertices [mm], triangles, and per face its ``material`` code and colour.

    meshio reads the material back as ``cell_data["material"]``, PyVista (VTK) the colour as
    cell data ``RGB``; both keep the vertices and triangles in the order written.
    """
    import io

    from gdfe.io import write_text

    v, t = np.asarray(surface.vertices, float), np.asarray(surface.triangles)
    mat = np.asarray(surface.triangle_material)
    header = "\n".join([
        "ply", "format ascii 1.0", "comment gdfe film surface [mm]; material: 0 rigid, "
        "1 contract_top, 2 contract_bottom, 3 free_shrink",
        f"element vertex {len(v)}", "property float x", "property float y", "property float z",
        f"element face {len(t)}", "property list uchar int vertex_indices", "property uchar material",
        "property uchar red", "property uchar green", "property uchar blue", "end_header", ""])
    body = io.StringIO()
    np.savetxt(body, v.astype(np.float32), fmt="%.9g")
    faces = np.column_stack([np.full(len(t), 3), t, mat, _colours(mat)]).astype(np.int64)
    np.savetxt(body, faces, fmt="%d")
    return write_text(path, header + body.getvalue())


def write_obj(path, surface):
    """Text OBJ with its material library ``NAME.mtl`` beside it (one ``usemtl`` group per material)."""
    from gdfe.design import Material
    from gdfe.io import write_text

    path = Path(path)
    mtl = path.with_suffix(".mtl")
    cols = _colours(np.arange(len(Material))) / 255.0
    lines = ["# gdfe film surface [mm]", f"mtllib {mtl.name}", f"o {path.stem}"]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in surface.vertices]
    mat = surface.triangle_material
    for m in Material:
        sel = surface.triangles[mat == int(m)]
        if len(sel):
            lines.append(f"usemtl {m.name.lower()}")
            lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in sel]
    mtl_lines = ["# gdfe materials"]
    for m in Material:
        r, g, b = cols[int(m)]
        mtl_lines += [f"newmtl {m.name.lower()}", f"Kd {r:.4f} {g:.4f} {b:.4f}", "Ka 0 0 0", "d 1", "illum 1", ""]
    write_text(mtl, "\n".join(mtl_lines))
    return write_text(path, "\n".join(lines) + "\n")


def write_fold_frames(path, result):
    """A FOLD file of a result's surface: frame 0 the flat print, the contraction ramp in ``file_frames``."""
    from gdfe._version import __version__
    from gdfe.design import Material
    from gdfe.io import json_default, write_text

    design = result.design
    surf = film_surface(design, result.frames[0])
    names = [Material(int(m)).name.lower() for m in surf.material]

    def coords(pts):
        return np.round(np.asarray(pts, float)[surf.point_index], 9).tolist()

    doc = {"file_spec": 1.1, "file_creator": f"gdfe {__version__}", "file_classes": ["animation"],
           "frame_title": "flat print", "frame_classes": ["foldedForm"], "frame_unit": "mm",
           "frame_gdfe:activation": float(result.activation[0]),
           "vertices_coords": coords(result.frames[0]), "faces_vertices": surf.quads.tolist(),
           "faces_gdfe:material": names,
           "file_frames": [{"frame_classes": ["foldedForm"], "frame_inherit": True, "frame_parent": 0,
                            "frame_title": f"activation {a:.4g}", "frame_gdfe:activation": float(a),
                            "vertices_coords": coords(p)}
                           for p, a in zip(result.frames[1:], result.activation[1:])]}
    return write_text(path, json.dumps(doc, default=json_default) + "\n")


def write_shape(path, design, points, fmt=None):
    """Write one shape of a design's film as STL, OBJ or PLY (format from ``fmt`` or the suffix)."""
    path = Path(path)
    fmt = check_choice("format", (fmt or path.suffix.lstrip(".")).lower(), ("stl", "obj", "ply"))
    surf = film_surface(design, points)
    return {"stl": write_stl, "obj": write_obj, "ply": write_ply}[fmt](path, surf)


def export_result(result, out_dir, name, formats, frame=-1):
    """Write a simulated shape in each of ``formats`` into ``out_dir`` as ``NAME.FORMAT``.

    Parameters
    ----------
    result : gdfe.Result
    out_dir : str or Path
    name : str
    formats : sequence of {"stl", "obj", "ply", "fold", "html", "zip"}
        ``fold`` writes every frame, ``html`` the interactive page of every frame
        (:func:`gdfe.fabrication.write_viewer`), ``zip`` the print package of the design
        (``NAME_print.zip``, :func:`gdfe.fabrication.write_print_package`); the others the
        frame ``frame``.
    frame : int
        Frame of the contraction ramp (``-1``: the fully contracted shape, ``0``: the flat print).

    Returns
    -------
    dict
        Format -> Path.
    """
    formats = [check_choice("export", f, EXPORT_FORMATS) for f in formats]
    nf = len(result.frames)
    if not isinstance(frame, (int, np.integer)) or not -nf <= frame < nf:
        raise GdfeError(f"frame: expected an integer in [{-nf}, {nf - 1}] (the result has {nf} frames), got {frame!r}")
    out_dir = Path(out_dir)
    paths = {}
    for fmt in formats:
        target = out_dir / f"{name}.{fmt}"
        if fmt == "fold":
            paths[fmt] = write_fold_frames(target, result)
        elif fmt == "zip":
            from gdfe.fabrication.package import write_print_package

            des = result.design
            paths[fmt] = write_print_package(out_dir / f"{name}_print.zip", {name: des}, d=des.meta.get("d_mm"),
                                             K=des.meta.get("K"), source=des.meta.get("source"))
        elif fmt == "html":
            from gdfe.fabrication.viewer import write_viewer

            paths[fmt] = write_viewer(target, result)
        else:
            paths[fmt] = write_shape(target, result.design, result.frames[frame], fmt)
    return paths
