"""Deformation models: principles, mechanisms on any design, model files, and the loop through the CLI."""

import json
from pathlib import Path

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.model import DeformationModel, Parameter, load_model, paper_model

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


def model(principle="eq1", mechanisms=(), **params):
    return DeformationModel(principle=principle, params=params, mechanisms=mechanisms)


# -- principles ------------------------------------------------------------------------------
def test_paper_model_is_eq3_to_the_last_bit():
    d = np.array([0.16, 0.24, 0.33, 0.51])
    np.testing.assert_array_equal(paper_model().ratio(d), gdfe.Calibration().ratio(d))
    # the hinge made through the model is the hinge made with R = Eq. 3
    a = gdfe.hinge(1.6, d=0.33)
    b = gdfe.hinge(1.6, R=float(gdfe.Calibration().ratio(0.33)))
    assert a.model.name == "paper" and b.model is None
    np.testing.assert_array_equal(np.column_stack(a.face_contraction()), np.column_stack(b.face_contraction()))
    assert gdfe.fold_angle(gdfe.simulate(a)) == gdfe.fold_angle(gdfe.simulate(b))


@pytest.mark.parametrize("reading", ["eq1", "eq1-d1", "power"])
def test_calibration_readings_are_the_model_principles(reading):
    fit = gdfe.fit_reading(gdfe.TABLE1, reading, n_boot=0)
    m = DeformationModel.from_calibration(fit)
    d = np.linspace(0.2, 0.5, 7)
    np.testing.assert_allclose(m.ratio(d, 0.29), fit.ratio(d, 0.29), rtol=1e-13)


def test_timoshenko_principle_is_the_diagnosis_passive_stiffness():
    from gdfe.diagnosis import Model

    m = model("timoshenko", E_ratio=3.0, mismatch=0.12)
    d = np.array([0.15, 0.33, 0.6])
    np.testing.assert_allclose(m.contraction(d, 0.29),
                               Model(("passive_stiffness",)).contraction([3.0, 0.12], d, 0.29), rtol=1e-14)


def test_thin_coat_is_an_error_naming_d_and_the_limit():
    with pytest.raises(gdfe.GdfeError, match=r"d=0.11 mm gives R=-0.58.* needs d > 0.1496 mm"):
        paper_model().ratio(0.11)
    # the same limit, found numerically for any principle, as Eq. 3's closed form says
    assert paper_model().d_min() == pytest.approx(0.29 * 0.3706 ** (2 / 3), rel=1e-9)
    # at a ratio R the design accepts: 1 - K (h/d)^1.5 = R, so d = h (K / (1 - R))^(2/3)
    assert paper_model().d_min(ratio=0.01) == pytest.approx(0.29 * (0.3706 / 0.99) ** (2 / 3), rel=1e-9)


def test_cure_depth_and_thickening_per_cell():
    # closed forms: c = K (h / (d + delta))^1.5, then c / (1 + beta c)
    m = model(mechanisms=("cure_depth", "film_thickening"), K=0.3, delta=0.05, beta=1.5)
    c = 0.3 * (0.29 / 0.38) ** 1.5
    assert m.contraction(0.33, 0.29) == pytest.approx(c / (1 + 1.5 * c), rel=1e-14)


# -- mechanisms on designs -----------------------------------------------------------------------
def hinge_fold(m, L=1.6, cells=16, panel=1.5):
    des = gdfe.hinge(L, d=0.33, model=m, panel_length=panel, cell_size=L / cells)
    return gdfe.fold_angle(gdfe.simulate(des).check())


def test_hinge_length_folds_like_a_wider_hinge_and_converges_in_lambda():
    """A hinge of width L with hinge_length lambda folds like L + lambda (the closed form), for a
    lambda that is no multiple of any cell size used; the error falls under refinement."""
    lam = 0.37  # 1.85, 3.7 and 7.4 cells of the three meshes below
    m = model(mechanisms=("hinge_length",), K=0.0608, **{"lambda": lam})
    ref = float(m.hinge_angle(1.6, 0.33))
    errs = [abs(hinge_fold(m, cells=n) - ref) for n in (8, 16, 32)]
    # the isotropic hinge itself converges to Eq. 2 at order 1.3-1.8 (studies/hinge_refinement.py);
    # lambda adds no error of its own
    assert errs[2] < errs[1] < errs[0], errs
    assert errs[2] < 3e-3 * ref
    # continuous in lambda: a small change of lambda changes the fold in proportion
    m2 = model(mechanisms=("hinge_length",), K=0.0608, **{"lambda": lam + 0.01})
    step = hinge_fold(m2, cells=16) - hinge_fold(m, cells=16)
    c = float(m.contraction(0.33, 0.29))
    assert step == pytest.approx(c * 0.01 / 0.29, rel=0.05)


