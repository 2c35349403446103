"""Masks from images and from arrays: one reading for every bit depth, mode and array type.

A pixel of a mask is *set* (passive material printed there, or film present) where it is
dark and opaque: its luminance below half of full scale (below 128 of 255) and, where there
is an alpha channel, its alpha above half. Full scale is that of the pixel's type: 1 for
1-bit images, 255 for 8-bit ones (greyscale, palette, RGB, CMYK, ...), 65535 for 16-bit
greyscale, 1.0 for floating-point pixels. Colour is turned into luminance with the ITU-R 601
weights (as Pillow's ``convert("L")``).

Numeric arrays are read as the pixels of such an image, so an array and the same picture saved
as a file mean the same mask: ``uint8`` (full scale 255), ``uint16`` (65535) or floats in
[0, 1]; ``(nx, ny)`` greyscale, ``(nx, ny, 2)`` greyscale and alpha, ``(nx, ny, 3)`` RGB or
``(nx, ny, 4)`` RGBA. A boolean array is the mask itself (True = set). Other integer arrays are
refused: 0/1 integers could mean either (a 1-bit picture, 0 = black = set, or a mask, 1 = set).

Arrays are indexed like a design's grid, ``[i (along x), j (along y)]``; images have their
row 0 at the top (the largest y).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, GdfeFileNotFoundError, GdfeTypeError, check_file
from gdfe.resources import check_design_cells

__all__ = ["read_mask_image", "mask_from_array", "read_mask", "DARK", "OPAQUE"]

#: A pixel is dark below this fraction of full scale (128 of 255), opaque above OPAQUE (127 of 255).
DARK = 128 / 255
OPAQUE = 127 / 255
#: Luminance weights of R, G, B (ITU-R 601).
_LUMA = np.array([0.299, 0.587, 0.114])


def _pixels_to_mask(name, pix, scale):
    """``(rows, cols[, channels])`` pixel values with full scale ``scale`` -> bool mask (dark and opaque)."""
    v = np.asarray(pix, float) / scale
    if v.ndim == 2:
        return v < DARK
    channels = v.shape[2]
    if channels == 1:
        return v[..., 0] < DARK
    if channels == 2:
        return (v[..., 0] < DARK) & (v[..., 1] > OPAQUE)
    if channels in (3, 4):
        lum = v[..., :3] @ _LUMA
        dark = lum < DARK
        return dark & (v[..., 3] > OPAQUE) if channels == 4 else dark
    raise GdfeError(f"{name}: expected 1 to 4 channels (grey, grey+alpha, RGB, RGBA), got {channels}")


def mask_from_array(name, value):
    """A boolean mask ``(nx, ny)`` from a boolean array or an array of pixels (module docstring)."""
    arr = np.asarray(value)
    if arr.ndim >= 2:  # a cell per pixel: refused before any copy when the design could not fit in memory
        check_design_cells(name, arr.shape[0] * arr.shape[1])
    if arr.dtype == bool:
        if arr.ndim != 2 or arr.size == 0:
            raise GdfeError(f"{name}: expected a non-empty 2-D mask, got shape {arr.shape}")
        return arr.copy()
    if arr.dtype.kind not in "uif":
        raise GdfeTypeError(f"{name}: expected a boolean mask or an array of pixel values, got an array of "
                            f"{arr.dtype}")
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] not in (1, 2, 3, 4)):
        raise GdfeError(f"{name}: expected a 2-D mask (or (nx, ny, channels) pixels), got shape {arr.shape}")
    if arr.dtype == np.uint8:
        scale = 255.0
    elif arr.dtype == np.uint16:
        scale = 65535.0
    elif arr.dtype.kind == "f":
        if not np.isfinite(arr).all() or arr.size and (arr.min() < 0 or arr.max() > 1):
            bad = arr[~(np.isfinite(arr) & (arr >= 0) & (arr <= 1))].flat[0]
            raise GdfeError(f"{name}: expected pixel values in [0, 1] (0 black = set, 1 white), got {bad:g}")
        scale = 1.0
    else:
        raise GdfeTypeError(f"{name}: expected a boolean mask (True = set) or pixels of type uint8, uint16 or "
                            f"float in [0, 1] (dark = set), got an array of {arr.dtype}: convert it with "
                            f".astype(bool) for a mask or .astype(np.uint8) for 8-bit pixels")
    if arr.size == 0:
        raise GdfeError(f"{name}: expected a non-empty mask, got shape {arr.shape}")
    return _pixels_to_mask(name, arr, scale)  # per pixel: the same in grid and in image order


def read_mask_image(name, source, label=None):
    """Read a mask image; returns ``(mask, dpi)``: ``mask[i, j]`` in grid order, ``dpi`` or None.

    ``source`` is a path or an open binary file (``label`` names it in messages). Every mode
    Pillow opens is read by the rule of the module docstring. A file Pillow cannot decode, a
    multi-frame image or one of 32-bit integer pixels beyond 16 bits is a :class:`GdfeError`
    naming the file.
    """
    from PIL import Image

    if isinstance(source, (str, Path)):
        source = check_file(name, source, what="mask image")
        label = source.name
    where = f"{name}: {label or 'image'}"
    try:
        with Image.open(source) as img:
            frames = getattr(img, "n_frames", 1)
            if frames > 1:
                raise GdfeError(f"{where}: expected a single image, got {frames} frames")
            check_design_cells(where, img.size[0] * img.size[1])  # before its pixels are decoded
            img.load()
            dpi = img.info.get("dpi")
            pix, scale = _pixels(where, img)
    except GdfeError:
        raise
    except Exception as exc:  # Pillow raises many kinds for files it cannot decode
        raise GdfeError(f"{where}: not a readable image ({type(exc).__name__}: {exc})") from None
    if pix.ndim < 2 or pix.size == 0:
        raise GdfeError(f"{where}: expected an image with pixels, got shape {pix.shape}")
    mask = _pixels_to_mask(where, pix, scale)
    return mask[::-1].T.copy(), dpi  # image row 0 is the top (largest y); the grid is (x, y)


def _pixels(where, img):
    """The pixel values of a Pillow image and their full scale."""
    mode = img.mode
    if mode == "1":
        return np.asarray(img, dtype=np.uint8), 1.0
    if mode.startswith("I;16"):
        return np.asarray(img).astype(np.uint16), 65535.0
    if mode == "I":
        pix = np.asarray(img)
        if pix.size and (pix.min() < 0 or pix.max() > 65535):
            raise GdfeError(f"{where}: expected 1-, 8- or 16-bit pixels, got 32-bit integers from {pix.min()} "
                            f"to {pix.max()}")
        return pix, 65535.0
    if mode == "F":
        pix = np.asarray(img, dtype=float)
        if pix.size and (not np.isfinite(pix).all() or pix.min() < 0 or pix.max() > 1):
            raise GdfeError(f"{where}: expected floating-point pixels in [0, 1], got values from {np.nanmin(pix):g} "
                            f"to {np.nanmax(pix):g}")
        return pix, 1.0
    if mode in ("L", "LA", "RGB", "RGBA"):
        return np.asarray(img), 255.0
    if "A" in mode or "a" in mode or (mode == "P" and "transparency" in img.info):
        return np.asarray(img.convert("RGBA")), 255.0
    return np.asarray(img.convert("RGB")), 255.0  # palette, CMYK, YCbCr, LAB, HSV, RGBX, ...: 8-bit colour


def read_mask(name, value, shape=None):
    """A boolean mask ``(nx, ny)`` from an image path or an array; ``shape`` the one it must have."""
    if isinstance(value, (str, Path)):
        if str(value) == "":
            raise GdfeTypeError(f"{name}: expected a mask (an array or the path of an image), got ''")
        path = Path(value)
        if not path.is_file():
            raise GdfeFileNotFoundError(f"{name}: mask image not found: {path}")
        arr, _ = read_mask_image(name, path)
    elif value is None or isinstance(value, (bool, np.bool_, int, float, bytes)):
        raise GdfeTypeError(f"{name}: expected a mask (an array or the path of an image), got {value!r}")
    else:
        arr = mask_from_array(name, value)
    if shape is not None and arr.shape != tuple(shape):
        raise GdfeError(f"{name}: expected a mask of shape {tuple(shape)} (like 'top'), got {arr.shape}")
    return arr
