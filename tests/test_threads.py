"""The solver's products on threads (gdfe.solver.threads): the same bits as one thread, no deadlock, clear errors."""

import functools
import multiprocessing
import os
import pickle
import threading

import numpy as np
import pytest
import scipy.sparse as sp

import gdfe
from gdfe._validation import GdfeError
from gdfe.solver import Solver
from gdfe.solver import newton, threads
from gdfe.solver.multigrid import Multigrid, lattice
from studies.bench import H, SHEET_PIXEL, SHEET_R, mask_sheet


@pytest.fixture
def every_size(monkeypatch):
    """Threads for products of any size (the small designs of the tests)."""
    monkeypatch.setattr(threads, "THREAD_ROWS", 0)


def _with(workers, monkeypatch, fn):
    monkeypatch.setattr(threads, "WORKERS", workers)
    return fn()


def _finishes(fn, seconds=60):
    """``fn()``'s result, or a failure when it has not returned within ``seconds`` (a deadlock)."""
    out = {}
    t = threading.Thread(target=lambda: out.update(value=fn()), daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"did not return within {seconds} s"
    return out["value"]


@pytest.mark.parametrize("workers", [2, 3, 5])
def test_row_blocks_give_the_matrix_products_bits(workers, every_size, monkeypatch):
    rng = np.random.default_rng(0)
    A = sp.random(997, 613, density=0.02, random_state=1, format="csr")
    rb = threads.RowBlocks(A)
    for x in (rng.standard_normal(613), rng.standard_normal((613, 3)), rng.standard_normal((613, 3)).astype(np.float32)):
        serial = A.astype(x.dtype) @ x if x.dtype == np.float32 else A @ x
        got = _with(workers, monkeypatch, lambda: threads.RowBlocks(A.astype(x.dtype)) @ x)
        assert got.dtype == serial.dtype and got.shape == serial.shape
        assert np.array_equal(got, serial)
    blocks = _with(workers, monkeypatch, lambda: rb.blocks(workers))
    assert len(blocks) == workers and sum(b.shape[0] for b in blocks) == A.shape[0]
    assert all(np.shares_memory(b.data, A.data) for b in blocks if b.nnz)  # views, not copies
    # about equal stored entries per block
    assert max(b.nnz for b in blocks) <= A.nnz / workers + A.getnnz(axis=1).max()


def test_small_products_stay_in_the_calling_thread(monkeypatch):
    monkeypatch.setattr(threads, "WORKERS", 2)
    A = sp.eye(10, format="csr")
    rb = threads.RowBlocks(A)
    rb @ np.ones(10)
    assert rb._blocks == {}  # below THREAD_ROWS: never split
    assert threads.ranges(10) == [(0, 10)]
    monkeypatch.setattr(threads, "THREAD_ROWS", 10)
    assert threads.ranges(10) == [(0, 5), (5, 10)]


def test_side_by_side_and_in_order_return_in_order_and_raise_with_the_traceback(every_size, monkeypatch):
    monkeypatch.setattr(threads, "WORKERS", 2)
    assert threads.side_by_side(lambda: 1, lambda: 2) == (1, 2)
    assert threads.in_order(lambda x: x * x, range(7)) == [0, 1, 4, 9, 16, 25, 36]

    def bad(x):
        if x == 3:
            raise ValueError("item 3")
        return x

    with pytest.raises(ValueError, match="item 3") as info:
        threads.in_order(bad, range(6))
    assert any(entry.name == "bad" for entry in info.traceback)
    started, ran = threading.Event(), []

    def second():
        started.set()
        threading.Event().wait(0.2)
        ran.append("second")

    def first():
        assert started.wait(30)
        raise KeyError("first")

    with pytest.raises(KeyError, match="first"):
        threads.side_by_side(first, second)
    assert ran == ["second"]  # the other half, once started, ran to its end before the error was raised


def test_work_handed_to_the_pool_from_the_pool_does_not_deadlock(every_size, monkeypatch):
    """A Jacobian made beside a factorisation splits its own cells (the case that hung before `_settle`)."""
    monkeypatch.setattr(threads, "WORKERS", 2)

    def nested():
        return threads.side_by_side(lambda: threads.in_order(lambda x: x + 1, range(5)),
                                    lambda: threads.in_order(lambda x: 2 * x, range(5)))

    assert _finishes(nested) == ([1, 2, 3, 4, 5], [0, 2, 4, 6, 8])
    A = sp.random(400, 400, density=0.05, random_state=2, format="csr")
    x = np.ones(400)
    got = _finishes(lambda: threads.side_by_side(lambda: threads.RowBlocks(A) @ x, lambda: threads.RowBlocks(A) @ x))
    assert np.array_equal(got[0], A @ x) and np.array_equal(got[1], A @ x)


def test_workers_are_checked(monkeypatch):
    monkeypatch.setenv("GDFE_THREADS", "two")
    with pytest.raises(GdfeError, match="GDFE_THREADS: expected an integer >= 1, got 'two'"):
        threads._default_workers()
    monkeypatch.setenv("GDFE_THREADS", "0")
    with pytest.raises(GdfeError, match="GDFE_THREADS"):
        threads._default_workers()
    monkeypatch.setenv("GDFE_THREADS", "3")
    assert threads._default_workers() == 3
    monkeypatch.setattr(threads, "WORKERS", 0)
    with pytest.raises(GdfeError, match="WORKERS: expected an integer >= 1 or None, got 0"):
        threads.workers()


def test_a_bad_gdfe_threads_is_one_line_from_the_command_line(capsys, monkeypatch):
    """Read when first needed, not when gdfe is imported: the command line reports it like any bad input."""
    from gdfe.cli import main

    monkeypatch.setattr(threads, "WORKERS", None)
    monkeypatch.setattr(threads, "_environment_workers", functools.lru_cache(maxsize=None)(threads._default_workers))
    monkeypatch.setenv("GDFE_THREADS", "lots")
    rc = main(["hinge", "-L", "1.6", "--d", "0.33"])
    err = capsys.readouterr().err
    assert rc == 1 and "Traceback" not in err and err.count("\n") == 1, err
    assert "GDFE_THREADS: expected an integer >= 1, got 'lots'" in err


def test_vcycle_and_its_solve_are_the_same_bits_on_threads(every_size, monkeypatch):
    des = gdfe.from_masks(*mask_sheet(2500), SHEET_PIXEL, SHEET_R, h=H, nz=2)
    sv = Solver(des)
    b = np.random.default_rng(3).standard_normal((len(sv.free), 3))

    def run():
        mg = Multigrid(sv.L_ff, lattice(des.mesh)[sv.free], coarsest=200)
        return mg.vcycle(b, single=True), mg.vcycle(b), mg.solve(b)

    one = _with(1, monkeypatch, run)
    two = _with(2, monkeypatch, run)
    assert all(np.array_equal(a, c) for a, c in zip(one, two))


def test_a_newton_cg_solve_is_the_same_bits_on_one_thread_and_on_two(every_size, monkeypatch):
    """The orientation step, the Jacobian, the coarse matrix and the Hessian product in threads."""
    des = gdfe.from_masks(*mask_sheet(2500), SHEET_PIXEL, SHEET_R, h=H, nz=1)
    monkeypatch.setattr(newton, "_COARSE_CHUNK", 256)  # the coarse matrix's blocks in several slabs

    def run():
        return gdfe.simulate(des, method="newton-cg")

    one = _with(1, monkeypatch, run)
    two = _with(2, monkeypatch, run)
    assert one.converged and two.converged
    assert one.iterations == two.iterations and one.energy == two.energy
    assert np.array_equal(one.points, two.points)


def _pool_thread_name():
    """In a forked child: which thread ran the second half of a side-by-side pair (after the parent's pool was made).

    The first half waits until the second has started, so the second is never left to the
    calling thread (it would be, cancelled, if no pool thread took it up).
    """
    threads.THREAD_ROWS = 0
    threads.WORKERS = 2
    started = threading.Event()

    def second():
        started.set()
        return threading.current_thread().name

    _, name = threads.side_by_side(lambda: started.wait(30), second)
    return name, threads._pool_key[1] == os.getpid()


def test_a_forked_process_makes_its_own_pool(every_size, monkeypatch):
    monkeypatch.setattr(threads, "WORKERS", 2)
    threads.side_by_side(lambda: None, lambda: None)  # the parent's pool exists
    with multiprocessing.get_context("fork").Pool(1) as pool:
        name, own = pool.apply(_pool_thread_name)
    assert own and name.startswith("gdfe-solver")  # really on a thread of the child's own pool


def _workers_here(_):
    return threads.WORKERS


def test_worker_processes_share_the_threads(monkeypatch):
    pytest.importorskip("joblib")
    from gdfe.parallel import parallel_map

    monkeypatch.setattr(threads, "WORKERS", 4)
    shared = pickle.loads(pickle.dumps(threads.Shared(_workers_here, 2)))
    assert shared.share == 2 and threads.Shared(_workers_here, 8).share == 1
    assert shared(None) == 2 and threads.WORKERS == 4  # its share while it runs, and back after
    monkeypatch.setattr(threads, "WORKERS", 2)
    assert parallel_map(_workers_here, range(4), n_jobs=2, progress=False) == [1, 1, 1, 1]