def test_negative_hinge_length_takes_contraction_from_the_free_side():
    m = model(mechanisms=("hinge_length",), K=0.0608, **{"lambda": -0.3})
    assert hinge_fold(m, cells=32) == pytest.approx(float(m.hinge_angle(1.6, 0.33)), rel=3e-3)


def test_hinge_length_acts_on_every_coat_edge_of_any_design():
    # a layout with two hinge stripes: each gains contraction lambda/2 into the rigid cells on
    # both of its sides, whatever the stripe's position
    rows = ["RRRRTTTTRRRRRRRRBBBBRRRR"] * 4
    m = model(mechanisms=("hinge_length",), K=0.0608, **{"lambda": 0.25})
    des = gdfe.from_rows(rows, d=0.33, model=m, pixel=0.125, nz=1)
    top, bottom = des.face_contraction()
    c = float(m.contraction(0.33, 0.29))
    i = des.mesh.cell_ij[:, 0]
    # 0.125 mm cells: the first rigid cell beside each edge is covered fully (lambda/2 = 0.125 mm)
    for col, face in ((3, top), (8, top), (15, bottom), (20, bottom)):
        np.testing.assert_allclose(face[i == col], c, rtol=1e-12)
    for col in (2, 9, 14, 21):
        assert np.all(top[i == col] == 0) and np.all(bottom[i == col] == 0)
    # total contraction: each stripe's four columns plus one column on either side
    assert top.sum() == pytest.approx(6 * 4 * c) and bottom.sum() == pytest.approx(6 * 4 * c)


def test_saturation_caps_the_fold_as_the_closed_form():
    m = model(mechanisms=("saturation",), K=0.3706, alpha_max=1.5)
    for L in (1.0, 2.6):
        des = gdfe.hinge(L, d=0.33, model=m)
        # GDFE's own discretisation error on this hinge is ~0.005 rad (Figure 6)
        assert gdfe.fold_angle(gdfe.simulate(des)) == pytest.approx(float(m.hinge_angle(L, 0.33)), abs=0.006)
    # beyond alpha_max the fold grows no more
    assert m.hinge_angle(50.0, 0.33) <= 1.5


def test_the_diagnosis_model_carried_to_a_design_gives_its_closed_form():
    from gdfe.diagnosis import diagnose

    diag = diagnose(gdfe.TABLE1, check=None)
    pair = next(f for f in diag.fits if f.name == "cure_depth+hinge_length")
    m = DeformationModel.from_effect_fit(pair, data=gdfe.TABLE1, n_tests=18)
    t = gdfe.load_folding_tests(gdfe.TABLE1)
    np.testing.assert_allclose(m.hinge_angle(t.L, t.d, t.h), pair.predicted, rtol=1e-12)
    assert m.data["n_tests"] == 18 and len(m.data["sha256"]) == 64
    # Table 1's cure_depth+hinge_length has lambda ~ 2.9 mm: outside the physical range, said out loud
    assert any("lambda" in w and "physical range" in w for w in m.warnings)
    # a reading offset is how the folds were read, not how the part folds: left out, and said
    off = next(f for f in diag.fits if f.name == "saturation+reading_offset")
    m = DeformationModel.from_effect_fit(off, data=gdfe.TABLE1, n_tests=18)
    offset = off.param_dict()["offset"]
    np.testing.assert_allclose(m.hinge_angle(t.L, t.d, t.h), off.predicted - offset, rtol=1e-12)
    assert m.mechanisms == ("saturation",) and any("measurement issue" in w for w in m.warnings)


def test_model_needs_the_passive_thickness():
    des = gdfe.hinge(1.0, R=0.8)
    with pytest.raises(gdfe.GdfeError, match="passive thickness d"):
        paper_model().apply(des)
    with pytest.raises(gdfe.GdfeError, match="R, model: expected a contraction ratio R or a deformation model"):
        gdfe.hinge(1.0, R=0.8, model=paper_model())


