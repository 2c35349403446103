"""The film's boundary surface in a shape: the quadrilaterals and triangles that the exports and the viewer draw.

The surface is the boundary of the hexahedral film (:func:`gdfe.io.boundary_quads`: top,
bottom and side faces, oriented outwards), each quadrilateral split into two triangles along
its 0-2 diagonal, with only the vertices it uses.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gdfe._validation import check_array

__all__ = ["FilmSurface", "film_surface", "hex_surface"]


@dataclasses.dataclass
class FilmSurface:
    """A film's boundary surface in one shape.

    Attributes
    ----------
    vertices : (v, 3) float array [mm]
    triangles : (t, 3) int array
        Outward-oriented triangles (two per quadrilateral, in order).
    quads : (q, 4) int array
        The boundary quadrilaterals (``triangles`` are ``quads[:, [0, 1, 2]]`` and ``[0, 2, 3]``).
    material : (q,) int array
        :class:`gdfe.Material` of the cell each quadrilateral belongs to.
    point_index : (v,) int array
        Index of each vertex in the design's mesh.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    quads: np.ndarray
    material: np.ndarray
    point_index: np.ndarray

    @property
    def triangle_material(self):
        """(t,) int array: material of each triangle."""
        return np.repeat(self.material, 2)


def film_surface(design, points=None):
    """The boundary surface of a design's film in a shape.

    Parameters
    ----------
    design : Design
    points : (n, 3) float array [mm], optional
        Vertex positions (default: the flat print).

    Returns
    -------
    FilmSurface
    """
    n = design.mesh.n_points
    P = design.mesh.points if points is None else check_array("points", points, shape=(n, 3))
    return hex_surface(P, design.mesh.cells, design.material)


def hex_surface(points, cells, material):
    """The boundary surface of a hexahedral mesh (VTK vertex order) with a material per cell.

    Parameters
    ----------
    points : (n, 3) float array [mm]
    cells : (m, 8) int array
    material : (m,) int array

    Returns
    -------
    FilmSurface
    """
    from gdfe.io import boundary_quads

    faces, owner = boundary_quads(cells)
    used, inv = np.unique(faces, return_inverse=True)
    quads = inv.reshape(faces.shape)
    tris = np.stack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]], axis=1).reshape(-1, 3)
    return FilmSurface(vertices=np.asarray(points, float)[used], triangles=tris, quads=quads,
                   material=np.asarray(material)[owner].astype(np.int32), point_index=used)
