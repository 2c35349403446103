"""Where the solver's array work runs: NumPy on the CPU, or CuPy on a GPU (optional).

One array-module abstraction (:func:`array_module`) for the batched polar decomposition
(:func:`polar`), the Hessian products and the multigrid smoothers of ``method="newton-cg"``
(:mod:`gdfe.solver.newton`, :mod:`gdfe.solver.amg`). ``device="cpu"`` is NumPy and SciPy;
``device="gpu"`` is CuPy and ``cupyx.scipy.sparse`` (``pip install -e ".[gpu]"``, CUDA 12);
``device="auto"`` (the default) is the GPU where CuPy imports and sees a device, else the CPU.
The code paths are the same on both: tests run them with NumPy as the array module.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from gdfe._validation import GdfeError, check_choice

__all__ = ["DEVICES", "dot", "gpu_available", "resolve", "array_module", "to_device", "to_host", "to_device_sparse",
           "polar"]

log = logging.getLogger(__name__)

#: The choices of ``device``.
DEVICES = ("auto", "cpu", "gpu")


def _cupy():
    """CuPy, or None where it does not import or sees no device."""
    try:
        import cupy
    except Exception:  # ImportError, or a CUDA library missing under it
        return None
    try:
        if cupy.cuda.runtime.getDeviceCount() < 1:
            return None
    except Exception:  # no driver
        return None
    return cupy


def gpu_available():
    """Whether CuPy imports and sees at least one GPU."""
    return _cupy() is not None


def resolve(device="auto"):
    """The device ``"cpu"`` or ``"gpu"`` that ``device`` (:data:`DEVICES`) names here.

    ``"gpu"`` without CuPy or a device is a :class:`gdfe.GdfeError`; ``"auto"`` falls back to the CPU.
    """
    device = check_choice("device", device, DEVICES)
    if device == "cpu":
        return "cpu"
    if gpu_available():
        return "gpu"
    if device == "gpu":
        raise GdfeError("device: expected 'auto' or 'cpu' here, got 'gpu': CuPy with a CUDA device is needed "
                        "(pip install -e \".[gpu]\")")
    return "cpu"


def array_module(device="auto"):
    """NumPy or CuPy for ``device`` (see :func:`resolve`)."""
    return _cupy() if resolve(device) == "gpu" else np


def to_device(a, xp):
    """``a`` as an array of the module ``xp`` (no copy when it already is one)."""
    return a if xp is np else xp.asarray(a)



def to_host(a):
    """``a`` as a NumPy array (from CuPy: copied off the device)."""
    get = getattr(a, "get", None)
    return np.asarray(a) if get is None else get()


def _is_cupy(xp):
    return getattr(xp, "__name__", "") == "cupy"


def to_device_sparse(A, xp):
    """The SciPy sparse matrix ``A`` on the module ``xp``: ``cupyx.scipy.sparse`` CSR for CuPy, else SciPy's CSR."""
    if not _is_cupy(xp):
        return sp.csr_matrix(A)
    from cupyx.scipy import sparse as csp

    return csp.csr_matrix(sp.csr_matrix(A))


def polar(S, xp=np):
    """The rotations closest to the matrices ``S`` ``(m, 3, 3)``, by one batched SVD on ``xp``.

    ``Q = U diag(1, 1, det(U V^T)) V^T`` with ``S = U Sigma V^T``: the proper rotation
    nearest ``S`` in the Frobenius norm (the orientation step of Eq. 5). Returns an array
    of ``xp``.
    """
    S = to_device(S, xp)
    U, _, Vt = xp.linalg.svd(S)
    d = xp.sign(xp.linalg.det(xp.matmul(U, Vt)))
    d = xp.where(d == 0, 1.0, d)
    U[:, :, 2] *= d[:, None]
    return xp.matmul(U, Vt)


def dot(a, b):
    """``sum(a * b)`` of two ``(n, k)`` arrays, as a float, without BLAS: a threaded BLAS dot on a
    busy 2-core machine took 5 ms for 15 000 numbers (threads woken and waited for) against 5 us in
    one thread. On CuPy arrays, the GPU's own."""
    if isinstance(a, np.ndarray):
        return float(np.einsum("ij,ij->", a, b))
    return float((a * b).sum())
