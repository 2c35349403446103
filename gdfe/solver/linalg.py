"""Sparse factorisation of the symmetric positive definite systems of the solver.

Three backends (:data:`FACTOR_BACKENDS`), fastest first:

``"cholmod"``
    CHOLMOD's supernodal Cholesky through scikit-sparse, which needs SuiteSparse from the
    system packages.
``"cvxopt"``
    The same CHOLMOD as CVXOPT's binary wheels bundle it (``pip install -e ".[factor]"``,
    part of ``all``): on the 10^5-cell corrugation's coarse matrix (25 350 unknowns) its analysis
    and factorisation take 20 + 54 ms against SuperLU's 0.35 s, a solve 6.4 ms against 8.7 ms.
``"superlu"``
    SciPy's SuperLU, which needs nothing beyond SciPy.

:func:`factor_backend` takes the first installed; the environment variable ``GDFE_FACTOR``
forces one. ``gdfe bench`` times them all on the solver's matrices (docs/bench/bench.txt).
A :class:`Factoriser` factorises a sequence of matrices with one sparsity pattern (the
coarse matrix of every Newton step) and, with CVXOPT's CHOLMOD, keeps that pattern's form.
Where CHOLMOD finds a matrix not positive definite, SuperLU factorises it (as before CHOLMOD:
an LU without pivoting, which an indefinite matrix with nonzero pivots also passes).
"""

from __future__ import annotations

import importlib.util
import logging
import os

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from gdfe._validation import GdfeError, check_choice

__all__ = ["FACTOR_BACKENDS", "factor_backend", "installed_backends", "factorise", "Factoriser"]

log = logging.getLogger(__name__)

#: Sparse factorisations, fastest first where several are installed (see the module docstring).
FACTOR_BACKENDS = ("cholmod", "cvxopt", "superlu")
#: What each backend beyond SciPy needs: its module, and how to install it.
_NEEDS = {"cholmod": ("sksparse", "scikit-sparse (pip install -e \".[cholmod]\", with SuiteSparse on the system)"),
          "cvxopt": ("cvxopt", "CVXOPT (pip install -e \".[factor]\")")}


def _installed(backend):
    return backend not in _NEEDS or importlib.util.find_spec(_NEEDS[backend][0]) is not None


def installed_backends():
    """The backends of :data:`FACTOR_BACKENDS` installed here, in that order (SuperLU always)."""
    return [b for b in FACTOR_BACKENDS if _installed(b)]


def _chosen(name, value):
    """``value`` checked as a backend that is installed here (``name`` says where it came from)."""
    backend = check_choice(name, value, FACTOR_BACKENDS)
    if not _installed(backend):
        raise GdfeError(f"{name}: the {backend!r} factorisation needs {_NEEDS[backend][1]}; "
                        f"installed here: {', '.join(installed_backends())}")
    return backend


def factor_backend():
    """Name of the backend :func:`factorise` uses here: ``GDFE_FACTOR`` if set, else the first of
    :data:`FACTOR_BACKENDS` that is installed."""
    forced = os.environ.get("GDFE_FACTOR", "").strip().lower()
    if forced:
        return _chosen("GDFE_FACTOR", forced)
    return installed_backends()[0]


class _Cholmod:
    """CHOLMOD's Cholesky factor (scikit-sparse) with the ``solve`` of SciPy's SuperLU."""

    def __init__(self, A):
        import warnings

        from sksparse.cholmod import cholesky

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # CHOLMOD's note on converting the index type
            self._f = cholesky(sp.csc_matrix(A, dtype=float))

    def solve(self, b):
        return self._f(np.asarray(b, float))


def _superlu(A):
    return spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def _canonical(A):
    """``A`` as CSC with sorted indices and no duplicates (a copy only where it is not already)."""
    A = sp.csc_matrix(A, dtype=float)
    if not A.has_canonical_format:
        A = A.copy()
        A.sum_duplicates()
    return A


