"""The one JSON vocabulary of the ``gdfe`` commands: the same quantity has the same key everywhere.

Every command's ``--json`` (and the ``result.json`` of an output folder) names a quantity by
the key of :data:`VOCABULARY`, the unit in its suffix: ``_mm`` millimetres, ``_rad`` radians,
``_s`` seconds of one stage, ``_mib`` mebibytes; a key without a suffix is a ratio, a count, a
flag or a word. The table, its units and the keys it replaces:

=============================  ====  =============================================  ==========================
key                            unit  quantity                                       replaces (old aliases)
=============================  ====  =============================================  ==========================
``fold_angle_rad``             rad   fold angle (simulated, or measured in a test)  ``alpha_rad``
``fold_angle_eq1_rad``         rad   Eq. 1's fold angle of the hinge                ``alpha_eq1_rad``
``fold_angle_eq2_rad``         rad   Eq. 2's fold angle, (1 - R) L / h              ``alpha_eq2_rad``
``fold_angle_model_rad``       rad   a deformation model's closed-form fold angle   ``alpha_model_rad``
``timoshenko_fold_angle_rad``  rad   Timoshenko's curvature times L                 ``timoshenko_alpha_rad``
``error_rad``                  rad   simulated minus closed-form fold angle
``length_mm``                  mm    hinge (fold) width L, or a strip's length      ``L_mm``
``d_mm``, ``h_mm``             mm    passive-layer and active-film thickness
``width_mm``                   mm    strip width
``R``, ``K``                         contraction ratio; coefficient of Eq. 1
``n_cells``                          cells (elements) of the film                   ``n_elements``
``n_tests``                          folding tests fitted                           ``n`` (``gdfe calibrate``)
``converged``                        whether the solver converged
``status``                           ``converged`` or ``NOT CONVERGED``
``iterations``                       solver iterations (all frames)
``residual``                         the solver's final residual
``seconds``                    s     wall time of the whole run
``rmse_rad``                   rad   RMS error of a fit                             ``rmse``
``loo_rmse_rad``               rad   leave-one-out RMS error of a fit               ``loo_rmse``
``held_out_rmse_rad``          rad   held-out RMS error of a fit                    ``held_out_rmse``
``penetration_mm``             mm    deepest self-penetration (0 when none)
=============================  ====  =============================================  ==========================

The full table, with every key, is :data:`VOCABULARY`.

Old keys are kept as aliases for one release: where a command's JSON held an old key, it now
holds the new key and, beside it, the old one with the same value; an object at the top adds
``"deprecated_keys": {"alpha_rad": "fold_angle_rad", ...}``, each old key used anywhere in it
with the key that replaces it (a list at the top, ``gdfe calibrate --model all``, carries the
aliases in each item, without ``deprecated_keys``). Readers should move to the new keys; the aliases and
``deprecated_keys`` go in the next release. (:func:`with_aliases` does this in
:func:`gdfe.cli._common.emit`, so commands write the new keys, or pass on the library's
dictionaries, and the aliases follow.)

Keys that belong to one command's own result (``gdfe view``'s ``quads``, ``gdfe design``'s
``parts``) are listed in :data:`COMMAND_KEYS`; ``tests/test_cli_json.py`` checks that every
top-level key of every command is in the vocabulary or there.
"""

from __future__ import annotations

__all__ = ["VOCABULARY", "ALIASES", "COMMAND_ALIASES", "COMMAND_KEYS", "with_aliases", "known_keys", "in_vocabulary"]

