"""Predicted fold angles with intervals, and what each interval is made of.

A model file with predictive content (:class:`gdfe.model.Uncertainty`, and from a diagnosis
the members of its named set with their weights, :mod:`gdfe.predictive`) predicts the fold
angle of a hinge specimen ``(L, d, h)`` — as it would be measured the way its tests were —
as a mixture over the members ``k`` with weights ``w_k``:

* member ``k``'s mean ``mu_k`` is its closed form (:meth:`gdfe.DeformationModel.hinge_angle`,
  what GDFE gives the hinge up to its discretisation) plus its fitted reading offset; with
  ``simulate`` the closed form is replaced by a GDFE solve of the hinge;
* **parameters**: ``s_par,k^2 = g^T C_k g``, ``g`` the derivative of ``mu_k`` with respect to
  the fitted parameters (central differences), ``C_k`` their covariance (the delta method);
* **noise**: ``s_noise,k``, the scatter of a new test about the model (the fit's residual
  scatter, with ``n - k`` degrees of freedom);
* **model choice**: the spread of the members' means, ``sum_k w_k (mu_k - mu)^2``.

The combined interval at ``level`` is the central interval of the mixture
``sum_k w_k (mu_k + sqrt(s_par,k^2 + s_noise,k^2) t_dof_k)`` (Student's t with the member's
degrees of freedom). The parts are reported as standard deviations (they add as variances
to the mixture's, by the law of total variance) and each as a normal interval about the
mean at the same level, alone.

A model without predictive content (a file of format 1, the paper's model) takes its
parameters' standard errors as uncorrelated and needs the noise given (``noise=``) or the
held-out RMSE it carries. Angles in radians, lengths in mm.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math

import numpy as np

from gdfe import paper
from gdfe._validation import LENGTH_RANGE, GdfeError, check_choice, check_file, check_number, data_float, read_text
from gdfe.calibration import MAX_ANGLE
from gdfe.model import DeformationModel, Member, Uncertainty

#: A member's parameter part (standard deviation) beyond which its linearisation says nothing:
#: a fold angle lies in [0, 2 pi], so a spread of pi covers half of all the folds there are [rad].
PARAMETER_SD_MAX = math.pi

__all__ = ["HingeSpecimens", "Prediction", "predict", "load_specimens", "members_of", "closed_form_jacobian", "draw_models",
           "mixture_interval", "LEVEL"]

#: Default level of the intervals.
LEVEL = 0.9
#: Relative step of the central differences of the closed form in a parameter.
STEP = 1e-5


@dataclasses.dataclass(frozen=True)
class HingeSpecimens:
    """Hinge specimens to predict: widths, passive and film thickness [mm], process columns,
    and the measured angles where the table has them.

    Attributes
    ----------
    L, d, h : (n,) float arrays [mm]
    extra : dict of str -> (n,) str array
        Further columns (process variables, group labels).
    alpha : (n,) float array or None [rad]
        Measured angles (an ``alpha_rad`` column), for the coverage of the intervals.
    """

    L: np.ndarray
    d: np.ndarray
    h: np.ndarray
    extra: dict = dataclasses.field(default_factory=dict)
    alpha: np.ndarray | None = None

    def __len__(self):
        return int(np.size(self.L))

    def process(self, i, model):
        """The process variables of row ``i`` that ``model`` (or a member) needs."""
        cols = dict((c, m) for m, c in model.columns.items())
        for mem in model.ensemble:
            cols.update((c, m) for m, c in mem.model.columns.items())
        out = {}
        for c, mech in cols.items():
            if c not in self.extra:
                raise GdfeError(f"specimens: model {model.name!r} needs column {c!r} ({mech}); columns: "
                                f"{', '.join(self.extra) or 'none besides L_mm, d_mm, h_mm'}")
            v = str(self.extra[c][i])
            if mech == "batch":
                out[c] = v  # a group label
                continue
            try:
                out[c] = data_float(v)  # as the specimens' own columns: 1_50 is not 150
            except ValueError:
                raise GdfeError(f"specimens: row {i + 2}, column {c}: expected a number ({mech}), got {v!r}") from None
        return out


#: The columns :func:`load_specimens` reads; any other is a process column or a label, carried to the output.
SPECIMEN_COLUMNS = ("L_mm", "d_mm", "h_mm", "alpha_rad")


def _check_extra_columns(name, header):
    """Refuse a column that is a misspelling of one of :data:`SPECIMEN_COLUMNS` the file lacks (``h_mn``,
    ``alpha_deg``): read as a label, its values would be left out of the prediction without a word."""
    import difflib

    absent = [c for c in SPECIMEN_COLUMNS if c not in header]
    for c in header:
        if c in SPECIMEN_COLUMNS:
            continue
        near = difflib.get_close_matches(c, absent, n=1, cutoff=0.75)
        if near:
            raise GdfeError(f"{name}: column {c!r}: did you mean {near[0]!r}? Expected {', '.join(SPECIMEN_COLUMNS)} "
                            f"(lengths in mm, angles in radians); other columns are process variables or labels")


def load_specimens(path):
    """Read specimens from a CSV with columns ``L_mm, d_mm`` and optionally ``h_mm`` (default the
    paper's film, 0.29 mm), ``alpha_rad`` (measured angles) and any process columns.

    Raises
    ------
    GdfeError
        Naming the file, row (the header is row 1) and column of a missing or bad value.
    """
    path = check_file("specimens", path, what="CSV file")
    text = read_text(path, "CSV file of specimens")
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise GdfeError(f"{path.name}: not a readable CSV ({exc})") from None
    rows = [(i + 1, r) for i, r in enumerate(rows) if any(c.strip() for c in r)]
    if not rows:
        raise GdfeError(f"{path.name}: expected a header and rows, got an empty file")
    header = [c.strip() for c in rows[0][1]]
    missing = [c for c in ("L_mm", "d_mm") if c not in header]
    if missing:
        raise GdfeError(f"{path.name}: missing column(s) {', '.join(missing)}; expected L_mm, d_mm and optionally "
                        f"h_mm, alpha_rad and process columns, got {', '.join(header) or 'no header'}")
    if not rows[1:]:
        raise GdfeError(f"{path.name}: no data rows")
    _check_extra_columns(path.name, header)
    cols = {c: [] for c in header}
    for line, r in rows[1:]:
        if len(r) != len(header):
            raise GdfeError(f"{path.name}: row {line}: expected {len(header)} fields (the header's), got {len(r)}")
        for c, v in zip(header, r):
            cols[c].append(v.strip())

    def numbers(c, positive):
        out = []
        for (line, _), v in zip(rows[1:], cols[c]):
            try:
                x = data_float(v)
            except ValueError:
                raise GdfeError(f"{path.name}: row {line}, column {c}: expected a number, got {v!r}") from None
            if not math.isfinite(x) or (positive and x <= 0):
                raise GdfeError(f"{path.name}: row {line}, column {c}: expected a "
                                f"{'positive length in mm' if positive else 'finite angle in rad'}, got {v!r}")
            if positive and not LENGTH_RANGE[0] <= x <= LENGTH_RANGE[1]:  # as gdfe calibrate reads lengths
                raise GdfeError(f"{path.name}: row {line}, column {c}: expected a length between {LENGTH_RANGE[0]:g} "
                                f"and {LENGTH_RANGE[1]:g} mm, got {v!r}")
            if not positive and abs(x) > MAX_ANGLE:  # as gdfe calibrate reads measured angles
                raise GdfeError(f"{path.name}: row {line}, column {c}: expected a fold angle in radians of at most "
                                f"{MAX_ANGLE:.4g} (three turns), got {v!r} (degrees?)")
            out.append(x)
        return np.array(out)

    L, d = numbers("L_mm", True), numbers("d_mm", True)
    h = numbers("h_mm", True) if "h_mm" in cols else np.full(L.size, paper.H)
    alpha = numbers("alpha_rad", False) if "alpha_rad" in cols else None
    extra = {c: np.array(v) for c, v in cols.items() if c not in ("L_mm", "d_mm", "h_mm", "alpha_rad")}
    return HingeSpecimens(L=L, d=d, h=h, extra=extra, alpha=alpha)


def members_of(model, noise=None):
    """The weighted members of ``model`` with their :class:`Uncertainty`.

    A model without an ensemble is its own single member. A member without predictive
    content (an old file) takes its parameters' standard errors as uncorrelated and the noise
    ``noise`` [rad], else its held-out RMSE.
    """
    members = model.ensemble or (Member(1.0, model),)
    out = []
    for m in members:
        u = m.model.uncertainty
        if u is None or noise is not None:
            u = _fallback_uncertainty(m.model, noise, u)
        out.append(Member(m.weight, dataclasses.replace(m.model, uncertainty=u, ensemble=(), weighting="")))
    return out


def _fallback_uncertainty(model, noise, u=None):
    if u is not None:  # a given noise replaces the file's
        return dataclasses.replace(u, noise_rad=check_number("noise", noise, minimum=0.0),
                                   noise_source="given")
    names = [k for k, p in model.params.items() if p.se is not None or p.ci95 is not None]
    var = []
    for k in names:
        p = model.params[k]
        var.append(p.se**2 if p.se is not None else ((p.ci95[1] - p.ci95[0]) / (2 * 1.959964)) ** 2)
    n = model.data.get("n_tests")
    dof = max(int(n) - len(model.params), 1) if n else 10**6
    if noise is not None:
        s, source = check_number("noise", noise, minimum=0.0), "given"
    elif model.data.get("held_out_rmse_rad") is not None:
        s, source = float(model.data["held_out_rmse_rad"]), "the model file's held-out RMSE (a file without noise)"
    else:
        raise GdfeError(f"model {model.name!r}: expected a model file with predictive content (gdfe diagnose or "
                        f"gdfe calibrate --model-out) or the noise of a test (--noise S in rad); this one has "
                        f"neither a noise nor a held-out RMSE")
    return Uncertainty(names=tuple(names), covariance=np.diag(var) if var else np.zeros((0, 0)), noise_rad=s,
                       dof=dof, noise_source=source)


def _with_values(model, values):
    params = {k: dataclasses.replace(p, value=float(values.get(k, p.value))) for k, p in model.params.items()}
    return dataclasses.replace(model, params=params, uncertainty=None, ensemble=(), weighting="", warnings=())


def _groups(spec, model):
    """Rows of ``spec`` sharing the process variables ``model`` needs: (process dict, row indices)."""
    if not model.columns:
        return [(None, np.arange(len(spec)))]
    keys = {}
    for i in range(len(spec)):
        p = spec.process(i, model)
        keys.setdefault(tuple(sorted(p.items())), []).append(i)
    return [(dict(k), np.array(v)) for k, v in keys.items()]


def _closed(model, spec, offset=0.0):
    out = np.empty(len(spec))
    for proc, idx in _groups(spec, model):
        out[idx] = model.hinge_angle(spec.L[idx], spec.d[idx], spec.h[idx], proc)
    return out + offset


def closed_form_jacobian(model, names, spec, offset=0.0):
    """Closed-form angles of ``spec`` and their derivatives in the parameters ``names``.

    ``"offset"`` among ``names`` is the reading offset (derivative 1).

    Returns
    -------
    mu : (n,) float array [rad]
    J : (n, k) float array
    """
    mu = _closed(model, spec, offset)
    J = np.zeros((len(spec), len(names)))
    for j, k in enumerate(names):
        if k == "offset":
            J[:, j] = 1.0
            continue
        v = model.value(k)
        step = STEP * max(abs(v), 1e-3)
        try:
            up = _closed(_with_values(model, {k: v + step}), spec)
            down = _closed(_with_values(model, {k: v - step}), spec)
            J[:, j] = (up - down) / (2 * step)
        except GdfeError:  # a step across a limit of the parameter: one-sided
            J[:, j] = (_closed(_with_values(model, {k: v + step}), spec) - (mu - offset)) / step
    return mu, J


def mixture_interval(weights, mu, scale, dof, level):
    """Central interval at ``level`` of mixtures of scaled Student-t distributions.

    Parameters
    ----------
    weights : (K,) float array
    mu, scale : (n, K) float arrays
    dof : (K,) array
    level : float

    Returns
    -------
    lo, hi : (n,) float arrays
    """
    from scipy import stats

    w = np.asarray(weights, float)
    mu, scale = np.atleast_2d(mu), np.maximum(np.atleast_2d(scale), 1e-12)
    dof = np.asarray(dof, float)

    def cdf(x):
        return np.sum(w * stats.t.cdf((x[:, None] - mu) / scale, dof), axis=1)

    out = []
    for q in ((1 - level) / 2, (1 + level) / 2):
        lo = (mu - 60 * scale).min(axis=1)
        hi = (mu + 60 * scale).max(axis=1)
        for _ in range(80):  # bisection, all rows at once
            mid = 0.5 * (lo + hi)
            below = cdf(mid) < q
            lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
        out.append(0.5 * (lo + hi))
    return out[0], out[1]


@dataclasses.dataclass
class Prediction:
    """Predicted angles of specimens with intervals and their parts.

    Attributes
    ----------
    specimens : HingeSpecimens
    level : float
    alpha : (n,) float array [rad]
        The mixture's mean.
    interval : (n, 2) float array [rad]
        Combined interval at ``level``.
    sd_parameters, sd_model, sd_noise : (n,) float arrays [rad]
        The parts' standard deviations (``sd_model``: the choice between models, or a
        discrepancy's, :attr:`model_part`).
    members : list of dict
        Name, weight and noise of each member.
    member_alpha, member_sd_parameters : (n, K) float arrays [rad]
    method : str
        ``"closed form"`` or ``"GDFE (RESOLUTION)"``.
    model_name, weighting : str
    converged : bool
        Whether every GDFE solve converged (True for the closed form).
    model_part : str
        The name of the model-form part: ``"model_choice"`` (the members' spread) or
        ``"discrepancy"`` (:mod:`gdfe.discrepancy`).
    """

    specimens: HingeSpecimens
    level: float
    alpha: np.ndarray
    interval: np.ndarray
    sd_parameters: np.ndarray
    sd_model: np.ndarray
    sd_noise: np.ndarray
    members: list
    member_alpha: np.ndarray
    member_sd_parameters: np.ndarray
    method: str
    model_name: str
    weighting: str
    converged: bool = True
    model_part: str = "model_choice"
    warnings: tuple = ()

    @property
    def width(self):
        """Width of each combined interval [rad]."""
        return self.interval[:, 1] - self.interval[:, 0]

    @property
    def inside(self):
        """Whether each measured angle lies in its interval (None without measured angles)."""
        a = self.specimens.alpha
        return None if a is None else (self.interval[:, 0] <= a) & (a <= self.interval[:, 1])

    def as_dict(self):
        from scipy import stats

        z = float(stats.norm.ppf(0.5 + self.level / 2))
        s = self.specimens
        rows = []
        for i in range(len(s)):
            m = float(self.alpha[i])

            def part(sd):
                return {"sd_rad": float(sd[i]), "interval_rad": [m - z * float(sd[i]), m + z * float(sd[i])]}

            row = {"row": i + 2, "L_mm": float(s.L[i]), "d_mm": float(s.d[i]), "h_mm": float(s.h[i]),
                   "alpha_rad": m, "alpha_interval_rad": [float(v) for v in self.interval[i]], "level": self.level,
                   "parts": {"parameters": part(self.sd_parameters), self.model_part: part(self.sd_model),
                             "noise": part(self.sd_noise)},
                   "members": [{"name": mem["name"], "weight": mem["weight"], "alpha_rad": float(self.member_alpha[i, k]),
                                "parameters_sd_rad": float(self.member_sd_parameters[i, k])}
                               for k, mem in enumerate(self.members)]}
            for c, v in s.extra.items():
                row[c] = str(v[i])
            if s.alpha is not None:
                row["measured_alpha_rad"] = float(s.alpha[i])
                row["inside"] = bool(self.inside[i])
            rows.append(row)
        out = {"model": self.model_name, "weighting": self.weighting, "method": self.method, "level": self.level,
               "n_specimens": len(s), "members": self.members, "converged": self.converged,
               "mean_width_rad": float(np.mean(self.width)), "rows": rows, "warnings": list(self.warnings),
               "parts": "sd_rad of each part (they add as variances); interval_rad: each part alone, a normal "
                        "interval about the mean at the same level; alpha_interval_rad: all together (the "
                        "mixture of the members, Student's t with each member's degrees of freedom)"}
        if s.alpha is not None:
            out["coverage"] = float(np.mean(self.inside))
            out["rmse_rad"] = float(np.sqrt(np.mean((s.alpha - self.alpha) ** 2)))
        return out

    def text(self):
        lines = [f"model {self.model_name!r}: {len(self.members)} member(s)"
                 + (f" weighted by {self.weighting}" if len(self.members) > 1 else "") + "; "
                 + ", ".join(f"{m['name']} {m['weight']:.2f}" for m in self.members),
                 f"{self.method}; intervals at level {self.level:g}",
                 f"{'row':>4s} {'L_mm':>6s} {'d_mm':>6s} {'alpha_rad':>9s} {'interval_rad':>17s} "
                 f"{'sd_par':>7s} {'sd_' + self.model_part[:5]:>8s} {'sd_noise':>8s}" + ("  measured" if self.specimens.alpha is not None
                                                                         else "")]
        s = self.specimens
        for i in range(len(s)):
            lo, hi = self.interval[i]
            line = (f"{i + 2:4d} {s.L[i]:6.3g} {s.d[i]:6.3g} {self.alpha[i]:9.3f} [{lo:7.3f}, {hi:7.3f}] "
                    f"{self.sd_parameters[i]:7.3f} {self.sd_model[i]:8.3f} {self.sd_noise[i]:8.3f}")
            if s.alpha is not None:
                line += f"  {s.alpha[i]:.3f}" + ("" if self.inside[i] else " (outside)")
            lines.append(line)
        lines += [f"warning: {w}" for w in self.warnings]
        if s.alpha is not None:
            lines.append(f"coverage {np.mean(self.inside):.2f} of {len(s)} measured angles; mean width "
                         f"{np.mean(self.width):.3f} rad")
        if not self.converged:
            lines.append("WARNING: a GDFE solve did not converge: its prediction is not trustworthy")
        return "\n".join(lines)


def predict(model, specimens, level=LEVEL, *, noise=None, simulate=None):
    """Fold angles of hinge specimens with intervals, split into their parts.

    Parameters
    ----------
    model : DeformationModel
        With predictive content (:mod:`gdfe.predictive`), or any model with ``noise``.
    specimens : HingeSpecimens or path of a CSV (:func:`load_specimens`)
    level : float
        Level of the intervals, in (0, 1).
    noise : float, optional [rad]
        The noise of a test, replacing the model file's.
    simulate : {"coarse", "default", "fine"}, optional
        Each member's mean from a GDFE solve of the hinge at this resolution (cells across the
        hinge: :data:`gdfe.diagnosis.forward.CELLS`) instead of the closed form; the spreads
        stay those of the closed form.

    Returns
    -------
    Prediction
    """
    if not isinstance(model, DeformationModel):
        raise GdfeError(f"model: expected a gdfe.DeformationModel, got {type(model).__name__}")
    level = check_number("level", level, minimum=0.0, maximum=1.0, include_minimum=False, include_maximum=False)
    spec = specimens if isinstance(specimens, HingeSpecimens) else load_specimens(specimens)
    members = members_of(model, noise)
    n, K = len(spec), len(members)
    mu, sp = np.zeros((n, K)), np.zeros((n, K))
    ok = True
    for k, m in enumerate(members):
        u = m.model.uncertainty
        mu[:, k], J = closed_form_jacobian(m.model, u.names, spec, u.reading_offset_rad)
        sp[:, k] = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", J, u.matrix(), J), 0.0))
        if simulate is not None:
            sim, conv = _simulated(m.model, spec, simulate)
            mu[:, k] = sim + u.reading_offset_rad
            ok = ok and conv
    w = np.array([m.weight for m in members])
    sn = np.array([m.model.uncertainty.noise_rad for m in members])
    dof = np.array([m.model.uncertainty.dof for m in members])
    mean = mu @ w
    lo, hi = mixture_interval(w, mu, np.sqrt(sp**2 + sn**2), dof, level)
    loose = [(m.model.name, int(np.argmax(sp[:, k])), float(np.max(sp[:, k]))) for k, m in enumerate(members)
             if np.max(sp[:, k]) > PARAMETER_SD_MAX]
    warnings = tuple(f"member {name}: its parameters' linearised spread is {v:.3g} rad on row {i + 2}, more than "
                     f"{PARAMETER_SD_MAX:.3g} rad (half of a full turn): the tests do not pin its parameters down (a "
                     f"parameter at a bound of its fit, or not identifiable), so the intervals it enters are not "
                     f"meaningful" for name, i, v in loose)
    info = [{"name": m.model.name, "weight": float(m.weight), "noise_rad": float(m.model.uncertainty.noise_rad),
             "dof": int(m.model.uncertainty.dof), "noise_source": m.model.uncertainty.noise_source,
             "reading_offset_rad": m.model.uncertainty.reading_offset_rad} for m in members]
    return Prediction(specimens=spec, level=level, alpha=mean, interval=np.column_stack([lo, hi]),
                      sd_parameters=np.sqrt((sp**2) @ w), sd_model=np.sqrt(((mu - mean[:, None]) ** 2) @ w),
                      sd_noise=np.full(n, float(np.sqrt(sn**2 @ w))), members=info, member_alpha=mu,
                      member_sd_parameters=sp, method="closed form" if simulate is None else f"GDFE ({simulate})",
                      model_name=model.name, weighting=model.weighting or "single", converged=ok,
                      warnings=warnings)


def _simulated(model, spec, resolution):
    """GDFE fold angles of the specimens' hinges under ``model``; and whether all converged."""
    import gdfe
    from gdfe.diagnosis.forward import CELLS

    check_choice("simulate", resolution, CELLS)
    cells, nz = CELLS[resolution]
    out, ok = np.empty(len(spec)), True
    for i in range(len(spec)):
        proc = spec.process(i, model) if model.columns else None
        L = float(spec.L[i])
        design = gdfe.hinge(L, d=float(spec.d[i]), h=float(spec.h[i]), model=model, process=proc,
                            cell_size=L / cells, nz=nz)
        res = gdfe.simulate(design)
        out[i] = gdfe.fold_angle(res)
        ok = ok and bool(res.converged)
    return out, ok


def draw_models(model, n, seed=0, noise=None):
    """``n`` deformation models drawn from ``model``'s predictive content, for ensembles through
    the simulator: a member by its weight, then its parameters from a normal distribution with
    their covariance (a reading offset left out: it is how tests were read, not how parts fold).
    A draw a film cannot have (``K <= 0``, ``R <= 0`` at the coat, ...) is drawn again.

    Parameters
    ----------
    model : DeformationModel
    n : int
    seed : int

    Returns
    -------
    list of DeformationModel
        Each without predictive content of its own.
    """
    from gdfe._validation import check_int

    n = check_int("n", n, minimum=1)
    seed = check_int("seed", seed, minimum=0)
    members = members_of(model, noise)
    w = np.array([m.weight for m in members])
    rng = np.random.default_rng(seed)
    out = []
    tries = 0
    while len(out) < n:
        tries += 1
        if tries > 100 * n:
            raise GdfeError(f"model {model.name!r}: fewer than one draw in 100 of its parameters is a film that can "
                            f"exist; its covariance is too wide to draw parts from")
        m = members[int(rng.choice(len(members), p=w))].model
        u = m.uncertainty
        keep = [i for i, k in enumerate(u.names) if k != "offset"]
        cov = u.matrix()[np.ix_(keep, keep)]
        mean = np.array([m.value(u.names[i]) for i in keep])
        x = rng.multivariate_normal(mean, cov, method="eigh") if keep else mean
        try:
            out.append(_with_values(m, {u.names[i]: float(v) for i, v in zip(keep, x)}))
        except GdfeError:
            continue
    return out
