"""The next folding tests to print for one part: those expected to narrow its predicted fold angles most.

A part is about to be printed (a design that :func:`gdfe.load_design` reads). Its predicted fold
angles come from a model file with predictive content (:mod:`gdfe.predictive`): a mixture over
the members ``k`` of the named set, with weights ``w_k``, of each member's closed form at the
part's own hinge specimens (:func:`target_folds`: each fold's width ``L``, passive thickness
``d`` and film ``h``). Which ``n`` hinge specimens, printed and measured first, are expected to
narrow that prediction most?

**The quantity.** ``q`` is the vector of the part's fold angles, each the closed form of its fold
(:meth:`gdfe.DeformationModel.hinge_angle`) without a reading offset (how tests were read, not
how parts fold) and without the noise of a test: the same part of the doubt as the ensembles
through the simulator (:mod:`gdfe.ensemble`) report, the parameters and the choice of model.
The scatter of one printed hinge about the model (the noise) is reported beside it; no test
narrows it.

**The update.** Given member ``k``, linearised about its fitted parameters (covariance ``C_k``,
derivatives ``G_k`` of ``q`` and ``J_k`` of the new tests' angles, noise ``s_k``), the tests'
angles ``y`` and ``q`` are jointly normal: one draw of the parameters for all of them, the
noise of every test independent (as in :mod:`gdfe.plan`, so a replicate narrows the noise's
part only). After ``y`` the parameters' covariance is
``C_k' = (C_k^-1 + J_k^T J_k / s_k^2)^-1 = C_k - C_k J_k^T S_k^-1 J_k C_k`` with
``S_k = J_k C_k J_k^T + s_k^2 I`` (the second form needs no inverse of ``C_k``, which may be
singular), so member ``k``'s fold ``f`` has the variance ``V_kf = G_kf C_k' G_kf^T``, whatever
``y`` is, and the mean ``m_kf(y) = q_kf + G_kf C_k J_k^T S_k^-1 (y - mu_k)``. The weights become
``w_k' ~ w_k N(y; mu_k, S_k)``. The prediction after the tests is the mixture
``sum_k w_k' N(m_kf(y), V_kf)``, of variance ``sum_k w_k' (V_kf + (m_kf - mbar_f)^2)``.

**The objective** is the expected fall of the **summed variance** of ``q`` over the outcomes
``y`` the model itself expects (the preposterior: a member by its weight, then ``y`` from its
normal), by Monte Carlo with common random numbers (the same draws for every candidate, those of
the tests chosen before kept at every step, as :func:`gdfe.plan.plan_tests` does; the members'
draws stratified, each weighed by ``w_k``). The variance, not the width of the 90 % interval:
it adds over folds and over the parts of the doubt (the law of total variance), it has its
closed form per member for every outcome, so a candidate costs no quantile search, and its
expectation after the tests is the variance before less the variance of the prediction's change
(``E[Var(q | y)] = Var(q) - Var(E[q | y])``), so it never rises with a test. The width of the
interval of a mixture is neither additive nor sure to fall with every outcome; it is what a
user reads, so it is reported (the expected width of each fold's central interval at ``level``
after 0, 1, 2, ... tests, its mixture's quantiles found by bisection), not optimised.

The ``n`` tests are chosen greedily over the candidate grid of :mod:`gdfe.plan` (replicates
allowed), each the candidate that, added to those chosen before, leaves the smallest expected
summed variance. :func:`expected_for_tests` gives the same figures for tests chosen otherwise
(random, a grid), with the same draws, so that a plan can be compared with them.

The tests are expected to help as the model expects them to: the outcomes are drawn from the
model, so these are the model's own expectations (a truth outside the named set, or a
linearisation that does not hold, is not in them). Lengths in mm, angles in rad.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_file, check_int, check_number
from gdfe.plan import D_RANGE, GRID, L_RANGE, SAMPLES, _member_predictions, candidate_grid, _no_valid_candidate
from gdfe.predict import LEVEL, HingeSpecimens, closed_form_jacobian, members_of

__all__ = ["TargetFolds", "TargetPlan", "target_folds", "plan_for_target", "expected_for_tests"]

log = logging.getLogger(__name__)

#: Largest number of (candidate, sample, member, fold) values held at once.
BLOCK = 4_000_000
#: Weights below this are members the mixture does not use.
WEIGHT_MIN = 1e-9


# -- the part's folds ------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class TargetFolds:
    """The folds of a part as hinge specimens.

    Attributes
    ----------
    labels : tuple of str
        One per fold, as ``gdfe simulate`` labels its fold angles (``"hinge"``, ``"crease 12"``,
        ``"panels 1-2"``).
    specimens : HingeSpecimens
        Each fold's width ``L``, passive thickness ``d`` and film ``h`` [mm].
    kind : str
        How the folds were found.
    name : str
        The design's file or name.
    panel_mm : float [mm]
        The narrowest rigid panel between two coat edges (``inf`` where none, or for a hinge
        specimen, whose panels are the test's own): a model whose contraction reaches further past
        a coat edge (``hinge_length``) folds the part otherwise than lone hinge specimens.
    """

    labels: tuple
    specimens: HingeSpecimens
    kind: str
    name: str = "design"
    panel_mm: float = math.inf

    def __len__(self):
        return len(self.labels)


def target_folds(design, name="target"):
    """The folds of a design as hinge specimens ``(L, d, h)``.

    * the paper's hinge specimen (:func:`gdfe.hinge`, a design file's ``[hinge]``): its hinge;
    * a crease pattern (``[fold]``, ``.fold``): every crease joining two faces, of its printed
      hinge width (``width_mm``, from Eq. 2 or the file);
    * any other design (``[layout]``, ``[masks]``, ``[svg]``): every pair of rigid panels (at
      least two cell columns) that a connected run of cells coated on one face joins, labelled
      as :func:`gdfe.measure.panel_angles` labels them. Its width is the median, over the run's
      cells, of the length of the free run across it between two coat edges (along x or y,
      the shorter: the width the model's geometric mechanisms see, :mod:`gdfe.model`).

    ``d`` is the median passive thickness of the fold's cells coated on one face, ``h`` the film's.

    Parameters
    ----------
    design : Design or path of a design file
    name : str
        The argument's name in messages (``"--target"`` on the command line).

    Returns
    -------
    TargetFolds

    Raises
    ------
    GdfeError
        When the design has no fold of that kind, or gives ``R`` instead of the passive
        thickness ``d`` of its folds.
    """
    import gdfe

    label = "design"
    if isinstance(design, (str, Path)):
        label = str(design)
        design, _ = gdfe.load_design(check_file(name, design, what="design file"))
    if not hasattr(design, "material") or not hasattr(design, "mesh"):
        raise GdfeError(f"{name}: expected a gdfe.Design or a design file, got {type(design).__name__}")
    if design.meta.get("kind") == "hinge" or {"panel_a", "panel_b", "hinge"} <= set(design.regions):
        folds, kind = _hinge_fold(design, name), "the hinge specimen"
    elif design.meta.get("kind") == "fold" and design.meta.get("hinges") is not None:
        folds, kind = _crease_folds(design), "creases of the crease pattern"
    else:
        folds, kind = _panel_folds(design), "rigid panels joined by runs coated on one face"
    if not folds:
        raise GdfeError(f"{name}: expected a design with folds (rigid panels joined by hinges coated on one face, "
                        f"a hinge specimen or a crease pattern), got {label} with none: a part without hinges has no "
                        f"fold angle of a hinge specimen to narrow (its measures have intervals from gdfe simulate "
                        f"--model M.toml --uncertainty N)")
    labels, L, d = zip(*folds)
    bad = [lab for lab, dd in zip(labels, d) if not (math.isfinite(dd) and dd > 0)]
    if bad:
        raise GdfeError(f"{name}: expected the passive thickness d of every fold (a design with d, not R), got none "
                        f"for {', '.join(bad[:4])}{' ...' if len(bad) > 4 else ''} of {label}")
    spec = HingeSpecimens(L=np.array(L, float), d=np.array(d, float), h=np.full(len(L), float(design.h)))
    panel = math.inf if kind == "the hinge specimen" else _narrowest_panel(design)
    return TargetFolds(labels=tuple(labels), specimens=spec, kind=kind, name=label, panel_mm=panel)


def _narrowest_panel(design):
    """The shortest run of rigid cells between two cells that are not rigid, along x or y [mm]."""
    from gdfe.material import Material
    from gdfe.model import _run_width

    mesh = design.mesh
    i, j = mesh.cell_ij.T
    shape = (int(i.max()) + 1, int(j.max()) + 1)
    dx, dy = (float(s) for s in mesh.spacing[:2])
    rigid, other = np.zeros(shape, bool), np.zeros(shape, bool)
    is_rigid = design.material == Material.RIGID
    rigid[i[is_rigid], j[is_rigid]] = True
    other[i[~is_rigid], j[~is_rigid]] = True
    other &= ~rigid
    w = np.minimum(_run_width(rigid, other, 0) * dx, _run_width(rigid, other, 1) * dy)
    return float(w[rigid].min()) if rigid.any() else math.inf


def _median_d(design, cells):
    from gdfe.material import Material

    if design.d is None or cells.size == 0:
        return math.nan
    one = (design.material[cells] == Material.CONTRACT_TOP) | (design.material[cells] == Material.CONTRACT_BOTTOM)
    d = np.asarray(design.d, float)[cells[one]]
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else math.nan


def _hinge_fold(design, name):
    L = design.meta.get("length_mm")
    if L is None:
        raise GdfeError(f"{name}: a hinge specimen without its length (meta length_mm)")
    return [("hinge", float(L), _median_d(design, design.region_cells("hinge")))]


def _crease_folds(design):
    out = []
    for rec in design.meta["hinges"]:
        if len(rec.get("faces", [])) != 2:
            continue
        region = f"hinge_{rec['edge']}"
        cells = design.regions[region] if region in design.regions else np.zeros(0, int)
        out.append((f"crease {rec['edge']}", float(rec["width_mm"]), _median_d(design, np.asarray(cells, int))))
    return out


def _panel_folds(design):
    """Folds between rigid panels joined by runs of one-face-coated cells (labels of ``panel_angles``)."""
    from scipy import ndimage

    from gdfe.material import Material
    from gdfe.model import _run_width

    mesh = design.mesh
    i, j = mesh.cell_ij.T
    nx, ny = int(i.max()) + 1, int(j.max()) + 1
    dx, dy = (float(s) for s in mesh.spacing[:2])
    mat = design.material
    grid = {}
    for key, sel in (("rigid", mat == Material.RIGID), ("top", mat == Material.CONTRACT_TOP),
                     ("bottom", mat == Material.CONTRACT_BOTTOM), ("other", mat != Material.RIGID),
                     ("shrink", mat == Material.FREE_SHRINK)):
        g = np.zeros((nx, ny), bool)
        g[i[sel], j[sel]] = True
        grid[key] = g
    rigid = grid["rigid"]
    present = rigid | grid["other"]
    # the free face of a cell coated on one face: a run of free film on that face, ended by coat on both sides
    width = np.full((nx, ny), np.inf)
    for face in ("top", "bottom"):
        free = grid[face] | grid["shrink"]
        coated = present & ~free
        w = np.minimum(_run_width(free, coated, 0) * dx, _run_width(free, coated, 1) * dy)
        width = np.where(grid[face], w, width)
    d2 = np.full((nx, ny), np.nan)
    if design.d is not None:
        one = (mat == Material.CONTRACT_TOP) | (mat == Material.CONTRACT_BOTTOM)
        d2[i[one], j[one]] = np.asarray(design.d, float)[one]
    panels, _ = ndimage.label(rigid)
    sizes = np.bincount(panels.ravel())
    hinges, _ = ndimage.label(grid["other"] & ~rigid)
    cross = ndimage.generate_binary_structure(2, 1)
    joints = {}
    for h, box in enumerate(ndimage.find_objects(hinges), start=1):
        box = tuple(slice(max(0, b.start - 1), b.stop + 1) for b in box)
        region = hinges[box] == h
        touching = np.unique(panels[box][ndimage.binary_dilation(region, cross) & rigid[box]])
        touching = [int(t) for t in touching if t and sizes[t] >= 2]
        one_face = region & (grid["top"][box] | grid["bottom"][box])
        for a_idx, a in enumerate(touching):
            for b in touching[a_idx + 1:]:
                w, d = joints.setdefault((a, b), ([], []))
                w.extend(width[box][one_face].tolist())
                d.extend(d2[box][one_face].tolist())
    out = []
    for (a, b) in sorted(joints):
        w, d = np.array(joints[(a, b)][0]), np.array(joints[(a, b)][1])
        w, d = w[np.isfinite(w)], d[np.isfinite(d)]
        if w.size == 0:  # no run ends in coat on both sides: not a hinge of a width
            continue
        out.append((f"panels {a}-{b}", float(np.median(w)), float(np.median(d)) if d.size else math.nan))
    return out


# -- the plan ----------------------------------------------------------------------------------------
@dataclasses.dataclass
class TargetPlan:
    """Tests to print for a part, and how they are expected to narrow its fold angles.

    Attributes
    ----------
    target : TargetFolds
    L, d, h : (n,) float arrays [mm]
        The tests, in the order chosen.
    members : list of str
    weights : (K,) float array
        The members' weights before the tests.
    alpha : (F,) float array [rad]
        Each fold's predicted angle before the tests (the mixture's mean).
    interval : (F, 2) float array [rad]
        Each fold's central interval at ``level`` before the tests.
    variance : (n + 1,) float array [rad^2]
        Expected summed variance of the folds after 0, 1, ..., n tests.
    sd : (n + 1, F) float array [rad]
        Each fold's expected standard deviation after 0, 1, ..., n tests (root of its expected variance).
    width : (n + 1, F) float array [rad]
        Each fold's expected interval width at ``level`` after 0, 1, ..., n tests.
    level : float
    noise_sd : float [rad]
        The members' weighted scatter of one printed hinge about the model (not in the intervals).
    candidates : int
        Candidates of the grid (0 for tests given).
    chosen_by : str
        ``"plan"`` or ``"given"``.
    warnings : tuple of str
        Members under which the part's folds are not lone hinge specimens.
    """

    target: TargetFolds
    L: np.ndarray
    d: np.ndarray
    h: np.ndarray
    members: list
    weights: np.ndarray
    alpha: np.ndarray
    interval: np.ndarray
    variance: np.ndarray
    sd: np.ndarray
    width: np.ndarray
    level: float
    noise_sd: float
    candidates: int
    chosen_by: str = "plan"
    warnings: tuple = ()

    @property
    def mean_width(self):
        """(n + 1,) expected mean interval width over the folds after 0, 1, ..., n tests [rad]."""
        return self.width.mean(axis=1)

    @property
    def expected_reduction(self):
        """Expected fraction of the summed variance of the folds that the tests remove."""
        return float(1.0 - self.variance[-1] / self.variance[0]) if self.variance[0] > 0 else 0.0

    def as_dict(self):
        t = self.target.specimens
        folds = [{"label": lab, "length_mm": float(t.L[f]), "d_mm": float(t.d[f]), "h_mm": float(t.h[f]),
                  "fold_angle_rad": float(self.alpha[f]), "interval_before_rad": [float(v) for v in self.interval[f]],
                  "width_before_rad": float(self.width[0, f]), "width_after_rad": float(self.width[-1, f]),
                  "sd_before_rad": float(self.sd[0, f]), "sd_after_rad": float(self.sd[-1, f])}
                 for f, lab in enumerate(self.target.labels)]
        tests = [{"length_mm": float(self.L[i]), "d_mm": float(self.d[i]), "h_mm": float(self.h[i]),
                  "expected_variance_rad2": float(self.variance[i + 1]),
                  "expected_mean_width_rad": float(self.mean_width[i + 1])} for i in range(self.L.size)]
        return {"target": self.target.name, "target_kind": self.target.kind, "level": self.level,
                "members": [{"name": m, "weight": float(w)} for m, w in zip(self.members, self.weights)],
                "folds": folds, "tests": tests,
                "expected_variance_rad2": [float(v) for v in self.variance],
                "expected_width_rad": [float(v) for v in self.mean_width],
                "expected_reduction": self.expected_reduction, "noise_sd_rad": self.noise_sd,
                "candidates": self.candidates, "chosen_by": self.chosen_by, "warnings": list(self.warnings),
                "objective": "expected fall of the summed variance of the target's fold angles (parameters and "
                             "choice of model; linearised Gaussian update of each member, member weights updated "
                             "by the tests' likelihood; Monte Carlo over outcomes drawn from the model); greedy "
                             "over a grid; expected_width_rad: the mean over folds of the expected width of each "
                             "fold's central interval at level, after 0, 1, ... tests"}

    def text(self):
        t = self.target
        n = self.L.size
        lines = [f"target {t.name}: {len(t)} fold(s), {t.kind}; each fold the closed form of its hinge specimen",
                 f"members: " + ", ".join(f"{m} {w:.2f}" for m, w in zip(self.members, self.weights))
                 + f"; intervals at level {self.level:g} (parameters and choice of model)",
                 f"{'fold':>14s} {'L_mm':>6s} {'d_mm':>6s} {'h_mm':>6s} {'alpha_rad':>9s} {'interval before':>18s} "
                 f"{'width':>6s} -> {'after':>6s}"]
        first, count, _ = _distinct(t)
        shown = list(zip(first, count))
        for f, alike in shown[:8]:
            lo, hi = self.interval[f]
            more = f"  (and {alike - 1} more alike)" if alike > 1 else ""
            lines.append(f"{t.labels[f]:>14s} {t.specimens.L[f]:6.3g} {t.specimens.d[f]:6.3g} {t.specimens.h[f]:6.3g} "
                         f"{self.alpha[f]:9.3f} [{lo:7.3f}, {hi:7.3f}] {self.width[0, f]:6.3f} -> "
                         f"{self.width[-1, f]:6.3f}{more}")
        if len(shown) > 8:
            lines.append(f"{'':>14s} and {len(shown) - 8} more distinct folds (in the JSON)")
        lines.append(f"{'test':>4s} {'L_mm':>6s} {'d_mm':>6s} {'h_mm':>6s}  {'E[summed var] rad^2':>19s}  "
                     f"{'E[mean width] rad':>17s}")
        lines.append(f"{'none':>4s} {'':>6s} {'':>6s} {'':>6s}  {self.variance[0]:19.4g}  {self.mean_width[0]:17.3f}")
        for i in range(n):
            lines.append(f"{i + 1:4d} {self.L[i]:6.3g} {self.d[i]:6.3g} {self.h[i]:6.3g}  "
                         f"{self.variance[i + 1]:19.4g}  {self.mean_width[i + 1]:17.3f}")
        lines.append(f"expected to remove {100 * self.expected_reduction:.0f} % of the summed variance of the part's "
                     f"fold angles; mean {100 * self.level:g} % interval width {self.mean_width[0]:.3f} -> "
                     f"{self.mean_width[-1]:.3f} rad")
        lines.append(f"each printed hinge scatters about the model by a further {self.noise_sd:.3f} rad (sd, the noise "
                     f"of a test), which no test narrows")
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _distinct(target):
    """The distinct specimens of ``target``'s folds: the first fold of each ``(F,)``, how many folds share it
    ``(F,)``, and the distinct specimen of every fold ``(n_folds,)``."""
    s = target.specimens
    keys, first, inverse = {}, [], np.empty(len(target), int)
    for f in range(len(target)):
        k = (round(float(s.L[f]), 9), round(float(s.d[f]), 9), round(float(s.h[f]), 9))
        if k not in keys:
            keys[k] = len(first)
            first.append(f)
        inverse[f] = keys[k]
    return np.array(first, int), np.bincount(inverse, minlength=len(first)), inverse


@dataclasses.dataclass(frozen=True)
class _Problem:
    """Everything the preposterior needs: the candidates' test means ``mu`` ``(C, K)`` (reading offset in)
    and derivatives ``jac`` (per member ``(C, p_k)``), the folds' means ``q`` ``(F, K)`` and derivatives
    ``G`` (per member ``(F, p_k)``) of the distinct folds, the covariances ``cov``, noises ``noise`` ``(K,)``,
    weights ``w`` ``(K,)`` and each distinct fold's count ``count`` ``(F,)``."""

    mu: np.ndarray
    jac: list
    cov: list
    noise: np.ndarray
    q: np.ndarray
    G: list
    w: np.ndarray
    count: np.ndarray


