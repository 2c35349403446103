"""The Newton solve's record of its steps and of its multilevel start, and what it shows: the factorised
Newton converges superlinearly to the solution, where with every cell's Hessian clamped positive it did not."""

import numpy as np
import pytest

import gdfe
from gdfe.measure import shape_distance
from gdfe.solver import STEP_TOL_FACTOR, Solver, default_tol
from gdfe.solver import newton as nw
from gdfe.solver.newton import NewtonStep, convergence_rates
from gdfe.solver.starts import MULTILEVEL_ITER, StartLevel
from studies.bench import mask_sheet


def _step(it, length, alpha=1.0, kind="newton"):
    return NewtonStep(iteration=it, residual_h=1.0, kind=kind, length_h=length, alpha=alpha, damping=1e-6, tries=1,
                      cg_iterations=0, model_agreement=1.0, energy=1.0, estimate_h=length, seconds=0.0)


def test_convergence_rates_are_those_of_consecutive_full_steps():
    steps = [_step(1, 1.0), _step(2, 0.5), _step(3, 0.4, alpha=0.5), _step(4, 0.2), _step(5, 0.02),
             _step(6, 0.01, kind="plain", alpha=None), _step(7, 0.001), _step(8, 1e-5)]
    np.testing.assert_allclose(convergence_rates(steps), [0.5, 0.1, 0.01])
    assert convergence_rates([]).size == 0


def _aligned_distance(A, B):
    """The largest vertex distance of ``A`` from ``B`` after the best rigid motion (the energy ignores it)."""
    return shape_distance(B, A)["max"]


@pytest.mark.parametrize("method", ["newton", "newton-cg"])
def test_every_step_is_recorded(method):
    des = gdfe.hinge(2.6, d=0.33)
    sv = Solver(des)
    V0 = sv.linearised_start(des.mesh.points.copy(), 1.0)
    stats = sv.solve(V0, 1.0, method=method, tol=default_tol(des, method))
    steps = stats.newton_steps
    assert stats.converged and len(steps) == stats.iterations - 1  # the last iteration finds the test met
    assert [s.iteration for s in steps] == list(range(1, stats.iterations))
    assert all(isinstance(s, NewtonStep) and s.kind == "newton" and s.tries >= 1 for s in steps)
    assert sum(s.cg_iterations for s in steps) == stats.cg_iterations
    assert (stats.cg_iterations > 0) == (method == "newton-cg")
    # the energies after the steps are the solve's, and they fall
    np.testing.assert_array_equal([s.energy for s in steps], stats.energies[1:len(steps) + 1])
    assert all(b.energy <= a.energy * (1 + 1e-13) for a, b in zip(steps, steps[1:]))
    assert steps[-1].estimate_h == stats.error_estimate
    assert all(s.seconds > 0 for s in steps) and steps[0].residual_h > steps[-1].residual_h
    assert set(steps[0].as_dict()) == {"iteration", "residual_h", "kind", "length_h", "alpha", "damping", "tries",
                                       "cg_iterations", "model_agreement", "energy", "estimate_h", "seconds"}


@pytest.mark.parametrize("length", [2.6, 9.0])
def test_factorised_newton_converges_superlinearly_to_the_solution(length, monkeypatch):
    """The factorised Newton with :data:`HESSIAN_FLOOR` ends in contractions far below its linear rate with every
    cell's Hessian clamped positive (floor 1), and within the asked accuracy of a tight reference."""
    des = gdfe.hinge(length, d=0.33)
    tol = default_tol(des, "newton")
    asked = STEP_TOL_FACTOR * tol * des.h
    ref = gdfe.simulate(des, method="newton-cg", contact="off", tol=tol * 1e-3)
    res = gdfe.simulate(des, method="newton", contact="off")
    rates = convergence_rates(res.newton_steps)
    assert res.converged and rates[-1] < 0.01
    assert _aligned_distance(res.points, ref.points) < 0.1 * asked
    # with every cell's Hessian positive semi-definite the convergence is linear (0.22 a step on the 2.6 mm
    # hinge, 0.52 on the 9 mm one), it takes more steps, and on the 9 mm hinge its test passes at 8.8 nm
    # estimated while the shape is 11.6 nm from the solution, beyond the 11.0 nm asked
    made = nw.factorised_directions
    monkeypatch.setattr(gdfe.solver.methods, "factorised_directions", lambda h, r: made(h, r, floor=1.0))
    clamped = gdfe.simulate(des, method="newton", contact="off")
    assert clamped.iterations > res.iterations
    assert np.all(convergence_rates(clamped.newton_steps)[-3:] > 0.2)
    if length == 9.0:
        assert _aligned_distance(clamped.points, ref.points) > asked


