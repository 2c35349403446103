"""Print packages: one zip of a design's printer masks and the numbers the printer needs.

A package holds, for every part, ``NAME_top.png`` and ``NAME_bottom.png`` (1-bit, black =
passive material, DPI set; :mod:`gdfe.fabrication.masks`), ``NAME_film.png`` where the
film is not the whole rectangle, a design file ``NAME.toml`` that reads the masks back
(``gdfe simulate NAME.toml`` after unzipping), and one ``print.json``:

``format``
    ``"gdfe-print-package"`` and ``version`` 1.
``pixel_mm``, ``dpi``
    The printer's pixel, the same for every mask.
``h_mm``, ``d_mm``, ``K``, ``R``
    Active-film thickness, passive-layer thickness to print (None when the design was given
    by its contraction ratio), coefficient of Eq. 1 and contraction ratio of the free faces
    (the design files inside give R itself, so that they read back the same design).
``source``
    Where the design came from (a file, with its SHA-256, or a description).
``parts``
    Per part: ``name``, the files, the grid (``nx``, ``ny``, width and height in mm) and
    the passive pixels per face.

The zip is written to a temporary name and renamed when complete.
"""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_file
from gdfe.design import register_design_reader
from gdfe.fabrication.masks import _png_bytes, face_masks

__all__ = ["write_print_package", "read_print_package", "PACKAGE_FORMAT"]

#: The ``format`` key of ``print.json``.
PACKAGE_FORMAT = "gdfe-print-package"


def _source_record(source):
    if source is None:
        return None
    path = Path(str(source))
    if path.is_file():
        return {"file": str(path), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}
    return {"description": str(source)}


def _free_ratios(design):
    """The contraction ratios of a design's free faces (rigid cells have none)."""
    from gdfe.design import Material

    free = design.material != Material.RIGID
    return np.unique(design.R[free] if free.any() else design.R)


def _film_table(design, d, K):
    """The ``[film]`` table of a part's design file: its one contraction ratio R (so that the file
    reads back the very design), else d and K for Eq. 3."""
    R = _free_ratios(design)
    film = {"h": float(design.h)}
    if R.size == 1:
        film["R"] = float(R[0])
    elif d is not None:
        film["d"] = float(d)
        if K is not None:
            film["K"] = float(K)
    else:
        raise GdfeError(f"design: a package needs one contraction ratio R for the whole film, or d; got "
                        f"{R.size} values of R and no d")
    film["nz"] = int(design.mesh.cell_k.max()) + 1
    film["isotropy"] = float(design.isotropy)
    return film


def write_print_package(path, designs, *, d=None, K=None, source=None, extra=None):
    """Write a print package (zip) of one or several designs.

    Parameters
    ----------
    path : str or Path
        The ``.zip`` to write.
    designs : Design or dict of str -> Design
        The parts, by name (a single design is called ``part``). Every part's cells are
        the printer's pixels: square, and of one size for all parts.
    d : float [mm], optional
        Passive-layer thickness the parts were designed with (recorded for the printer).
    K : float, optional
        Coefficient of Eq. 1 used with ``d``.
    source : str or Path, optional
        The design's source, recorded in ``print.json`` (a file also gets its SHA-256).
    extra : dict, optional
        More entries for ``print.json``.

    Returns
    -------
    Path
    """
    from gdfe._version import __version__
    from gdfe.fabrication.masks import design_toml_text
    from gdfe.io import atomic_path

    if not isinstance(designs, dict):
        designs = {"part": designs}
    if not designs:
        raise GdfeError("designs: expected at least one design to package, got none")
    path = Path(path)
    if path.suffix.lower() != ".zip":
        raise GdfeError(f"path: expected a .zip file name, got {path.name!r}")
    parts, files, pixel, info_R = [], {}, None, set()
    for name, des in designs.items():
        masks = face_masks(des)
        if pixel is None:
            pixel = masks.pixel
        elif not np.isclose(masks.pixel, pixel, rtol=1e-9):
            raise GdfeError(f"designs[{name!r}]: expected the printer pixel {pixel:g} mm of the other parts, "
                            f"got {masks.pixel:g} mm")
        names = {"top": f"{name}_top.png", "bottom": f"{name}_bottom.png"}
        files[names["top"]] = _png_bytes(masks.top, pixel)
        files[names["bottom"]] = _png_bytes(masks.bottom, pixel)
        if not masks.film.all():
            names["film"] = f"{name}_film.png"
            files[names["film"]] = _png_bytes(masks.film, pixel)
        film = _film_table(des, d, K)
        toml = design_toml_text({"film": film, "masks": {"pixel": float(pixel), **names}})
        names["design"] = f"{name}.toml"
        files[names["design"]] = toml.encode()
        info_R.update(_free_ratios(des).round(12).tolist())
        parts.append({"name": name, "files": names, **masks.summary()})
    first = next(iter(designs.values()))
    info = {"format": PACKAGE_FORMAT, "version": 1, "pixel_mm": pixel, "dpi": 25.4 / pixel,
            "black": "passive material (film masks: film)", "image_rows": "row 0 is the largest y",
            "h_mm": float(first.h), "d_mm": None if d is None else float(d), "K": None if K is None else float(K),
            "R": sorted(info_R) if len(info_R) > 1 else next(iter(info_R)),
            "source": _source_record(source), "gdfe": __version__, "parts": parts, **(extra or {})}
    files["print.json"] = (json.dumps(info, indent=2) + "\n").encode()
    with atomic_path(path) as tmp:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for fname, data in files.items():
                zf.writestr(fname, data)
    return path


