"""Files of a plate solution: the deformed FEM mesh as a VTU series over the load steps, and JSON.

Each accepted load step is written as ``NAME_###.vtu`` (the mesh's hexahedra at their deformed
corner nodes; point data ``displacement`` [mm]; cell data ``ply``: 0 bottom coat, 1 film, 2 top
coat, and the design cell ``cell_i``, ``cell_j``), with a ``NAME.pvd`` collection whose time is
the load factor, as GDFE's series (:func:`gdfe.io.write_series`). Files are written to a temporary
name and renamed when complete.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gdfe.io import atomic_path, write_text

__all__ = ["write_plate_vtu", "write_plate_series"]


def write_plate_vtu(path, result, displacement=None, point_data=None, cell_data=None):
    """Write the plate's mesh at one displacement (default the final one) as a VTU file.

    Parameters
    ----------
    path : str or Path
    result : PlateResult
    displacement : (N, 3) float array [mm], optional
        Displacement of every degree of freedom (the corner nodes are the first ones).
    point_data : dict of str -> (n_vertices, ...) array, optional
    cell_data : dict of str -> (n_elements,) array, optional

    Returns
    -------
    Path
    """
    import meshio
    from skfem.io.meshio import to_meshio

    mesh = result.plate.mesh
    nv = mesh.p.shape[1]
    U = result.displacement if displacement is None else np.asarray(displacement)
    base = to_meshio(mesh)
    pts = mesh.p.T + U[:nv]
    cells = {"ply": result.plate.ply.astype(np.int32), "cell_i": result.plate.cell[:, 0].astype(np.int32),
             "cell_j": result.plate.cell[:, 1].astype(np.int32), **(cell_data or {})}
    out = meshio.Mesh(pts, base.cells, point_data={"displacement": U[:nv], **(point_data or {})},
                      cell_data={k: [np.asarray(v)] for k, v in cells.items()})
    with atomic_path(path) as tmp:
        meshio.write(tmp, out, file_format="vtu")
    return Path(path)


def write_plate_series(result, out_dir, name="fem"):
    """Write every saved load step of a result and a ``.pvd`` collection; returns the ``.pvd`` path."""
    out_dir = Path(out_dir)
    loads = [s["load"] for s in result.steps if s.get("snapshot") is not None]
    frames = list(zip(loads, result.snapshots)) if len(loads) == len(result.snapshots) else \
        [(result.load_factor, result.snapshots[-1])]
    frames = [(0.0, np.zeros_like(result.displacement))] + frames
    entries = []
    for k, (load, U) in enumerate(frames):
        fname = f"{name}_{k:03d}.vtu"
        write_plate_vtu(out_dir / fname, result, U)
        entries.append(f'    <DataSet timestep="{load:.6g}" group="" part="0" file="{fname}"/>')
    pvd = "\n".join(['<?xml version="1.0"?>',
                     "<!--cell data 'ply': 0 = bottom coat, 1 = film, 2 = top coat; time: load factor-->",
                     '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                     "  <Collection>", *entries, "  </Collection>", "</VTKFile>", ""])
    return write_text(out_dir / f"{name}.pvd", pvd)