def _weighted_members(model):
    members = [m for m in members_of(model) if m.weight > WEIGHT_MIN]
    w = np.array([m.weight for m in members], float)
    return members, w / w.sum()


def _fold_predictions(members, spec, name):
    """Each member's closed form of the folds ``(F, K)`` without a reading offset, and its derivatives."""
    q = np.empty((len(spec), len(members)))
    G = []
    for k, m in enumerate(members):
        u = m.model.uncertainty
        if m.model.columns:
            raise GdfeError(f"{name}: member {m.model.name!r} needs process columns "
                            f"({', '.join(m.model.columns.values())}); plans over process variables are not supported")
        try:
            q[:, k], J = closed_form_jacobian(m.model, u.names, spec, 0.0)
        except GdfeError as exc:
            raise GdfeError(f"{name}: member {m.model.name!r} has no valid fold for the part's folds ({exc})") from None
        J = np.array(J, float)
        J[:, [i for i, p in enumerate(u.names) if p == "offset"]] = 0.0  # how tests were read, not how parts fold
        if not (np.all(np.isfinite(q[:, k])) and np.all(np.isfinite(J))):
            raise GdfeError(f"{name}: member {m.model.name!r} gives no finite fold angle for the part's folds")
        G.append(J)
    return q, G


def _problem(model, target, tests, name):
    """The :class:`_Problem` of ``model``'s members, the distinct folds of ``target`` and the candidate ``tests``."""
    members, w = _weighted_members(model)
    first, count, _ = _distinct(target)
    s = target.specimens
    q, G = _fold_predictions(members, HingeSpecimens(s.L[first], s.d[first], s.h[first]), name)
    mu, jac, cov, noise = _member_predictions(members, tests)
    return members, _Problem(mu=mu, jac=jac, cov=cov, noise=noise, q=q, G=G, w=w,
                             count=count.astype(float))


