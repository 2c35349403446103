"""The solver's sparse products on the machine's cores.

SciPy's sparse products release the interpreter lock while they run, so threads of one
process can run them side by side. A conjugate-gradient iteration of
``method="newton-cg"`` is a handful of such products (:mod:`gdfe.solver.newton`): the
Hessian product's ``L v`` and ``J^T J v`` are independent (:func:`side_by_side`), and a
V-cycle's products with its level matrices split by rows (:class:`RowBlocks`). NumPy's
array operations release it too: the per-cell work of a Newton step (the rotations, the
Jacobian's blocks, the coarse matrix's blocks) runs on ranges of cells side by side
(:func:`ranges`, :func:`in_order`).

Every row of every product is computed exactly as the serial product computes it: a
row block is a view of the matrix's own rows, and nothing is summed in another order.
The answers are bitwise those of one thread, whatever :data:`WORKERS` is.

``GDFE_THREADS`` (an integer >= 1) in the environment sets how many (:func:`workers`); ``1``
runs everything in the calling thread. The self-penetration check's searches and the IPC
Toolkit's crossing test run on as many (:mod:`gdfe.solver.penetration`, :mod:`gdfe.solver.contact`). Worker processes that share the cores take a share each
(:class:`Shared`, used by :func:`gdfe.parallel.parallel_map`), and a forked process makes
its own pool (the parent's threads are not in it).
"""

from __future__ import annotations

import functools
import os
import threading
from concurrent.futures import ThreadPoolExecutor, wait

import numpy as np
import scipy.sparse as sp

from gdfe._validation import GdfeError

__all__ = ["WORKERS", "THREAD_ROWS", "workers", "side_by_side", "in_order", "ranges", "RowBlocks", "Shared"]


def _default_workers():
    """The threads ``GDFE_THREADS`` asks for, else the cores this process may use, at most 4."""
    forced = os.environ.get("GDFE_THREADS", "").strip()
    if forced:
        try:
            value = int(forced)
        except ValueError:
            value = 0
        if value < 1:
            raise GdfeError(f"GDFE_THREADS: expected an integer >= 1, got {forced!r}")
        return value
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, min(4, cores))


#: Threads the solver's products run on (the calling thread among them); None (the default): the
#: cores this process may use, at most 4, or ``GDFE_THREADS``, read when first needed, so that a
#: bad value is refused where the command line reports errors, not when gdfe is imported.
WORKERS = None
_environment_workers = functools.lru_cache(maxsize=None)(_default_workers)  # an error is not kept
#: Products with fewer rows than this run in the calling thread alone: handing a product to
#: another thread costs tens of microseconds, more than the product itself on small designs.
THREAD_ROWS = 5000

_pool = None
_pool_key = None  # (size, process id) of the pool: a forked child makes its own (the parent's threads are not in it)
_pool_lock = threading.Lock()


def workers() -> int:
    """The threads to use: :data:`WORKERS` checked (it may be set at run time), or from the environment where None."""
    if WORKERS is None:
        return _environment_workers()
    if not isinstance(WORKERS, (int, np.integer)) or isinstance(WORKERS, bool) or WORKERS < 1:
        raise GdfeError(f"gdfe.solver.threads.WORKERS: expected an integer >= 1 or None, got {WORKERS!r}")
    return int(WORKERS)


def _executor():
    """The shared pool of ``workers() - 1`` threads (the calling thread is the other), made on first use."""
    global _pool, _pool_key
    key = (workers() - 1, os.getpid())
    with _pool_lock:
        if _pool is None or _pool_key != key:
            if _pool is not None and _pool_key[1] == key[1]:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(key[0], thread_name_prefix="gdfe-solver")
            _pool_key = key
        return _pool


def _settle(futures):
    """Cancel those of ``futures`` no thread has started, and wait for the others.

    The caller does the cancelled ones' work itself. No thread ever waits for work that has
    not started: a product handed to the pool from a pool thread (a Jacobian made beside a
    factorisation, its cells in ranges) cannot wait behind the thread that is waiting for it.
    """
    wait([f for f in futures if not f.cancel()])


def side_by_side(first, second, rows=None):
    """``(first(), second())``, the two run at once on two threads.

    ``rows``, the size of the products (rows of the result); below :data:`THREAD_ROWS`, or
    with one worker, both run in the calling thread, first then second. An exception
    raised by either is raised here, with its traceback.
    """
    if workers() < 2 or (rows is not None and rows < THREAD_ROWS):
        return first(), second()
    future = _executor().submit(second)
    try:
        a = first()
    finally:
        _settle([future])  # even when first() raised: no product is left running
    return a, (second() if future.cancelled() else future.result())


