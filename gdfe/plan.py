"""The next folding tests to print: those that best tell apart the models the data cannot.

A diagnosis names every model its tests cannot tell from the chosen one (the named set).
Which hinge specimens ``(L, d, h)``, within the printable ranges, would tell them apart? The
answer here is the design that maximises the **expected information** the new tests' angles
``Y`` carry about which member ``M`` of the set is right, the mutual information

    ``I(M; Y) = E[ log p(Y | M) - log sum_k w_k p(Y | k) ]``,

with ``w_k`` uniform over the named set (the diagnosis could not tell them apart: no member is
favoured before the tests are printed) and ``p(y | k)`` member ``k``'s predictive distribution
(:mod:`gdfe.predict`: normal about its mean, the parameters' part shared by all the new
tests — one draw of the parameters for all — and the noise independent, so that a replicate
narrows the noise's part only). ``I`` is the expected fall of the entropy of the
member weights, ``H(w) = log K`` nats before; a design whose ``I`` reaches ``H(w)`` is expected
to name one member alone. The expectation is by Monte Carlo with common random numbers (the
same draws for every candidate, so that candidates are compared without the draws' noise),
and the ``n`` tests are chosen greedily, each the candidate of a grid over the ranges that
adds the most to the tests chosen before it (replicates allowed).

Lengths in mm; information in nats.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from gdfe._validation import LENGTH_RANGE, GdfeError, check_int
from gdfe.predict import HingeSpecimens, closed_form_jacobian, members_of

__all__ = ["Plan", "plan_tests", "candidate_grid", "parse_range", "models_to_tell_apart", "GRID", "SAMPLES", "L_RANGE",
           "D_RANGE"]

log = logging.getLogger(__name__)

#: Candidates along each varied range (fewer where three vary: at most MAX_CANDIDATES in all).
GRID = 21
MAX_CANDIDATES = 1500
#: Monte Carlo draws of the expectation.
SAMPLES = 3000
#: Candidates evaluated at once (memory: CHUNK x SAMPLES x tests).
CHUNK = 64
#: Printable ranges [mm] by default: Table 1's widths and coats.
L_RANGE = (1.0, 6.0)
D_RANGE = (0.11, 0.5)


def models_to_tell_apart(diag):
    """The fits of a diagnosis a plan should tell apart: its named set and every usable model whose
    held-out error is within one standard error of the chosen one's (its ``candidates``), the
    chosen one first. Where the named set is one model (the baseline, say) the candidates are the
    alternatives the tests have not ruled out yet."""
    names = set(diag.candidates) | {f.name for f in diag.named}
    fits = [diag.best] + [f for f in [diag.baseline, *diag.fits]
                          if f.name in names and f is not diag.best and f.usable and hasattr(f.model, "process")]
    seen, out = set(), []
    for f in fits:
        if f.name not in seen:
            seen.add(f.name)
            out.append(f)
    return out


def parse_range(name, text):
    """``"LO:HI"`` or ``"VALUE"`` [mm] as ``(lo, hi)``, both positive, ``lo <= hi``."""
    parts = str(text).split(":")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise GdfeError(f"{name}: expected LO:HI or a value in mm, got {text!r}") from None
    if len(vals) not in (1, 2) or not all(math.isfinite(v) and v > 0 for v in vals):
        raise GdfeError(f"{name}: expected LO:HI or a value of positive lengths in mm, got {text!r}")
    lo, hi = vals[0], vals[-1]
    if lo > hi:
        raise GdfeError(f"{name}: expected LO <= HI, got {text!r}")
    if lo < LENGTH_RANGE[0] or hi > LENGTH_RANGE[1]:
        raise GdfeError(f"{name}: expected lengths between {LENGTH_RANGE[0]:g} and {LENGTH_RANGE[1]:g} mm, got {text!r}")
    return lo, hi


def _no_valid_candidate(L_range, d_range, h_range):
    """The error of a plan none of whose candidates every member predicts (a contraction ratio outside (0, 1),
    as where the coat is too thin for the film)."""
    span = ", ".join(f"{k} {lo:g}-{hi:g} mm" for k, (lo, hi) in (("--L", L_range), ("--d", d_range), ("--h", h_range)))
    return GdfeError(f"plan: no candidate in the ranges ({span}) has a valid prediction by every member (a "
                     f"contraction ratio in (0, 1)); the coat d and the film h decide it: widen --d or change --h")


@dataclasses.dataclass
class Plan:
    """Proposed folding tests and what they are expected to tell.

    Attributes
    ----------
    L, d, h : (n,) float arrays [mm]
        The proposed specimens, in the order chosen.
    information : (n,) float array [nats]
        Expected information about the named set's member after the first 1, 2, ... tests.
    entropy : float [nats]
        Entropy of the member weights before (``log K``).
    members : list of str
    predicted : (n, K) float array [rad]
        Each member's predicted angle of each proposed test.
    spread : (n, K) float array [rad]
        Each member's predictive standard deviation there.
    candidates : int
    """

    L: np.ndarray
    d: np.ndarray
    h: np.ndarray
    information: np.ndarray
    entropy: float
    members: list
    predicted: np.ndarray
    spread: np.ndarray
    candidates: int

    @property
    def expected_reduction(self):
        """Expected fraction of the entropy of the member weights the tests remove."""
        return float(self.information[-1] / self.entropy) if self.entropy > 0 else 0.0

    def as_dict(self):
        rows = [{"L_mm": float(self.L[i]), "d_mm": float(self.d[i]), "h_mm": float(self.h[i]),
                 "information_nats": float(self.information[i]),
                 "predicted_rad": {m: float(self.predicted[i, k]) for k, m in enumerate(self.members)},
                 "spread_rad": {m: float(self.spread[i, k]) for k, m in enumerate(self.members)}}
                for i in range(self.L.size)]
        return {"members": self.members, "entropy_nats": self.entropy, "information_nats": float(self.information[-1])
                if self.L.size else 0.0, "expected_reduction": self.expected_reduction, "tests": rows,
                "candidates": self.candidates,
                "objective": "expected information about which member of the named set is right (mutual "
                             "information, nats), members equally likely before; greedy over a grid"}

    def text(self):
        if len(self.members) < 2:
            return f"one model ({self.members[0]}): there is no choice of model left to resolve"
        lines = [f"models to tell apart: {', '.join(self.members)} (entropy {self.entropy:.3f} nats, equally likely)",
                 f"{'test':>4s} {'L_mm':>6s} {'d_mm':>6s} {'h_mm':>6s}  {'info_nats':>9s}  predicted by each member [rad]"]
        for i in range(self.L.size):
            pred = ", ".join(f"{self.predicted[i, k]:.2f}+-{self.spread[i, k]:.2f}" for k in range(len(self.members)))
            lines.append(f"{i + 1:4d} {self.L[i]:6.3g} {self.d[i]:6.3g} {self.h[i]:6.3g}  {self.information[i]:9.3f}  {pred}")
        lines.append(f"expected to remove {100 * self.expected_reduction:.0f} % of the uncertainty of which model is right")
        return "\n".join(lines)


def _member_predictions(members, spec):
    """Every member's means ``(C, K)`` on the candidates, derivatives in its parameters (a list of
    ``(C, p_k)``), covariances and noises; NaN means where a member has no valid contraction."""
    C = len(spec)
    mu = np.full((C, len(members)), np.nan)
    jac, cov, noise = [], [], []
    for k, m in enumerate(members):
        u = m.model.uncertainty
        if m.model.columns:
            raise GdfeError(f"plan: member {m.model.name!r} needs process columns ({', '.join(m.model.columns.values())}); "
                            f"plans over process variables are not supported")
        J = np.zeros((C, len(u.names)))
        try:
            mu[:, k], J[:] = closed_form_jacobian(m.model, u.names, spec, u.reading_offset_rad)
        except GdfeError:  # some candidates give no valid contraction: one by one
            for i in range(C):
                one = HingeSpecimens(spec.L[[i]], spec.d[[i]], spec.h[[i]])
                try:
                    a, Ji = closed_form_jacobian(m.model, u.names, one, u.reading_offset_rad)
                except GdfeError:
                    continue
                mu[i, k], J[i] = a[0], Ji[0]
        jac.append(J)
        cov.append(u.matrix())
        noise.append(u.noise_rad)
    return mu, jac, cov, np.array(noise)


def _information(mu, jac, cov, noise, chosen, cands, Z, truth):
    """Expected information (nats) of the chosen tests plus each candidate of ``cands``.

    Given member ``k`` the angles of tests ``x_1 .. x_m`` are normal with mean ``mu_k(x)`` and
    covariance ``J_k C_k J_k^T + s_k^2 I``: one draw of the parameters for all of them (so a
    replicate does not narrow the parameters' part), the noise independent. The draws of sample
    ``s`` are ``y = mu_t + chol_t Z_s`` under its true member ``t`` (the leading rows of a
    Cholesky factor are those of the tests chosen before: the same draws at every step)."""
    B, K, S = len(cands), mu.shape[1], Z.shape[0]
    rows = np.column_stack([np.broadcast_to(np.array(chosen, int), (B, len(chosen))), cands])  # (B, m)
    m = rows.shape[1]
    M = mu[rows]  # (B, m, K)
    chol, logdet = [], []
    for J, C_, s in zip(jac, cov, noise):
        Jr = J[rows]  # (B, m, p)
        Sig = np.einsum("bip,pq,bjq->bij", Jr, C_, Jr) + (s**2 + 1e-12) * np.eye(m)
        Lc = np.linalg.cholesky(Sig)
        chol.append(Lc)
        logdet.append(2 * np.log(np.diagonal(Lc, axis1=1, axis2=2)).sum(axis=1))
    lp = np.empty((B, S, K))
    for t in range(K):
        sel = truth == t
        Y = M[:, :, t, None] + chol[t] @ Z[sel].T  # (B, m, S_t)
        for k in range(K):
            r = np.linalg.solve(chol[k], Y - M[:, :, k, None])  # the triangular factor: whitened residuals
            lp[:, sel, k] = -0.5 * (r**2).sum(axis=1) - 0.5 * logdet[k][:, None] - 0.5 * m * math.log(2 * math.pi)
    own = lp[:, np.arange(S), truth]
    mix = np.logaddexp.reduce(lp, axis=2) - math.log(K)
    return (own - mix).mean(axis=1)


def candidate_grid(L_range=L_RANGE, d_range=D_RANGE, h_range=None, grid=GRID):
    """The candidate specimens of a plan: ``grid`` values along each range that varies (fewer when there
    would be more than :data:`MAX_CANDIDATES` in all), every combination.

    Returns
    -------
    L, d, h : (C,) float arrays [mm]
    """
    from gdfe import paper

    h_range = (paper.H, paper.H) if h_range is None else h_range
    ranges = (L_range, d_range, h_range)
    varied = sum(hi > lo for lo, hi in ranges)
    per_axis = max(2, min(grid, int(MAX_CANDIDATES ** (1.0 / max(varied, 1)))))
    axes = [np.linspace(lo, hi, per_axis) if hi > lo else np.array([lo]) for lo, hi in ranges]
    return tuple(a.ravel() for a in np.meshgrid(*axes, indexing="ij"))


def plan_tests(model, n, L_range=L_RANGE, d_range=D_RANGE, h_range=None, *, grid=GRID, samples=SAMPLES, seed=0):
    """The ``n`` hinge specimens within the ranges that tell the named set of ``model`` apart best.

    Parameters
    ----------
    model : DeformationModel
        From a diagnosis (:func:`gdfe.predictive.from_diagnosis`): its members are the named set.
    n : int
        Tests to propose.
    L_range, d_range, h_range : (lo, hi) [mm]
        Printable ranges (``h_range`` default: the paper's film, 0.29 mm).
    grid : int
        Candidates along each range that varies (fewer when there would be more than
        :data:`MAX_CANDIDATES` in all).
    samples : int
        Monte Carlo draws.
    seed : int

    Returns
    -------
    Plan
    """
    n = check_int("n", n, minimum=1)
    grid = check_int("grid", grid, minimum=2)
    samples = check_int("samples", samples, minimum=100)
    seed = check_int("seed", seed, minimum=0)
    Lg, dg, hg = candidate_grid(L_range, d_range, h_range, grid)
    members = members_of(model)
    names = [m.model.name for m in members]
    K = len(members)
    if K < 2:
        return Plan(L=np.zeros(0), d=np.zeros(0), h=np.zeros(0), information=np.zeros(0), entropy=0.0, members=names,
                    predicted=np.zeros((0, 1)), spread=np.zeros((0, 1)), candidates=int(Lg.size))
    mu, jac, cov, noise = _member_predictions(members, HingeSpecimens(Lg, dg, hg))
    ok = np.all(np.isfinite(mu), axis=1)
    if not ok.any():
        raise _no_valid_candidate(L_range, d_range, (float(hg.min()), float(hg.max())))
    mu, Lg, dg, hg = mu[ok], Lg[ok], dg[ok], hg[ok]
    jac = [J[ok] for J in jac]
    rng = np.random.default_rng(seed)
    truth = np.arange(samples) % K  # stratified: every member equally often
    Z = np.zeros((samples, 0))
    chosen, info = [], []
    for _ in range(n):
        Z = np.column_stack([Z, rng.standard_normal(samples)])
        mi = np.concatenate([_information(mu, jac, cov, noise, chosen, np.arange(a, min(a + CHUNK, len(mu))), Z, truth)
                             for a in range(0, len(mu), CHUNK)])
        c = int(np.argmax(mi))
        chosen.append(c)
        info.append(float(min(mi[c], math.log(K))))
        log.info("test %d: L=%.3g d=%.3g h=%.3g mm, information %.3f nats", len(chosen), Lg[c], dg[c], hg[c], mi[c])
    sd = np.sqrt(np.stack([np.einsum("ij,jk,ik->i", J, C_, J) for J, C_ in zip(jac, cov)], axis=1) + noise**2)
    idx = np.array(chosen)
    return Plan(L=Lg[idx], d=dg[idx], h=hg[idx], information=np.array(info), entropy=math.log(K), members=names,
                predicted=mu[idx], spread=sd[idx], candidates=int(ok.sum()))
