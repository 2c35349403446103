"""The paper's deformation principle: fold angle, contraction ratio and their calibration.

Eq. 1 (fold angle of a hinge of width ``L`` coated on one face)::

    alpha = K * sqrt(h / d**3) * L

Eq. 2 (a hinge that bends into a circular arc of angle ``alpha``, thickness ``h``)::

    R = 1 - alpha * h / L

Eq. 3 (Eq. 1 in Eq. 2)::

    R = 1 - K * (h / d)**1.5

All lengths in millimetres, angles in radians. ``K`` multiplies a length-free regressor
``sqrt(h/d**3) * L``, so it is dimensionless.

Every reading of Eq. 1 says the fold angle grows in proportion to the hinge width ``L``,
so Eq. 2 turns each into a contraction ratio ``R(d, h) = 1 - alpha h / L`` (a reading of
Eq. 3). :func:`fit_reading` fits three:

==========  =============================  ==========================  ============================
model       fold angle                     parameters                  Eq. 3 reading
==========  =============================  ==========================  ============================
``eq1``     ``K sqrt(h/d^3) L`` (printed)  K (dimensionless)           ``1 - K (h/d)^1.5``
``eq1-d1``  ``K sqrt(h/d) L``              K [1/mm]                    ``1 - K h (h/d)^0.5``
``power``   ``c (L/h) (h/d)^p``            c (dimensionless), p        ``1 - c (h/d)^p``
==========  =============================  ==========================  ============================

R² is reported about the mean (``r2``) and about zero (``r2_uncentered``).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import logging
import math

import numpy as np

from gdfe import paper
from gdfe._validation import (LENGTH_RANGE, GdfeError, check_array, check_choice, check_file, check_int, check_number,
                              check_positive, check_ratio, data_float, degenerate_tests, read_text)

log = logging.getLogger(__name__)

__all__ = [
    "TABLE1",
    "PAPER_K",
    "DEFAULT_H",
    "Calibration",
    "CalibrationFit",
    "READINGS",
    "fit_reading",
    "fit_quality",
    "held_out_rmse",
    "regressor",
    "FoldingTests",
    "load_folding_tests",
    "ratio_from_angle",
    "angle_from_ratio",
]

#: Table 1 of the paper (18 folding tests), shipped with the package.
TABLE1 = paper.TABLE1

#: K of Eq. 1 as printed in the paper.
PAPER_K = paper.K
#: Active-film thickness of all of the paper's tests [mm].
DEFAULT_H = paper.H


def ratio_from_angle(alpha, L, h=DEFAULT_H):
    """Eq. 2: contraction ratio of a hinge that folds by ``alpha`` [rad] over width ``L`` [mm].

    Raises
    ------
    ValueError
        Where the angle needs a ratio outside (0, 1]: a fold against the coat (alpha < 0) or
        one the film cannot reach, ``alpha >= L / h`` (it would have to vanish).
    """
    L = check_positive("L", L)
    h = check_positive("h", h)
    alpha = check_number("alpha", alpha, allow_array=True)
    R = 1.0 - alpha * h / L
    bad = (np.asarray(R) <= 0) | (np.asarray(R) > 1)
    if np.any(bad):
        a = np.atleast_1d(alpha)[np.atleast_1d(bad)][0]
        limit = np.atleast_1d(np.broadcast_to(L / h, np.shape(R)))[np.atleast_1d(bad)][0]
        raise GdfeError(f"alpha: expected a fold angle in [0, L/h) = [0, {limit:.4g}) rad for a contraction ratio in "
                        f"(0, 1], got {a:g}")
    return R


def angle_from_ratio(R, L, h=DEFAULT_H):
    """Eq. 2 inverted: fold angle [rad] of a fully contracting hinge, ``(1 - R) L / h``."""
    L = check_positive("L", L)
    h = check_positive("h", h)
    return (1.0 - check_ratio("R", R)) * L / h


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
            raise GdfeError(
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
        return fit_reading(tests, "eq1", n_boot=n_boot, seed=seed)


#: Bootstrap indices drawn at a time by :func:`fit_reading` (bounds its memory: 8 bytes each).
BOOTSTRAP_CHUNK = 4_000_000
#: Fewest resamples of a bootstrap interval (0 asks for none): its 2.5 and 97.5 percentiles
#: need at least this many to lie between resamples rather than on the few extreme ones.
MIN_BOOT = 100
#: Most resamples of a bootstrap interval (beyond it the interval changes in digits nobody reads).
MAX_BOOT = 100_000

#: The readings of Eq. 1 that :func:`fit_reading` fits (see the module docstring).
READINGS = ("eq1", "eq1-d1", "power")

#: What each reading says, in words.
DESCRIPTIONS = {
    "eq1": "alpha = K sqrt(h/d^3) L (Eq. 1 as printed)",
    "eq1-d1": "alpha = K sqrt(h/d) L (d to the first power)",
    "power": "alpha = c (L/h) (h/d)^p (exponent of d fitted)",
}


@dataclasses.dataclass(frozen=True)
class CalibrationFit:
    """A reading of Eq. 1 fitted to folding tests (or given, with :meth:`reading`).

    Attributes
    ----------
    model : str
        The reading, one of :data:`READINGS`.
    K : float
        ``K`` of ``eq1`` (dimensionless) or ``eq1-d1`` [1/mm]; ``c`` of ``power``.
    p : float
        Exponent of ``h/d`` (1.5 for ``eq1``, 0.5 for ``eq1-d1``, fitted for ``power``).
    r2 : float
        Coefficient of determination about the mean, ``1 - SS_res / SS_tot``.
    r2_uncentered : float
        ``1 - SS_res / sum(alpha**2)``, the convention some tools use for fits through the origin.
    rmse : float
        Root-mean-square residual [rad].
    n : int
        Number of tests (0 for a reading with no fit behind it).
    K_ci, p_ci : (2,) tuples
        95 % percentile-bootstrap intervals over the tests (``p_ci`` is ``(p, p)`` where p is fixed);
        ``(nan, nan)`` where no bootstrap was run (``n_boot=0``, or a reading with no fit).
    residuals : (n,) float array [rad]
        Measured minus fitted angle.
    """

    model: str
    K: float
    p: float
    r2: float
    r2_uncentered: float
    rmse: float
    n: int
    K_ci: tuple
    p_ci: tuple
    residuals: np.ndarray

    @classmethod
    def reading(cls, model, K, p):
        """The reading ``model`` with given ``K`` and ``p`` and no fit behind it (fit fields empty)."""
        check_choice("model", model, READINGS)
        return cls(model=model, K=K, p=p, r2=np.nan, r2_uncentered=np.nan, rmse=np.nan, n=0,
                   K_ci=(np.nan, np.nan), p_ci=(np.nan, np.nan) if model == "power" else (p, p),
                   residuals=np.zeros(0))

    @property
    def calibration(self) -> "Calibration":
        """Eq. 1-3 with this K (the ``eq1`` reading only)."""
        if self.model != "eq1":
            raise GdfeError(f"calibration: only the eq1 reading is Eq. 1-3 with a K, got {self.model!r}")
        return Calibration(K=self.K)

    def slope(self, d, h):
        """``alpha / L`` [rad/mm] of this reading."""
        return reading_slope(self.model, self.K, self.p, d, h)

    def alpha(self, L, d, h):
        """Fold angle [rad] of this reading."""
        return self.slope(d, h) * np.asarray(L, float)

    def ratio(self, d, h):
        """Eq. 3 of this reading: ``R = 1 - alpha h / L`` (may be <= 0 for thin passive layers)."""
        return 1.0 - self.slope(d, h) * np.asarray(h, float)

    def d_min(self, h):
        """Passive thickness [mm] below which this reading's Eq. 3 gives R <= 0."""
        if self.model == "eq1-d1":
            return h * (self.K * h) ** 2
        return h * self.K ** (1.0 / self.p)

    def as_dict(self):
        return {"model": self.model, "description": DESCRIPTIONS[self.model], "K": self.K, "p": self.p,
                "K_ci95": list(self.K_ci), "p_ci95": list(self.p_ci), "r2": self.r2,
                "r2_uncentered": self.r2_uncentered, "rmse": self.rmse, "n": self.n,
                "residuals": np.asarray(self.residuals).tolist()}

    def text(self):
        """Human-readable lines of the fit."""
        unit = " 1/mm" if self.model == "eq1-d1" else ""

        def ci(lo, hi):
            if not (math.isfinite(lo) and math.isfinite(hi)):
                return "no interval: no bootstrap was run"
            return f"95 % bootstrap CI {lo:.4f} .. {hi:.4f}"

        lines = [f"model  {self.model}: {DESCRIPTIONS[self.model]}", f"K      {self.K:.4f}{unit}  ({ci(*self.K_ci)})"]
        if self.model == "power":
            lines.append(f"p      {self.p:.4f}  ({ci(*self.p_ci)})")
        r2 = "undefined" if math.isnan(self.r2) else f"{self.r2:.4f}"
        r2u = "undefined" if math.isnan(self.r2_uncentered) else f"{self.r2_uncentered:.4f}"
        lines += [f"r2     {r2}  (about the mean; {r2u} about zero)"
                  + ("; every angle is the same, so there is no spread to explain" if math.isnan(self.r2) else ""),
                  f"rmse   {self.rmse:.4f} rad", f"n      {self.n}"]
        return "\n".join(lines)