def test_simulate_with_a_model_replaces_the_contraction():
    des = gdfe.hinge(1.6, d=0.33)
    m = model(K=0.1)
    a = gdfe.fold_angle(gdfe.simulate(des, model=m))
    assert a == pytest.approx(float(m.hinge_angle(1.6, 0.33)), abs=0.005)


# -- model files ------------------------------------------------------------------------------
def test_model_file_round_trip(tmp_path):
    m = DeformationModel(principle="eq1", params={"K": Parameter(0.12, se=0.01, ci95=(0.1, 0.14)),
                                                  "delta": 0.02, "lambda": Parameter(0.3, at_bound=True)},
                         mechanisms=("hinge_length", "cure_depth"), source="test",
                         data={"file": "t.csv", "n_tests": 5})
    path = m.save(tmp_path / "m.toml")
    text = path.read_text()
    assert text.startswith("# gdfe deformation model") and "[parameters.K]" in text
    back = load_model(path)
    assert back.mechanisms == ("cure_depth", "hinge_length")  # the order they act in
    assert {k: p.value for k, p in back.params.items()} == {"K": 0.12, "delta": 0.02, "lambda": 0.3}
    assert back.params["K"].ci95 == (0.1, 0.14) and back.params["lambda"].at_bound
    assert any("lambda" in w and "bound" in w for w in back.warnings)


@pytest.mark.parametrize("body, match", [
    ('principle = "eq1"\n[parameters]\nK = 0.3\nlamda = 1\n',
     r"m.toml: \[parameters\]: unknown key 'lamda'; expected some of K"),
    ('principle = "eq1"\nmechanisms = ["cure_depth"]\n[parameters]\nK = 0.3\ndelt = 0.01\n',
     r"m.toml: \[parameters\]: unknown key 'delt' \(did you mean 'delta'\?\)"),
    ('principle = "eq1"\nmechansims = []\n[parameters]\nK = 0.3\n',
     r"m.toml: unknown key 'mechansims' \(did you mean 'mechanisms'\?\)"),
    ('principle = "eq2"\n[parameters]\nK = 0.3\n', r"m.toml: principle: expected one of eq1, .*got 'eq2'"),
    ('principle = "eq1"\n[parameters]\nK = "0.3"\n', r"m.toml: parameters.K: expected a number or a table"),
    ('principle = "eq1"\n[parameters]\nK = -0.3\n', r"m.toml: K: expected a positive number, got -0.3"),
    ('principle = "eq1"\n[parameters.K]\nvalue = true\n', r"m.toml: parameters.K.value: expected a number"),
    ('principle = "eq1"\n[parameters.K]\nvalu = 0.3\n', r"parameters.K: unknown key 'valu' \(did you mean 'value'\?\)"),
    ('principle = "eq1"\nmechanisms = ["warp"]\n[parameters]\nK = 0.3\n', r"m.toml: mechanisms: expected names"),
    ('principle = "eq1"\nmechanisms = ["saturation"]\n[parameters]\nK = 0.3\n',
     r"m.toml: params: expected K, alpha_max .* missing alpha_max"),
    ('[parameters]\nK = 0.3\n', r"m.toml: missing key 'principle'"),
    ('principle = "eq1"\nparameters = 3\n', r"m.toml: parameters: expected a table"),
    ('principle = "eq1"\n[parameters]\nK = 0.3\n[data]\nn_tests = 2.5\n', r"m.toml: data.n_tests: expected an integer"),
    ('principle = eq1\n', r"m.toml: not valid TOML"),
])
def test_malformed_model_files_name_the_key(tmp_path, body, match):
    path = tmp_path / "m.toml"
    path.write_text(body)
    with pytest.raises(gdfe.GdfeError, match=match):
        load_model(path)


def test_missing_and_binary_model_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="model file not found"):
        load_model(tmp_path / "none.toml")
    (tmp_path / "b.toml").write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff")
    with pytest.raises(gdfe.GdfeError, match="b.toml: not a text file"):
        load_model(tmp_path / "b.toml")


