"""Run independent simulations in parallel, with a progress bar."""

from __future__ import annotations

import logging
import os

from gdfe._validation import check_int

__all__ = ["parallel_map"]

log = logging.getLogger(__name__)


def parallel_map(func, items, n_jobs=None, desc=None, progress=None):
    """``[func(x) for x in items]``, spread over processes when joblib is installed.

    Parameters
    ----------
    func : callable
        A picklable (module-level) function of one argument.
    items : iterable
    n_jobs : int, optional
        Worker processes; default the ``GDFE_JOBS`` environment variable, else the
        number of CPU cores. 1 runs in this process.
    desc : str, optional
        Label of the progress bar.
    progress : bool, optional
        Show a tqdm progress bar (default: when stderr is a terminal).

    Returns
    -------
    list
        Results in the order of ``items``.
    """
    items = list(items)
    if n_jobs is None:
        n_jobs = int(os.environ.get("GDFE_JOBS", os.cpu_count() or 1))
    n_jobs = check_int("n_jobs", n_jobs)
    if progress is None:
        import sys

        progress = sys.stderr.isatty()
    try:
        from tqdm.auto import tqdm
    except ModuleNotFoundError:  # progress bars are optional
        tqdm = None
    bar = tqdm(total=len(items), desc=desc, disable=not progress) if tqdm else None
    try:
        if n_jobs == 1 or len(items) <= 1:
            out = []
            for x in items:
                out.append(func(x))
                if bar:
                    bar.update()
            return out
        try:
            from joblib import Parallel, delayed
        except ModuleNotFoundError:
            log.info("joblib not installed: running %d tasks serially", len(items))
            return parallel_map(func, items, n_jobs=1, desc=desc, progress=progress)
        out = []
        for res in Parallel(n_jobs=n_jobs, return_as="generator")(delayed(func)(x) for x in items):
            out.append(res)
            if bar:
                bar.update()
        return out
    finally:
        if bar:
            bar.close()