def _draws(samples, n, K, w, seed):
    """The preposterior's draws: standard normals ``Z`` ``(S, n)`` (one column per test, drawn in order so
    that a plan and given tests share them), each sample's true member (stratified) and its weight."""
    seed = check_int("seed", seed, minimum=0)
    rng = np.random.default_rng(seed)
    Z = np.column_stack([rng.standard_normal(samples) for _ in range(n)]) if n else np.zeros((samples, 0))
    truth = np.arange(samples) % K
    per = np.bincount(truth, minlength=K)
    omega = w[truth] / per[truth]
    return Z, truth, omega


def _posterior(P, rows, Z, truth):
    """Each outcome's posterior: weights ``(B, S, K)``, member means ``(K, B, S, F)`` and variances ``(K, B, F)``
    of the distinct folds after the tests ``rows`` ``(B, m)`` (candidate indices, ``m >= 1``)."""
    B, m = rows.shape
    S, K, F = Z.shape[0], P.w.size, P.q.shape[0]
    M = P.mu[rows]  # (B, m, K)
    chol, logdet, W, V = [], [], [], []
    for k in range(K):
        Jr, C, G = P.jac[k][rows], P.cov[k], P.G[k]  # (B, m, p), (p, p), (F, p)
        Sig = np.einsum("bip,pq,bjq->bij", Jr, C, Jr) + (P.noise[k] ** 2 + 1e-12) * np.eye(m)
        Lc = np.linalg.cholesky(Sig)
        chol.append(Lc)
        logdet.append(2 * np.log(np.diagonal(Lc, axis1=1, axis2=2)).sum(axis=1))
        Wk = np.linalg.solve(Lc, np.einsum("bip,pq,fq->bif", Jr, C, G))  # L^-1 J C G^T: (B, m, F)
        W.append(Wk)
        prior = np.einsum("fp,pq,fq->f", G, C, G)
        V.append(np.maximum(prior[None, :] - (Wk**2).sum(axis=1), 0.0))
    lp = np.empty((B, S, K))
    means = np.empty((K, B, S, F))
    Zm = Z[:, :m]
    for t in range(K):
        sel = truth == t
        Y = M[:, :, t, None] + chol[t] @ Zm[sel].T  # (B, m, S_t)
        for k in range(K):
            r = np.linalg.solve(chol[k], Y - M[:, :, k, None])  # whitened residuals
            lp[:, sel, k] = -0.5 * (r**2).sum(axis=1) - 0.5 * logdet[k][:, None]
            means[k][:, sel, :] = P.q[None, None, :, k] + np.einsum("bmf,bms->bsf", W[k], r)
    lw = lp + np.log(P.w)
    wp = np.exp(lw - np.logaddexp.reduce(lw, axis=2, keepdims=True))
    return wp, means, np.array(V)


