"""The baseline of a diagnosis: which form of the hinge law the gap is measured against.

The gap of folding tests to the model is measured against a baseline, and the baseline is a
choice: the paper's Eq. 1 as printed, ``alpha = K sqrt(h / d**3) L``, or one of its refitted
readings (:data:`gdfe.calibration.READINGS`), or Timoshenko's bilayer
(:mod:`gdfe.timoshenko`). Part of a gap to Eq. 1 can lie in the form of the law rather than in
an effect beyond it, and the diagnosis says how much (:func:`form_shares`).

:data:`BASELINES`:

``eq1``
    ``alpha = K (L / h) (h / d)**1.5``, Eq. 1 as printed (the GDFE hinge with Eq. 3);
``eq1-d1``
    ``alpha = K sqrt(h / d) L``, ``d`` to the first power (``K`` in 1/mm);
``power``
    ``alpha = K (L / h) (h / d)**p``, the exponent of ``h / d`` fitted;
``timoshenko``
    ``alpha = kappa_T(h, d, E_ratio, mismatch) L``, the elastic bilayer (the catalogue's
    ``passive_stiffness`` effect taken as the law itself).

The forms are fitted by the same least squares and held-out refits as the effects
(:func:`gdfe.diagnosis.fit.evaluate`); the catalogue's effects stay extensions of Eq. 1 (of the
bilayer for ``passive_stiffness``), so with another baseline an effect is named only where it
beats that baseline on held-out tests. Angles in radians, lengths in mm.
"""

from __future__ import annotations

import numpy as np

from gdfe._validation import GdfeError
from gdfe.calibration import reading_slope
from gdfe.diagnosis.effects import Model, Param

__all__ = ["BASELINES", "DESCRIPTIONS", "FormModel", "baseline_model", "form_shares"]

#: The baselines a diagnosis can measure the gap against.
BASELINES = ("eq1", "eq1-d1", "power", "timoshenko")

#: What each baseline says.
DESCRIPTIONS = {
    "eq1": "GDFE hinge with the contraction ratio of Eq. 3 refitted to the data; its converged fold is Eq. 1 "
           "as printed, alpha = K sqrt(h/d^3) L",
    "eq1-d1": "Eq. 1 with d to the first power, alpha = K sqrt(h/d) L (K in 1/mm), refitted",
    "power": "Eq. 1 with the exponent of h/d fitted, alpha = K (L/h) (h/d)^p",
    "timoshenko": "Timoshenko's elastic bilayer, alpha = kappa_T(h, d, E_ratio, mismatch) L "
                  "(the catalogue's passive_stiffness as the law)",
}

_PARAMS = {
    "eq1-d1": (Param("K", "1/mm", "coefficient of alpha = K sqrt(h/d) L"),),
    "power": (Param("K", "", "coefficient of alpha = K (L/h) (h/d)^p"),
              Param("p", "", "exponent of h/d (1.5 in Eq. 1 as printed)")),
}


