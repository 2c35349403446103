"""The small plates the shape benchmark prints: material grids with named regions.

Two designs on 0.5 mm pixels, h = 0.29 mm, d = 0.33 mm, each with two hinges 1 mm wide
(two pixels) between rigid panels (coated on both faces):

- ``strip``: a 7 x 2 mm strip; ``hinge_a`` at x = 1.5-2.5 mm coated underneath (it folds
  towards the top), ``hinge_b`` at x = 3.5-4.5 mm coated on top (it folds the other way);
  both bend about y;
- ``ell``: an L of two 2 mm wide arms 6 mm long; ``hinge_a`` across the x arm at x = 3.5-4.5 mm
  (bends about y, coated underneath), ``hinge_b`` across the y arm at y = 2.5-3.5 mm (bends
  about x, coated on top).

Neither design is symmetric under a rotation that maps one hinge onto the other (an S-strip
with equal end panels is: turned over end to end it is the same shape, and a scan could not
say which hinge is which); their end panels differ in length.

Every cell belongs to one named region (``panel_*`` rigid, ``hinge_*`` contracting on one face);
the regions travel with the design (``regions2d``), so the shape diagnosis reports on the
names the generators put their effects in. Lengths in mm.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gdfe import paper
from gdfe._validation import check_choice
from gdfe.material import Material

__all__ = ["PlateDesign", "DESIGNS", "plate_design", "H", "D", "PIXEL"]

H = paper.H
D = paper.FIG6_D
PIXEL = 0.5
#: The designs, by name.
DESIGNS = ("strip", "ell")


@dataclasses.dataclass(frozen=True)
class PlateDesign:
    """A plate design as printed.

    Attributes
    ----------
    name : str
    material : (nx, ny) int array
        :class:`gdfe.Material` code of each pixel (meaningless where there is no film).
    film : (nx, ny) bool array
    regions : dict of str -> (nx, ny) bool array
        Named regions; together they cover the film once.
    pixel : float [mm]
    """

    name: str
    material: np.ndarray
    film: np.ndarray
    regions: dict
    pixel: float = PIXEL

    @property
    def hinges(self):
        """Names of the contracting regions (where a coat effect can be put)."""
        return tuple(k for k in self.regions if k.startswith("hinge"))

    def d(self, factor=None):
        """Coat thickness of every pixel [mm] (NaN where no face is coated on one side only);
        ``factor``: ``{region: multiplier}`` of the coat thickness there."""
        one_side = np.isin(self.material, (int(Material.CONTRACT_TOP), int(Material.CONTRACT_BOTTOM)))
        d = np.where(one_side & self.film, D, np.nan)
        for name, f in (factor or {}).items():
            d = np.where(self.regions[name], d * f, d)
        return d

    def gdfe_design(self, R, material=None, d_factor=None):
        """The GDFE design with contraction ratio ``R`` on every free face.

        ``material`` (another grid, e.g. a misprinted one) and ``d_factor`` (see :meth:`d`)
        are for the reference FEM's part; the design given to a diagnosis is the nominal one.
        """
        import gdfe

        mat = self.material if material is None else material
        return gdfe.grid_design(np.where(self.film, mat, int(Material.RIGID)), float(R), h=H, pixel=self.pixel,
                                nz=1, film=self.film, regions2d=dict(self.regions),
                                d=self.d(d_factor) if material is None else _d_of(mat, self.film),
                                meta={"d_mm": D, "d_top_mm": D, "d_bottom_mm": D})


def _d_of(material, film):
    one_side = np.isin(material, (int(Material.CONTRACT_TOP), int(Material.CONTRACT_BOTTOM)))
    return np.where(one_side & film, D, np.nan)


def _cells(mm):
    return int(round(mm / PIXEL))


def plate_design(name):
    """The design ``name`` (one of :data:`DESIGNS`)."""
    check_choice("design", name, DESIGNS)
    top, bottom = int(Material.CONTRACT_TOP), int(Material.CONTRACT_BOTTOM)
    if name == "strip":
        nx, ny = _cells(7.0), _cells(2.0)
        x = (np.arange(nx) + 0.5) * PIXEL
        X = np.repeat(x[:, None], ny, axis=1)
        film = np.ones((nx, ny), bool)
        a, b = (X >= 1.5) & (X < 2.5), (X >= 3.5) & (X < 4.5)
        regions = {"panel_1": X < 1.5, "hinge_a": a, "panel_2": (X >= 2.5) & (X < 3.5), "hinge_b": b,
                   "panel_3": X >= 4.5}
    else:
        n = _cells(6.0)
        c = (np.arange(n) + 0.5) * PIXEL
        X, Y = np.meshgrid(c, c, indexing="ij")
        film = (Y < 2.0) | (X < 2.0)
        a = (X >= 3.5) & (X < 4.5) & (Y < 2.0)
        b = (Y >= 2.5) & (Y < 3.5) & (X < 2.0)
        regions = {"panel_corner": film & (X < 3.5) & (Y < 2.5), "hinge_a": a,
                   "panel_x": (X >= 4.5) & (Y < 2.0), "hinge_b": b, "panel_y": (Y >= 3.5) & (X < 2.0)}
    material = np.full(film.shape, int(Material.RIGID))
    material[a], material[b] = top, bottom
    return PlateDesign(name=name, material=material, film=film, regions=regions)