def _prior(P):
    """The prediction before any test, as :func:`_posterior` gives it (one outcome)."""
    V = np.array([np.einsum("fp,pq,fq->f", G, C, G) for G, C in zip(P.G, P.cov)])[:, None, :]  # (K, 1, F)
    return P.w[None, None, :], P.q.T[:, None, None, :], V


def _mixture_variance(wp, means, V):
    """``(B, S, F)`` variance of each outcome's mixture ``sum_k w_k' N(m_k, V_k)``."""
    mbar = np.einsum("bsk,kbsf->bsf", wp, means)
    return np.einsum("bsk,kbsf->bsf", wp, V[:, :, None, :] + (means - mbar[None]) ** 2)


def _mixture_interval(wp, means, V, level):
    """``(B, S, F)`` ends of the central interval at ``level`` of each outcome's normal mixture
    ``sum_k w_k' N(m_k, V_k)`` (bisection on its distribution function, all at once)."""
    from scipy.special import ndtr

    sd = np.sqrt(np.maximum(V, 1e-24))[:, :, None, :]  # (K, B, 1, F)
    w = np.moveaxis(wp, 2, 0)[..., None]  # (K, B, S, 1)
    ends = []
    for p in ((1 - level) / 2, (1 + level) / 2):
        lo = (means - 12 * sd).min(axis=0)
        hi = (means + 12 * sd).max(axis=0)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            below = (w * ndtr((mid[None] - means) / sd)).sum(axis=0) < p
            lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
        ends.append(0.5 * (lo + hi))
    return ends[0], ends[1]


