"""The solver studies at coarse resolution: the hinge's error sources and the stopping test."""

from studies import hinge_error, stopping


def _files(r, tmp_path):
    assert (tmp_path / f"{r['study']}.png").is_file() and (tmp_path / f"{r['study']}.json").is_file()


def test_hinge_error_sources(tmp_path):
    r = hinge_error.run("coarse", tmp_path)
    _files(r, tmp_path)
    assert r["converged"]
    failed = [h for h in r["headlines"] if not h["passed"]]
    assert not failed, failed
    # refined along the hinge only, the cells grow longer across and the fold falls, not converges
    along = [x["outer_rad"] for x in r["along"]]
    assert along[-1] < along[1]


def test_stopping_study(tmp_path):
    r = stopping.run("coarse", tmp_path)
    _files(r, tmp_path)
    assert r["converged"]
    failed = [h for h in r["headlines"] if not h["passed"]]
    assert not failed, failed
    for d in r["designs"]:
        its = [s["iterations"] for s in d["solves"] if not s["default"]]
        assert its == sorted(its)  # a tighter tol never takes fewer iterations
