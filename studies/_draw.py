"""Drawing helpers shared by the studies (matplotlib, imported lazily by the callers)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: Face colours of the materials (rigid, contract top, contract bottom, free shrink).
COLOURS = ((0.62, 0.62, 0.66), (0.95, 0.55, 0.15), (0.2, 0.5, 0.9), (0.3, 0.75, 0.4))


def side_view(ax, points, design, row=0, alpha=1.0):
    """Draw the cells of one row (fixed y index) of a strip in the x-z plane, by material."""
    from matplotlib.collections import PolyCollection

    mesh = design.mesh
    sel = np.nonzero(mesh.cell_ij[:, 1] == row)[0]
    quads = points[mesh.cells[sel]][:, [0, 1, 5, 4]][..., [0, 2]]
    cols = [COLOURS[int(m)] for m in design.material[sel]]
    ax.add_collection(PolyCollection(quads, facecolors=cols, edgecolors=(0.2, 0.2, 0.2, 0.4), linewidths=0.3,
                                     alpha=alpha))
    ax.set_aspect("equal")
    ax.autoscale_view()


def surface(ax, points, design, elev=28, azim=-60, edges=True):
    """Draw the boundary faces of a design on a 3-D axis, coloured by material."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from gdfe.io import surface_faces

    faces, owner = surface_faces(design)
    # only the top and bottom faces (normal along z in the flat print): enough for a film, and lighter
    flat_n = np.cross(design.mesh.points[faces[:, 1]] - design.mesh.points[faces[:, 0]],
                      design.mesh.points[faces[:, 3]] - design.mesh.points[faces[:, 0]])
    keep = np.abs(flat_n[:, 2]) > 0.5 * np.linalg.norm(flat_n, axis=1)
    faces, owner = faces[keep], owner[keep]
    cols = np.array([COLOURS[int(m)] for m in design.material[owner]])
    coll = Poly3DCollection(points[faces], facecolors=cols,
                            edgecolors=(0.25, 0.25, 0.25, 0.25) if edges else "none", linewidths=0.15)
    ax.add_collection3d(coll)
    lo, hi = points.min(0), points.max(0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set(xlim=(c[0] - r, c[0] + r), ylim=(c[1] - r, c[1] + r), zlim=(c[2] - r, c[2] + r))
    ax.view_init(elev=elev, azim=azim)
    ax.set_box_aspect((1, 1, 1))
    ax.set_axis_off()


def pattern_strip(ax, material, cell, y=0.0, height=1.0):
    """Draw a 1-D pattern (material per column) as coloured bars."""
    from matplotlib.collections import PolyCollection

    n = len(material)
    x0 = np.arange(n) * cell
    quads = [[(a, y), (a + cell, y), (a + cell, y + height), (a, y + height)] for a in x0]
    ax.add_collection(PolyCollection(quads, facecolors=[COLOURS[int(m)] for m in material], edgecolors="none"))
    ax.set_xlim(0, n * cell)


def save_figure(fig, out, name, title=None, dpi=110):
    """Give ``fig`` its title (if any), lay it out and write it to ``out/NAME.png`` with
    :func:`gdfe.io.save_figure` (renamed into place when complete, then closed)."""
    from gdfe.io import save_figure as write_figure

    if title is not None:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return write_figure(fig, Path(out) / f"{name}.png", dpi=dpi)
