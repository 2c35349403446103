"""Bad material or geometry input raises a clear error; a failed Newton solve says so."""

import pytest

from reference_fem import Material, Segment, hinge_mesh, layered_strip, solve_nonlinear, strip_mesh


@pytest.mark.parametrize("kwargs,match", [
    (dict(E_active=0.0), r"E_active must be a positive number, got 0\.0"),
    (dict(E_passive=-1.0), r"E_passive must be a positive number, got -1\.0"),
    (dict(nu_active=0.5), r"nu_active must satisfy -1 < nu_active < 0\.5 .*got 0\.5"),
    (dict(nu_passive=0.7), r"nu_passive must satisfy -1 < nu_passive < 0\.5 .*got 0\.7"),
    (dict(eigenstrain=-1.0), r"eigenstrain must be greater than -1 .*got -1\.0"),
    (dict(eigenstrain=(-0.1, -1.5, 0.0)), r"eigenstrain\[1\] must be greater than -1 .*got -1\.5"),
    (dict(eigenstrain=(-0.1, 0.0)), r"eigenstrain must be a number or a triple"),
    (dict(eigenstrain="a lot"), r"eigenstrain must be a real number, got 'a lot'"),
    (dict(E_active=float("nan")), r"E_active must be a finite number"),
])
def test_bad_material(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Material(**kwargs)


def test_bad_ratio():
    with pytest.raises(ValueError, match=r"E_ratio must be a positive number, got -2"):
        Material.from_ratio(-2, -0.1)


@pytest.mark.parametrize("kwargs,match", [
    (dict(length=0.0), r"length must be a positive number, got 0\.0"),
    (dict(d=-0.33), r"d must be a positive number, got -0\.33"),
    (dict(h=0), r"h must be a positive number, got 0"),
    (dict(width=-1.0), r"width must be a positive number, got -1\.0"),
    (dict(panel_length=0), r"panel_length must be a positive number, got 0"),
    (dict(layers_per_ply=1), r"layers_per_ply must be an integer >= 2, got 1"),
    (dict(element_size=0.0), r"element_size must be a positive number, got 0\.0"),
    (dict(free_face="side"), r"free_face must be one of \['bottom', 'top'\], got 'side'"),
    (dict(resolution="ultra"), r"resolution must be one of .*got 'ultra'"),
])
def test_bad_hinge_geometry(kwargs, match):
    args = dict(length=1.6, d=0.33, h=0.29)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        hinge_mesh(**args)


def test_bad_strip_geometry():
    with pytest.raises(ValueError, match=r"segment length must be a positive number, got -1"):
        Segment(-1, "top")
    with pytest.raises(ValueError, match=r"coating must be one of .*got 'middle'"):
        Segment(1.0, "middle")
    with pytest.raises(ValueError, match=r"segments must hold at least one segment"):
        layered_strip([], 0.29, 0.33)
    with pytest.raises(ValueError, match=r"symmetry='xy' needs segments that are mirror-symmetric"):
        layered_strip([(1.0, "top"), (2.0, "both")], 0.29, 0.33, symmetry="xy")
    with pytest.raises(ValueError, match=r"d must be a positive number, got 0"):
        strip_mesh(5.0, 0.29, 0)


def test_bad_solver_input():
    strip = hinge_mesh(1.0, 0.33, resolution="coarse")
    with pytest.raises(ValueError, match=r"model must be one of \['neohookean', 'svk'\], got 'rubber'"):
        solve_nonlinear(strip, Material(), model="rubber")
    with pytest.raises(ValueError, match=r"steps must be an integer >= 1, got 0"):
        solve_nonlinear(strip, Material(), steps=0)
    with pytest.raises(TypeError, match=r"material must be a reference_fem.Material"):
        solve_nonlinear(strip, {"E": 1})


def test_newton_that_does_not_converge_says_so():
    strip = hinge_mesh(3.0, 0.14, resolution="coarse")
    res = solve_nonlinear(strip, Material.from_ratio(7.7, -0.3), steps=1, max_iter=1, min_step=0.3)
    assert res.converged is False
    assert res.load_factor < 1.0
    assert res.summary()["converged"] is False
