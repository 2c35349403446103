"""The damping of ``method="newton-cg"``: its fall after a step the quadratic model predicted well."""

import pytest

import gdfe
from gdfe.solver import newton as nw
from gdfe.solver.newton import MU_MIN, MU_RESIDUAL, MU_RESIDUAL_CONTACT, _next_damping


@pytest.mark.parametrize("res", [1e-1, 1e-3, 1e-6])
def test_a_well_predicted_full_step_drops_the_damping_to_its_floor(res):
    floor = min(MU_MIN, MU_RESIDUAL * res)
    assert _next_damping(1e-3, full=True, fast=True, res=res, vanishing_damping=True) == floor
    # from anywhere above it, in one step
    assert _next_damping(1e3, full=True, fast=True, res=res, vanishing_damping=True) == floor


def test_contact_solves_keep_the_higher_floor():
    res = 1e-4
    assert MU_RESIDUAL_CONTACT > MU_RESIDUAL
    assert _next_damping(1e-9, full=True, fast=False, res=res, vanishing_damping=True,
                         contact=True) == min(MU_MIN, MU_RESIDUAL_CONTACT * res)


def test_other_steps_keep_the_old_rule():
    mu = 1e-3
    assert _next_damping(mu, full=True, fast=False, res=1e-2, vanishing_damping=True) == mu / 4
    assert _next_damping(mu, full=False, fast=True, res=1e-2, vanishing_damping=True) == 2 * mu
    # the factorised method's floor stays MU_MIN, however well the model predicted
    assert _next_damping(mu, full=True, fast=True, res=1e-9, vanishing_damping=False) == MU_MIN
    assert _next_damping(MU_MIN / 2, full=True, fast=False, res=1e-2, vanishing_damping=False) == MU_MIN


def _divided_by_16(mu, full, fast, res, vanishing_damping, contact=False):
    """The rule before: a well-predicted full step divided the damping by 16, to a floor of 1e-3 res."""
    if not full:
        return 2.0 * mu
    floor = min(MU_MIN, 1e-3 * res) if vanishing_damping else MU_MIN
    return max(mu / (16.0 if fast else 4.0), floor)


@pytest.mark.slow
def test_the_twist_converges_in_eight_steps_to_the_same_state(tmp_path, monkeypatch):
    """The 10^5-cell Figure 8 twist: the damping divided by 16 per well-predicted step took 10 Newton
    steps; dropped to its floor it takes at most 8, to the same shape within the stopping test."""
    from studies.bench import _design

    des, _ = _design("fig08-twist", 100_000, tmp_path)
    new = gdfe.simulate(des)
    with monkeypatch.context() as m:
        m.setattr(nw, "_next_damping", _divided_by_16)
        old = gdfe.simulate(des)
    assert new.converged and old.converged
    assert new.iterations <= 8 < old.iterations
    # the same minimum: energies equal to the round-off a Newton step may raise the energy by
    assert abs(new.energy - old.energy) <= nw.ENERGY_ROUNDOFF * old.energy
    assert gdfe.shape_distance(new.points, old.points)["max"] <= 2 * nw.STEP_TOL_FACTOR * new.tol * des.h
