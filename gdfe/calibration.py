"""The paper's deformation principle: fold angle, contraction ratio and their calibration.

Eq. 1 (fold angle of a hinge of width ``L`` coated on one face)::

    alpha = K * sqrt(h / d**3) * L

Eq. 2 (a hinge that bends into a circular arc of angle ``alpha``, thickness ``h``)::

    R = 1 - alpha * h / L

Eq. 3 (Eq. 1 in Eq. 2)::

    R = 1 - K * (h / d)**1.5

All lengths in millimetres, angles in radians. ``K`` multiplies a length-free regressor
``sqrt(h/d**3) * L``, so it is dimensionless.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np

from gdfe._validate import check_positive

__all__ = [
    "TABLE1",
    "PAPER_K",
    "DEFAULT_H",
    "Calibration",
    "CalibrationFit",
    "FoldingTests",
    "load_folding_tests",
    "ratio_from_angle",
    "angle_from_ratio",
]

#: Table 1 of the paper (18 folding tests), shipped with the package.
TABLE1 = Path(__file__).resolve().parent / "data" / "table1.csv"

#: K of Eq. 1 as printed in the paper.
PAPER_K = 0.3706
#: Active-film thickness of all of the paper's tests [mm].
DEFAULT_H = 0.29


def ratio_from_angle(alpha, L, h=DEFAULT_H):
    """Eq. 2: contraction ratio of a hinge that folds by ``alpha`` [rad] over width ``L`` [mm]."""
    L = check_positive("L", L)
    h = check_positive("h", h)
    return 1.0 - np.asarray(alpha, dtype=float) * h / L


def angle_from_ratio(R, L, h=DEFAULT_H):
    """Eq. 2 inverted: fold angle [rad] of a fully contracting hinge, ``(1 - R) L / h``."""
    L = check_positive("L", L)
    h = check_positive("h", h)
    return (1.0 - np.asarray(R, dtype=float)) * L / h


@dataclasses.dataclass(frozen=True)
class Calibration:
    """Eq. 1-3 with a coefficient ``K``.

    Parameters
    ----------
    K : float
        Coefficient of Eq. 1 (dimensionless). Default: the paper's 0.3706.
    h : float
        Default active-film thickness [mm].
    """

    K: float = PAPER_K
    h: float = DEFAULT_H

    def __post_init__(self):
        check_positive("K", self.K)
        check_positive("h", self.h)

    def regressor(self, L, d, h=None):
        """``sqrt(h / d**3) * L``, the abscissa of the paper's Fig. 2 (dimensionless)."""
        h = self.h if h is None else h
        return np.sqrt(check_positive("h", h) / check_positive("d", d) ** 3) * check_positive("L", L)

    def alpha(self, L, d, h=None):
        """Eq. 1: fold angle [rad] of a hinge of width ``L`` [mm], passive thickness ``d`` [mm]."""
        return self.K * self.regressor(L, d, h)

    def ratio(self, d, h=None):
        """Eq. 3: contraction ratio R of the film's free face for passive thickness ``d`` [mm].

        Raises
        ------
        ValueError
            If the calibration gives R <= 0 for this ``d`` (a thin passive layer with a
            large K): such a film would have to vanish, so no simulation is run with it.
        """
        h = self.h if h is None else h
        d_arr = check_positive("d", d)
        h = check_positive("h", h)
        R = 1.0 - self.K * (h / d_arr) ** 1.5
        if np.any(R <= 0):
            bad = np.atleast_1d(d_arr)[np.atleast_1d(R) <= 0][0]
            Rb = 1.0 - self.K * (h / bad) ** 1.5
            raise ValueError(
                f"d={bad:g} mm gives R={Rb:.4g} by Eq. 3 (K={self.K:g}, h={h:g} mm); "
                f"a contraction ratio must lie in (0, 1], which needs d > {self.d_min(h):.4g} mm"
            )
        return R

    def d_min(self, h=None):
        """Thinnest passive layer [mm] for which Eq. 3 gives R > 0: ``h * K**(2/3)``."""
        h = self.h if h is None else h
        return check_positive("h", h) * self.K ** (2.0 / 3.0)

    @classmethod
    def fit(cls, tests, n_boot=2000, seed=0):
        """Refit K of Eq. 1 to folding tests by least squares through the origin.

        Parameters
        ----------
        tests : FoldingTests or str or Path
            The tests, or the path of a CSV with columns ``L_mm, d_mm, h_mm, alpha_rad``.
        n_boot : int
            Bootstrap resamples for the 95 % confidence interval of K.
        seed : int
            Seed of the bootstrap's random generator.

        Returns
        -------
        CalibrationFit
        """
        if not isinstance(tests, FoldingTests):
            tests = load_folding_tests(tests)
        x = np.sqrt(tests.h / tests.d**3) * tests.L
        return _fit_through_origin(x, tests.alpha, n_boot, seed, "eq1", cls)