# -- the loop through the command line -----------------------------------------------------------
def test_calibrate_writes_a_model_that_hinge_reads(tmp_path, capsys):
    path = tmp_path / "k.toml"
    assert main(["calibrate", str(gdfe.TABLE1), "--model", "eq1-d1", "--boot", "100", "--model-out", str(path)]) == 0
    m = load_model(path)
    assert m.principle == "eq1-d1" and m.data["held_out_rmse_rad"] == pytest.approx(0.3381, abs=1e-4)
    capsys.readouterr()
    assert main(["hinge", "-L", "2.6", "--d", "0.33", "--model", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    # K = 0.3708 /mm: c = K h sqrt(h/d) = 0.1008, (1 - R) L / h = 0.904 rad
    assert out["alpha_model_rad"] == pytest.approx(0.3708285 * 2.6 * np.sqrt(0.29 / 0.33), rel=1e-6)
    assert out["alpha_rad"] == pytest.approx(out["alpha_model_rad"], abs=0.005)


def test_a_model_changes_the_tube_as_it_says(tmp_path, capsys):
    """docs/examples/tube.toml with a model file: twelve hinges of two 0.25 mm cells turn by
    12 c(d) L / h, with c from the model, not Eq. 3."""
    m = model(K=0.2)
    path = m.save(tmp_path / "m.toml")
    assert main(["simulate", str(EXAMPLES / "tube.toml"), "--model", str(path), "--out", str(tmp_path / "o"),
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"]["principle"] == "eq1" and out["model"]["parameters"]["K"]["value"] == 0.2
    design, options = gdfe.load_design(EXAMPLES / "tube.toml", model=path)
    res = gdfe.simulate(design, **options)
    c = float(m.contraction(0.33, 0.29))
    assert gdfe.curvature_profile(res)["turn"] == pytest.approx(12 * c * 0.5 / 0.29, rel=0.05)


def test_design_file_reads_its_model_and_refuses_mixtures(tmp_path):
    m = model(K=0.2)
    m.save(tmp_path / "m.toml")
    (tmp_path / "d.toml").write_text('[film]\nd = 0.33\nmodel = "m.toml"\n[hinge]\nlength = 1.6\n')
    des, _ = gdfe.load_design(tmp_path / "d.toml")
    assert des.model.value("K") == 0.2
    (tmp_path / "r.toml").write_text('[film]\nR = 0.7\nmodel = "m.toml"\n[hinge]\nlength = 1.6\n')
    with pytest.raises(gdfe.GdfeError, match="r.toml: \\[film\\] gives R and a deformation model"):
        gdfe.load_design(tmp_path / "r.toml")
    (tmp_path / "x.toml").write_text('[film]\nd = 0.33\nmodel = "nope.toml"\n[hinge]\nlength = 1.6\n')
    with pytest.raises(gdfe.GdfeError, match=r"x.toml: \[film\] model: model file not found: .*nope.toml"):
        gdfe.load_design(tmp_path / "x.toml")


# -- inverse design with a model ------------------------------------------------------------------
def test_a_model_without_geometric_mechanisms_plans_by_the_paper_rule_at_its_ratio():
    from gdfe import inverse as inv

    m = model(mechanisms=("cure_depth",), K=0.3, delta=0.02)
    a = inv.strip_pattern([(6.0, 3.0), (2.0, 0.0)], model=m, d=0.33)
    b = inv.strip_pattern([(6.0, 3.0), (2.0, 0.0)], R=float(m.ratio(0.33)))
    np.testing.assert_array_equal(a.material, b.material)
    assert a.R == b.R and a.model is m and b.model is None


def test_planning_with_a_spreading_model_matches_the_turn_it_simulates():
    """With hinge_length every block folds wider than printed: the planner takes fewer blocks, and
    the strip the model folds turns as the planner said."""
    from gdfe import inverse as inv

    m = model(mechanisms=("hinge_length",), K=0.3706, **{"lambda": 0.3})
    couples = [(8.0, 4.0)]  # 2 rad
    plain = inv.strip_pattern(couples, R=float(m.ratio(0.33)), cell=0.125)
    pat = inv.strip_pattern(couples, model=m, d=0.33, cell=0.125)
    assert pat.blocks[0] < plain.blocks[0]
    # the planned turn is within the model's block quantum c (w + lambda) / h of the target
    c = float(m.contraction(0.33, 0.29))
    assert abs(pat.angle_printed[0] - 2.0) <= 0.5 * c * (0.125 + 0.3) / 0.29 + 1e-9
    res = gdfe.inverse.simulate_strip(pat.design(width=0.25, ny=2))
    assert gdfe.curvature_profile(res)["turn"] == pytest.approx(pat.angle_printed[0], rel=0.03)


def test_a_couple_the_model_cannot_fold_is_an_error_naming_it():
    from gdfe import inverse as inv

    m = model(mechanisms=("hinge_length",), K=0.1, **{"lambda": 0.5})
    with pytest.raises(gdfe.GdfeError, match=r"couples\[0\]: radius 1 mm turns by 3.*at d = 0.33 mm"):
        inv.strip_pattern([(3.0, 1.0)], model=m, d=0.33)
    pat = inv.strip_pattern([(3.0, 1.0)], model=m, d=0.33, clamp=True)
    assert pat.clamped[0]


# -- the diagnosis's model, process mechanisms ------------------------------------------------------
def test_diagnose_writes_the_chosen_model_and_another_on_request(tmp_path, capsys):
    best, sat = tmp_path / "best.toml", tmp_path / "sat.toml"
    # Table 1's chosen model is saturation+reading_offset (implausible offset); the pair is asked for
    assert main(["diagnose", str(gdfe.TABLE1), "--check", "none", "--model-out", str(best),
                 "--effect", "cure_depth+hinge_length"]) == 0
    assert main(["diagnose", str(gdfe.TABLE1), "--check", "none", "--model-out", str(sat),
                 "--effect", "saturation"]) == 0
    out = capsys.readouterr().out
    assert "WARNING: lambda" in out  # the chosen pair's doubtful parameters are said out loud
    m, s = load_model(best), load_model(sat)
    assert m.name == "cure_depth+hinge_length" and m.params["lambda"].se is not None
    assert s.mechanisms == ("saturation",) and s.data["n_tests"] == 18
    # the tube of docs/examples with the saturation model: twelve hinges of two 0.25 mm cells
    design, options = gdfe.load_design(EXAMPLES / "tube.toml", model=sat)
    turn = gdfe.curvature_profile(gdfe.simulate(design, **options))["turn"]
    assert turn == pytest.approx(12 * float(s.hinge_angle(0.5, 0.33)), rel=0.06)
    capsys.readouterr()
    assert main(["diagnose", str(gdfe.TABLE1), "--check", "none", "--model-out", str(sat), "--effect", "warp"]) == 1
    assert "--effect: expected one of the fitted models" in capsys.readouterr().err


def test_partial_activation_and_batch_act_through_the_process_variables(tmp_path):
    m = DeformationModel("eq1", {"K": 0.37, "x50": 120.0, "rate": 0.1, "scale[B]": 0.8},
                         mechanisms=("partial_activation", "batch"),
                         columns={"partial_activation": "T_C", "batch": "lot"}, labels=("B", "A"))
    assert m.labels == ("A", "B")  # sorted: A is the reference
    c_full = 0.37 * (0.29 / 0.33) ** 1.5
    f = 1 / (1 + np.exp(-0.1 * (130 - 120)))
    assert m.contraction(0.33, 0.29, {"T_C": 130, "lot": "B"}) == pytest.approx(c_full * f * 0.8, rel=1e-12)
    assert m.contraction(0.33, 0.29, {"T_C": 130, "lot": "A"}) == pytest.approx(c_full * f, rel=1e-12)
    with pytest.raises(gdfe.GdfeError, match="process: model .* needs T_C"):
        m.contraction(0.33, 0.29, {"lot": "A"})
    with pytest.raises(gdfe.GdfeError, match="process lot: expected one of the groups .*A, B.*got 'C'"):
        m.contraction(0.33, 0.29, {"T_C": 130, "lot": "C"})
    back = load_model(m.save(tmp_path / "p.toml"))
    assert back.columns == m.columns and back.labels == m.labels
    # a design file's [process] table, and the GDFE hinge against the closed form
    (tmp_path / "d.toml").write_text('[film]\nd = 0.33\nmodel = "p.toml"\n[hinge]\nlength = 2.0\n'
                                     '[process]\nT_C = 130\nlot = "B"\n')
    des, _ = gdfe.load_design(tmp_path / "d.toml")
    alpha = gdfe.fold_angle(gdfe.simulate(des))
    assert alpha == pytest.approx(float(m.hinge_angle(2.0, 0.33, 0.29, {"T_C": 130, "lot": "B"})), abs=0.005)
