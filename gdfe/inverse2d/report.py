"""The files of a 2-D design: printer masks, a design file that reads them back, the numbers, a figure.

:func:`write_design` writes, for a :class:`gdfe.inverse2d.SurfaceDesign` named ``NAME``:

- ``NAME_top.png``, ``NAME_bottom.png`` (and ``NAME_film.png`` for a film that is not the whole
  rectangle): the printable masks as printer images through
  :func:`gdfe.fabrication.write_masks` (1-bit, black = passive coat, the pixel as DPI);
- ``NAME.toml``: a design file whose ``[masks]`` table reads those images back with the
  film's h and d (and ``NAME_model.toml``, the deformation model, where it is not the
  paper's); the design it reads is compared with the one that was checked, face by face;
- ``NAME_check.pvd``: the printed design's fold (the forward check) for ParaView;
- ``NAME.json``: :meth:`SurfaceDesign.summary` (``rms_mm``, ``max_mm``, ``hausdorff_mm`` of the
  printed fold at the top level, the relaxed design's and the start's beside them,
  reachability, iterations, evaluations, seconds) with the files and the read-back check;
- ``NAME.png``: the target and the printed fold, the masks and the convergence history.

Lengths in mm.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_instance

__all__ = ["DesignFiles", "write_design", "plot_design", "read_back"]


@dataclasses.dataclass(frozen=True)
class DesignFiles:
    """What :func:`write_design` wrote.

    Attributes
    ----------
    files : dict
        ``top``, ``bottom`` (``film``), ``design``, (``model``), (``check``), ``json``, (``figure``) -> Path.
    read_back : dict
        ``identical`` (the design read from ``NAME.toml`` is the one checked), ``pixel_mm`` (read
        from the masks' DPI) and ``max_contraction_difference``.
    summary : dict
        The JSON written.
    """

    files: dict
    read_back: dict
    summary: dict


def _is_paper_model(model):
    from gdfe.model import paper_model

    def key(m):
        d = m.as_dict()
        d.pop("gdfe_version", None)
        return d

    return key(model) == key(paper_model())


def read_back(path, design):
    """Read the design file ``path`` and compare it with the printed design of ``design`` (a SurfaceDesign).

    Returns
    -------
    dict
        ``identical``: same cells, same contraction on every face (to 1e-12); ``pixel_mm`` from
        the top mask's DPI; ``max_contraction_difference``.
    """
    import gdfe
    from gdfe.fabrication.masks import read_mask_png

    path = Path(path)
    read, _ = gdfe.load_design(path)
    printed = design.film.printable(design.top, design.bottom)
    _, pixel = read_mask_png(path.parent / f"{path.stem}_top.png")
    same_cells = (read.n_cells == printed.n_cells and read.mesh.points.shape == printed.mesh.points.shape
                  and np.allclose(read.mesh.points, printed.mesh.points, atol=1e-9))
    diff = float("inf")
    if same_cells:
        a, b = np.asarray(read.face_contraction()), np.asarray(printed.face_contraction())
        diff = float(np.max(np.abs(a - b))) if a.size else 0.0
    return {"identical": bool(same_cells and diff <= 1e-12), "pixel_mm": pixel,
            "max_contraction_difference": diff if np.isfinite(diff) else None}


def write_design(design, out, name=None, figure=True, check=True):
    """Write the masks, design file, JSON (and figure, fold) of a 2-D design into ``out``.

    Parameters
    ----------
    design : SurfaceDesign
    out : path
        Folder (made if missing).
    name : str, optional
        Stem of the files (default the target's name).
    figure : bool
        Write ``NAME.png``.
    check : bool
        Write the printed fold as ``NAME_check.pvd`` (VTU).

    Returns
    -------
    DesignFiles
    """
    from gdfe.fabrication.masks import FaceMasks, write_design_toml, write_masks
    from gdfe.inverse2d.design import SurfaceDesign
    from gdfe.io import write_json, write_series

    check_instance("design", design, SurfaceDesign)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    name = name or design.target.name
    film = design.film
    present = film.mask if film.mask is not None else np.ones(film.shape, bool)
    files = dict(write_masks(FaceMasks(top=design.top, bottom=design.bottom, film=present, pixel=film.pixel),
                             out, name))
    table = {"h": film.h, "d": film.d, "nz": 1}
    if not _is_paper_model(film.model):
        files["model"] = film.model.save(out / f"{name}_model.toml")
        table["model"] = files["model"].name
    r = design.reachability
    comment = (f"gdfe design --target: {design.target.source}\n"
               f"film {film.shape[0]} x {film.shape[1]} pixels of {film.pixel:g} mm, h {film.h:g} mm, d {film.d:g} mm, "
               f"model {film.model.name}\n"
               f"printed fold: RMS {design.printable_distance.rms_mm:.4g} mm from the target ({design.verdict()})\n"
               f"reachability: {r.text()}")
    files["design"] = write_design_toml(out / f"{name}.toml", files, film.pixel, table, comment=comment)
    back = read_back(files["design"], design)
    if not back["identical"]:
        raise GdfeError(f"{files['design'].name}: the design read back from the masks differs from the one checked "
                        f"(largest contraction difference {back['max_contraction_difference']}): please report it")
    if check:
        files["check"] = write_series(design.printable, out, name=f"{name}_check")
    if figure:
        files["figure"] = plot_design(design, out / f"{name}.png")
    files["json"] = out / f"{name}.json"
    summary = {**design.summary(), "files": {k: str(v) for k, v in files.items()}, "read_back": back}
    write_json(files["json"], summary)
    return DesignFiles(files=files, read_back=back, summary=summary)


def plot_design(design, path):
    """The figure of a 2-D design: target and printed fold, both masks, the optimisation's history.

    Returns the path of the PNG.
    """
    from gdfe._plotting import pyplot
    from gdfe.io import save_figure

    plt = pyplot()
    film = design.film
    fig = plt.figure(figsize=(16, 4.4))
    ax = fig.add_subplot(1, 4, 1, projection="3d")
    surf = design.target_surface
    if surf is not None:
        ax.plot_trisurf(*surf.vertices.T, triangles=surf.triangles, color=(0.7, 0.7, 0.75), alpha=0.35,
                        linewidth=0)
    d = design.printable_distance
    A = d.aligned
    tri = film.mid.triangles
    face_d = d.per_point[tri].mean(axis=1)
    coll = ax.plot_trisurf(*A.T, triangles=tri, cmap="viridis", linewidth=0, antialiased=False)
    coll.set_array(face_d)
    coll.set_clim(0.0, max(float(face_d.max()), 1e-12))
    fig.colorbar(coll, ax=ax, shrink=0.6, label="distance to target [mm]")
    lo, hi = A.min(0), A.max(0)
    c, rad = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set(xlim=(c[0] - rad, c[0] + rad), ylim=(c[1] - rad, c[1] + rad), zlim=(c[2] - rad, c[2] + rad))
    ax.set_box_aspect((1, 1, 1))
    ax.set_title(f"{design.target.name}: printed fold (colour)\non the target (grey): RMS {d.rms_mm:.3g} mm, "
                 f"max {d.max_mm:.3g} mm", fontsize=9)
    ext = (-0.5 * film.shape[0] * film.pixel, 0.5 * film.shape[0] * film.pixel,
           -0.5 * film.shape[1] * film.pixel, 0.5 * film.shape[1] * film.pixel)
    for k, (mask, face) in enumerate(((design.top, "top"), (design.bottom, "bottom"))):
        a = fig.add_subplot(1, 4, 2 + k)
        img = np.where(mask, 0.0, 1.0)
        if film.mask is not None:
            img = np.where(film.mask, img, 0.6)
        a.imshow(img.T, origin="lower", extent=ext, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        a.set(title=f"{face} mask (black = coated, {100 * mask[film.mask if film.mask is not None else slice(None)].mean():.0f} %)",
              xlabel="x [mm]", ylabel="y [mm]")
    a = fig.add_subplot(1, 4, 4)
    hist = design.history
    if hist:
        a.semilogy([r["evaluation"] for r in hist], [max(r["rms_mm"], 1e-12) for r in hist], "k.-", lw=0.8,
                   label="optimisation (folds continued)")
    for val, lab, colour, ls in ((design.initial_distance.rms_mm, "start, folded from flat", "C0", ":"),
                                 (design.relaxed_distance.rms_mm, "relaxed, folded from flat", "C2", "--"),
                                 (d.rms_mm, "printed, folded from flat", "C3", "-"),
                                 (design.tolerance_mm, "tolerance", "k", ":")):
        a.axhline(max(val, 1e-12), color=colour, ls=ls, lw=1, label=f"{lab}: {val:.3g} mm")
    a.set(xlabel="evaluation (fold + adjoint)", ylabel="RMS distance to target [mm]",
          title=f"{design.iterations} L-BFGS-B iterations, {design.evaluations} evaluations")
    a.legend(fontsize=7)
    fig.suptitle(design.verdict(), fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)
