"""A Kennedy-O'Hagan anchor: a model's closed form plus a Gaussian-process discrepancy.

Kennedy and O'Hagan (2001) write a measurement as the simulator plus a discrepancy plus noise,
``y(x) = eta(x, theta) + delta(x) + eps``, with ``delta`` a Gaussian process over the design
variables ``x``. Here ``eta`` is a model file's hinge closed form (by default the paper's
principle refitted to the tests, ``gdfe calibrate --model eq1``), its parameters ``theta`` as
fitted (the modular form of the method: ``theta`` by least squares first, the discrepancy
fitted to what it leaves), and ``delta`` scikit-learn's :class:`GaussianProcessRegressor` on
the residuals ``y - eta`` with the kernel ``C RBF(l_1 .. l_p) + White`` over the logarithms of
the design variables that vary (``L``, ``d``, ``h``, and numeric process columns as given),
standardised; its hyper-parameters by maximum marginal likelihood from seeded restarts, the
length scales no shorter than :data:`LENGTH_SCALES` allows.

The predicted angle of a specimen is ``eta + E[delta]`` with a normal interval whose variance
is the sum of three parts: the parameters' (the delta method on ``theta``'s covariance), the
discrepancy's (the process's posterior variance there) and the noise (the white kernel's
level). Far from the tests the discrepancy returns to its prior: the interval widens to
what the tests say about the size of the model's error, instead of trusting the closed form.

Where the noise of a test is known (replicates, a stated measurement error), the white kernel
is fixed at it (``noise=``): Kennedy and O'Hagan's observation error is then given, not
fitted, and the process cannot take the tests' scatter for a discrepancy of the model.

Hyper-parameters plugged in at their marginal-likelihood optimum are overconfident on a few
tests: on 17 of Table 1's the optimum often puts the white kernel on its lower bound and the
process interpolates the tests, so a held-out test falls outside its interval more often than
the level says. The process's part of the interval (the discrepancy's and the noise's) is
therefore scaled by its own leave-one-out calibration (Sundararajan and Keerthi 2001;
Rasmussen and Williams 2006, sec. 5.4.2): with ``K`` the fitted kernel matrix of the tests and
``r`` their residuals, test ``i`` left out is predicted at ``r_i - [K^-1 r]_i / [K^-1]_ii`` with
variance ``1 / [K^-1]_ii``, in closed form from one fit; ``s`` is the root mean square of those
standardised leave-one-out errors, and the process's standard deviation is multiplied by
``max(s, 1)`` (widened where the fit is overconfident, never narrowed below the plug-in).

Needs scikit-learn (``pip install gdfe[uncertainty]``). Angles in radians, lengths in mm.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings

import numpy as np

from gdfe._validation import GdfeError, check_positive
from gdfe.model import DeformationModel
from gdfe.predict import HingeSpecimens, Prediction, closed_form_jacobian, members_of

__all__ = ["Discrepancy", "fit_discrepancy", "loo_scale", "RESTARTS", "LENGTH_SCALES"]

log = logging.getLogger(__name__)

#: Restarts of the marginal-likelihood optimiser (seeded).
RESTARTS = 8
#: Range of the kernel's length scales, in standard deviations of the log inputs: a discrepancy
#: that turns within a third of the tests' spread cannot be told from noise by them (below it the
#: process interpolates the noise and the white kernel vanishes).
LENGTH_SCALES = (0.3, 50.0)


def _sklearn():
    try:
        from sklearn.gaussian_process import GaussianProcessRegressor
        from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
    except ModuleNotFoundError:
        raise GdfeError("the Kennedy-O'Hagan discrepancy needs scikit-learn: pip install 'gdfe[uncertainty]' "
                        "(or pip install scikit-learn)") from None
    return GaussianProcessRegressor, RBF, ConstantKernel, WhiteKernel


@dataclasses.dataclass
class Discrepancy:
    """A model's closed form plus a Gaussian-process discrepancy fitted to folding tests.

    Attributes
    ----------
    model : DeformationModel
        The baseline ``eta`` (with its parameters' covariance where it has one).
    gp : sklearn.gaussian_process.GaussianProcessRegressor
        Fitted to the residuals of ``model``.
    inputs : tuple of str
        The design variables the discrepancy varies over (``L_mm``, ``d_mm``, ``h_mm``, process
        columns).
    center, scale : (p,) float arrays
        Standardisation of the logarithms of the inputs.
    n_tests : int
    noise_rad : float [rad]
        The white kernel's standard deviation.
    loo_scale : float
        The factor (>= 1) of the process's standard deviation from its leave-one-out
        calibration (:func:`loo_scale`).
    warnings : tuple of str
        Hyper-parameters the marginal likelihood left on a bound of their range (the tests do
        not determine them), as scikit-learn said it.
    """

    model: DeformationModel
    gp: object
    inputs: tuple
    center: np.ndarray
    scale: np.ndarray
    n_tests: int
    noise_rad: float
    warnings: tuple = ()
    loo_scale: float = 1.0

    def _X(self, spec):
        cols = []
        for name in self.inputs:
            if name in ("L_mm", "d_mm", "h_mm"):
                v = {"L_mm": spec.L, "d_mm": spec.d, "h_mm": spec.h}[name]
                cols.append(np.log(np.asarray(v, float)))
            else:
                if name not in spec.extra:
                    raise GdfeError(f"specimens: the discrepancy varies over column {name!r}; columns: "
                                    f"{', '.join(spec.extra) or 'none'}")
                try:
                    cols.append(np.asarray(spec.extra[name], float))
                except ValueError:
                    raise GdfeError(f"specimens: column {name}: expected numbers") from None
        X = np.column_stack(cols) if cols else np.zeros((len(spec), 0))
        return (X - self.center) / self.scale

    def predict(self, specimens, level=0.9):
        """Angles of ``specimens`` with intervals at ``level`` (a :class:`gdfe.predict.Prediction`
        whose model part is the discrepancy's)."""
        from scipy import stats

        from gdfe.predict import load_specimens

        spec = specimens if isinstance(specimens, HingeSpecimens) else load_specimens(specimens)
        member = _baseline(self.model)
        u = member.uncertainty
        eta, J = closed_form_jacobian(member, u.names, spec, u.reading_offset_rad)
        sp = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", J, u.matrix(), J), 0.0))
        mean, sd = self.gp.predict(self._X(spec), return_std=True)
        latent = self.loo_scale * np.sqrt(np.maximum(sd**2 - self.noise_rad**2, 0.0))
        noise = self.loo_scale * self.noise_rad
        total = np.sqrt(sp**2 + latent**2 + noise**2)
        z = float(stats.norm.ppf(0.5 + level / 2))
        alpha = eta + mean
        n = len(spec)
        return Prediction(specimens=spec, level=level, alpha=alpha,
                          interval=np.column_stack([alpha - z * total, alpha + z * total]), sd_parameters=sp,
                          sd_model=latent, sd_noise=np.full(n, noise),
                          members=[{"name": f"{self.model.name} + GP discrepancy", "weight": 1.0,
                                    "noise_rad": noise, "kernel": str(self.gp.kernel_),
                                    "loo_scale": self.loo_scale,
                                    "inputs": list(self.inputs), "warnings": list(self.warnings)}],
                          member_alpha=alpha[:, None], member_sd_parameters=sp[:, None],
                          method="closed form + Gaussian-process discrepancy (Kennedy-O'Hagan)",
                          model_name=f"{self.model.name} + GP discrepancy", weighting="single",
                          model_part="discrepancy")


def _baseline(model):
    """The model's own closed form (its first member for a file with a named set: the chosen one)
    with its parameters' covariance; its noise is the discrepancy's white kernel here."""
    single = dataclasses.replace(model, ensemble=(), weighting="")
    return members_of(single, noise=0.0)[0].model


def loo_scale(gp):
    """Root mean square of a fitted process's standardised leave-one-out errors on its own
    training data, at least 1 (closed form from the kernel matrix; see the module's text)."""
    K = gp.kernel_(gp.X_train_)
    Kinv = np.linalg.inv(K)
    y = np.asarray(gp.y_train_, float).ravel()
    diag = np.diag(Kinv)
    z = (Kinv @ y) / np.sqrt(diag)  # (r_i - mu_-i) / sd_-i: [K^-1 r]_i / [K^-1]_ii * sqrt([K^-1]_ii)
    return max(1.0, float(np.sqrt(np.mean(z**2))))


def fit_discrepancy(model, tests, *, inputs=None, noise=None, seed=0, restarts=RESTARTS):
    """Fit a Gaussian-process discrepancy to the residuals of ``model`` on ``tests``.

    Parameters
    ----------
    model : DeformationModel
        The baseline; its parameters stay as they are.
    tests : FoldingTests or HingeSpecimens with measured angles
    inputs : sequence of str, optional
        The design variables (default: those of ``L_mm``, ``d_mm``, ``h_mm`` that vary).
    noise : float, optional
        The known noise of a test [rad] (standard deviation): the white kernel fixed at it.
        Default: fitted with the other hyper-parameters.
    seed : int
        Seed of the optimiser's restarts.

    Returns
    -------
    Discrepancy
    """
    GaussianProcessRegressor, RBF, ConstantKernel, WhiteKernel = _sklearn()
    if not isinstance(model, DeformationModel):
        raise GdfeError(f"model: expected a gdfe.DeformationModel, got {type(model).__name__}")
    alpha = getattr(tests, "alpha", None)
    if alpha is None:
        raise GdfeError("tests: expected folding tests with measured angles (alpha_rad)")
    spec = HingeSpecimens(L=np.asarray(tests.L, float), d=np.asarray(tests.d, float), h=np.asarray(tests.h, float),
                          extra=dict(getattr(tests, "extra", {}) or {}), alpha=np.asarray(alpha, float))
    n = len(spec)
    if n < 4:
        raise GdfeError(f"tests: expected at least 4 tests to fit a discrepancy, got {n}")
    # as gdfe diagnose reads them: a sign would be fitted as a discrepancy of twice the fold; with a known
    # noise a small negative fold within NEGATIVE_SIGMAS of it is a measured small fold
    from gdfe.diagnosis.angles import NEGATIVE_SIGMAS

    tol = NEGATIVE_SIGMAS * check_positive("noise", noise) if noise is not None else 0.0
    negative = np.flatnonzero(spec.alpha < -tol)
    if negative.size:
        rows = ", ".join(str(i + 2) for i in negative[:10]) + (", ..." if negative.size > 10 else "")
        raise GdfeError(f"tests: alpha_rad: expected fold angles as magnitudes (>= 0, positive towards the uncoated "
                        f"face), got {negative.size} negative{' beyond twice the noise' if tol else ''} in "
                        f"row{'s' if negative.size > 1 else ''} {rows}")
    if inputs is None:
        inputs = tuple(k for k, v in (("L_mm", spec.L), ("d_mm", spec.d), ("h_mm", spec.h)) if np.ptp(v) > 0)
    if not inputs:
        raise GdfeError("inputs: expected at least one design variable that varies over the tests, got none")
    member = _baseline(model)
    eta = closed_form_jacobian(member, (), spec, member.uncertainty.reading_offset_rad)[0]
    r = spec.alpha - eta
    probe = Discrepancy(model, None, tuple(inputs), np.zeros(len(inputs)), np.ones(len(inputs)), n, 0.0)
    X = probe._X(spec)
    center, scale = X.mean(axis=0), np.where(X.std(axis=0) > 0, X.std(axis=0), 1.0)
    X = (X - center) / scale
    var = max(float(np.mean(r**2)), 1e-8)
    p = X.shape[1]
    if noise is None:
        white = WhiteKernel(0.25 * var, (1e-6 * var, 2.0 * var))
    else:
        noise = check_positive("noise", noise)
        white = WhiteKernel(noise**2, "fixed")
    kernel = ConstantKernel(var, (1e-6 * var, 1e2 * var)) * RBF(np.ones(p), LENGTH_SCALES) + white
    gp = GaussianProcessRegressor(kernel=kernel, normalize_y=False, n_restarts_optimizer=restarts,
                                  random_state=seed)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gp.fit(X, r)
    notes = sorted({str(w.message).split(". Increasing")[0].split(". Decreasing")[0] for w in caught
                    if "bound" in str(w.message) or "converge" in str(w.message).lower()})
    for note in notes:  # a hyper-parameter on a bound: the tests do not determine it
        log.warning("discrepancy of %s: %s", model.name, note)
    noise = float(np.sqrt(gp.kernel_.k2.noise_level))
    s = loo_scale(gp)
    log.info("discrepancy of %s on %d tests: %s, leave-one-out scale %.3g", model.name, n, gp.kernel_, s)
    return Discrepancy(model=model, gp=gp, inputs=tuple(inputs), center=center, scale=scale, n_tests=n,
                       noise_rad=noise, warnings=tuple(notes), loo_scale=s)
