"""Run independent simulations in parallel: local processes (joblib) or a Dask cluster.

:func:`parallel_map` is the one place the studies, the calibrations and the diagnosis
benchmark spread their independent work. Without a scheduler it runs in local worker
processes through joblib (or in this process); given the address of a Dask ``distributed``
scheduler (``scheduler=`` or the environment variable ``GDFE_SCHEDULER``, which the command
line's ``--scheduler ADDRESS`` sets) it sends every item to that cluster. The results are the
same either way and come back in the order of the items: each item's computation is
deterministic and runs whole on one worker.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal

from gdfe._validation import GdfeError, check_int

__all__ = ["parallel_map", "scheduler_address", "SCHEDULER_ENV", "stop_workers", "stopping_workers", "Stopped"]

log = logging.getLogger(__name__)

#: Environment variable holding the address of a Dask scheduler (``tcp://host:8786``).
SCHEDULER_ENV = "GDFE_SCHEDULER"


def scheduler_address(scheduler=None):
    """The Dask scheduler to use: ``scheduler``, else ``$GDFE_SCHEDULER``, else None (local)."""
    if scheduler is None:
        scheduler = os.environ.get(SCHEDULER_ENV, "").strip() or None
    if scheduler is not None and not isinstance(scheduler, str):
        # a distributed.Client or a cluster object is accepted as it is
        return scheduler
    return scheduler


def parallel_map(func, items, n_jobs=None, desc=None, progress=None, scheduler=None):
    """``[func(x) for x in items]``, spread over processes or a Dask cluster.

    Parameters
    ----------
    func : callable
        A picklable (module-level) function of one argument.
    items : iterable
    n_jobs : int, optional
        Local worker processes; default the ``GDFE_JOBS`` environment variable, else the
        number of CPU cores. 1 runs in this process. Ignored with a scheduler. Each process
        runs the solver on its share of :data:`gdfe.solver.threads.WORKERS`
        (:class:`gdfe.solver.threads.Shared`).
    desc : str, optional
        Label of the progress bar.
    progress : bool, optional
        Show a tqdm progress bar (default: when stderr is a terminal).
    scheduler : str or distributed.Client, optional
        Address of a Dask scheduler (``"tcp://10.0.0.5:8786"``), or a client; default
        ``$GDFE_SCHEDULER``; None runs locally.

    Returns
    -------
    list
        Results in the order of ``items``.
    """
    items = list(items)
    if progress is None:
        import sys

        progress = sys.stderr.isatty()
    scheduler = scheduler_address(scheduler)
    if scheduler is not None and items:
        return _dask_map(func, items, scheduler, desc, progress)
    if n_jobs is None:
        n_jobs = int(os.environ.get("GDFE_JOBS", os.cpu_count() or 1))
    n_jobs = check_int("n_jobs", n_jobs)
    try:
        from tqdm.auto import tqdm
    except ModuleNotFoundError:  # progress bars are optional
        tqdm = None
    bar = tqdm(total=len(items), desc=desc, disable=not progress) if tqdm else None
    try:
        if n_jobs == 1 or len(items) <= 1:
            out = []
            for x in items:
                _report(desc, len(out), len(items))
                out.append(func(x))
                if bar:
                    bar.update()
            return out
        try:
            from joblib import Parallel, delayed
        except ModuleNotFoundError:
            log.info("joblib not installed: running %d tasks serially", len(items))
            return parallel_map(func, items, n_jobs=1, desc=desc, progress=progress)
        from gdfe.solver.threads import Shared

        shared = Shared(func, min(n_jobs, len(items)))  # the solver's threads divided among the processes
        out = []
        _report(desc, 0, len(items))
        for res in Parallel(n_jobs=n_jobs, return_as="generator")(delayed(shared)(x) for x in items):
            out.append(res)
            _report(desc, len(out), len(items))
            if bar:
                bar.update()
        return out
    finally:
        if bar:
            bar.close()


def _report(desc, done, total):
    """A progress record (``gdfe.cli._progress``'s ``"steps"``): ``done`` of ``total`` items finished, the
    next under way; none once all are. The command line shows it off a terminal too, where the bar is not."""
    if done < total:
        log.debug("%s %d/%d", desc or "items", done + 1, total,
                  extra={"progress": {"event": "steps", "stage": desc or "items", "step": done + 1, "total": total}})


def _dask_map(func, items, scheduler, desc, progress):
    """Every item as one task on a Dask cluster; results gathered in the order of the items."""
    try:
        from distributed import Client, as_completed
    except ModuleNotFoundError:
        raise GdfeError(f"scheduler: a Dask scheduler was given ({scheduler!r}) but the 'distributed' "
                        f"package is not installed: pip install 'gdfe[cluster]'") from None
    own = not hasattr(scheduler, "submit")
    try:
        client = Client(scheduler, timeout="10s") if own else scheduler
    except OSError as exc:  # no scheduler at that address
        raise GdfeError(f"scheduler: cannot reach the Dask scheduler at {scheduler!r} ({exc})") from None
    try:
        futures = client.map(func, items, pure=False)
        index = {f.key: k for k, f in enumerate(futures)}
        out = [None] * len(items)
        try:
            from tqdm.auto import tqdm
        except ModuleNotFoundError:
            tqdm = None
        bar = tqdm(total=len(items), desc=desc, disable=not progress) if tqdm else None
        try:
            _report(desc, 0, len(items))
            for done, fut in enumerate(as_completed(futures), start=1):
                out[index[fut.key]] = fut.result()  # a task's own exception is raised here, with its traceback
                _report(desc, done, len(items))
                if bar:
                    bar.update()
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM (Stopped): the cluster's workers drop our tasks too
            client.cancel(futures)
            raise
        if bar:
            bar.close()
        log.info("%s: %d tasks on the Dask scheduler %s", desc or "parallel_map", len(items), client.scheduler.address)
        return out
    finally:
        if own:
            client.close()


# -- stopping: a signal stops the worker processes too ---------------------------------------------
class Stopped(KeyboardInterrupt):
    """A command stopped by a signal (Ctrl-C's SIGINT, or SIGTERM from ``kill`` or ``timeout``).

    A :class:`KeyboardInterrupt`, so that every ``finally`` and every output folder's clean-up
    runs as for Ctrl-C; ``signum`` is the signal.
    """

    def __init__(self, signum):
        super().__init__(f"stopped by {signal.Signals(signum).name}")
        self.signum = int(signum)


def _descendants(pid):
    """The processes below ``pid`` (children first), from psutil or Linux's /proc."""
    try:
        import psutil
    except ModuleNotFoundError:
        psutil = None
    if psutil is not None:
        try:
            return [p.pid for p in psutil.Process(pid).children(recursive=True)]
        except psutil.Error:
            return []
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{p}/task")
        except OSError:
            continue
        for t in tasks:
            try:
                with open(f"/proc/{p}/task/{t}/children") as f:
                    kids = [int(x) for x in f.read().split()]
            except OSError:
                continue
            out += kids
            todo += kids
    return out


def stop_workers(grace=2.0):
    """Terminate every process this one started (local workers, a benchmark's child process, theirs).

    SIGTERM first; those still running after ``grace`` seconds get SIGKILL. Returns the process ids
    that were stopped.
    """
    import time

    trackers = _resource_trackers()
    pids = [p for p in _descendants(os.getpid()) if p not in trackers]
    for pid in pids:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGTERM)
    end = time.monotonic() + grace
    alive = list(pids)
    while alive and time.monotonic() < end:
        alive = [p for p in alive if _running(p)]
        if alive:
            time.sleep(0.02)
    for pid in alive:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
    if pids:
        log.info("stopped %d worker process(es)", len(pids))
    return pids


def _resource_trackers():
    """The process ids of the resource trackers started here: multiprocessing's and joblib's (loky's).

    They must outlive the workers: each frees what its workers leave (semaphores, joblib's memory-mapped
    folders) and ends by itself with this process. Stopped with the workers, loky's was started again
    by the next parallel run, with a warning that resources might leak.
    """
    import sys

    modules = ("multiprocessing.resource_tracker", "joblib.externals.loky.backend.resource_tracker")
    pids = {getattr(getattr(sys.modules.get(m), "_resource_tracker", None), "_pid", None) for m in modules}
    return pids - {None}


def _running(pid):
    """Whether ``pid`` still runs (reaped here when it is our child and has ended)."""
    try:
        done, _ = os.waitpid(pid, os.WNOHANG)
        if done == pid:
            return False
    except ChildProcessError:  # not our child: ask whether it exists
        pass
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        try:
            os.kill(pid, 0)
        except OSError:
            return False
        return True


@contextlib.contextmanager
def stopping_workers(signals=(signal.SIGINT, signal.SIGTERM)):
    """While in the block, a signal stops every worker process and raises :class:`Stopped` here.

    Without it a SIGTERM ends this process alone and leaves its workers running, orphaned (a
    benchmark's child holding gigabytes); Ctrl-C's SIGINT reaches the workers of a terminal's
    process group but not those of a pool that ignores it. Outside the main thread it does nothing.
    """
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame):
        for sig in signals:  # a second signal while stopping is not a second interruption
            signal.signal(sig, signal.SIG_IGN)
        stop_workers()
        raise Stopped(signum)

    old = {sig: signal.signal(sig, stop) for sig in signals}
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
