"""The C heap during a large solve: freed memory given back between steps, large arrays reused within them.

glibc's ``malloc`` serves blocks below its mmap threshold from its heap, and raises that
threshold (up to 32 MiB) each time a larger block is freed; the chunked temporaries of a
large solve (tens of MiB each) then come from the heap, and what they leave free there stays
resident. On the 2.5 x 10^5-cell corrugation the peak resident set of a simulation was
3.4 GiB that way; ``malloc_trim`` after each Newton step brought it to 2.8 GiB in the same
time (121 s against 119 s): :func:`release`.

Above those 32 MiB every block is the other way round: fresh memory mapped from the system
at each request, its pages faulted in (and zeroed) at first use, and unmapped when freed. A
10^6-cell sheet has 2 x 10^6 vertices, so every ``(n, 3)`` array its solve makes (a Hessian
product, a V-cycle's residual, a plain step) is 46 MiB, new memory each time: in five Newton
steps from a kept start the process spent 35-37 s in the kernel against 113-115 s in its own
code. :func:`heap_blocks` raises the threshold above such arrays for the length of a solve
(``mallopt``), so that they are served from the heap and the next one reuses what the last
left free. Elsewhere (another C library, another system) both do nothing.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import functools
import os
import threading

__all__ = ["DYNAMIC_MMAP_MAX", "heap_blocks", "release"]

#: The mmap threshold glibc's dynamic rule stops at on 64-bit systems (its ``DEFAULT_MMAP_THRESHOLD_MAX``):
#: blocks above it are mapped afresh at every request, and :func:`heap_blocks` acts only above it.
DYNAMIC_MMAP_MAX = 32 * 2**20
#: ``mallopt``'s parameters (glibc's ``malloc.h``).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_INT_MAX = 2**31 - 1

_held = []  # the sizes asked for by the heap_blocks now open (in any thread)
_lock = threading.Lock()


@functools.lru_cache(maxsize=1)
def _libc():
    """The C library, or None where it cannot be loaded."""
    try:
        return ctypes.CDLL(ctypes.util.find_library("c"))
    except (OSError, TypeError):
        return None


def _function(name, argtypes):
    """The C library's function ``name``, or None where it has none."""
    libc = _libc()
    fn = getattr(libc, name, None) if libc is not None else None
    if fn is not None:
        fn.argtypes = argtypes
        fn.restype = ctypes.c_int
    return fn


@functools.lru_cache(maxsize=1)
def _malloc_trim():
    """glibc's ``malloc_trim``, or None where the C library has none."""
    return _function("malloc_trim", [ctypes.c_size_t])


@functools.lru_cache(maxsize=1)
def _mallopt():
    """glibc's ``mallopt``, or None where the C library has none."""
    return _function("mallopt", [ctypes.c_int, ctypes.c_int])


def release() -> bool:
    """Return the C heap's free memory to the operating system; whether there was a way to."""
    trim = _malloc_trim()
    if trim is None:
        return False
    trim(0)
    return True


def _chosen_by_the_user():
    """Whether this process's environment sets glibc's mmap or trim threshold itself (read by glibc at start)."""
    if any(os.environ.get(name) for name in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")):
        return True
    tunables = os.environ.get("GLIBC_TUNABLES", "")
    return "malloc.mmap_threshold" in tunables or "malloc.trim_threshold" in tunables


def _set_thresholds(mmap_bytes):
    """The mmap threshold at ``mmap_bytes`` and the trim threshold at twice it (glibc's own ratio), each at most
    the largest C ``int`` (``mallopt`` takes one); whether the C library took both."""
    mallopt = _mallopt()
    mmap_bytes = min(int(mmap_bytes), _INT_MAX)
    took = mallopt(_M_MMAP_THRESHOLD, mmap_bytes)
    return bool(took) & bool(mallopt(_M_TRIM_THRESHOLD, min(2 * mmap_bytes, _INT_MAX)))


@contextlib.contextmanager
def heap_blocks(nbytes):
    """Serve blocks of up to ``nbytes`` bytes from the C heap inside the ``with`` block, reused, not mapped afresh.

    Does nothing where ``nbytes`` is at most :data:`DYNAMIC_MMAP_MAX` (glibc's dynamic threshold
    serves such blocks from its heap already), where the C library has no ``mallopt`` (or one that
    refuses it), and where the process's environment sets the thresholds itself
    (``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_``, or either in ``GLIBC_TUNABLES``): a
    choice made there is not overwritten, during the block or after it. The threshold
    is the process's: blocks open in several threads hold the largest size asked for, and when
    the last closes the thresholds are set to the largest glibc's dynamic rule gives them
    (:data:`DYNAMIC_MMAP_MAX`, trim at twice it; it reaches them once a block that large has been
    freed, as in any large solve), and the heap's free memory is returned (:func:`release`). The
    rule itself is not restored: glibc keeps thresholds fixed once they are set. The arithmetic
    is not touched, so no result changes.

    Yields
    ------
    bool
        Whether the threshold was raised (the C library took it).
    """
    nbytes = int(nbytes)
    if nbytes <= DYNAMIC_MMAP_MAX or _mallopt() is None or _chosen_by_the_user():
        yield False
        return
    with _lock:
        _held.append(nbytes)
        raised = _set_thresholds(max(_held))
    try:
        yield raised
    finally:
        with _lock:
            _held.remove(nbytes)
            _set_thresholds(max(_held) if _held else DYNAMIC_MMAP_MAX)
            if not _held:
                release()
