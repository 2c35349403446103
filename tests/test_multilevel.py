"""Coarsened designs and the multilevel start of large sheets."""

import numpy as np
import pytest

import gdfe
import gdfe.solver.simulation
from gdfe.design import Material
from gdfe.multilevel import coarsen


def _face_contraction(des):
    """Total (1 - R) x cell area contracted on the top and on the bottom face, per layer."""
    area = des.mesh.spacing[0] * des.mesh.spacing[1]
    top, bottom = des.face_contraction()
    return top.sum() * area, bottom.sum() * area


def _holey_design(nz=1, holes=True):
    rng = np.random.default_rng(3)
    # odd sizes: the last coarse column and row are half empty
    nx, ny = (13, 9) if holes else (14, 10)
    mat = np.full((nx, ny), Material.RIGID)
    mat[4:7, :] = Material.CONTRACT_TOP  # stripes 3 pixels wide: 1.5 coarse cells
    mat[9:11, :] = Material.CONTRACT_BOTTOM
    film = rng.random((nx, ny)) > (0.15 if holes else -1.0)
    film[:, 4] = True  # keep it in one piece
    R = rng.uniform(0.6, 0.9, size=(nx, ny))
    return gdfe.grid_design(mat, R, h=0.29, pixel=0.1, nz=nz, film=film)


@pytest.mark.parametrize("nz", [1, 2])
def test_coarsening_keeps_the_contraction_of_each_face(nz):
    des = _holey_design(nz, holes=False)
    coarse, prolong = coarsen(des)
    assert coarse.mesh.spacing == pytest.approx(des.mesh.spacing * [2, 2, 1])
    assert coarse.h == des.h and coarse.isotropy == des.isotropy
    # top and bottom stripes never share a coarse cell here, so nothing is lost
    np.testing.assert_allclose(_face_contraction(coarse), _face_contraction(des), rtol=1e-12)
    assert set(np.unique(coarse.material)) <= {Material.RIGID, Material.CONTRACT_TOP, Material.CONTRACT_BOTTOM}
    assert np.all((coarse.R > 0) & (coarse.R <= 1))
    assert prolong.shape == (des.mesh.n_points, coarse.mesh.n_points)
    # with holes and half-empty edge cells: a coarse cell wherever a 2 x 2 block has film
    fine = _holey_design(nz)
    holey, _ = coarsen(fine)
    i, j = fine.mesh.cell_ij.T
    blocks = {(a // 2, b // 2) for a, b in zip(i, j)}
    assert holey.n_cells == nz * len(blocks)


def test_prolongation_is_exact_for_affine_shapes():
    des = _holey_design(nz=2)
    coarse, prolong = coarsen(des)
    A = np.array([[0.9, -0.3, 0.2], [0.4, 1.1, -0.5], [0.1, 0.7, 1.3]])
    b = np.array([1.0, -2.0, 0.5])
    np.testing.assert_allclose(prolong @ (coarse.mesh.points @ A.T + b), des.mesh.points @ A.T + b,
                               atol=1e-12)
    np.testing.assert_allclose(prolong.sum(axis=1), 1.0)


def test_free_shrink_and_mixed_blocks():
    mat = np.array([[Material.FREE_SHRINK, Material.FREE_SHRINK], [Material.FREE_SHRINK, Material.RIGID]])
    coarse, _ = coarsen(gdfe.grid_design(mat, 0.6, pixel=0.1, nz=1))
    assert coarse.n_cells == 1
    assert coarse.material[0] == Material.FREE_SHRINK
    assert coarse.R[0] == pytest.approx(1 - 0.75 * 0.4)  # three of four cells shrink by 1 - R = 0.4
    rigid, _ = coarsen(gdfe.grid_design(np.zeros((4, 2), int), 0.6, pixel=0.1, nz=1))
    assert np.all(rigid.material == Material.RIGID) and np.all(rigid.R == 1.0)


def test_coarsen_rejects_non_designs():
    with pytest.raises(TypeError, match="design: expected a gdfe.Design"):
        coarsen("sheet")


def _stripes(n=48):
    top = np.ones((n, n), bool)
    bottom = np.ones((n, n), bool)
    top[8:14] = False  # hinge free on top: folds one way
    bottom[28:34] = False  # free on the bottom: folds back
    return gdfe.from_masks(top, bottom, 0.1, 0.7, nz=1, isotropy=0.0)


def test_multilevel_start_reaches_the_same_shape():
    des = _stripes()
    lin = gdfe.simulate(des, init="linear").check()
    ml = gdfe.simulate(des, init="multilevel").check()
    assert "start" in ml.timings and "start" not in lin.timings
    assert ml.energy == pytest.approx(lin.energy, rel=1e-9)
    assert gdfe.shape_distance(ml.points, lin.points)["rms"] < 1e-6


def test_auto_init_switches_to_multilevel_above_the_threshold(monkeypatch):
    des = _stripes(24)
    assert "start" not in gdfe.simulate(des).timings
    monkeypatch.setattr(gdfe.solver.simulation, "MULTILEVEL_CELLS", des.n_cells - 1)
    res = gdfe.simulate(des).check()
    assert "start" in res.timings


def test_the_set_up_made_beside_the_start_changes_nothing(monkeypatch):
    """gdfe.simulate makes the fine solve's constants beside the multilevel start (Solver.prepare): the same answer."""
    import sys

    import gdfe.solver.simulation  # noqa: F401

    sim = sys.modules["gdfe.solver.simulation"]
    des = _stripes(24)
    monkeypatch.setattr(sim, "MULTILEVEL_CELLS", des.n_cells - 1)
    made = []
    prepare = sim._prepare

    def spy(solver, method, a, monitor):
        prepare(solver, method, a, monitor)
        made.append(sorted(k for k in ("multigrid", "reduced_hessian") if k in solver.__dict__))
        if "reduced_hessian" in solver.__dict__:
            made[-1] += [k for k in ("coarse", "_j_pattern") if k in solver.reduced_hessian.__dict__]
    monkeypatch.setattr(sim, "_prepare", spy)
    res = gdfe.simulate(des, method="newton-cg").check()
    assert made == [["reduced_hessian", "coarse", "_j_pattern"]]
    monkeypatch.setattr(sim, "_prepare", lambda *args: None)
    plain = gdfe.simulate(des, method="newton-cg").check()
    assert np.array_equal(res.points, plain.points) and res.iterations == plain.iterations


def test_each_start_level_is_freed_when_it_is_solved(monkeypatch):
    """A level's Hessian and multigrid refer back to its solver, a reference cycle that only the cyclic
    collector frees, which may not run for the rest of a solve: on the 10^6-cell corrugation the
    2.5 x 10^5-cell level's matrices stayed resident through the fine level. Each level now drops them
    when solved, so that reference counting alone frees the level (the collector held off here)."""
    import gc
    import weakref

    import gdfe.solver.starts as starts

    made = []

    class Spy(starts.Solver):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(weakref.ref(self))

    monkeypatch.setattr(starts, "Solver", Spy)
    des = _stripes()
    gc.collect()
    gc.disable()
    try:
        V = starts.multilevel_start(des, 1.0)
        assert len(made) == 1 and all(ref() is None for ref in made)
    finally:
        gc.enable()
    assert V.shape == (des.mesh.n_points, 3) and np.isfinite(V).all()