#: key -> (unit, quantity, old aliases replaced everywhere).
VOCABULARY = {
    "fold_angle_rad": ("rad", "fold angle (simulated, or measured in a folding test)", ("alpha_rad",)),
    "fold_angle_eq1_rad": ("rad", "Eq. 1's fold angle of the hinge", ("alpha_eq1_rad",)),
    "fold_angle_eq2_rad": ("rad", "Eq. 2's fold angle, (1 - R) L / h", ("alpha_eq2_rad",)),
    "fold_angle_model_rad": ("rad", "a deformation model's closed-form fold angle", ("alpha_model_rad",)),
    "timoshenko_fold_angle_rad": ("rad", "Timoshenko's curvature times the hinge width", ("timoshenko_alpha_rad",)),
    "error_rad": ("rad", "simulated minus closed-form fold angle", ()),
    "length_mm": ("mm", "hinge (fold) width L, or a strip's length", ("L_mm",)),
    "d_mm": ("mm", "passive-layer thickness", ()),
    "h_mm": ("mm", "active-film thickness", ()),
    "width_mm": ("mm", "strip width", ()),
    "panel_length_mm": ("mm", "length of each rigid panel", ()),
    "R": ("", "contraction ratio of a free face", ()),
    "K": ("", "coefficient K of Eq. 1", ()),
    "isotropy": ("", "transverse / longitudinal shrink", ()),
    "nz": ("", "cell layers through the film", ()),
    "n_cells": ("", "cells (elements) of the film", ("n_elements",)),
    "n_points": ("", "vertices of the film", ()),
    "n_tests": ("", "folding tests", ()),
    "converged": ("", "whether the solver converged", ()),
    "status": ("", "'converged' or 'NOT CONVERGED'", ()),
    "iterations": ("", "solver iterations over all frames", ()),
    "frame_iterations": ("", "solver iterations of each frame", ()),
    "frames": ("", "frames of the contraction ramp", ()),
    "residual": ("", "the solver's final residual", ()),
    "seconds": ("s", "wall time of the run", ()),
    "method": ("", "solver method", ()),
    "device": ("", "where the solver's array work ran: 'cpu' or 'gpu'", ()),
    "tol": ("", "the solver's tolerance [units of h]", ()),
    "energy": ("", "elastic energy of the result", ()),
    "drift": ("", "drift between near-equal states, or null", ()),
    "error_estimate_mm": ("mm", "estimated distance to the solution", ()),
    "newton_steps": ("", "the last frame's Newton steps: residual, length and estimate in units of h, fraction "
                         "taken, damping, CG iterations, the model's agreement, energy, seconds", ()),
    "start_levels": ("", "the multilevel start's levels, the coarsest first: cells, iterations, residual in "
                         "units of h, whether converged or drifted, seconds", ()),
    "penetration_mm": ("mm", "deepest self-penetration (0 when none)", ()),
    "penetration": ("", "the self-penetration check", ()),
    "contact": ("", "whether the solve used self-contact", ()),
    "contact_info": ("", "the self-contact report", ()),
    "model": ("", "the deformation model (or its name)", ()),
    "contraction_source": ("", "what gave the contraction: R given, or a deformation model by name", ()),
    "process": ("", "the part's process variables given: name -> value", ()),
    "process_used": ("", "the process variables the deformation model read", ()),
    "process_unused": ("", "the process variables given that nothing read (a warning said so)", ()),
    "rmse_rad": ("rad", "RMS error of a fit", ("rmse",)),
    "loo_rmse_rad": ("rad", "leave-one-out RMS error of a fit", ("loo_rmse",)),
    "held_out_rmse_rad": ("rad", "held-out RMS error of a fit", ("held_out_rmse",)),
    "r2": ("", "coefficient of determination of a fit", ()),
    "files": ("", "files written: kind -> path", ()),
    "title": ("", "title of the picture", ()),
    "path": ("", "a file's path", ()),
    "name": ("", "a name", ()),
}

#: old key -> new key, renamed wherever it appears in a command's JSON.
ALIASES = {old: new for new, (_, _, olds) in VOCABULARY.items() for old in olds}

#: command -> {old key -> new key} of the command's own keys, at the top of its JSON: the old key, where
#: present, gains the new one beside it; the new key, where the command now writes it, gains the old one
#: (so the JSON of a command that renamed a key still carries the old one for a release). Here too go
#: names too generic to rename everywhere (``n`` is a count of a histogram's bins in ``gdfe diagnose``).
COMMAND_ALIASES = {
    "hinge": {"alpha_rad": "fold_angle_rad", "alpha_eq1_rad": "fold_angle_eq1_rad",
              "alpha_eq2_rad": "fold_angle_eq2_rad", "alpha_model_rad": "fold_angle_model_rad",
              "L_mm": "length_mm", "n_elements": "n_cells"},
    "fem hinge": {"alpha_rad": "fold_angle_rad", "timoshenko_alpha_rad": "timoshenko_fold_angle_rad"},
    "calibrate": {"n": "n_tests", "held_out_rmse": "held_out_rmse_rad"},
}

