"""Bad material or geometry input raises a clear error; a failed Newton solve says so."""

import pytest

from reference_fem import BilayerMaterial, Segment, hinge_mesh, layered_strip, solve_linear, solve_nonlinear, strip_mesh


@pytest.mark.parametrize("kwargs,match", [
    (dict(E_active=0.0), r"E_active: expected a positive finite number, got 0$"),
    (dict(E_passive=-1.0), r"E_passive: expected a positive finite number, got -1$"),
    (dict(nu_active=0.5), r"nu_active: expected a Poisson's ratio in \(-1, 0\.5\), got 0\.5"),
    (dict(nu_passive=0.7), r"nu_passive: expected a Poisson's ratio in \(-1, 0\.5\), got 0\.7"),
    (dict(eigenstrain=-1.0), r"eigenstrain: expected a strain > -1 .*got -1$"),
    (dict(eigenstrain=(-0.1, -1.5, 0.0)), r"eigenstrain\[1\]: expected a strain > -1 .*got -1\.5"),
    (dict(eigenstrain=(-0.1, 0.0)), r"eigenstrain: expected a number or a triple"),
    (dict(eigenstrain="a lot"), r"eigenstrain: expected a strain > -1 .*got 'a lot'"),
    (dict(E_active=float("nan")), r"E_active: expected a positive finite number, got nan"),
])
def test_bad_material(kwargs, match):
    with pytest.raises(ValueError, match=match):
        BilayerMaterial(**kwargs)


def test_bad_ratio():
    with pytest.raises(ValueError, match=r"E_ratio: expected a positive finite number, got -2"):
        BilayerMaterial.from_ratio(-2, -0.1)


@pytest.mark.parametrize("kwargs,match", [
    (dict(length=0.0), r"length: expected a positive finite number, got 0$"),
    (dict(d=-0.33), r"d: expected a positive finite number, got -0\.33"),
    (dict(h=0), r"h: expected a positive finite number, got 0"),
    (dict(width=-1.0), r"width: expected a positive finite number, got -1$"),
    (dict(panel_length=0), r"panel_length: expected a positive finite number, got 0"),
    (dict(layers_per_ply=1), r"layers_per_ply: expected an integer >= 2, got 1"),
    (dict(element_size=0.0), r"element_size: expected a positive finite number, got 0$"),
    (dict(free_face="side"), r"free_face: expected one of 'bottom', 'top', got 'side'"),
    (dict(resolution="ultra"), r"resolution: expected one of .*got 'ultra'"),
])
def test_bad_hinge_geometry(kwargs, match):
    args = dict(length=1.6, d=0.33, h=0.29)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        hinge_mesh(**args)


def test_bad_strip_geometry():
    with pytest.raises(ValueError, match=r"segment length: expected a positive finite number, got -1"):
        Segment(-1, "top")
    with pytest.raises(ValueError, match=r"coating: expected one of .*got 'middle'"):
        Segment(1.0, "middle")
    with pytest.raises(ValueError, match=r"segments: expected at least one segment"):
        layered_strip([], 0.29, 0.33)
    with pytest.raises(ValueError, match=r"symmetry: 'xy' expected segments that are mirror-symmetric"):
        layered_strip([(1.0, "top"), (2.0, "both")], 0.29, 0.33, symmetry="xy")
    with pytest.raises(ValueError, match=r"d: expected a positive finite number, got 0"):
        strip_mesh(5.0, 0.29, 0)


def test_bad_solver_input():
    strip = hinge_mesh(1.0, 0.33, resolution="coarse")
    with pytest.raises(ValueError, match=r"model: expected one of 'neohookean', 'svk', got 'rubber'"):
        solve_nonlinear(strip, BilayerMaterial(), model="rubber")
    with pytest.raises(ValueError, match=r"steps: expected an integer >= 1, got 0"):
        solve_nonlinear(strip, BilayerMaterial(), steps=0)
    with pytest.raises(TypeError, match=r"material: expected a reference_fem.BilayerMaterial"):
        solve_nonlinear(strip, {"E": 1})


def test_newton_that_does_not_converge_says_so():
    strip = hinge_mesh(3.0, 0.14, resolution="coarse")
    res = solve_nonlinear(strip, BilayerMaterial.from_ratio(7.7, -0.3), steps=1, max_iter=1, min_step=0.3)
    assert res.converged is False
    assert res.load_factor < 1.0
    assert res.summary()["converged"] is False


def test_load_step_whose_extrapolated_start_inverts_an_element_is_cut():
    # at eps* = -0.7 the start extrapolated from the last two load levels turns an element of
    # the coarse hinge inside out (J_e <= 0, no tangent); the step is halved and the solve goes on
    strip = hinge_mesh(1.6, 0.33, resolution="coarse")
    res = solve_nonlinear(strip, BilayerMaterial(eigenstrain=-0.7))
    assert res.converged and res.load_factor == 1.0
    assert res.load_steps >= 4


def test_a_solve_names_its_linear_solver():
    """The FEM's time depends several-fold on what factorised its tangents: the result says which."""
    import importlib.util

    from reference_fem.linear_solvers import AMG_THRESHOLD

    strip = hinge_mesh(1.6, 0.33, resolution="coarse")
    res = solve_nonlinear(strip, BilayerMaterial())
    assert res.dofs < AMG_THRESHOLD  # a direct solve: PARDISO where installed
    expected = "pardiso" if importlib.util.find_spec("pypardiso") else "superlu"
    assert res.linear_solver == expected
    assert res.summary()["linear_solver"] == expected
    assert solve_linear(strip, BilayerMaterial()).linear_solver == "superlu"
