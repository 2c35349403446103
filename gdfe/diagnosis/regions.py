"""Regions of a design: the named sets of cells a shape diagnosis reports on and corrects.

A design's own regions (e.g. ``panel_a``/``hinge``/``panel_b`` of :func:`gdfe.hinge`) are used
as they are; otherwise each connected area (4-neighbours in the cell grid) of one kind of
material is a region: ``hinge_k`` (contracting on one face), ``shrink_k`` (free shrink) and
``panel_k`` (rigid), numbered by the centroid of their cells along x, then y.
"""

from __future__ import annotations

import numpy as np

from gdfe._validation import check_instance
from gdfe.design import Design, Material

__all__ = ["design_regions"]


def design_regions(design):
    """Named regions of a design: its own, else the connected areas of each material.

    Automatic names: ``hinge_k`` (cells contracting on one face), ``shrink_k`` (free shrink),
    ``panel_k`` (rigid), numbered along x then y.

    Parameters
    ----------
    design : Design

    Returns
    -------
    dict of str -> (k,) int array
        Cell indices (through the thickness).
    """
    from scipy import ndimage

    check_instance("design", design, Design)
    if design.regions:
        return {k: np.asarray(v) for k, v in design.regions.items()}
    ij = design.mesh.cell_ij
    nx, ny = ij.max(0) + 1
    grid = np.full((nx, ny), -1)
    grid[ij[:, 0], ij[:, 1]] = design.material
    kinds = {"hinge": (Material.CONTRACT_TOP, Material.CONTRACT_BOTTOM),
             "shrink": (Material.FREE_SHRINK,), "panel": (Material.RIGID,)}
    regions = {}
    for word, codes in kinds.items():
        comps = []
        for code in codes:
            lab, n = ndimage.label(grid == int(code))
            for k in range(1, n + 1):
                cells = np.nonzero(lab[ij[:, 0], ij[:, 1]] == k)[0]
                c = ij[cells].mean(0)
                comps.append((c[0], c[1], cells))
        for k, (_, _, cells) in enumerate(sorted(comps, key=lambda t: (t[0], t[1])), start=1):
            regions[f"{word}_{k}"] = cells
    return regions
