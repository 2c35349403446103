"""Coarser copies of a design, and the map of a coarse shape onto the fine mesh.

Large sheets (10^5 cells from a printer mask) spend most Newton iterations finding the
large-scale shape: which way long strips curve, where an incompatible sheet buckles.
That shape is decided at lengths far above the pixel, so a design coarsened 2 x 2 in
the plane finds it at a quarter of the cost; its shape, interpolated onto the fine mesh,
starts the fine solve (``gdfe.simulate(..., init="multilevel")``, the default above
:data:`gdfe.solver.MULTILEVEL_CELLS` cells; see :func:`gdfe.solver.starts.multilevel_start`).

Coarsening keeps the contraction, not the pixels: a coarse cell contracts on a face by
the mean contraction ``1 - R`` of its fine cells on that face (a rigid fine cell counts
as zero), so a hinge stripe three pixels wide keeps its fold when it covers one and a
half coarse cells.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from gdfe._validation import check_instance
from gdfe.design import Design, Material
from gdfe.mesh import sheet_mesh

__all__ = ["coarsen"]


def coarsen(design):
    """The design on cells twice as large in x and y, and the prolongation to ``design``.

    Parameters
    ----------
    design : Design
        A sheet meshed by :func:`gdfe.mesh.sheet_mesh` (any film outline, any ``nz``).

    Returns
    -------
    coarse : Design
        Cell ``(I, J, k)`` covers fine cells ``(2I..2I+1, 2J..2J+1, k)``; it exists where
        any of them does. Its faces contract by the mean contraction of those cells;
        the face that contracts more decides the material (both faces within a factor
        2 of each other: free shrink). Same ``h``, ``nz`` and isotropy.
    prolong : (n_fine, n_coarse) sparse matrix
        Bilinear interpolation in the plane: ``prolong @ coarse_points`` is a fine shape.
    """
    check_instance("design", design, Design)
    mesh = design.mesh
    dx, dy, _ = mesh.spacing
    nz = int(mesh.cell_k.max()) + 1
    i, j = mesh.cell_ij.T
    k = mesh.cell_k
    I, J = i // 2, j // 2
    nI, nJ = int(I.max()) + 1, int(J.max()) + 1
    top, bottom = design.face_contraction()
    # sums over the fine cells of each coarse column (layers kept apart)
    idx = (k * nJ + J) * nI + I
    size = nz * nI * nJ
    count = np.bincount(idx, minlength=size)
    top_c = np.bincount(idx, top, minlength=size)
    bot_c = np.bincount(idx, bottom, minlength=size)
    present = count > 0
    top_c[present] /= count[present]
    bot_c[present] /= count[present]
    # in-plane film outline: a coarse column exists where any of its fine cells does (layer 0)
    keep = present[: nI * nJ].reshape(nJ, nI).T
    # the grid's corner: vertex 0 of cell (i, j) lies at origin + (i dx, j dy)
    corner = mesh.points[mesh.cells[0, 0]]
    origin = (corner[0] - i[0] * dx, corner[1] - j[0] * dy)
    coarse_mesh = sheet_mesh(keep, 2 * dx, 2 * dy, design.h, nz=nz, origin=origin)
    ci, cj = coarse_mesh.cell_ij.T
    cidx = (coarse_mesh.cell_k * nJ + cj) * nI + ci
    t, b = top_c[cidx], bot_c[cidx]
    hi, lo = np.maximum(t, b), np.minimum(t, b)
    material = np.where(t >= b, Material.CONTRACT_TOP, Material.CONTRACT_BOTTOM)
    material = np.where((lo > 0) & (lo >= 0.5 * hi), Material.FREE_SHRINK, material)
    shrink = np.where(material == Material.FREE_SHRINK, 0.5 * (t + b), hi)
    material = np.where(hi > 0, material, Material.RIGID)
    R = np.where(material == Material.RIGID, 1.0, 1.0 - shrink)
    regions = {}
    for name, cells in design.regions.items():
        hit = np.zeros(size, bool)
        hit[idx[cells]] = True
        regions[name] = np.nonzero(hit[cidx])[0]
    coarse = Design(mesh=coarse_mesh, material=material.astype(np.int8), R=R, h=design.h,
                    isotropy=design.isotropy, regions=regions,
                    meta={**design.meta, "coarsened_from": design.n_cells})
    return coarse, _prolongation(mesh, coarse_mesh, origin)


def _prolongation(fine, coarse, origin):
    """Bilinear interpolation matrix from the coarse mesh's vertices to the fine mesh's."""
    dx, dy, dz = coarse.spacing
    cp = coarse.points
    nI = int(np.rint((cp[:, 0] - origin[0]) / dx).max()) + 2
    nJ = int(np.rint((cp[:, 1] - origin[1]) / dy).max()) + 2
    ck = np.rint(cp[:, 2] / dz).astype(int)
    ci = np.rint((cp[:, 0] - origin[0]) / dx).astype(int)
    cj = np.rint((cp[:, 1] - origin[1]) / dy).astype(int)
    lookup = np.full((ck.max() + 1) * nJ * nI, -1)
    lookup[(ck * nJ + cj) * nI + ci] = np.arange(len(cp))
    fp = fine.points
    u = (fp[:, 0] - origin[0]) / dx
    v = (fp[:, 1] - origin[1]) / dy
    fk = np.rint(fp[:, 2] / dz).astype(int)
    u0 = np.floor(u + 1e-9).astype(int)
    v0 = np.floor(v + 1e-9).astype(int)
    tu, tv = np.clip(u - u0, 0, 1), np.clip(v - v0, 0, 1)
    rows, cols, vals = [], [], []
    for a, wa in ((0, 1 - tu), (1, tu)):
        for b, wb in ((0, 1 - tv), (1, tv)):
            wgt = wa * wb
            use = wgt > 1e-12
            col = lookup[(fk[use] * nJ + v0[use] + b) * nI + u0[use] + a]
            if np.any(col < 0):
                raise RuntimeError("coarse mesh does not cover the fine mesh")
            rows.append(np.nonzero(use)[0])
            cols.append(col)
            vals.append(wgt[use])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(len(fp), len(cp)))