def ranges(n):
    """``[(start, stop), ...]``: ``range(n)`` in :func:`workers` contiguous parts of about equal size
    (one part below :data:`THREAD_ROWS`)."""
    parts = 1 if n < THREAD_ROWS else min(workers(), n)
    edges = np.linspace(0, n, parts + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def in_order(fn, items):
    """``[fn(x) for x in items]``, on :func:`workers` threads (the calling thread among them).

    Each thread takes the next item when it is done with its last, so at most
    :func:`workers` calls run at once (their memory with them). The results come in the
    order of ``items``; an exception raised by a call is raised here (the first in that
    order), with its traceback, once every call has ended.
    """
    items = list(items)
    k = min(workers(), len(items))
    if k < 2:
        return [fn(x) for x in items]
    results = [None] * len(items)
    errors = {}
    order = iter(range(len(items)))
    lock = threading.Lock()

    def work():
        while True:
            with lock:
                i = next(order, None)
            if i is None:
                return
            try:
                results[i] = fn(items[i])
            except BaseException as exc:  # noqa: B036 - raised again in the calling thread
                errors[i] = exc

    pool = _executor()
    futures = [pool.submit(work) for _ in range(k - 1)]
    try:
        work()  # takes every item no other thread has taken
    finally:
        _settle(futures)
    if errors:
        raise errors[min(errors)]
    return results


class Shared:
    """``func`` run in one of ``jobs`` worker processes that share the cores (:func:`gdfe.parallel.parallel_map`).

    While it runs, :data:`WORKERS` is its share, ``workers() // jobs`` and at least one, so
    that the processes' threads do not outnumber the cores; the answers do not depend on it.
    Picklable where ``func`` is.
    """

    def __init__(self, func, jobs):
        self.func, self.jobs = func, max(1, int(jobs))
        self.share = max(1, workers() // self.jobs)

    def __call__(self, x):
        global WORKERS
        before, WORKERS = WORKERS, self.share
        try:
            return self.func(x)
        finally:
            WORKERS = before


def _row_view(A, s, e):
    """Rows ``s:e`` of the CSR matrix ``A`` as a CSR matrix on views of its values and column indices.

    Its arrays are set after it is made: SciPy's constructor copies a view of less than half
    of its base (to free the rest), which would double the memory of a level matrix.
    """
    a, b = A.indptr[s], A.indptr[e]
    block = sp.csr_matrix((e - s, A.shape[1]), dtype=A.dtype)
    block.indptr = A.indptr[s:e + 1] - a
    block.indices = A.indices[a:b]
    block.data = A.data[a:b]
    return block


class RowBlocks:
    """A CSR matrix whose products with vectors or ``(n, r)`` arrays run on :func:`workers` threads.

    The rows are split into contiguous blocks of about equal stored entries, each a view of
    the matrix's own arrays (no copy of its values or column indices); the blocks' products
    are stacked. Below :data:`THREAD_ROWS` rows, or with one worker, it is the matrix's own
    product.

    Parameters
    ----------
    A : sparse matrix
        Converted to CSR if it is not.
    """

    def __init__(self, A):
        self.matrix = A if sp.isspmatrix_csr(A) or isinstance(A, sp.csr_array) else sp.csr_matrix(A)
        self.shape = self.matrix.shape
        self._blocks = {}

    def blocks(self, parts):
        """The matrix's rows in ``parts`` contiguous CSR blocks of about equal stored entries (kept)."""
        kept = self._blocks.get(parts)
        if kept is None:
            A = self.matrix
            cuts = np.searchsorted(A.indptr, np.linspace(0, A.nnz, parts + 1)[1:-1])
            edges = np.unique(np.concatenate([[0], cuts, [A.shape[0]]]))
            kept = self._blocks[parts] = [_row_view(A, s, e) for s, e in zip(edges[:-1], edges[1:])]
        return kept

    def __matmul__(self, x):
        parts = workers()
        if parts < 2 or self.shape[0] < THREAD_ROWS:
            return self.matrix @ x
        first, *rest = self.blocks(parts)
        pool = _executor()
        futures = [pool.submit(block.__matmul__, x) for block in rest]
        try:
            head = first @ x
        finally:
            _settle(futures)
        return np.concatenate([head] + [block @ x if f.cancelled() else f.result()
                                        for block, f in zip(rest, futures)])
