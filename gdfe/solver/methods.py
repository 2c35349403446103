"""The solver of one design and its methods: :class:`Solver`, :data:`METHODS`, :func:`auto_method`.

A :class:`Solver` holds one design's factorised system (:class:`LocalGlobal`) and
minimises Eq. 5 with the method asked for: damped Newton with the 3n x 3n Hessian
factorised (``"newton"``) or solved by preconditioned CG (``"newton-cg"``)
(:mod:`gdfe.solver.newton`), or the paper's alternation, plain or Anderson-accelerated
(:mod:`gdfe.solver.alternation`). ``"auto"`` picks a Newton method by the design's size.
"""

from __future__ import annotations

import functools

from gdfe import _memory
from gdfe._validation import GdfeError, check_array, check_choice, check_instance, check_int, check_number
from gdfe.solver.alternation import solve_alternation
from gdfe.solver.contact import Contact
from gdfe.solver.energy import LocalGlobal, SolveStats
from gdfe.solver.linearised import linearised_start
from gdfe.solver.newton import (FORCINGS, ON_DRIFT, PRECONDITIONERS, RELEASE_POINTS, ReducedHessian, cg_directions,
                                factorised_directions, solve_newton)

__all__ = ["METHODS", "AUTO_NEWTON_CELLS", "auto_method", "Solver"]

#: Methods of :func:`gdfe.simulate` and :meth:`Solver.solve`.
METHODS = ("newton", "newton-cg", "auto", "anderson", "plain")
#: Largest design (cells) for which ``method="auto"`` factorises the full Hessian; above
#: it ``"newton-cg"`` is the faster on every design ``gdfe bench`` times, the Figure 6
#: hinges included (docs/bench/bench.txt).
AUTO_NEWTON_CELLS = 64


def auto_method(design):
    """The method ``"auto"`` picks for ``design``: ``"newton"`` or ``"newton-cg"``."""
    return "newton" if design.n_cells <= AUTO_NEWTON_CELLS else "newton-cg"


def check_tol(tol):
    """``tol`` as a positive finite float, else a :class:`gdfe._validation.GdfeError`."""
    return check_number("tol", tol, minimum=0.0, include_minimum=False, what="a positive finite number")


