"""Model files and the options that use them: what a file or an option says is what is used, or an error
naming it (units, repeated process variables, group labels, seeds, too few draws, a hand-edited ensemble)."""

import argparse
import dataclasses
import json
import tomllib

import numpy as np
import pytest
import tomli_w

import gdfe
from gdfe import GdfeError
from gdfe.cli import main
from gdfe.cli._common import _process
from gdfe.ensemble import Ensemble, draws_for, fold_ensemble
from gdfe.model import DeformationModel, Member, Parameter, Uncertainty, load_model

HINGE = ["hinge", "-L", "1.6", "--d", "0.33"]


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def _predictive(name="eq3", K=0.3706, **kw):
    """A small model with predictive content: Eq. 3 with K's variance."""
    u = Uncertainty(names=("K",), covariance=((1e-5,),), noise_rad=0.05, dof=10)
    return DeformationModel(principle="eq1", params={"K": Parameter(K, se=0.003)}, name=name, uncertainty=u,
                            source="test", **kw)


# -- 1. a parameter's unit -------------------------------------------------------------------------------
@pytest.mark.parametrize("body, match", [
    ('principle = "eq1"\nmechanisms = ["hinge_length"]\n[parameters.K]\nvalue = 0.3706\n'
     '[parameters.lambda]\nvalue = 0.3\nunit = "um"\n', r"m\.toml: lambda\.unit: expected the unit 'mm', got 'um'"),
    ('principle = "eq1"\nmechanisms = ["saturation"]\n[parameters.K]\nvalue = 0.3706\n'
     '[parameters.alpha_max]\nvalue = 2.5\nunit = "deg"\n', r"m\.toml: alpha_max\.unit: expected the unit 'rad'"),
    ('principle = "eq1-d1"\n[parameters.K]\nvalue = 370.8\nunit = "1/m"\n', r"K\.unit: expected the unit '1/mm'"),
    ('principle = "eq1"\n[parameters.K]\nvalue = 0.37\nunit = "mm"\n', r"K\.unit: expected no unit"),
    ('principle = "eq1"\n[parameters.K]\nvalue = 0.37\n[ensemble]\nweighting = "single"\n[[ensemble.members]]\n'
     'weight = 1.0\nprinciple = "eq1"\nmechanisms = ["cure_depth"]\n[ensemble.members.parameters]\nK = 0.37\n'
     '[ensemble.members.parameters.delta]\nvalue = 20\nunit = "um"\n',
     r"m\.toml: ensemble\.members\[0\]: delta\.unit: expected the unit 'mm'"),
])
def test_a_unit_other_than_the_parameters_own_is_refused(tmp_path, body, match):
    path = _write(tmp_path, "m.toml", body)
    with pytest.raises(GdfeError, match=match):
        load_model(path)


def test_the_command_line_refuses_a_model_in_other_units(tmp_path, capsys):
    path = _write(tmp_path, "m.toml", 'principle = "eq1"\nmechanisms = ["hinge_length"]\n[parameters.K]\n'
                                      'value = 0.3706\n[parameters.lambda]\nvalue = 0.3\nunit = "um"\n')
    assert main([*HINGE, "--model", str(path)]) == 1
    assert "m.toml: lambda.unit: expected the unit 'mm', got 'um'" in capsys.readouterr().err


def test_own_or_missing_units_load_and_a_process_parameter_keeps_its_columns_unit(tmp_path):
    path = _write(tmp_path, "m.toml", 'principle = "eq1-d1"\nmechanisms = ["hinge_length", "partial_activation"]\n'
                                      '[columns]\npartial_activation = "T_C"\n[parameters]\nlambda = 0.3\n'
                                      '[parameters.K]\nvalue = 0.37\nunit = "1/mm"\n'
                                      '[parameters.x50]\nvalue = 120\nunit = "C"\n[parameters.rate]\nvalue = 0.2\n')
    m = load_model(path)
    assert {k: p.unit for k, p in m.params.items()} == {"K": "1/mm", "x50": "C", "rate": "1 / unit of the column",
                                                        "lambda": "mm"}
    back = load_model(m.save(tmp_path / "back.toml"))
    assert back.params == m.params
    with pytest.raises(GdfeError, match=r"lambda\.unit: expected the unit 'mm', got 'um'"):
        DeformationModel(principle="eq1", mechanisms=("hinge_length",),
                         params={"K": 0.37, "lambda": Parameter(300, unit="um")})