class _CvxoptPattern:
    """One sparsity pattern in CVXOPT's form: the lower triangle's entries and a sparse matrix on them.

    Each factorisation analyses it (CHOLMOD's ordering and symbolic factorisation, 20 ms on the
    10^5-cell corrugation's coarse matrix) into storage of its own, which goes with its factor:
    an analysis kept across Newton steps would keep its numeric factor too, beside the next
    step's line search (at 10^6 cells it raised the peak memory above 6 GiB).
    """

    def __init__(self, A):
        import cvxopt
        from cvxopt import cholmod

        self._cvxopt, self._cholmod = cvxopt, cholmod
        self.indptr, self.indices = A.indptr.copy(), A.indices.copy()
        cols = np.repeat(np.arange(A.shape[1]), np.diff(A.indptr))
        self.lower = np.flatnonzero(A.indices >= cols)  # CSC order, rows sorted: CVXOPT's own order of them
        self.matrix = cvxopt.spmatrix(A.data[self.lower], A.indices[self.lower].astype(int),
                                      cols[self.lower].astype(int), A.shape)

    def fits(self, A):
        """Whether ``A`` (canonical CSC) has this pattern."""
        return np.array_equal(A.indptr, self.indptr) and np.array_equal(A.indices, self.indices)

    def factorise(self, A):
        """The Cholesky factorisation of ``A`` (this pattern); ``ArithmeticError`` when it is not positive definite."""
        self.matrix.V = self._cvxopt.matrix(np.ascontiguousarray(A.data[self.lower]))
        options = self._cholmod.options  # CVXOPT's, for the whole process: set for this analysis and given back
        before = options.get("supernodal")
        options["supernodal"] = 2  # always supernodal (BLAS on dense blocks)
        try:
            factor = self._cholmod.symbolic(self.matrix, uplo="L")
        finally:
            if before is None:
                del options["supernodal"]
            else:
                options["supernodal"] = before
        self._cholmod.numeric(self.matrix, factor)
        return _CvxoptFactor(self._cvxopt, self._cholmod, factor)


class _CvxoptFactor:
    """A Cholesky factorisation by CVXOPT's CHOLMOD, with the ``solve`` of SciPy's SuperLU."""

    def __init__(self, cvxopt, cholmod, factor):
        self._cvxopt, self._cholmod, self._factor = cvxopt, cholmod, factor

    def solve(self, b):
        b = np.asarray(b, float)
        x = self._cvxopt.matrix(np.asfortranarray(b).reshape(b.shape[0], -1, order="F"))
        self._cholmod.solve(self._factor, x)
        return np.array(x).reshape(b.shape)


def factorise(A, backend=None):
    """Factorise a sparse symmetric positive definite matrix.

    Parameters
    ----------
    A : (k, k) sparse matrix
    backend : {"cholmod", "cvxopt", "superlu"}, optional
        Default :func:`factor_backend`. ``"cholmod"`` and ``"cvxopt"``: supernodal Cholesky,
        falling back to SuperLU if CHOLMOD finds the matrix not positive definite;
        ``"superlu"``: sparse LU with a symmetric ordering and no pivoting.

    Returns
    -------
    factor
        Has ``solve(b)`` for ``b`` of shape ``(k,)`` or ``(k, r)``. SuperLU raises
        ``RuntimeError`` when ``A`` is exactly singular.
    """
    return Factoriser(backend)(A)


class Factoriser:
    """Factorisations of a sequence of symmetric positive definite matrices that share a pattern.

    With CVXOPT's CHOLMOD the pattern's lower triangle and CVXOPT's sparse matrix on it are
    made at the first matrix and kept (24 ms on the 10^5-cell corrugation's coarse matrix);
    each call then makes CHOLMOD's analysis and numeric factorisation (20 + 54 ms there,
    against SuperLU's 0.35 s). A matrix of another pattern replaces the kept one. The other
    backends factorise every matrix from scratch.

    Parameters
    ----------
    backend : str, optional
        See :func:`factorise`.
    """

    def __init__(self, backend=None):
        self.backend = factor_backend() if backend is None else _chosen("backend", backend)
        self._pattern = None

    def __call__(self, A):
        """Factorise ``A`` (see :func:`factorise`)."""
        if self.backend == "superlu":
            return _superlu(A)
        try:
            if self.backend == "cholmod":
                from sksparse.cholmod import CholmodError

                try:
                    return _Cholmod(A)
                except CholmodError as exc:
                    raise ArithmeticError(str(exc)) from exc
            A = _canonical(A)
            if self._pattern is None or not self._pattern.fits(A):
                self._pattern = _CvxoptPattern(A)
            return self._pattern.factorise(A)
        except ArithmeticError as exc:
            log.info("CHOLMOD found the matrix not positive definite (%s); using SuperLU", exc)
            return _superlu(A)