class Solver(LocalGlobal):
    """A GDFE solver for one design: the factorised system, reused for every solve.

    Parameters
    ----------
    design : Design
    device : {"auto", "cpu", "gpu"}
        Where ``method="newton-cg"`` runs its Hessian products, its preconditioner's
        smoothers and the orientation step's polar decompositions
        (:mod:`gdfe.solver.device`): ``"auto"`` is the GPU where CuPy sees one, else the CPU.
    preconditioner : {"auto", "two-level", "amg"}
        The preconditioner of ``method="newton-cg"`` (:func:`gdfe.solver.newton.cg_directions`):
        ``"auto"`` is ``"amg"`` on a GPU, else ``"two-level"``.
    forcing : {"eisenstat-walker", "sqrt"}
        The forcing sequence of ``method="newton-cg"`` (:func:`gdfe.solver.newton.forcing_term`).
    vanishing_damping : bool
        ``method="newton-cg"``'s damping floor falls with the residual near the solution
        (:func:`gdfe.solver.newton.solve_newton`); False holds it at ``MU_MIN``.

    Attributes
    ----------
    device : str
        ``"cpu"`` or ``"gpu"``, as resolved.
    preconditioner : str
        ``"two-level"`` or ``"amg"``, as resolved.
    reduced_hessian : ReducedHessian
        The Hessian's mesh-only constants, made on first use (by a Newton method or the CG
        linearised start).

    See :class:`LocalGlobal` for the factorised system (``factor``, ``L_ff``, ``free``,
    ``pin``), the steps (:meth:`orient`, :meth:`assemble`) and ``timings``.
    """

    def __init__(self, design, device="auto", preconditioner="auto", forcing="eisenstat-walker",
                 vanishing_damping=True):
        from gdfe.solver import device as _device

        self.device = _device.resolve(device)
        if self.device == "gpu" and device == "auto":
            from gdfe.solver.amg import available

            if not available():  # the GPU's preconditioner is built with pyamg: without it the CPU
                self.device = "cpu"
        preconditioner = check_choice("preconditioner", preconditioner, ("auto",) + PRECONDITIONERS)
        if preconditioner == "auto":
            preconditioner = "amg" if self.device == "gpu" else "two-level"
        if preconditioner == "two-level" and self.device == "gpu":
            raise GdfeError("preconditioner: expected 'auto' or 'amg' on the GPU, got 'two-level' (its "
                            "factorisations run on the CPU)")
        self.preconditioner = preconditioner
        self.forcing = check_choice("forcing", forcing, FORCINGS)
        self.vanishing_damping = bool(vanishing_damping)
        super().__init__(design)
        if self.device == "gpu":
            self.xp = _device.array_module("gpu")

    @functools.cached_property
    def reduced_hessian(self) -> ReducedHessian:
        """The Hessian's mesh-only constants (made on first use)."""
        return ReducedHessian(self)

    def prepare(self, method, activation=1.0):
        """Make now what a solve by ``method`` makes on first use from the mesh alone.

        The multigrid (where the design uses one) and, for ``method="newton-cg"`` with the
        two-level preconditioner, the Hessian's coarse space and patterns
        (:meth:`ReducedHessian.prepare`). The solves' answers do not change: :func:`gdfe.simulate`
        runs it beside the multilevel start, on the solver's second thread.
        """
        rest = self.rest(activation)
        if self.uses_multigrid:
            self.multigrid  # noqa: B018  (made on first use)
        if method == "newton-cg" and self.preconditioner == "two-level":
            self.reduced_hessian.prepare(rest)

    def drop_caches(self):
        """Drop what the solves made on first use (the Newton Hessian's structures, the multigrid).

        They are made again when a solve needs them; a Newton solve of 10^6 cells holds about
        1 GiB in them.
        """
        for name in ("reduced_hessian", "multigrid"):
            self.__dict__.pop(name, None)
        if self.n > RELEASE_POINTS:
            _memory.release()

    def hessian(self, Q, S, activation=1.0, mu=0.0):
        """Positive semi-definite Hessian of the rotation-reduced energy, plus ``mu`` times ``2 L``.

        Parameters
        ----------
        Q, S : (m, 3, 3) float arrays
            Rotations and cross-covariances of an orientation step (:class:`Orientation`).
        activation : float
        mu : float
            Damping.

        Returns
        -------
        (3n, 3n) sparse matrix
            Unknowns ordered vertex-major (``3 v + c``); see :class:`ReducedHessian`.
        """
        return self.reduced_hessian.matrix(Q, S, self.rest(activation), mu=mu)

    def linearised_start(self, V, activation=1.0):
        """Shape ``(n, 3)`` [mm] from the small-rotation solution of Eq. 5 around the flat ``V``.

        See :func:`gdfe.solver.linearised.linearised_start`.
        """
        V = check_array("V", V, shape=(self.n, 3))
        return linearised_start(self, self.reduced_hessian, V, activation)

    def solve(self, V0, activation=1.0, method="newton", tol=1e-7, max_iter=200, history=6,
              contact=None, on_drift="warn", monitor=None) -> SolveStats:
        """Minimise Eq. 5 from ``V0`` (plus the self-contact barrier, with ``contact``).

        Parameters
        ----------
        V0 : (n, 3) float array [mm]
            Start; its pinned vertex (:attr:`pin`) stays where it is.
        activation : float
            Fraction of the contraction applied, 0 .. 1.
        method : {"newton", "newton-cg", "auto", "anderson", "plain"}
            See :func:`gdfe.simulate`.
        tol : float
            Tolerance on the plain step's residual, in units of h.
        max_iter : int
            Limit on the assembly steps.
        history : int
            Anderson history length.
        contact : gdfe.solver.contact.Contact, optional
            Self-contact of this design (Newton methods only); ``V0`` must then be free of
            self-intersection. See :func:`gdfe.solver.newton.solve_newton`.
        on_drift : {"warn", "stop"}
            What a Newton solve does when it drifts between near-equal states
            (:func:`gdfe.solver.newton.solve_newton`).
        monitor : callable, optional
            Newton methods without contact: called with each accepted iterate, see
            :func:`gdfe.solver.newton.solve_newton` (ignored by the alternation methods).

        Returns
        -------
        SolveStats
        """
        method = check_choice("method", method, METHODS)
        V0 = check_array("V0", V0, shape=(self.n, 3))
        tol = check_tol(tol)
        max_iter = check_int("max_iter", max_iter)
        history = check_int("history", history)
        on_drift = check_choice("on_drift", on_drift, ON_DRIFT)
        if method == "auto":
            method = auto_method(self.design)
        if contact is not None:
            check_instance("contact", contact, Contact)
            if not method.startswith("newton"):
                raise GdfeError(f"contact: the contact solve needs a Newton method ('auto', 'newton' or "
                                f"'newton-cg'), got method={method!r}")
        if method == "newton":
            directions = factorised_directions(self.reduced_hessian, self.rest(activation))
            return solve_newton(self, V0, activation, tol, max_iter, directions, contact=contact,
                                on_drift=on_drift, monitor=monitor)
        if method == "newton-cg":
            directions = cg_directions(self.reduced_hessian, self.rest(activation), forcing=self.forcing,
                                       preconditioner=self.preconditioner, device=self.device)
            return solve_newton(self, V0, activation, tol, max_iter, directions, alphas=(1.0, 0.5, 0.25),
                                contact=contact, on_drift=on_drift, monitor=monitor,
                                vanishing_damping=self.vanishing_damping,
                                extrapolate=self.forcing == "sqrt" and not self.vanishing_damping)
        return solve_alternation(self, V0, activation, tol, max_iter, anderson=method == "anderson",
                                 history=history)