# -- 2. a process variable given twice ---------------------------------------------------------------------
def test_a_process_variable_given_twice_is_refused(tmp_path, capsys):
    with pytest.raises(argparse.ArgumentTypeError, match="T_C more than once"):
        _process("T_C=150,T_C=100")
    with pytest.raises(argparse.ArgumentTypeError, match="T_C more than once"):
        _process("T_C=150, lot=B, T_C =150")
    assert _process("T_C=150,lot=B") == {"T_C": 150.0, "lot": "B"}
    path = _write(tmp_path, "pa.toml", 'principle = "eq1"\nmechanisms = ["partial_activation"]\n[columns]\n'
                                       'partial_activation = "T_C"\n[parameters]\nK = 0.3706\nx50 = 120\nrate = 0.2\n')
    with pytest.raises(SystemExit):
        main([*HINGE, "--model", str(path), "--process", "T_C=150,T_C=100"])
    assert "--process: expected each name once, got T_C more than once" in capsys.readouterr().err


# -- 3. numeric group labels ----------------------------------------------------------------------------
def _batch(labels):
    return DeformationModel(principle="eq1", mechanisms=("batch",), params={"K": 0.06, f"scale[{labels[1]}]": 1.25},
                            columns={"batch": "lot"}, labels=labels)


def test_a_number_names_the_group_label_of_the_same_number():
    m = _batch(("1", "2"))
    for v in (2, 2.0, np.int64(2), "2"):
        assert m.process_factor({"lot": v}) == 1.25, v
    assert m.process_factor({"lot": 1.0}) == 1.0
    assert _batch(("1.0", "2.0")).process_factor({"lot": 2}) == 1.25
    for v in (2.5, "2.0", True):
        with pytest.raises(GdfeError, match="process lot: expected one of the groups"):
            m.process_factor({"lot": v})
    # a label that is no number matches nothing new
    for v in (2.0, float("nan"), float("inf")):
        with pytest.raises(GdfeError, match=r"expected one of the groups the model was fitted to \(A, B\)"):
            _batch(("A", "B")).process_factor({"lot": v})
    with pytest.raises(GdfeError, match=r"process lot: 2\.0 names more than one group .*\(02, 2\)"):
        _batch(("02", "2")).process_factor({"lot": 2.0})


def test_a_batch_model_with_numeric_labels_is_used_from_the_command_line(tmp_path, capsys):
    path = _batch(("1", "2")).save(tmp_path / "mb.toml")
    assert main([*HINGE, "--model", str(path), "--process", "lot=2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    ref = _batch(("1", "2")).hinge_angle(1.6, 0.33, process={"lot": "2"})
    assert out["fold_angle_model_rad"] == pytest.approx(ref, rel=1e-12)
    assert main([*HINGE, "--model", str(path), "--process", "lot=3"]) == 1
    assert "process lot: expected one of the groups the model was fitted to (1, 2), got '3.0'" in \
        capsys.readouterr().err


# -- 4. the seed of the draws --------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [[*HINGE, "--uncertainty", "4", "--seed", "-1"],
                                  ["simulate", "HINGE_FILE", "--out", "OUT", "--uncertainty", "3", "--seed", "-5"]])
def test_a_negative_seed_is_an_error_naming_it(tmp_path, capsys, argv):
    model = _predictive().save(tmp_path / "m.toml")
    hinge = _write(tmp_path, "hinge.toml", "[film]\nd = 0.33\n[hinge]\nlength = 1.6\n")
    argv = [{"HINGE_FILE": str(hinge), "OUT": str(tmp_path / "o")}.get(a, a) for a in argv]
    assert main([*argv, "--model", str(model)]) == 1
    err = capsys.readouterr().err
    assert "--seed: expected an integer >= 0, got" in err and "internal error" not in err


def test_fold_ensemble_refuses_a_negative_seed():
    with pytest.raises(GdfeError, match=r"seed: expected an integer >= 0, got -1"):
        fold_ensemble(gdfe.hinge(1.6, d=0.33), _predictive(), 4, nominal=None, measure=None, seed=-1)
    from gdfe.predict import draw_models

    with pytest.raises(GdfeError, match=r"seed: expected an integer >= 0, got -2"):
        draw_models(_predictive(), 4, seed=-2)


