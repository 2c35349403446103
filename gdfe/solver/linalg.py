"""Sparse factorisation of the symmetric positive definite systems of the solver.

Two backends (:data:`FACTOR_BACKENDS`): CHOLMOD's supernodal Cholesky through
scikit-sparse (needs SuiteSparse from the system packages), else SciPy's SuperLU, which
needs nothing beyond SciPy. ``gdfe bench`` times both on the solver's matrices
(docs/bench/bench.txt). The environment variable ``GDFE_FACTOR`` (``cholmod`` or
``superlu``) forces one.
"""

from __future__ import annotations

import logging
import os

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from gdfe._validation import check_choice

__all__ = ["FACTOR_BACKENDS", "factor_backend", "factorise"]

log = logging.getLogger(__name__)

#: Sparse factorisations, fastest first where both are installed (see the module docstring).
FACTOR_BACKENDS = ("cholmod", "superlu")


def factor_backend():
    """Name of the backend :func:`factorise` uses here: ``GDFE_FACTOR`` if set, else CHOLMOD if installed."""
    forced = os.environ.get("GDFE_FACTOR", "").strip().lower()
    if forced:
        return check_choice("GDFE_FACTOR", forced, FACTOR_BACKENDS)
    try:
        import sksparse.cholmod  # noqa: F401
    except ImportError:
        return "superlu"
    return "cholmod"


class _Cholmod:
    """CHOLMOD's Cholesky factor with the ``solve`` of SciPy's SuperLU."""

    def __init__(self, A):
        import warnings

        from sksparse.cholmod import cholesky

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # CHOLMOD's note on converting the index type
            self._f = cholesky(sp.csc_matrix(A, dtype=float))

    def solve(self, b):
        return self._f(np.asarray(b, float))


def factorise(A, backend=None):
    """Factorise a sparse symmetric positive definite matrix.

    Parameters
    ----------
    A : (k, k) sparse matrix
    backend : {"cholmod", "superlu"}, optional
        Default :func:`factor_backend`. ``"cholmod"``: supernodal Cholesky, falling back
        to SuperLU if CHOLMOD finds the matrix not positive definite; ``"superlu"``:
        sparse LU with a symmetric ordering and no pivoting.

    Returns
    -------
    factor
        Has ``solve(b)`` for ``b`` of shape ``(k,)`` or ``(k, r)``. SuperLU raises
        ``RuntimeError`` when ``A`` is exactly singular.
    """
    backend = factor_backend() if backend is None else check_choice("backend", backend, FACTOR_BACKENDS)
    if backend == "cholmod":
        from sksparse.cholmod import CholmodError

        try:
            return _Cholmod(A)
        except CholmodError as exc:
            log.info("CHOLMOD failed (%s); using SuperLU", exc)
    return spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})
