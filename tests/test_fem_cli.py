"""``gdfe fem ...`` through the main command line."""

import json

import pytest

from gdfe.cli import main

HINGE = ["fem", "hinge", "--length", "1.6", "--d", "0.33", "--resolution", "coarse"]


def test_hinge_json_reports_angle_curvature_and_solver_state(capsys):
    assert main(HINGE + ["--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("fold_angle_rad", "kappa_per_mm", "timoshenko_kappa_per_mm", "converged", "seconds",
                "dofs", "iterations", "residual"):
        assert key in out
    assert out["converged"] is True and out["nonlinear"] is False
    assert out["fold_angle_rad"] > 0 and out["dofs"] > 0


def test_hinge_nonlinear_text(capsys):
    assert main(HINGE + ["--nonlinear", "--E-ratio", "7.7", "--eigenstrain", "-0.05"]) == 0
    text = capsys.readouterr().out
    assert "nonlinear (neohookean)" in text and "converged" in text and "fold angle" in text


def test_hinge_that_does_not_converge_exits_non_zero(capsys):
    argv = ["fem", "hinge", "--length", "3", "--d", "0.14", "--E-ratio", "7.7", "--eigenstrain",
            "-0.3", "--resolution", "coarse", "--nonlinear", "--max-iter", "1", "--min-step", "0.3",
            "--json"]
    assert main(argv) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["converged"] is False and out["load_factor"] < 1


@pytest.mark.parametrize("argv,match", [
    (["--length", "0"], "length: expected a positive finite number, got 0\n"),
    (["--length", "1", "--d", "-0.2"], "d: expected a positive finite number, got -0.2\n"),
    (["--length", "1", "--nu", "0.5"], "nu: expected a Poisson's ratio in (-1, 0.5), got 0.5\n"),
    (["--length", "1", "--eigenstrain", "-1.2"],
     "--eigenstrain: expected the film's free contraction R_free - 1 in (-1, 0] (the film shrinks when heated), "
     "got -1.2\n"),
    (["--length", "1", "--E-ratio", "0"], "E_ratio: expected a positive finite number, got 0\n"),
])
def test_bad_hinge_input_is_one_line_and_exit_1(capsys, argv, match):
    base = {"--length": "1.6", "--d": "0.33"}
    args = dict(base)
    it = iter(argv)
    for k in it:
        args[k] = next(it)
    flat = [x for kv in args.items() for x in kv]
    assert main(["fem", "hinge", *flat, "--resolution", "coarse"]) == 1
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1


def test_timoshenko_check_json(capsys):
    assert main(["fem", "timoshenko-check", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["passed"] is True
    hex1 = next(c for c in out["checks"] if c["element"] == "hex1")
    assert len(hex1["rows"]) >= 3 and 1.8 < hex1["rate"] < 2.2 and hex1["finest_error"] < 0.01


def test_calibrate_with_the_closed_form(tmp_path, capsys):
    csv = tmp_path / "tests.csv"
    csv.write_text("L_mm,d_mm,h_mm,alpha_rad\n1.5,0.11,0.29,1.75\n3.27,0.15,0.29,2.27\n"
                   "1.8,0.24,0.29,0.92\n5.08,0.24,0.29,1.84\n3.14,0.31,0.29,1.05\n"
                   "1.22,0.51,0.29,0.52\n")
    assert main(["fem", "calibrate", "--table", str(csv), "--model", "timoshenko", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_tests"] == 6 and out["eigenstrain"] < 0 and out["E_ratio"] > 0
    assert out["loo_rmse_rad"] >= out["rmse_rad"]