# -- 5. the model's warnings on gdfe hinge ------------------------------------------------------------------
def test_hinge_says_the_models_warnings_as_simulate_does(tmp_path, capsys):
    note = "offset fitted too: a measurement issue, left out of this model"
    m = DeformationModel(principle="eq1", mechanisms=("hinge_length",), params={"K": 0.12, "lambda": 2.5},
                         warnings=(note,), source="test")
    assert len(m.warnings) == 2  # the note, and lambda outside its physical range
    path = m.save(tmp_path / "m.toml")
    assert main([*HINGE, "--model", str(path)]) == 0
    hinge_text = capsys.readouterr().out
    sim = _write(tmp_path, "hinge.toml", "[film]\nd = 0.33\n[hinge]\nlength = 1.6\n")
    assert main(["simulate", str(sim), "--model", str(path), "--out", str(tmp_path / "o")]) == 0
    sim_text = capsys.readouterr().out
    for w in m.warnings:
        assert f"WARNING: {w}" in sim_text and f"WARNING: {w}" in hinge_text, w
    assert main([*HINGE, "--model", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["model"]["warnings"] == list(m.warnings)


# -- 6. intervals at a level the draws cannot resolve --------------------------------------------------------
def _ensemble(n, level, n_converged=None):
    n_converged = n if n_converged is None else n_converged
    angles = np.linspace(0.28, 0.30, n_converged).reshape(-1, 1)
    return Ensemble(n=n, level=level, labels=["hinge"], nominal_angles=np.array([0.29]), angles=angles,
                    nominal_measures={}, measures={}, nominal_points=np.zeros((3, 3)),
                    points=np.zeros((n_converged, 3, 3)), spread_mm=np.zeros(3),
                    converged=np.arange(n) < n_converged, iterations=np.ones(n, int), seconds=1.0,
                    draw_seconds=np.ones(n), models=["eq3"] * n, draw_cpu_seconds=np.ones(n))


def test_draws_for_a_level():
    assert [draws_for(x) for x in (0.5, 0.8, 0.9, 0.95, 0.99, 0.9999)] == [4, 10, 20, 40, 200, 20000]


@pytest.mark.parametrize("n, level, converged, need", [(2, 0.9, None, 20), (4, 0.9999, None, 20000),
                                                      (19, 0.9, None, 20), (25, 0.9, 12, 20)])
def test_too_few_draws_for_the_level_are_said(n, level, converged, need):
    ens = _ensemble(n, level, converged)
    (w,) = ens.as_dict()["warnings"]
    assert f"needs at least {need} draws" in w
    assert f"WARNING: {w}" in ens.text()


@pytest.mark.parametrize("n, level", [(20, 0.9), (40, 0.95), (4, 0.5)])
def test_enough_draws_say_nothing(n, level):
    ens = _ensemble(n, level)
    assert ens.as_dict()["warnings"] == [] and "WARNING" not in ens.text()


def test_hinge_uncertainty_with_too_few_draws_warns_in_text_and_json(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("GDFE_JOBS", "1")
    path = _predictive().save(tmp_path / "m.toml")
    assert main([*HINGE, "--model", str(path), "--uncertainty", "2", "--json", str(tmp_path / "o.json")]) == 0
    text = capsys.readouterr().out
    (w,) = json.loads((tmp_path / "o.json").read_text())["uncertainty"]["warnings"]
    assert "2 converged draws cannot resolve 90 % intervals" in w and "at least 20 draws" in w
    assert f"WARNING: {w}" in text


# -- 7. a hand-edited model with members ----------------------------------------------------------------------
def _with_members(tmp_path):
    a, b = _predictive("eq3 a", 0.37), _predictive("eq3 b", 0.30)
    top = dataclasses.replace(a, ensemble=(Member(0.6, a), Member(0.4, b)), weighting="stacking")
    return top.save(tmp_path / "m.toml")


def test_a_model_with_members_loads_as_written(tmp_path):
    m = load_model(_with_members(tmp_path))
    assert m.value("K") == m.ensemble[0].model.value("K") == 0.37


@pytest.mark.parametrize("edit, match", [
    (lambda doc: doc["parameters"]["K"].update(value=0.1),
     r"m\.toml: parameters\.K: expected 0\.37, the value of ensemble\.members\[0\] \('eq3 a'\).*got 0\.1"),
    (lambda doc: doc["ensemble"]["members"][0]["parameters"]["K"].update(value=0.1),
     r"m\.toml: parameters\.K: expected 0\.1, the value of ensemble\.members\[0\].*got 0\.37"),
    (lambda doc: doc.update(principle="eq1-d1"),
     r"m\.toml: principle: expected the same as ensemble\.members\[0\]"),
])
def test_a_top_level_that_differs_from_its_member_is_refused(tmp_path, edit, match):
    path = _with_members(tmp_path)
    doc = tomllib.loads(path.read_text())
    edit(doc)
    path.write_text(tomli_w.dumps(doc))
    with pytest.raises(GdfeError, match=match):
        load_model(path)
