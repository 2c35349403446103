"""Materials of the heat-shrinking bilayer: elastic constants and the film's contraction eigenstrain.

Units: moduli in MPa (N/mm²), strains dimensionless. Only the ratio
``E_passive / E_active``, the Poisson's ratios and the eigenstrain change a shape; the
absolute modulus only scales the stresses.

Defaults and where they come from
---------------------------------
``E_passive = 1500 MPa``
    The printed acrylate resin; cured acrylate photopolymers measure 1-3 GPa at room temperature.
    Only the ratio to the film's modulus matters for a shape, so this just sets the stress scale.
``E_active = E_passive / 8.58 = 175 MPa``
    What counts is the film's stiffness while it shrinks, near and above the glass transition of
    polystyrene (glassy polystyrene: 3.0-3.5 GPa at room temperature; rubbery, above T_g: a few MPa),
    where neither modulus is known. The ratio ``E_passive / E_active = 8.58``
    (:data:`CALIBRATED_E_RATIO`) is the one the linear hinge FEM fits to the 18 folding tests of
    the paper's Table 1 (``gdfe fem calibrate``; RMSE 0.264 rad, leave-one-out
    RMSE 0.301 rad).
``nu_active = nu_passive = 0.35``
    Typical of glassy polymers (polystyrene 0.33-0.35, acrylates 0.35-0.40).
``eigenstrain = -0.160``
    The free in-plane contraction of the film, ``eps* = R_free - 1``, fitted together with the
    modulus ratio (:data:`CALIBRATED_EIGENSTRAIN`). Pre-strained polystyrene ("Shrinky Dinks")
    film shrinks by up to 50-60 % in-plane when fully activated; the smaller effective value
    reflects the limited heating of the printed specimens and whatever the linear model lumps into
    it. A scalar is isotropic in-plane (``eps*_xx = eps*_yy``, ``eps*_zz = 0``); a triple
    ``(eps*_xx, eps*_yy, eps*_zz)`` gives an anisotropic film.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from gdfe import _validation as v
from gdfe._validation import GdfeError

__all__ = ["BilayerMaterial", "CALIBRATED_E_RATIO", "CALIBRATED_EIGENSTRAIN", "DEFAULT_E_PASSIVE"]

#: ``E_passive / E_active`` fitted to Table 1 by the linear hinge model (``gdfe fem calibrate``,
#: default resolution, nu = 0.35, 1 mm wide hinges with 2 mm panels).
CALIBRATED_E_RATIO = 8.58
#: Effective free in-plane contraction of the film fitted together with :data:`CALIBRATED_E_RATIO`.
CALIBRATED_EIGENSTRAIN = -0.160
#: Modulus of the passive coat [MPa]; sets the stress scale only.
DEFAULT_E_PASSIVE = 1500.0


@dataclass(frozen=True)
class BilayerMaterial:
    """Elastic constants of the two layers and the contraction of the active film.

    Parameters
    ----------
    E_active : float [MPa]
        Young's modulus of the active (pre-strained polystyrene) film, > 0.
    E_passive : float [MPa]
        Young's modulus of the passive (printed acrylate) layer, > 0.
    nu_active, nu_passive : float
        Poisson's ratios, -1 < nu < 0.5.
    eigenstrain : float or (3,) sequence of float
        Free contraction of the active film, ``eps* = R_free - 1`` > -1. A scalar applies to both
        in-plane directions (``eps*_zz = 0``); a triple ``(xx, yy, zz)`` sets each axis.

    Examples
    --------
    >>> BilayerMaterial(E_active=175.0, E_passive=1500.0, eigenstrain=-0.1).eigenstrain_xyz
    (-0.1, -0.1, 0.0)
    """

    E_active: float = DEFAULT_E_PASSIVE / CALIBRATED_E_RATIO
    E_passive: float = DEFAULT_E_PASSIVE
    nu_active: float = 0.35
    nu_passive: float = 0.35
    eigenstrain: float | tuple = CALIBRATED_EIGENSTRAIN
    eigenstrain_xyz: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "E_active", v.check_positive("E_active", self.E_active))
        object.__setattr__(self, "E_passive", v.check_positive("E_passive", self.E_passive))
        object.__setattr__(self, "nu_active", v.check_poisson("nu_active", self.nu_active))
        object.__setattr__(self, "nu_passive", v.check_poisson("nu_passive", self.nu_passive))
        eps = self.eigenstrain
        if isinstance(eps, (list, tuple)) or getattr(eps, "shape", None) == (3,):
            if len(eps) != 3:
                raise GdfeError(f"eigenstrain: expected a number or a triple (xx, yy, zz), got {eps!r}")
            xyz = tuple(v.check_number(f"eigenstrain[{i}]", e, minimum=-1.0, include_minimum=False, what="a strain > -1 (a free stretch 1 + strain > 0)") for i, e in enumerate(eps))
            object.__setattr__(self, "eigenstrain", xyz)
        else:
            e = v.check_number("eigenstrain", eps, minimum=-1.0, include_minimum=False, what="a strain > -1 (a free stretch 1 + strain > 0)")
            object.__setattr__(self, "eigenstrain", e)
            xyz = (e, e, 0.0)
        object.__setattr__(self, "eigenstrain_xyz", xyz)

    @classmethod
    def from_ratio(cls, E_ratio: float, eigenstrain, *, E_passive: float = DEFAULT_E_PASSIVE,
                   nu: float = 0.35) -> "BilayerMaterial":
        """BilayerMaterial with ``E_active = E_passive / E_ratio`` and one Poisson's ratio for both layers."""
        E_ratio = v.check_positive("E_ratio", E_ratio)
        E_passive = v.check_positive("E_passive", E_passive)
        nu = v.check_poisson("nu", nu)
        return cls(E_active=E_passive / E_ratio, E_passive=E_passive, nu_active=nu, nu_passive=nu,
                   eigenstrain=eigenstrain)

    @property
    def E_ratio(self) -> float:
        """``E_passive / E_active``."""
        return self.E_passive / self.E_active

    @property
    def isotropic(self) -> bool:
        """True when the in-plane eigenstrain is the same along x and y and zero through the thickness."""
        ex, ey, ez = self.eigenstrain_xyz
        return ex == ey and ez == 0.0

    def scaled(self, factor: float) -> "BilayerMaterial":
        """The same material with every eigenstrain component multiplied by ``factor``."""
        return BilayerMaterial(self.E_active, self.E_passive, self.nu_active, self.nu_passive,
                        tuple(factor * e for e in self.eigenstrain_xyz))

    def lame(self, which: str) -> tuple[float, float]:
        """Lamé constants ``(lambda, mu)`` [MPa] of the ``"active"`` or ``"passive"`` layer."""
        v.check_choice("which", which, {"active", "passive"})
        E, nu = ((self.E_active, self.nu_active) if which == "active"
                 else (self.E_passive, self.nu_passive))
        return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
