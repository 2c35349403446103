"""Fabrication: from drawings to the printer and from the simulation back out.

- **In**: SVG drawings whose filled regions are each face's coating
  (:mod:`gdfe.fabrication.svg`), FOLD crease patterns whose creases become hinges
  (:mod:`gdfe.fabrication.fold`); both on the printer's pixel grid
  (:mod:`gdfe.fabrication.raster`).
- **To the printer**: 1-bit PNG masks per face with their DPI
  (:mod:`gdfe.fabrication.masks`), and print packages, a zip of the masks and a
  ``print.json`` (:mod:`gdfe.fabrication.package`).
- **Out**: the simulated film's surface as STL, OBJ, PLY and a multi-frame FOLD
  (:mod:`gdfe.fabrication.surface`, :mod:`gdfe.fabrication.export`), and an interactive, offline 3-D page
  (:mod:`gdfe.fabrication.viewer`).

svgelements, Pillow and meshio are imported by the functions that need them.
All lengths in millimetres.
"""

from __future__ import annotations

from gdfe.fabrication.export import (EXPORT_FORMATS, export_result, write_fold_frames, write_obj, write_ply,
                                     write_shape, write_stl)
from gdfe.fabrication.designs import crease_angles, fold_design, svg_design
from gdfe.fabrication.drawings import (DRAWING_KEYS, DRAWING_SUFFIXES, drawing_design, fold_design_with, load_drawing,
                                      svg_design_with)
from gdfe.fabrication.fold import CreasePattern, FoldMasks, fold_masks, read_fold
from gdfe.fabrication.masks import (FaceMasks, face_masks, read_mask_png, write_design_toml, write_mask_png,
                                    write_masks)
from gdfe.fabrication.package import read_print_package, write_print_package
from gdfe.fabrication.raster import fill_polygons
from gdfe.fabrication.surface import FilmSurface, film_surface, hex_surface
from gdfe.fabrication.svg import FACE_COLOURS, FACES, SvgMasks, svg_masks, svg_polyline
from gdfe.fabrication.viewer import ViewData, read_series, view_data, viewer_fragment, viewer_page, write_viewer

__all__ = [
    "EXPORT_FORMATS", "FilmSurface", "export_result", "film_surface", "hex_surface", "write_fold_frames", "write_obj",
    "write_ply", "write_shape", "write_stl",
    "CreasePattern", "FoldMasks", "crease_angles", "fold_design", "fold_design_with", "fold_masks", "read_fold",
    "FaceMasks", "face_masks", "read_mask_png", "write_design_toml", "write_mask_png", "write_masks",
    "read_print_package", "write_print_package", "fill_polygons",
    "FACE_COLOURS", "FACES", "SvgMasks", "svg_design", "svg_design_with", "svg_masks", "svg_polyline",
    "ViewData", "read_series", "view_data", "viewer_fragment", "viewer_page", "write_viewer",
    "DRAWING_SUFFIXES", "DRAWING_KEYS", "drawing_design", "load_drawing",
]