@dataclasses.dataclass(frozen=True)
class CalibrationFit:
    """A least-squares fit of ``alpha = K x`` to folding tests.

    Attributes
    ----------
    K : float
        Fitted coefficient.
    r2 : float
        Coefficient of determination about the mean, ``1 - SS_res / SS_tot``.
    r2_uncentered : float
        ``1 - SS_res / sum(alpha**2)``, the convention some tools use for fits through the origin.
    rmse : float
        Root-mean-square residual [rad].
    n : int
        Number of tests.
    K_ci : tuple of float
        95 % bootstrap confidence interval of K (percentile method).
    residuals : (n,) float array [rad]
        Measured minus fitted angle.
    model : str
        Name of the regressor (``"eq1"``: ``sqrt(h/d^3) L``).
    """

    K: float
    r2: float
    r2_uncentered: float
    rmse: float
    n: int
    K_ci: tuple
    residuals: np.ndarray
    model: str
    calibration: Calibration

    def as_dict(self):
        return {
            "model": self.model,
            "K": self.K,
            "K_ci95": list(self.K_ci),
            "r2": self.r2,
            "r2_uncentered": self.r2_uncentered,
            "rmse": self.rmse,
            "n": self.n,
            "residuals": self.residuals.tolist(),
        }


def _fit_through_origin(x, y, n_boot, seed, model, cls=Calibration):
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if x.size < 2:
        raise ValueError(f"tests: need at least 2 folding tests to fit K, got {x.size}")
    K = float(x @ y / (x @ x))
    res = y - K * x
    ss = float(res @ res)
    r2 = 1.0 - ss / float(((y - y.mean()) ** 2).sum())
    r2u = 1.0 - ss / float(y @ y)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, x.size, size=(int(n_boot), x.size))
    xb, yb = x[idx], y[idx]
    Kb = (xb * yb).sum(1) / (xb * xb).sum(1)
    ci = (float(np.percentile(Kb, 2.5)), float(np.percentile(Kb, 97.5)))
    return CalibrationFit(
        K=K, r2=r2, r2_uncentered=r2u, rmse=math.sqrt(ss / x.size), n=int(x.size), K_ci=ci,
        residuals=res, model=model, calibration=cls(K=K),
    )


@dataclasses.dataclass(frozen=True)
class FoldingTests:
    """Folding tests: hinge width ``L``, passive ``d`` and active ``h`` thickness [mm], angle [rad].

    ``extra`` holds any further columns of the CSV (strings), e.g. a group or a temperature.
    """

    L: np.ndarray
    d: np.ndarray
    h: np.ndarray
    alpha: np.ndarray
    extra: dict = dataclasses.field(default_factory=dict)

    def __len__(self):
        return int(self.L.size)


_COLUMNS = ("L_mm", "d_mm", "h_mm", "alpha_rad")


def load_folding_tests(path, default_h=None):
    """Read folding tests from a CSV with columns ``L_mm, d_mm, h_mm, alpha_rad``.

    ``h_mm`` may be omitted when ``default_h`` is given. Further columns are kept as
    strings in :attr:`FoldingTests.extra`.

    Raises
    ------
    ValueError
        Naming the row (1-based, header is row 1) and column of each missing, non-numeric
        or non-positive value, or the missing columns.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"folding-test CSV not found: {path}")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        header = [c.strip() for c in (reader.fieldnames or [])]
        reader.fieldnames = header
        required = [c for c in _COLUMNS if not (c == "h_mm" and default_h is not None)]
        missing = [c for c in required if c not in header]
        if missing:
            raise ValueError(
                f"{path.name}: missing column(s) {', '.join(missing)}; expected {', '.join(_COLUMNS)}, "
                f"got {', '.join(header) or 'no header'}"
            )
        rows = list(reader)
    if not rows:
        raise ValueError(f"{path.name}: no data rows")
    cols = {c: [] for c in _COLUMNS}
    extra = {c: [] for c in header if c not in _COLUMNS}
    errors = []
    for i, row in enumerate(rows, start=2):
        for c in _COLUMNS:
            raw = (row.get(c) or "").strip()
            if c == "h_mm" and raw == "" and default_h is not None:
                cols[c].append(float(default_h))
                continue
            try:
                v = float(raw)
            except ValueError:
                errors.append(f"row {i}, column {c}: expected a number, got {raw!r}")
                cols[c].append(math.nan)
                continue
            if not math.isfinite(v):
                errors.append(f"row {i}, column {c}: expected a finite number, got {raw!r}")
            elif c != "alpha_rad" and v <= 0:
                errors.append(f"row {i}, column {c}: expected a positive length in mm, got {v:g}")
            cols[c].append(v)
        for c in extra:
            extra[c].append((row.get(c) or "").strip())
    if errors:
        raise ValueError(f"{path.name}: " + "; ".join(errors))
    return FoldingTests(
        L=np.array(cols["L_mm"]), d=np.array(cols["d_mm"]), h=np.array(cols["h_mm"]),
        alpha=np.array(cols["alpha_rad"]), extra={k: np.array(v) for k, v in extra.items()},
    )