class FormModel(Model):
    """A baseline form other than Eq. 1 (``eq1-d1``, ``power``, ``timoshenko``): a
    :class:`gdfe.diagnosis.effects.Model` with no effect switched on and its own law."""

    def __init__(self, form):
        if form not in _PARAMS and form != "timoshenko":
            raise GdfeError(f"form: expected one of {', '.join(_PARAMS)}, timoshenko, got {form!r}")
        super().__init__(())
        self.form = form
        self.name = f"baseline[{form}]"
        # the bilayer is the catalogue's passive_stiffness, here as the law itself
        self._bilayer = Model(("passive_stiffness",)) if form == "timoshenko" else None
        self.param_names = (self._bilayer.param_names if self._bilayer else
                            tuple(p.name for p in _PARAMS[form]))

    def parameters(self):
        return self._bilayer.parameters() if self._bilayer else list(_PARAMS[self.form])

    def __repr__(self):
        return f"FormModel({self.form!r})"

    def implausible(self, params, L, d, h, x=None, group=None):
        """The bilayer's parameters outside their physical range (:meth:`Model.implausible`);
        for the readings of Eq. 1 only a contraction outside its range."""
        if self._bilayer:
            return self._bilayer.implausible(params, L, d, h)
        from gdfe.physical_ranges import check_contraction

        with np.errstate(all="ignore"):
            found = check_contraction(self.contraction(np.asarray(params, float), np.asarray(d, float),
                                                       np.asarray(h, float)))
        return [] if found is None else [found]

    def contraction(self, params, d, h, x=None, group=None):
        """``c = 1 - R`` this form gives (``alpha = c L / h``)."""
        if self._bilayer:
            return self._bilayer.contraction(params, d, h)
        p = params[1] if self.form == "power" else None
        return reading_slope(self.form, params[0], p, d, h) * np.asarray(h, float)

    def predict(self, params, L, d, h, x=None, group=None):
        return self.contraction(params, d, h) * L / h

    def bounds(self, L, d, alpha, x=None):
        if self._bilayer:
            return self._bilayer.bounds(L, d, alpha)
        if self.form == "eq1-d1":
            return np.array([1e-9]), np.array([np.inf])
        return np.array([1e-9, -2.0]), np.array([np.inf, 5.0])

    def starts(self, L, d, h, alpha, x=None, group=None, weights=None):
        if self._bilayer:
            return self._bilayer.starts(L, d, h, alpha, weights=weights)
        w = np.ones_like(alpha) if weights is None else weights
        out = []
        for p in ([None] if self.form == "eq1-d1" else [-1.0, 0.0, 0.5, 1.0, 1.5, 2.5]):
            xs = np.array([1.0] if p is None else [1.0, p])
            pred = self.predict(xs, L, d, h)
            den = float(pred @ (w * pred))
            k = float(pred @ (w * alpha)) / den if den > 0 else 1.0
            xs[0] = min(max(k, 1e-6), 1e6)
            out.append(xs)
        return out


def baseline_model(name):
    """The model of a baseline of :data:`BASELINES`."""
    if name == "eq1":
        return Model(())
    return FormModel(name)


def form_shares(gaps, rmse, best_form, best_model, chosen):
    """How much of the gap to Eq. 1 lies in the form of the law, and how much beyond it.

    Parameters
    ----------
    gaps : dict of str -> float
        :func:`gdfe.diagnosis.verdict.gap` of every baseline form.
    rmse : dict of str -> float
        Held-out RMSE [rad] of every form and of ``"best_model"``.
    best_form : str
        The form with the smallest gap.
    best_model : tuple of (str, float)
        The chosen model's reported name and gap.
    chosen : str
        The baseline the diagnosis measured against.

    Returns
    -------
    dict
        ``forms`` (per form: ``gap``, ``held_out_rmse_rad``, ``gap_percent_of_eq1``), ``baseline``,
        ``best_form``, ``best_model``, ``form_share`` (part of Eq. 1's gap the best form removes),
        ``beyond_share`` (part the best model removes beyond the best form; negative when it does
        worse than that form), ``text``.
    """
    g0 = gaps["eq1"]

    def pct(g):
        return 100.0 * max(g, 0.0) / g0 if g0 > 0 else None

    name, gb = best_model
    forms = {k: {"gap": g, "held_out_rmse_rad": rmse[k], "gap_percent_of_eq1": pct(g)} for k, g in gaps.items()}
    gf = gaps[best_form]
    form_share = 1.0 - max(gf, 0.0) / g0 if g0 > 0 else None
    beyond = (max(gf, 0.0) - max(gb, 0.0)) / g0 if g0 > 0 else None
    if g0 > 0:
        text = (f"gap to Eq. 1 as printed: held-out RMSE {rmse['eq1']:.3f} rad (100 %) -> best form of the law, "
                f"{best_form}: {rmse[best_form]:.3f} rad ({pct(gf):.0f} % of the gap left) -> chosen model, "
                f"{name}: {rmse['best_model']:.3f} rad ({pct(gb):.0f} % left); the form of the law accounts for "
                f"{100 * form_share:.0f} % of the gap, effects beyond it for {100 * beyond:.0f} %")
        if beyond < 0:
            text += f" (the chosen model does worse on held-out tests than the {best_form} form alone)"
    else:
        text = "Eq. 1 as printed leaves no gap above the noise: no share to split between form and effects"
    return {"baseline": chosen, "forms": forms, "best_form": best_form,
            "best_model": {"name": name, "gap": gb, "held_out_rmse_rad": rmse["best_model"],
                           "gap_percent_of_eq1": pct(gb)},
            "form_share": form_share, "beyond_share": beyond, "text": text}
