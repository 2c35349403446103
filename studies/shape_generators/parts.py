"""The "real parts": the plate FEM of a design with one effect built into its geometry or material.

Every part is the plate model of :mod:`reference_fem` (film and coats meshed from the design,
the Table-1 calibration of the FEM's material, geometrically nonlinear, free-floating) with
at most one change to what was designed:

- **thicker coat** in a region: the coat's thickness there times a factor (the plate's coat
  node planes follow it);
- **stiffer coat** in a region: Young's modulus of the coat's elements there times a factor
  (:attr:`reference_fem.Plate.stiffness`);
- **anisotropic film**: the film's in-plane eigenstrain differs along x and y, the weaker
  direction ``ratio`` times the stronger, their mean kept at the material's
  (:attr:`reference_fem.Plate.eigenstrain`);
- **coat offset**: one face's coat printed ``pixels`` pixels off its mask along x or y; the
  cells it leaves or reaches change material (coat that lands off the film is lost);
- **contraction gradient**: the film's eigenstrain (all three components) scaled by a factor
  that varies linearly along x or y, ``1 + spread (s - mean s) / (s_max - s_min)`` over the film's
  elements (``s`` an element's centre along the axis), so the mean is kept and the two ends
  differ by ``spread`` of it (:func:`gradient_eigenstrain`): a part heated unevenly.

None of this is GDFE's model of the effect: GDFE's principle has no coat thickness, stiffness,
film anisotropy by direction of the draw beyond its ``isotropy``, misregistration of a face,
or contraction varying within a region. Lengths in mm.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gdfe.material import Material
from studies.shape_generators.calibration import fem_options

__all__ = ["solve_part", "offset_material", "coat_stiffness", "anisotropic_eigenstrain", "gradient_eigenstrain"]


def offset_material(design, face, axis, pixels):
    """The material grid of ``design`` with one face's coat moved ``pixels`` (signed) along
    ``axis`` (0: x, 1: y); ``face`` is ``"top"`` or ``"bottom"``."""
    mat, film = design.material, design.film
    top = film & np.isin(mat, (int(Material.RIGID), int(Material.CONTRACT_BOTTOM)))
    bottom = film & np.isin(mat, (int(Material.RIGID), int(Material.CONTRACT_TOP)))
    moved = top if face == "top" else bottom
    shifted = np.zeros_like(moved)
    k = int(pixels)
    src = [slice(None), slice(None)]
    dst = [slice(None), slice(None)]
    src[axis] = slice(0, moved.shape[axis] - k) if k >= 0 else slice(-k, None)
    dst[axis] = slice(k, None) if k >= 0 else slice(0, moved.shape[axis] + k)
    shifted[tuple(dst)] = moved[tuple(src)]
    shifted &= film
    if face == "top":
        top = shifted
    else:
        bottom = shifted
    out = np.where(top & bottom, int(Material.RIGID),
                   np.where(bottom, int(Material.CONTRACT_TOP),
                            np.where(top, int(Material.CONTRACT_BOTTOM), int(Material.FREE_SHRINK))))
    return np.where(film, out, mat)


def coat_stiffness(plate, region, factor):
    """Per-element modulus factors: ``factor`` on the coat's elements in ``region`` ((nx, ny)
    bool array), 1 elsewhere."""
    from reference_fem.mesh import FILM

    i, j = plate.cell[:, 0], plate.cell[:, 1]
    s = np.ones(plate.n_elements)
    s[(np.asarray(plate.ply) != FILM) & region[i, j]] = float(factor)
    return s


def anisotropic_eigenstrain(plate, material, ratio, weak_axis):
    """Per-element eigenstrain of a film that contracts ``ratio`` times less along ``weak_axis``
    (0: x, 1: y) than along the other, the mean of the two kept at the material's."""
    ex, _, ez = material.eigenstrain_xyz
    strong = 2.0 * ex / (1.0 + ratio)
    e = np.zeros((plate.n_elements, 3))
    e[:, :] = (strong, strong, ez)
    e[:, weak_axis] = ratio * strong
    return e


def gradient_eigenstrain(plate, material, spread, axis):
    """Per-element eigenstrain of a film whose shrink varies linearly along ``axis`` (0: x, 1: y):
    the material's times ``1 + spread (s - mean s) / (s_max - s_min)``, ``s`` the element's cell
    centre along the axis, mean and range over the film's elements (the coat's carry none)."""
    from reference_fem.mesh import FILM

    s = np.asarray(plate.cell, float)[:, axis] + 0.5
    film = np.asarray(plate.ply) == FILM
    span = float(s[film].max() - s[film].min())
    factor = 1.0 + float(spread) * (s - s[film].mean()) / (span if span > 0 else 1.0)
    return factor[:, None] * np.asarray(material.eigenstrain_xyz, float)[None, :]


def solve_part(design, R, *, d_factor=None, stiffer=None, anisotropy=None, material=None, gradient=None):
    """The plate FEM of ``design`` (a :class:`~.designs.PlateDesign`) with at most one effect.

    Parameters
    ----------
    design : PlateDesign
    R : float
        The contraction ratio of the GDFE design the plate is meshed from (only its materials
        and coat thicknesses reach the FEM).
    d_factor : dict, optional
        ``{region: factor}`` on the coat thickness.
    stiffer : (str, float), optional
        ``(region, factor)`` on the coat's modulus.
    anisotropy : (float, int), optional
        ``(ratio, weak_axis)``.
    material : (nx, ny) int array, optional
        A misprinted material grid (:func:`offset_material`).
    gradient : (float, int), optional
        ``(spread, axis)`` of a contraction varying along the part (:func:`gradient_eigenstrain`).

    Returns
    -------
    reference_fem.PlateResult
    """
    import reference_fem as rf

    mat = rf.BilayerMaterial()
    plate = rf.plate_mesh(design.gdfe_design(R, material=material, d_factor=d_factor), **fem_options())
    if stiffer is not None:
        region, factor = stiffer
        plate = dataclasses.replace(plate, stiffness=coat_stiffness(plate, design.regions[region], factor))
    if anisotropy is not None:
        ratio, axis = anisotropy
        plate = dataclasses.replace(plate, eigenstrain=anisotropic_eigenstrain(plate, mat, ratio, axis))
    if gradient is not None:
        spread, axis = gradient
        plate = dataclasses.replace(plate, eigenstrain=gradient_eigenstrain(plate, mat, spread, axis))
    return rf.solve_plate(plate, mat)