def test_the_result_carries_the_last_frame_steps_and_the_start_levels():
    des = gdfe.from_masks(*mask_sheet(10_000), 0.1, 0.7, nz=1)
    res = gdfe.simulate(des, init="multilevel", contact="off")
    levels = res.start_levels
    assert [type(lv) for lv in levels] == [StartLevel] * len(levels) and len(levels) == 2
    assert [lv.cells for lv in levels] == sorted(lv.cells for lv in levels)  # the coarsest first
    assert levels[-1].cells < des.n_cells < 5 * levels[-1].cells
    assert all(1 <= lv.iterations <= MULTILEVEL_ITER and lv.seconds > 0 for lv in levels)
    assert all(len(lv.newton_steps) == lv.iterations - 1 for lv in levels)
    assert sum(lv.seconds for lv in levels) <= res.timings["start"]
    assert "newton_steps" in levels[0].as_dict() and "newton_steps" not in levels[0].as_dict(steps=False)
    assert len(res.newton_steps) == res.iterations - 1
    np.testing.assert_array_equal([s.energy for s in res.newton_steps], res.energy_history[1:res.iterations])
    assert gdfe.simulate(des, contact="off", init="linear").start_levels == []
    assert gdfe.simulate(des, method="plain", contact="off", max_iter=3).newton_steps == []


def test_a_contact_solve_where_no_step_lowers_the_energy_stops_unconverged_and_says_so(caplog):
    """Collision detection that allows no move at all: every direction and the plain step are cut to nothing,
    the solve stops at once, not converged, and its record ends in a step of kind "none"."""
    import logging
    import types

    des = gdfe.hinge(2.6, d=0.33)
    sv = Solver(des)
    V0 = sv.linearised_start(des.mesh.points.copy(), 1.0)
    state = types.SimpleNamespace(energy=0.0, active=0)
    blocked = types.SimpleNamespace(evaluate=lambda V: state, gradient=lambda s: np.zeros((des.mesh.n_points, 3)),
                                    hessian=lambda s, project=True: None, max_step=lambda V, W, s: 0.0)
    directions = nw.factorised_directions(sv.reduced_hessian, sv.rest(1.0))
    with caplog.at_level(logging.WARNING, logger="gdfe.solver.newton"):
        stats = nw.solve_newton(sv, V0, 1.0, 1e-9, 50, directions, contact=blocked)
    assert not stats.converged and stats.iterations == 1 and "no step lowers the energy" in caplog.text
    (only,) = stats.newton_steps
    assert only.kind == "none" and only.length_h == 0.0 and only.alpha is None and only.tries == 20
    assert np.array_equal(stats.points, V0) and stats.energies == [stats.energies[0]] * 3


@pytest.mark.parametrize("make", [nw.factorised_directions, nw.cg_directions])
@pytest.mark.parametrize("floor", [0.0, -0.5, float("nan")])
def test_a_clamp_that_is_not_positive_is_refused(make, floor):
    """The clamp divides by each cell's clamped eigenvalues: at 0 or below a cell's zero eigenvalue would make
    the Hessian infinite, so such a floor is refused by name before any solve."""
    sv = Solver(gdfe.hinge(2.6, d=0.33))
    with pytest.raises(gdfe.GdfeError, match="floor: expected a positive finite number"):
        make(sv.reduced_hessian, sv.rest(1.0), floor=floor)