def read_print_package(path):
    """Read a print package back: the designs of its parts, and its ``print.json``.

    Returns
    -------
    designs : dict of str -> Design
    info : dict
        The package's ``print.json``.
    """
    import tomllib

    from gdfe.calibration import Calibration
    from gdfe.design import from_masks

    path = check_file("package", path, suffixes=(".zip",), what="print package")
    try:
        zf = zipfile.ZipFile(path)
    except zipfile.BadZipFile:
        raise GdfeError(f"{path.name}: not a zip file") from None
    with zf:
        names = set(zf.namelist())
        if "print.json" not in names:
            raise GdfeError(f"{path.name}: expected a print.json in the package, got {sorted(names)}")
        try:
            info = json.loads(zf.read("print.json"))
        except json.JSONDecodeError as exc:
            raise GdfeError(f"{path.name}: print.json line {exc.lineno}: not valid JSON ({exc.msg})") from None
        if info.get("format") != PACKAGE_FORMAT:
            raise GdfeError(f"{path.name}: print.json: expected format {PACKAGE_FORMAT!r}, got {info.get('format')!r}")
        designs = {}
        for part in info.get("parts", []):
            fl = part.get("files", {})
            missing = [f for f in fl.values() if f not in names]
            if missing:
                raise GdfeError(f"{path.name}: part {part.get('name')!r}: missing {missing}")
            film = tomllib.loads(zf.read(fl["design"]).decode())["film"]
            R = film["R"] if "R" in film else float(
                Calibration(**({"K": film["K"]} if "K" in film else {}), h=film["h"]).ratio(film["d"]))

            def img(key):
                from gdfe._images import read_mask_image

                return read_mask_image(path.name, io.BytesIO(zf.read(fl[key])), label=fl[key])[0]

            des = from_masks(img("top"), img("bottom"), info["pixel_mm"], R, h=film["h"], nz=film.get("nz", 1),
                             isotropy=film.get("isotropy", 1.0), film=img("film") if "film" in fl else None,
                             d=film.get("d"))
            des.meta.update(kind="package", source=str(path), part=part.get("name"))
            designs[part["name"]] = des
    return designs, info


def _read_package(source):
    """The design of a print package read alone (:func:`gdfe.load_design`): its one part, with the
    package's own film, or with the given model at the package's d."""
    designs, info = read_print_package(source.path)
    if len(designs) != 1:
        raise GdfeError(f"{source.path.name}: expected a package of one part to read as a design, got "
                        f"{len(designs)} parts ({', '.join(designs) or 'none'}); read it with "
                        f"gdfe.fabrication.read_print_package")
    des = next(iter(designs.values()))
    f = source.film
    if not f.default:  # a model given: it replaces the package's film
        if des.d is None:
            raise GdfeError(f"{source.path.name}: model: the package gives R, not the passive thickness d that "
                            f"a deformation model needs")
        des = f.model.apply(des, f.process)
        des.meta["contraction_source"] = f"model {f.model.name!r}"
    else:
        des.meta["contraction_source"] = "the package's film"
    if f.process:
        from gdfe.design import process_used

        des.meta["process"] = dict(f.process)
        des.meta["process_used"] = process_used(f.model, f.process)
    return des


register_design_reader("package", _read_package, suffixes=(".zip",))
