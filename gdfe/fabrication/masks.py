"""Printer masks: one 1-bit PNG per face of the film, black where passive material is printed.

A design on a grid of square cells (:func:`gdfe.grid_design`, :func:`gdfe.from_masks`) is
printed by a DLP printer one face at a time: the *top* mask is black where the top face
is coated (``RIGID`` and ``CONTRACT_BOTTOM`` cells), the *bottom* mask where the bottom face
is (``RIGID`` and ``CONTRACT_TOP``); a *film* mask, black where there is film, gives the
outline the film is cut to when the part is not the whole rectangle. One image pixel is
one cell; row 0 of an image is the largest y (as :func:`gdfe.from_masks` reads it), column
0 the smallest x. The pixel size is written into each PNG as its resolution (the pHYs
chunk, which holds whole pixels per metre: exact for pixels of 1/k mm, such as 0.1, 0.125,
0.05 mm).

Pillow is imported by the functions that write and read images.
"""

from __future__ import annotations

import dataclasses
import io
import math
import os
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_file, check_positive
from gdfe.design import Material

__all__ = ["FaceMasks", "face_masks", "mask_image", "write_mask_png", "read_mask_png", "write_masks",
           "write_design_toml", "MM_PER_INCH"]

#: Millimetres per inch (DPI = MM_PER_INCH / pixel).
MM_PER_INCH = 25.4


@dataclasses.dataclass
class FaceMasks:
    """The masks of a design's two faces and of its film, on the printer's pixel grid.

    Attributes
    ----------
    top, bottom : (nx, ny) bool arrays
        True where passive material is printed on that face (``[i, j]``: column i along x,
        row j along y).
    film : (nx, ny) bool array
        True where there is film.
    pixel : float [mm]
        Pixel (cell) size.
    """

    top: np.ndarray
    bottom: np.ndarray
    film: np.ndarray
    pixel: float

    @property
    def shape(self):
        return self.top.shape

    @property
    def dpi(self) -> float:
        """Printer resolution in dots per inch."""
        return MM_PER_INCH / self.pixel

    def summary(self) -> dict:
        nx, ny = self.shape
        return {"pixel_mm": self.pixel, "dpi": self.dpi, "nx": int(nx), "ny": int(ny),
                "width_mm": nx * self.pixel, "height_mm": ny * self.pixel,
                "passive_pixels": {"top": int(self.top.sum()), "bottom": int(self.bottom.sum())},
                "film_pixels": int(self.film.sum()), "rectangular": bool(self.film.all())}


def face_masks(design):
    """The printer masks of a design made on a grid of square cells.

    Parameters
    ----------
    design : Design
        Its cells' in-plane size is the printer pixel (``dx == dy``).

    Returns
    -------
    FaceMasks

    Raises
    ------
    GdfeError
        If the cells are not square (a printer pixel is).
    """
    mesh = design.mesh
    dx, dy = (float(v) for v in mesh.spacing[:2])
    if not math.isclose(dx, dy, rel_tol=1e-9):
        raise GdfeError(f"design: expected square cells for printer masks (one cell per pixel), "
                        f"got {dx:g} x {dy:g} mm")
    first = mesh.cell_k == 0
    i, j = mesh.cell_ij[first].T
    mat = design.material[first]
    shape = (int(i.max()) + 1, int(j.max()) + 1)
    top = np.zeros(shape, bool)
    bottom = np.zeros(shape, bool)
    film = np.zeros(shape, bool)
    film[i, j] = True
    top[i, j] = (mat == Material.RIGID) | (mat == Material.CONTRACT_BOTTOM)
    bottom[i, j] = (mat == Material.RIGID) | (mat == Material.CONTRACT_TOP)
    return FaceMasks(top=top, bottom=bottom, film=film, pixel=dx)


def mask_image(mask, pixel):
    """A 1-bit Pillow image of a mask: black where ``mask`` is True, with its DPI set.

    Parameters
    ----------
    mask : (nx, ny) bool array
        ``[i, j]``: column i along x, row j along y.
    pixel : float [mm]
    """
    from PIL import Image

    pixel = check_positive("pixel", pixel)
    mask = np.asarray(mask, bool)
    if mask.ndim != 2 or mask.size == 0:
        raise GdfeError(f"mask: expected a non-empty 2-D array, got shape {mask.shape}")
    img = Image.fromarray(~mask.T[::-1])  # image row 0 is the largest y; True (white) = no material
    dpi = MM_PER_INCH / pixel
    img.info["dpi"] = (dpi, dpi)
    return img