#: command -> its own top-level keys (not shared quantities).
COMMAND_KEYS = {
    "hinge": ("K", "fold_angle_eq1_rad", "fold_angle_eq2_rad", "fold_angle_model_rad", "error_rad",
              "panel_lengthened_from_mm", "panel_reach_mm", "model_file", "uncertainty"),
    "simulate": ("design", "spacing_mm", "cells_by_material", "kind", "face", "source", "d_mm_range",
                 "fold_angle_rad", "crease_angles", "panel_angles", "bbox_mm", "exported", "pixel_mm", "model_file",
                 "uncertainty"),
    "design": ("choices", "parts", "package", "letters", "uncertainty"),
    "view": ("series", "activation", "vertices", "quads", "html"),
    "data": ("data_sets", "copied_to"),
    "calibrate": ("K_ci95", "description", "p", "p_ci95", "r2_uncentered", "R_at_d", "model_file"),
    "fem hinge": ("E_ratio", "eigenstrain", "nu", "kappa_per_mm", "kappa_L_rad", "timoshenko_kappa_per_mm",
                  "dofs", "element", "load_factor", "load_steps", "nonlinear", "resolution", "linear_solver"),
    "fem timoshenko-check": ("checks", "passed"),
    "fem calibrate": ("E_ratio", "eigenstrain", "at_bound", "tests", "loo_params", "profile", "settings"),
    "fem simulate": ("design", "E_ratio", "eigenstrain", "nu", "dofs", "element", "load_factor", "load_steps",
                     "rejected_steps", "nonlinear", "resolution", "n_elements", "pixel_mm", "refine", "element_size_mm",
                     "size_mm", "coat_levels_mm", "coarsen", "layers_per_ply", "solver", "cost", "support", "memory_mib"),
    "bench": ("mode", "machine", "hinges", "sheets", "fem_comparison", "verdicts"),
    "diagnose": ("verdict", "verdict_text", "regime", "gap_removed", "noise", "columns", "excluded", "baseline",
                 "best", "best_detail", "selected", "selection", "effects", "candidates", "catalogue", "where",
                 "residuals", "lack_of_fit", "structure", "separation", "held_out", "named", "verdict_rules",
                 "warnings", "report", "model_file", "angles", "confounded", "baseline_form", "artefacts",
                 "attribution"),
    "diagnose-shape": ("verdict", "matches", "match", "design", "measured", "alignment", "n_measured_points",
                       "rms_before", "rms_after", "shrink", "named", "corrected_R", "regions", "element_deviation",
                       "n_simulations", "transform", "name_gain", "rival_tolerance", "outcome", "credited",
                       "not_ruled_out", "forms", "floor_mm", "noise_mm", "level_mm", "gain_beyond_floor", "report"),
    "report": ("index", "studies", "ok", "resolution", "generated", "versions", "view"),
    "predict": ("weighting", "level", "n_specimens", "members", "mean_width_rad", "rows", "parts", "coverage",
                "warnings"),
    "plan": ("best", "named", "members", "entropy_nats", "information_nats", "expected_reduction", "tests",
             "candidates", "objective", "target", "target_kind", "level", "folds", "expected_variance_rad2",
             "expected_width_rad", "noise_sd_rad", "chosen_by", "warnings"),
    # every study: its name, figure and headlines; each study's own numbers under "study NAME"
    "study": ("study", "figure", "title", "resolution", "headlines", "summary", "files"),
    "study fig06": ("R_eq3", "cells_across_hinge", "hinges", "specimen_L26"),
}


def known_keys(command):
    """The keys ``command``'s JSON may hold at its top: the vocabulary, the aliases it still carries,
    ``deprecated_keys`` and the command's own (:data:`COMMAND_KEYS`)."""
    own = set(COMMAND_KEYS.get(command, ()))
    if command.startswith("study "):  # a study's own numbers, beside those of every study
        own |= set(COMMAND_KEYS["study"])
    return set(VOCABULARY) | set(ALIASES) | set(COMMAND_ALIASES.get(command, {})) | {"deprecated_keys"} | own


def _renamed(obj, renames, used, top=None):
    """``obj`` with every old key of ``renames`` (and, at this level, of ``top``) followed by its new key
    with the same value, recursively, and each new key of ``top`` followed by its old one; ``used``
    collects old -> new."""
    if isinstance(obj, list):
        return [_renamed(v, renames, used) for v in obj]
    if not isinstance(obj, dict):
        return obj
    here = {**renames, **(top or {})}
    former = {new: old for old, new in (top or {}).items()}
    out = {}
    for key, value in obj.items():
        value = _renamed(value, renames, used)
        new = here.get(key) if isinstance(key, str) else None
        if new is not None:
            used[key] = new
            out.setdefault(new, obj.get(new, value))
        out[key] = value
        old = former.get(key) if isinstance(key, str) else None
        if old is not None:
            used[old] = key
            out[old] = obj.get(old, value)
    return out


def with_aliases(obj, command=None):
    """``obj`` (a command's JSON) in the vocabulary: beside each old key its new one, beside each new key
    that ``command`` used to write under an old name that old one, and, in an object at the top,
    ``deprecated_keys`` (old -> new) where any alias is carried."""
    used, top = {}, COMMAND_ALIASES.get(command)
    if isinstance(obj, list):  # several results (gdfe calibrate --model all): each is a top
        return [_renamed(v, ALIASES, used, top) for v in obj]
    out = _renamed(obj, ALIASES, used, top)
    if used and isinstance(out, dict):
        out["deprecated_keys"] = {**out.get("deprecated_keys", {}), **dict(sorted(used.items()))}
    return out


def in_vocabulary(module):
    """A study module whose ``run`` returns its numbers in the vocabulary (:func:`with_aliases`), for
    ``gdfe study``, which prints what ``run`` returns."""
    import types

    def run(**kwargs):
        return with_aliases(module.run(**kwargs), "study")

    return types.SimpleNamespace(NAME=module.NAME, __name__=module.__name__, __doc__=module.__doc__, run=run)
