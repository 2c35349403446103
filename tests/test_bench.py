"""``gdfe bench`` runs and reports every goal; the large-design solver paths agree with Newton."""

import json

import numpy as np
import pytest

import gdfe
from studies.bench import H, format_table, mask_sheet, write_mask_pngs
from gdfe.cli import main
from gdfe.solver import AUTO_NEWTON_CELLS, Solver, auto_method, factor_backend, factorise
from gdfe.solver.linearised import linearised_start_cg


def test_quick_bench_reports_every_section_and_verdict(capsys, tmp_path):
    assert main(["bench", "--quick", "--json", "--out", str(tmp_path)]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["machine"]["cores"] >= 1
    assert res["machine"]["factor_backend"] in ("cholmod", "cvxopt", "superlu")
    methods = {r["method"] for r in res["hinges"]}
    assert methods == {"newton", "newton-cg", "anderson", "plain"}
    assert all(r["converged"] for r in res["hinges"] if r["method"].startswith("newton"))
    assert [r["design"] for r in res["sheets"]] == ["corrugation"] * 3 + ["fig08-dome"]
    for row in res["sheets"]:
        assert row["converged"]
        assert row["peak_rss_mib"] >= row["rss_before_mib"] > 0
        assert set(row["split_s"]) >= {"orientation", "assembly"}
        lb = row["lower_bound"]
        assert lb["bound_s"] == pytest.approx(lb["solve_3rhs_s"] + lb["svd_s"])
        assert lb["bound_polar_s"] == pytest.approx(lb["solve_3rhs_s"] + lb["polar_s"])
        assert lb["bound_iterations"] == pytest.approx(row["seconds"] / lb["bound_s"])
        assert row["tol"] > 0 and row["error_estimate_mm"] is not None
        assert lb["local_global_ratio"] > 0
        assert "superlu" in row["factorisation"]["n"]
        assert row["coarse_solver"] == "factor"
        # the median run's Newton steps, one per iteration but the last, which finds the test met
        assert len(row["newton_steps"]) == row["iterations"] - 1
        assert row["newton_steps"][-1]["estimate_h"] * H == pytest.approx(row["error_estimate_mm"])
        assert row["start_levels"] == []  # below MULTILEVEL_CELLS: the linearised start
    assert "skipped" in res["fem_comparison"]
    v = res["verdicts"]
    assert set(v) == {"hinges", "fem", "sheet", "sheet_1e6", "lower_bound", "growth", "newton", "gpu"}
    assert v["newton"]["met"] is None  # no 10^5-cell twist in --quick
    assert v["gpu"]["note"].startswith("not measured") and v["gpu"]["met"] is None
    assert isinstance(v["hinges"]["met"], bool)
    assert isinstance(v["lower_bound"]["met"], bool)
    assert isinstance(v["growth"]["value"], float)
    assert v["fem"]["met"] is None and v["sheet"]["met"] is None and v["sheet_1e6"]["met"] is None  # not in --quick
    assert (tmp_path / "bench.json").is_file() and (tmp_path / "bench_scaling.png").is_file()
    assert (tmp_path / "bench.txt").read_text().startswith("gdfe bench (quick)")
    assert len(list((tmp_path / "masks").glob("*.png"))) == 6
    text = format_table(res)
    assert f"{res['machine']['cores']} cores" in text and "Goals" in text and "lower bound" in text
    assert text.count("fine steps (length h / CG iterations") == len(res["sheets"])


def test_bench_runs_the_sheets_with_the_coarse_solver_asked_for(capsys):
    """``--coarse-solver amg`` reaches the sheets' own processes: recorded per sheet and in the table."""
    pytest.importorskip("pyamg")
    assert main(["bench", "--quick", "--no-hinges", "--freeform-sizes", "none", "--sizes", "256",
                 "--coarse-solver", "amg", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert [(r["coarse_solver"], r["method"], r["converged"]) for r in res["sheets"]] == [("amg", "newton-cg", True)]
    assert "Newton-CG's coarse matrix: amg" in format_table(res)
    with pytest.raises(SystemExit):
        main(["bench", "--quick", "--coarse-solver", "lu"])
    assert "invalid choice: 'lu'" in capsys.readouterr().err


def test_bench_rejects_bad_sizes(capsys):
    assert main(["bench", "--quick", "--sizes", "1"]) == 1
    assert "sizes" in capsys.readouterr().err


def test_mask_sheet_png_round_trip(tmp_path):
    top, bottom = mask_sheet(900)
    assert top.shape == (30, 30)
    assert (~top).any() and (~bottom).any() and (top & bottom).any()  # both hinge kinds and panels
    ptop, pbot = write_mask_pngs(tmp_path, top, bottom)
    a = gdfe.from_masks(ptop, pbot, 0.1, 0.7, nz=1)
    b = gdfe.from_masks(top, bottom, 0.1, 0.7, nz=1)
    np.testing.assert_array_equal(a.material, b.material)


def test_auto_method_switches_to_newton_cg_above_a_few_cells():
    top, bottom = mask_sheet(AUTO_NEWTON_CELLS + 100)
    assert auto_method(gdfe.from_masks(top, bottom, 0.1, 0.7, nz=1)) == "newton-cg"
    assert auto_method(gdfe.hinge(1.0, d=0.33)) == "newton-cg"
    assert auto_method(gdfe.hinge(1.0, d=0.33, cell_size=0.25, width=0.5, panel_length=0.25)) == "newton"


@pytest.mark.parametrize("L", [1.0, 2.6])
def test_newton_cg_reaches_newtons_answer(L):
    des = gdfe.hinge(L, d=0.33)
    a = gdfe.simulate(des, method="newton", tol=1e-10).check()
    b = gdfe.simulate(des, method="newton-cg", tol=1e-10).check()
    assert b.method == "newton-cg"
    # the shape is unique up to a rotation about the pinned vertex
    assert gdfe.shape_distance(a.points, b.points)["max"] < 1e-8
    assert gdfe.fold_angle(b) == pytest.approx(gdfe.fold_angle(a), abs=1e-8)
    assert b.energy == pytest.approx(a.energy, rel=1e-9)


def test_newton_cg_on_a_single_cell():
    des = gdfe.grid_design(np.array([[int(gdfe.Material.CONTRACT_TOP)]]), 0.6, pixel=0.3, nz=1)
    res = gdfe.simulate(des, method="newton-cg").check()
    assert res.energy < 1e-20


def test_iterative_linearised_start_leads_to_the_same_fixed_point():
    des = gdfe.from_masks(*mask_sheet(400), 0.1, 0.7, nz=1)
    s = Solver(des)
    V0 = linearised_start_cg(s, s.reduced_hessian, des.mesh.points.copy())
    stats = s.solve(V0, method="newton-cg", tol=1e-10)
    ref = gdfe.simulate(des, method="newton", tol=1e-10).check()
    assert stats.converged
    assert gdfe.shape_distance(stats.points, ref.points)["max"] < 1e-8


def test_factorisation_backends_agree(monkeypatch):
    des = gdfe.hinge(1.0, d=0.33)
    A = Solver(des).L_ff
    b = np.random.default_rng(1).standard_normal((A.shape[0], 3))
    x = factorise(A, backend="superlu").solve(b)
    np.testing.assert_allclose(A @ x, b, atol=1e-9)
    pytest.importorskip("sksparse.cholmod")
    y = factorise(A, backend="cholmod").solve(b)
    np.testing.assert_allclose(y, x, rtol=1e-9, atol=1e-12)
    monkeypatch.setenv("GDFE_FACTOR", "superlu")
    assert factor_backend() == "superlu"


def test_the_bench_asks_for_no_factorisation_above_its_limits():
    """Above ``FACTOR_MAX_CELLS`` the bound's solve is the multigrid's: no backend is asked for a factor;
    above ``SUPERLU_MAX_CELLS`` SuperLU alone is not; below both, every backend is (the sheet's own cell count
    decides, as ``_sheet_case`` passes it)."""
    from studies.bench import FACTOR_MAX_CELLS, SUPERLU_MAX_CELLS, _factor_candidates, _time_factorisations

    A = Solver(gdfe.hinge(1.0, d=0.33)).L_ff
    out = _time_factorisations(A, 3, 1, cells=FACTOR_MAX_CELLS + 1)
    assert set(out) == set(_factor_candidates())
    assert all(v == {"skipped": f"above {FACTOR_MAX_CELLS} cells no factor fits in memory beside the solver"}
               for v in out.values())
    out = _time_factorisations(A, 3, 1, cells=SUPERLU_MAX_CELLS + 1)
    assert out["superlu"] == {"skipped": f"above {SUPERLU_MAX_CELLS} cells SuperLU's factor does not fit in memory"}
    assert all("solve_s" in v for name, v in out.items() if name != "superlu")
    for cells in (None, SUPERLU_MAX_CELLS):
        assert all("solve_s" in v for v in _time_factorisations(A, 3, 1, cells=cells).values())


def test_unknown_factor_backend_is_rejected(monkeypatch):
    monkeypatch.setenv("GDFE_FACTOR", "mumps")
    with pytest.raises(ValueError, match="GDFE_FACTOR: expected one of 'cholmod', 'cvxopt', 'superlu', got 'mumps'"):
        factor_backend()
    with pytest.raises(ValueError, match="backend: expected one of 'cholmod', 'cvxopt', 'superlu', got 'mumps'"):
        factorise(gdfe.system_matrix(gdfe.hinge(1.0, d=0.33)), backend="mumps")


def test_time_at_equal_error_interpolates_log_log():
    from studies.bench import _time_at_error

    levels = [(1e-1, 1.0), (1e-3, 100.0)]
    assert _time_at_error(levels, 1e-2) == pytest.approx(10.0)
    assert _time_at_error(levels, 1e-3) == pytest.approx(100.0)


def test_richardson_limit_and_order_of_a_power_series():
    from studies.bench import _richardson

    a = [1.7 - 0.3 * h ** 1.6 for h in (0.4, 0.2, 0.1)]
    limit, order = _richardson(a)
    assert limit == pytest.approx(1.7, abs=1e-12) and order == pytest.approx(1.6, abs=1e-12)
    assert _richardson([1.0, 1.2, 1.1])[1] is None  # not monotone: no order


def test_time_at_error_interpolates_and_flags_extrapolation():
    from studies.bench import _time_at

    levels = [(1e-1, 1.0), (1e-2, 10.0), (1e-3, 100.0)]
    assert _time_at(levels, 3e-2) == (pytest.approx(10 ** (1 - np.log10(3))), False)
    t, extrapolated = _time_at(levels, 1e-4)  # finer than the finest level: along the log-log line
    assert extrapolated and t == pytest.approx(1000.0)
    assert _time_at(levels, 0.5) == (1.0, False)


def test_freeform_sheet_is_the_figure8_plate_at_the_asked_cell_count():
    from studies.bench import freeform_sheet
    from studies.fig08_freeform import SIZE

    top, bottom, film, pixel, R = freeform_sheet(10_000, "dome")
    assert top.shape == (100, 100) and pixel == pytest.approx(SIZE / 100)
    assert not film.all() and film.sum() == pytest.approx(np.pi / 4 * 100 ** 2, rel=0.02)
    assert R == pytest.approx(0.6947, abs=1e-4)


def test_fem_ratio_where_the_fem_does_not_get_there_is_a_lower_bound_from_its_finest_level():
    """FEM levels at 2e-2 .. 5e-3 relative error, GDFE down to 1e-4: at 1e-2 the ratio is interpolated;
    at 3e-3 and 1e-3 the FEM's finest level (500 s) bounds the FEM's time from below."""
    from studies.bench import _at_errors, _measured_ratio

    fem = [{"relative_error": e, "seconds": t, "elements": n} for e, t, n in
           ((2e-2, 1.0, 60), (1e-2, 20.0, 400), (5e-3, 500.0, 2500))]
    gdfe_rows = [{"relative_error": e, "seconds": t, "reference_only": False} for e, t in
                 ((1e-2, 0.01), (3e-3, 0.03), (1e-3, 0.1), (1e-4, 3.0))]
    at = [a for a in _at_errors(fem, gdfe_rows, gdfe_rows, 0.49) if a["comparison"] == "same_fold"]
    by = {a["relative_error"]: a for a in at}
    assert by[1e-2]["ratio"] == pytest.approx(2000.0) and by[1e-2]["ratio_at_least"] is None
    assert by[3e-3]["fem_extrapolated"] and by[3e-3]["ratio_at_least"] == pytest.approx(500.0 / 0.03)
    assert by[1e-3]["ratio_at_least"] == pytest.approx(5000.0)
    assert [_measured_ratio(a) for a in at] == [pytest.approx(2000.0), pytest.approx(500 / 0.03), pytest.approx(5000.0)]


def test_the_fem_lines_name_the_fems_linear_solver():
    """A FEM timing is quoted with what factorised its tangents, and SuperLU's with the faster option."""
    from studies.bench import _fem_lines

    def rows(solver):
        return {"fem_nonlinear": [{"level": "size 0.5 mm", "elements": 62, "seconds": 0.4, "alpha_rad": 0.48,
                                   "relative_error": 2e-2, "linear_solver": solver}]}

    slow, fast = "\n".join(_fem_lines(rows("superlu"))), "\n".join(_fem_lines(rows("pardiso")))
    assert "the FEM's linear solves: superlu (MKL PARDISO" in slow and "fem-fast" in slow
    assert "the FEM's linear solves: pardiso" in fast and "fem-fast" not in fast
    old = {"fem_nonlinear": [{k: v for k, v in rows("superlu")["fem_nonlinear"][0].items() if k != "linear_solver"}]}
    assert "linear solves" not in "\n".join(_fem_lines(old))  # a bench.json from before the field


def test_the_newton_verdict_reads_the_twist_iterations_and_its_last_contraction():
    from studies.bench import _newton_verdict

    def row(design, iterations, lengths, converged=True):
        steps = [{"iteration": k + 1, "residual_h": 1.0, "kind": "newton", "length_h": x, "alpha": 1.0,
                  "damping": 1e-6, "tries": 1, "cg_iterations": 3, "model_agreement": 1.0, "energy": 1.0,
                  "estimate_h": x, "seconds": 0.1} for k, x in enumerate(lengths)]
        return {"design": design, "cells": 99_856, "iterations": iterations, "converged": converged,
                "newton_steps": steps}

    fast = [1e-2, 1e-3, 1e-5]
    assert _newton_verdict([row("fig08-twist", 8, fast), row("corrugation", 6, [1e-2, 5e-3])])["met"] is True
    assert _newton_verdict([row("fig08-twist", 9, fast)])["met"] is False  # too many iterations
    assert _newton_verdict([row("fig08-twist", 8, [1e-2, 5e-3, 2.5e-3])])["met"] is False  # linear at the end
    assert _newton_verdict([row("fig08-twist", 8, fast, converged=False)])["met"] is False
    v = _newton_verdict([row("corrugation", 6, [1e-2, 5e-3])])
    assert v["met"] is None and v["last_contractions"] == {"corrugation 99856": [0.5]}


def test_the_gpu_verdict_times_the_sheets_that_ran_on_the_gpu():
    """The 10^6 corrugation on the GPU meets the goal only within the time and where its shape agrees with the
    CPU's: no further apart than the two solves' estimated distances from the solution summed."""
    from studies.bench import GPU_SECONDS, _gpu_verdict

    cpu_rows = [{"design": "corrugation", "cells": 1_000_000, "device": "cpu", "seconds": 300.0, "converged": True,
                 "energy": 0.66}]
    assert _gpu_verdict(cpu_rows, gpu_here=False)["note"].startswith("not measured: no GPU here")
    assert _gpu_verdict(cpu_rows, gpu_here=True)["note"] == "not measured: a GPU is here but no sheet ran on it"

    def answer(agrees):
        return {"energy": 0.0655, "iterations": 6, "seconds": 12.0, "energy_relative_difference": 1e-15,
                "max_distance_mm": 1e-9 if agrees else 1e-3, "allowed_mm": 2e-7, "agrees": agrees}
    small = {"design": "corrugation", "cells": 99_856, "device": "gpu", "seconds": 3.0, "converged": True,
             "energy": 0.0655, "cpu_answer": answer(True)}
    v = _gpu_verdict([small], gpu_here=True)
    assert v["met"] is None and v["agreement"] == {"corrugation 99856": answer(True)}
    for seconds, agrees, met in ((0.5 * GPU_SECONDS, True, True), (2 * GPU_SECONDS, True, False),
                                 (0.5 * GPU_SECONDS, False, False)):
        big = {"design": "corrugation", "cells": 1_000_000, "device": "gpu", "seconds": seconds, "converged": True,
               "energy": 0.66, "cpu_answer": answer(agrees)}
        v = _gpu_verdict([small, big], gpu_here=True)
        assert v["value"] == seconds and v["met"] is met
    del big["cpu_answer"]  # not compared with the CPU: not met, whatever the time
    assert _gpu_verdict([big], gpu_here=True)["met"] is False


def test_the_exponents_span_over_the_runs_is_that_of_every_choice_of_runs():
    """The fit's least and greatest exponent over each size's runs, against every choice of one run per size."""
    import itertools

    from studies.bench import _exponent_span, _fit_exponent

    rng = np.random.default_rng(3)
    cells = [1_024, 10_000, 99_856, 1_000_000]
    runs = [list(2e-4 * c ** 1.1 * rng.uniform(0.85, 1.2, size=k)) for c, k in zip(cells, (3, 3, 2, 1))]
    every = [_fit_exponent(cells, pick) for pick in itertools.product(*runs)]
    assert _exponent_span(cells, runs) == pytest.approx([min(every), max(every)], abs=1e-12)
    one = [[r[0]] for r in runs]
    lo, hi = _exponent_span(cells, one)
    assert lo == pytest.approx(hi) == pytest.approx(_fit_exponent(cells, [r[0] for r in runs]))


def _corrugation(cells, runs):
    return {"design": "corrugation", "cells": cells, "converged": True, "seconds": float(np.median(runs)),
            "seconds_all": runs}


def test_the_growth_verdict_is_judged_over_the_span_of_sizes_and_marginal_within_the_runs_spread():
    from studies.bench import GROWTH_EXPONENT, _growth_verdict, _verdict_note, _verdict_word

    def sheets(expo, spread):
        return [_corrugation(c, [t * (1 - spread), t, t * (1 + spread)])
                for c in (1_024, 10_000, 99_856) for t in [1e-4 * c ** expo]] + [_corrugation(10 ** 6, [1e-4 * 1e6 ** expo])]

    v = _growth_verdict(sheets(1.05, 0.01), None)
    assert v["met"] is True and not v["marginal"] and _verdict_word(v) == "MET"
    assert v["span"][0] <= v["value"] <= v["span"][1] < GROWTH_EXPONENT
    v = _growth_verdict(sheets(1.09, 0.2), None)  # met by the medians, not by the fastest small runs
    assert v["met"] is True and v["marginal"] and _verdict_word(v) == "MARGINAL" and v["span"][1] > GROWTH_EXPONENT
    v = _growth_verdict(sheets(1.2, 0.01), None)
    assert v["met"] is False and not v["marginal"] and _verdict_word(v) == "NOT MET"
    v = _growth_verdict(sheets(1.2, 0.01)[:3], None)  # no 10^6 sheet: stated, not judged
    assert _verdict_word(v) == "STATED" and "stated, not judged" in v["note"]
    assert "stated, not judged: the sheets span 1024 to 99856 cells" in _verdict_note(v)
    assert _verdict_word(_growth_verdict(sheets(1.2, 0.01)[:1], None)) == "STATED"
    one_size = [_corrugation(1_024, [0.1]), _corrugation(1_024, [0.12])]  # two sheets, one cell count: no slope
    v = _growth_verdict(one_size, None)
    assert v["value"] is None and _verdict_word(v) == "STATED" and "fewer than two sheet sizes" in v["note"]


def test_a_sheet_verdict_met_by_its_median_runs_but_not_its_slowest_is_marginal():
    from studies.bench import _sheet_verdict, _verdict_word

    def row(runs):
        return {**_corrugation(99_856, runs), "iterations": 6, "peak_rss_mib": 700.0,
                "lower_bound": {"bound_s": 0.3, "bound_iterations": float(np.median(runs)) / 0.3,
                                "bound_polar_iterations": 70.0}}

    machine = {"cores": 2}
    v = _sheet_verdict("sheet", [row([10.8, 11.1, 11.4])], machine)  # 36-38 x bound
    assert _verdict_word(v) == "MET" and v["sheets"][0]["bound_iterations_runs"] == pytest.approx([36.0, 38.0])
    v = _sheet_verdict("sheet", [row([10.8, 11.4, 12.6])], machine)  # 36-42: the median 38 meets 40
    assert _verdict_word(v) == "MARGINAL" and v["met"] is True
    v = _sheet_verdict("sheet", [row([12.3, 12.6, 12.9])], machine)  # 41-43
    assert _verdict_word(v) == "NOT MET" and not v["marginal"]
    text = format_table({"machine": {"cores": 2, "platform": "p", "factor_backend": "superlu",
                                     "load_average_1min_at_start": 0.1}, "mode": "full", "hinges": [],
                         "sheets": [], "fem_comparison": {}, "verdicts": {"sheet": v}, "seconds": 1.0})
    assert "(41-43 over its 3 runs)" in text
    one = _sheet_verdict("sheet_1e6", [{**row([300.0]), "cells": 1_000_000}], machine)
    assert not one["marginal"] and one["sheets"][0]["runs"] == 1
    text = format_table({"machine": {"cores": 2, "platform": "p", "factor_backend": "superlu",
                                     "load_average_1min_at_start": 0.1}, "mode": "full", "hinges": [],
                         "sheets": [], "fem_comparison": {}, "verdicts": {"sheet_1e6": one}, "seconds": 1.0})
    assert "1000000: 300 s, 1000 x bound (one run: its spread not measured)" in text


def test_the_hinge_verdict_is_marginal_where_its_fastest_and_slowest_runs_disagree():
    from studies.bench import HINGE_SECONDS, _hinge_verdict, _verdict_word

    def rows(runs):
        out = [{"method": "newton", "auto": False, "converged": True, "iterations": 7, "seconds": 0.2,
                "seconds_all": [0.2]}]
        return out + [{"method": "newton-cg", "auto": True, "converged": True, "iterations": 11,
                       "seconds": float(np.median(r)), "seconds_all": r} for r in runs]

    fast = [0.5 * HINGE_SECONDS] * 3
    v = _hinge_verdict(rows([fast, [0.7 * HINGE_SECONDS, 0.8 * HINGE_SECONDS, 0.9 * HINGE_SECONDS]]), 16)
    assert _verdict_word(v) == "MET" and v["value"] == {"max_iterations": 11, "max_seconds": 0.8 * HINGE_SECONDS}
    assert v["newton"] == {"max_iterations": 7, "max_seconds": 0.2, "converged": True}
    v = _hinge_verdict(rows([fast, [0.8 * HINGE_SECONDS, 0.9 * HINGE_SECONDS, 1.3 * HINGE_SECONDS]]), 16)
    assert v["met"] is True and _verdict_word(v) == "MARGINAL"
    v = _hinge_verdict(rows([fast, [1.1 * HINGE_SECONDS] * 3]), 4)
    assert _verdict_word(v) == "NOT MET" and "--quick" in v["note"]


def test_the_cpu_answer_compares_shapes_after_the_rigid_motion_and_claims_no_agreement_without_estimates():
    """A shape solved again on the CPU agrees with itself moved rigidly; without an estimated distance there is
    no bound to agree within."""
    import dataclasses

    from studies.bench import SHEET_PIXEL, SHEET_R, _cpu_answer

    des = gdfe.from_masks(*mask_sheet(16), SHEET_PIXEL, SHEET_R, h=H, nz=1)
    res = gdfe.simulate(des, method="auto", device="cpu")
    c, s = np.cos(0.3), np.sin(0.3)
    turned = res.points @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T + [1.0, 2.0, 3.0]
    a = _cpu_answer(des, dataclasses.replace(res, points=turned))
    assert a["agrees"] and a["max_distance_mm"] < 1e-9 and a["energy_relative_difference"] == 0.0
    assert a["allowed_mm"] == pytest.approx(2 * res.error_estimate_mm)
    a = _cpu_answer(des, dataclasses.replace(res, error_estimate_mm=None))
    assert a["allowed_mm"] is None and not a["agrees"]
    text = format_table({"machine": {"cores": 2, "platform": "p", "factor_backend": "superlu",
                                     "load_average_1min_at_start": 0.1}, "mode": "full", "hinges": [],
                         "sheets": [], "fem_comparison": {}, "seconds": 1.0,
                         "verdicts": {"gpu": {"goal": "g", "value": None, "met": None, "note": "n",
                                              "agreement": {"corrugation 256": a}}}})
    assert "DO NOT AGREE: at most - mm" in text