def _expected_variance(P, rows, Z, truth, omega):
    """``(B, F)`` expected variance of each distinct fold after the tests ``rows`` ``(B, m)``."""
    wp, means, V = _posterior(P, rows, Z, truth)
    return np.einsum("bsf,s->bf", _mixture_variance(wp, means, V), omega)


def _chunk(P, S):
    return max(1, int(BLOCK // max(1, S * P.w.size * P.q.shape[0])))


def _figures(P, chosen, Z, truth, omega, level):
    """Expected variance and interval width of each distinct fold after 0, 1, ..., n of the tests ``chosen``
    (``(n + 1, F)`` each), and each one's interval before the tests ``(F, 2)``."""
    wp, means, V = _prior(P)
    lo, hi = _mixture_interval(wp, means, V, level)
    var, width = [_mixture_variance(wp, means, V)[0, 0]], [(hi - lo)[0, 0]]
    interval = np.column_stack([lo[0, 0], hi[0, 0]])
    for j in range(1, len(chosen) + 1):
        wp, means, V = _posterior(P, np.array(chosen[:j], int)[None, :], Z, truth)
        lo, hi = _mixture_interval(wp, means, V, level)
        var.append(_mixture_variance(wp, means, V)[0].T @ omega)
        width.append((hi - lo)[0].T @ omega)
    return np.array(var), np.array(width), interval


def _result(P, members, target, tests, chosen, Z, truth, omega, level, candidates, chosen_by):
    var, width, interval = _figures(P, chosen, Z, truth, omega, level)
    _, _, expand = _distinct(target)  # the distinct specimen of every fold
    idx = np.array(chosen, int)
    return TargetPlan(target=target, L=tests.L[idx] if idx.size else np.zeros(0), d=tests.d[idx] if idx.size else
                      np.zeros(0), h=tests.h[idx] if idx.size else np.zeros(0), members=[m.model.name for m in members],
                      weights=P.w.copy(), alpha=(P.q @ P.w)[expand], interval=interval[expand],
                      variance=var @ P.count, sd=np.sqrt(var)[:, expand], width=width[:, expand], level=level,
                      noise_sd=float(np.sqrt(P.noise**2 @ P.w)), candidates=candidates, chosen_by=chosen_by,
                      warnings=_reach_warnings(members, target))


def _reach_warnings(members, target):
    """A warning for each member whose contraction reaches past a coat edge (``hinge_length``, half its
    ``lambda``) further than the part's narrowest panel: its closed forms take each fold for a lone hinge."""
    out = []
    for m in members:
        if "hinge_length" not in m.model.mechanisms:
            continue
        reach = 0.5 * m.model.value("lambda")
        if reach > target.panel_mm:
            out.append(f"member {m.model.name}: its contraction reaches {reach:.3g} mm past each coat edge, further "
                       f"than the part's narrowest panel ({target.panel_mm:.3g} mm): the folds do not fold as lone "
                       f"hinge specimens under it, and its closed forms are not its fold of the part (gdfe simulate "
                       f"--model M.toml --uncertainty N folds the part itself)")
    return tuple(out)


def _as_target(target, name):
    return target if isinstance(target, TargetFolds) else target_folds(target, name)


def plan_for_target(model, target, n, L_range=L_RANGE, d_range=D_RANGE, h_range=None, *, level=LEVEL, grid=GRID,
                    samples=SAMPLES, seed=0, name="target"):
    """The ``n`` hinge specimens within the ranges expected to narrow the prediction of ``target``'s folds most.

    Parameters
    ----------
    model : DeformationModel
        With predictive content (a diagnosis's model file: its members and their stacking weights).
    target : TargetFolds, Design or path of a design file
        The part (:func:`target_folds`).
    n : int
        Tests to propose.
    L_range, d_range, h_range : (lo, hi) [mm]
        Printable ranges (``h_range`` default: the paper's film, 0.29 mm).
    level : float
        Level of the intervals whose expected widths are reported.
    grid : int
        Candidates along each range that varies (:func:`gdfe.plan.candidate_grid`).
    samples : int
        Monte Carlo draws of the outcomes.
    seed : int
    name : str
        The target's name in messages.

    Returns
    -------
    TargetPlan
    """
    n = check_int("n", n, minimum=1)
    grid = check_int("grid", grid, minimum=2)
    samples = check_int("samples", samples, minimum=100)
    level = check_number("level", level, minimum=0.0, maximum=1.0, include_minimum=False, include_maximum=False)
    target = _as_target(target, name)
    Lg, dg, hg = candidate_grid(L_range, d_range, h_range, grid)
    members, P = _problem(model, target, HingeSpecimens(Lg, dg, hg), name)
    ok = np.all(np.isfinite(P.mu), axis=1)
    if not ok.any():
        raise _no_valid_candidate(L_range, d_range, (float(hg.min()), float(hg.max())))
    P = dataclasses.replace(P, mu=P.mu[ok], jac=[J[ok] for J in P.jac])
    cands = HingeSpecimens(Lg[ok], dg[ok], hg[ok])
    Z, truth, omega = _draws(samples, n, P.w.size, P.w, seed)
    chunk = _chunk(P, samples)
    chosen = []
    for step in range(n):
        ev = []
        for a in range(0, len(cands), chunk):
            c = np.arange(a, min(a + chunk, len(cands)))
            rows = np.column_stack([np.broadcast_to(np.array(chosen, int), (c.size, step)), c])
            ev.append(_expected_variance(P, rows, Z[:, :step + 1], truth, omega) @ P.count)
        ev = np.concatenate(ev)
        best = int(np.argmin(ev))
        chosen.append(best)
        log.info("test %d: L=%.3g d=%.3g h=%.3g mm, expected summed variance %.4g rad^2", step + 1, cands.L[best],
                 cands.d[best], cands.h[best], ev[best])
    return _result(P, members, target, cands, chosen, Z, truth, omega, level, int(ok.sum()), "plan")


def expected_for_tests(model, target, tests, *, level=LEVEL, samples=SAMPLES, seed=0, name="target"):
    """How the given tests are expected to narrow the prediction of ``target``'s folds: the figures of
    :func:`plan_for_target` for tests chosen otherwise (random, a grid), with the same draws (same ``seed``
    and ``samples``), so that a plan can be compared with them.

    Parameters
    ----------
    model : DeformationModel
    target : TargetFolds, Design or path of a design file
    tests : HingeSpecimens
        The tests, in order.
    level, samples, seed, name :
        As :func:`plan_for_target`.

    Returns
    -------
    TargetPlan
        With ``chosen_by`` ``"given"``.
    """
    samples = check_int("samples", samples, minimum=100)
    level = check_number("level", level, minimum=0.0, maximum=1.0, include_minimum=False, include_maximum=False)
    if not isinstance(tests, HingeSpecimens) or len(tests) < 1:
        raise GdfeError(f"tests: expected HingeSpecimens of at least one test, got {type(tests).__name__}")
    target = _as_target(target, name)
    members, P = _problem(model, target, HingeSpecimens(np.asarray(tests.L, float), np.asarray(tests.d, float),
                                                        np.asarray(tests.h, float)), name)
    bad = np.nonzero(~np.all(np.isfinite(P.mu), axis=1))[0]
    if bad.size:
        i = int(bad[0])
        raise GdfeError(f"tests: test {i + 1} (L = {tests.L[i]:g}, d = {tests.d[i]:g}, h = {tests.h[i]:g} mm) has no "
                        f"valid prediction by every member")
    n = len(tests)
    Z, truth, omega = _draws(samples, n, P.w.size, P.w, seed)
    return _result(P, members, target, tests, list(range(n)), Z, truth, omega, level, 0, "given")