def _png_bytes(mask, pixel):
    img = mask_image(mask, pixel)
    buf = io.BytesIO()
    img.save(buf, format="PNG", dpi=img.info["dpi"], optimize=True)
    return buf.getvalue()


def write_mask_png(path, mask, pixel):
    """Write a mask as a 1-bit PNG (black = True), its DPI set from ``pixel`` [mm]; renamed into place."""
    from gdfe.io import atomic_path

    data = _png_bytes(mask, pixel)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def read_mask_png(path):
    """Read a mask PNG: ``(mask, pixel)``, ``mask[i, j]`` True where the pixel is dark (and opaque),
    at any bit depth and mode (:mod:`gdfe._images`).

    Returns
    -------
    mask : (nx, ny) bool array
    pixel : float [mm] or None
        From the file's resolution; None when the file has none.
    """
    from gdfe._images import read_mask_image

    path = check_file("mask", path, suffixes=(".png",), what="mask image")
    arr, dpi = read_mask_image("mask", path)
    pixel = None
    if dpi and float(dpi[0]) > 0:
        if not math.isclose(float(dpi[0]), float(dpi[1]), rel_tol=1e-3):
            raise GdfeError(f"{path.name}: expected square pixels, got {dpi[0]:g} x {dpi[1]:g} DPI")
        pixel = MM_PER_INCH / float(dpi[0])
    return arr, pixel


def write_masks(masks, out_dir, name):
    """Write ``NAME_top.png``, ``NAME_bottom.png`` and, when the film is not the whole rectangle,
    ``NAME_film.png`` (black = film) into ``out_dir``.

    Returns
    -------
    dict
        ``top``, ``bottom`` (and ``film``) -> Path.
    """
    out_dir = Path(out_dir)
    paths = {"top": write_mask_png(out_dir / f"{name}_top.png", masks.top, masks.pixel),
             "bottom": write_mask_png(out_dir / f"{name}_bottom.png", masks.bottom, masks.pixel)}
    if not masks.film.all():
        paths["film"] = write_mask_png(out_dir / f"{name}_film.png", masks.film, masks.pixel)
    return paths


def _plain(v):
    """A value of a design file's table as TOML takes it: numpy scalars as Python's, paths as text."""
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v if isinstance(v, (str, dict)) else str(v)


def design_toml_text(tables, comment=None):
    """The text of a design file: ``tables`` (table name -> {key: value}; None values left out, empty
    tables too) written by ``tomli_w``, after ``comment``'s lines as TOML comments."""
    import tomli_w

    doc = {name: {k: _plain(v) for k, v in table.items() if v is not None} for name, table in tables.items()}
    doc = {name: table for name, table in doc.items() if table}
    head = "".join(f"# {line}\n" for line in (comment or "").splitlines())
    return head + tomli_w.dumps(doc)


def write_design_toml(path, files, pixel, film, comment=None, simulate=None):
    """Write a design file (TOML) whose ``[masks]`` table points at mask images beside it.

    Parameters
    ----------
    path : str or Path
        The ``.toml`` file; the mask paths are written relative to its folder.
    files : dict
        ``top``, ``bottom`` and optionally ``film`` -> path of the mask image.
    pixel : float [mm]
    film : dict
        The ``[film]`` table (``h``, ``d`` or ``R``, ``K``, ``nz``, ...).
    comment : str, optional
        Lines written as TOML comments at the top (the design's source).
    simulate : dict, optional
        The ``[simulate]`` table.

    Returns
    -------
    Path
    """
    from gdfe.io import write_text

    path = Path(path)
    masks = {"pixel": float(pixel)}
    for key in ("top", "bottom", "film"):
        if key in files:
            masks[key] = Path(os.path.relpath(Path(files[key]).resolve(), path.parent.resolve())).as_posix()
    return write_text(path, design_toml_text({"film": film, "masks": masks, "simulate": simulate or {}}, comment))