def reading_slope(model, K, p, d, h):
    """``alpha / L`` [rad/mm] of a reading of Eq. 1 with coefficient ``K`` and exponent ``p``:
    ``K sqrt(h/d)`` (eq1-d1) or ``K / h (h/d)^p`` (eq1 is power with p = 1.5, power any p)."""
    d = np.asarray(d, float)
    h = np.asarray(h, float)
    if model == "eq1-d1":
        return K * np.sqrt(h / d)
    return K / h * (h / d) ** p


def regressor(model, L, d, h):
    """Abscissa of a through-origin reading: ``sqrt(h/d^3) L`` (eq1) or ``sqrt(h/d) L`` (eq1-d1)."""
    L, d, h = (np.asarray(v, float) for v in (L, d, h))
    if model == "eq1":
        return np.sqrt(h / d**3) * L
    if model == "eq1-d1":
        return np.sqrt(h / d) * L
    raise GdfeError(f"model: expected 'eq1' or 'eq1-d1' (a reading with one regressor), got {model!r}")


def fit_quality(y, fitted):
    """R² about the mean, R² about zero, rmse and residuals of ``fitted`` against ``y``.

    R² about the mean is NaN where every angle is the same (nothing varies to explain), and
    about zero where every angle is 0.
    """
    res = y - fitted
    ss = float(res @ res)
    ss_mean, ss_zero = float(((y - y.mean()) ** 2).sum()), float(y @ y)
    return (1.0 - ss / ss_mean if ss_mean > 0 else math.nan, 1.0 - ss / ss_zero if ss_zero > 0 else math.nan,
            math.sqrt(ss / y.size), res)


def _power_fit(x_over_h, q, y):
    """Least squares of ``y = c * x_over_h * q**p`` over c (closed form) and p (bounded search)."""
    from scipy.optimize import minimize_scalar

    lq = np.log(q)

    def sse(p):
        z = x_over_h * np.exp(p * lq)
        c = (z @ y) / (z @ z)
        r = y - c * z
        return r @ r

    opt = minimize_scalar(sse, bounds=(-2.0, 5.0), method="bounded", options={"xatol": 1e-8})
    p = float(opt.x)
    z = x_over_h * np.exp(p * lq)
    return float((z @ y) / (z @ z)), p


def fit_reading(tests, model="eq1", n_boot=2000, seed=0):
    """Fit one reading of Eq. 1 to folding tests.

    ``eq1`` and ``eq1-d1`` are fitted by least squares through the origin, ``power`` by
    least squares in ``alpha`` (``c`` in closed form for each ``p``, ``p`` by a bounded 1-D
    search). Intervals are 95 % percentile bootstraps over the tests.

    Parameters
    ----------
    tests : FoldingTests or str or Path
        The tests, or a CSV with columns ``L_mm, d_mm, h_mm, alpha_rad``.
    model : {"eq1", "eq1-d1", "power"}
    n_boot : int
        Bootstrap resamples: 0 (no interval) or from :data:`MIN_BOOT` to :data:`MAX_BOOT`.
    seed : int
        Seed of the bootstrap's random generator.

    Returns
    -------
    CalibrationFit
    """
    check_choice("model", model, READINGS)
    n_boot = check_boot("n_boot", n_boot)
    if not isinstance(tests, FoldingTests):
        tests = load_folding_tests(tests)
    L, d, h, y = tests.L, tests.d, tests.h, tests.alpha
    degenerate_tests("tests", L, d, h, y, same_angles=False)  # refuses what no fit can use
    n = y.size
    need = 3 if model == "power" else 2
    if n < need:
        raise GdfeError(f"tests: expected at least {need} folding tests to fit {model}, got {n}")
    if model == "power" and np.unique(h / d).size < 2:
        raise GdfeError("tests: expected at least two values of h/d to fit the exponent p of the power reading, "
                        f"got h/d = {float((h / d)[0]):.4g} in every test")
    rng = np.random.default_rng(seed)
    # resamples drawn in chunks of at most BOOTSTRAP_CHUNK indices: memory stays bounded for
    # any number of tests (one chunk, and the same numbers, for small data sets)
    per = max(1, BOOTSTRAP_CHUNK // n)
    chunks = [min(per, int(n_boot) - k) for k in range(0, int(n_boot), per)]
    if model == "power":
        K, p = _power_fit(L / h, h / d, y)
        fitted = K * (L / h) * (h / d) ** p
        boots = np.array([_power_fit((L / h)[i], (h / d)[i], y[i])
                          for k in chunks for i in rng.integers(0, n, size=(k, n))]).reshape(-1, 2)
        K_ci = tuple(np.percentile(boots[:, 0], [2.5, 97.5]).tolist()) if n_boot else (np.nan, np.nan)
        p_ci = tuple(np.percentile(boots[:, 1], [2.5, 97.5]).tolist()) if n_boot else (np.nan, np.nan)
    else:
        x = regressor(model, L, d, h)
        K = float(x @ y / (x @ x))
        p = 1.5 if model == "eq1" else 0.5
        fitted = K * x
        Kb = []
        for k in chunks:
            idx = rng.integers(0, n, size=(k, n))
            xb, yb = x[idx], y[idx]
            Kb.append((xb * yb).sum(1) / (xb * xb).sum(1))
        Kb = np.concatenate(Kb) if Kb else np.zeros(0)
        K_ci = tuple(np.percentile(Kb, [2.5, 97.5]).tolist()) if n_boot else (np.nan, np.nan)
        p_ci = (p, p)
    r2, r2u, rmse, res = fit_quality(y, fitted)
    if n_boot and not K_ci[0] <= K <= K_ci[1]:  # possible for a biased, skewed bootstrap of few tests
        log.warning("the 95 %% bootstrap interval of K (%.4g .. %.4g) excludes the fitted K = %.4g: with %d tests "
                    "the bootstrap is unreliable", K_ci[0], K_ci[1], K, n)
    return CalibrationFit(model=model, K=float(K), p=float(p), r2=r2, r2_uncentered=r2u, rmse=rmse, n=int(n),
                          K_ci=K_ci, p_ci=p_ci, residuals=res)


def check_boot(name, n_boot):
    """A number of bootstrap resamples: 0 (no interval) or from :data:`MIN_BOOT` to :data:`MAX_BOOT`."""
    n_boot = check_int(name, n_boot, minimum=0, maximum=MAX_BOOT)
    if 0 < n_boot < MIN_BOOT:
        raise GdfeError(f"{name}: expected 0 (no interval) or at least {MIN_BOOT} resamples for a 95 % interval, "
                        f"got {n_boot}")
    return n_boot


def held_out_rmse(tests, model="eq1"):
    """Leave-one-test-out RMSE [rad] of a reading of Eq. 1: each test predicted by the reading
    refitted to the others.

    ``eq1`` and ``eq1-d1`` in closed form (the through-origin fit without test ``i``:
    ``K_-i = (x.y - x_i y_i) / (x.x - x_i^2)``); ``power`` refitted once per test.
    """
    check_choice("model", model, READINGS)
    if not isinstance(tests, FoldingTests):
        tests = load_folding_tests(tests)
    L, d, h, y = tests.L, tests.d, tests.h, tests.alpha
    n = y.size
    need = 4 if model == "power" else 3
    if n < need:
        raise GdfeError(f"tests: expected at least {need} folding tests to hold one out for {model}, got {n}")
    if model == "power":
        keep = np.ones(n, bool)
        pred = np.empty(n)
        for i in range(n):
            keep[i] = False
            c, p = _power_fit((L / h)[keep], (h / d)[keep], y[keep])
            pred[i] = c * (L[i] / h[i]) * (h[i] / d[i]) ** p
            keep[i] = True
    else:
        x = regressor(model, L, d, h)
        pred = (x @ y - x * y) / (x @ x - x * x) * x
    return float(np.sqrt(np.mean((y - pred) ** 2)))


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

    def __post_init__(self):
        arrays = {}
        for name in ("L", "d", "h", "alpha"):
            a = check_array(name, np.atleast_1d(getattr(self, name)), ndim=1)
            if name != "alpha":
                check_positive(name, a)
            arrays[name] = a
        sizes = {a.size for a in arrays.values()}
        if len(sizes) != 1:
            raise GdfeError(f"L, d, h, alpha: expected arrays of one length, got lengths "
                            f"{', '.join(str(a.size) for a in arrays.values())}")
        for name, a in arrays.items():
            object.__setattr__(self, name, a)

    def __len__(self):
        return int(self.L.size)


_COLUMNS = ("L_mm", "d_mm", "h_mm", "alpha_rad")
#: Largest fold angle a folding test may report [rad]: three turns (larger values are degrees).
MAX_ANGLE = 6 * math.pi
#: Errors a message lists before it says how many more there are.
MAX_ERRORS = 5


def _warn_repeated_rows(name, lines, rows):
    """Warn of rows that repeat an earlier one in every column: a test pasted twice weighs twice in every fit,
    while a real replicate (the same design printed again) rarely measures the same angle to the last digit."""
    first, repeats = {}, []
    for line, row in zip(lines, rows):
        if row in first:
            repeats.append(f"{line} (= {first[row]})")
        else:
            first[row] = line
    if repeats:
        log.warning("%s: row(s) %s repeat an earlier row in every column, the angle included; a test pasted "
                    "twice counts twice in every fit: remove it unless it is a replicate", name,
                    ", ".join(repeats[:5]) + (f" and {len(repeats) - 5} more" if len(repeats) > 5 else ""))


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
    path = check_file("folding tests", path, what="CSV file")
    text = read_text(path, "CSV file of folding tests")
    try:
        reader = csv.DictReader(io.StringIO(text, newline=""))
        header = [c.strip() for c in (reader.fieldnames or [])]
        reader.fieldnames = header
        required = [c for c in _COLUMNS if not (c == "h_mm" and default_h is not None)]
        missing = [c for c in required if c not in header]
        if missing:
            raise GdfeError(
                f"{path.name}: missing column(s) {', '.join(missing)}; expected {', '.join(_COLUMNS)}, "
                f"got {', '.join(header) or 'no header'}"
            )
        twice = sorted({c for c in header if header.count(c) > 1})
        if twice:
            raise GdfeError(f"{path.name}: expected each column once, got {', '.join(twice)} more than once")
        numbered = [(reader.line_num, row) for row in reader]  # the row's line: blank lines are skipped
    except csv.Error as exc:
        raise GdfeError(f"{path.name}: line {reader.line_num}: not a readable CSV row ({exc})") from None
    for i, row in numbered:
        if any((v or "").strip() for v in row.get(None, ())):  # more fields than the header names
            raise GdfeError(f"{path.name}: row {i}: expected {len(header)} fields (the header's), got "
                            f"{len(header) + len(row[None])}")
    if not numbered:
        raise GdfeError(f"{path.name}: no data rows")
    cols = {c: [] for c in _COLUMNS}
    extra = {c: [] for c in header if c not in _COLUMNS}
    errors = []
    for i, row in numbered:
        for c in _COLUMNS:
            raw = (row.get(c) or "").strip()
            if c == "h_mm" and raw == "" and default_h is not None:
                cols[c].append(float(default_h))
                continue
            try:
                v = data_float(raw)
            except ValueError:
                errors.append(f"row {i}, column {c}: expected a number, got {raw!r}")
                cols[c].append(math.nan)
                continue
            if not math.isfinite(v):
                errors.append(f"row {i}, column {c}: expected a finite number, got {raw!r}")
            elif c != "alpha_rad" and v <= 0:
                errors.append(f"row {i}, column {c}: expected a positive length in mm, got {v:g}")
            elif c != "alpha_rad" and not LENGTH_RANGE[0] <= v <= LENGTH_RANGE[1]:
                errors.append(f"row {i}, column {c}: expected a length between {LENGTH_RANGE[0]:g} and "
                              f"{LENGTH_RANGE[1]:g} mm, got {v:g}")
            elif c == "alpha_rad" and abs(v) > MAX_ANGLE:
                errors.append(f"row {i}, column {c}: expected a fold angle in radians of at most {MAX_ANGLE:.4g} "
                              f"(three turns), got {v:g} (degrees?)")
            cols[c].append(v)
        for c in extra:
            extra[c].append((row.get(c) or "").strip())
    if errors:
        shown = errors[:MAX_ERRORS] + ([f"and {len(errors) - MAX_ERRORS} more"] if len(errors) > MAX_ERRORS else [])
        raise GdfeError(f"{path.name}: " + "; ".join(shown))
    _warn_repeated_rows(path.name, [i for i, _ in numbered], [tuple((row.get(c) or "").strip() for c in header)
                                                               for _, row in numbered])
    return FoldingTests(
        L=np.array(cols["L_mm"]), d=np.array(cols["d_mm"]), h=np.array(cols["h_mm"]),
        alpha=np.array(cols["alpha_rad"]), extra={k: np.array(v) for k, v in extra.items()},
    )
