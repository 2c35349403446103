"""Self-contact of a film: a barrier on its boundary surface and collision-free steps.

The contact term is the incremental-potential-contact barrier of the IPC Toolkit
(``ipctk``, the optional extra ``gdfe[contact]``), on the film's boundary surface
(:func:`gdfe.solver.penetration.surface_triangles`, the boundary quads of the hex mesh
split in two):

    B(V) = kappa * sum_k b(d_k),   b(d) = -(d^2 - dhat^2)^2 ln(d^2 / dhat^2)  for d < dhat,

summed over the vertex-triangle and edge-edge pairs ``k`` of the surface that share no
vertex and are closer than ``dhat`` (ipctk's broad phase finds them), 0 beyond. ``b``
grows without bound as a gap closes and is twice continuously differentiable at ``dhat``,
so the Newton solver (:func:`gdfe.solver.newton.solve_newton`) minimises Eq. 5 plus ``B``
with ``B``'s gradient and its Hessian (made positive semi-definite pair by pair) in its
system, and every trial step is first shortened by continuous collision detection
(:meth:`Contact.max_step`) so that no step carries a face through another. Contact is
frictionless: ``B`` depends on distances only.

**The gap ``dhat``** (:func:`default_dhat`): a tenth of the film thickness, ``0.1 h``
(29 um for the paper's film), which makes contacting surfaces come to rest less than 0.1 h
apart - well inside what a film 0.29 mm thick can resolve - and keeps the film's own
thickness (its top and bottom faces are ``h`` apart) out of contact. It is capped at
``0.25 R_min`` times the smallest cell side: in a cell of side ``s`` the closest primitives
that share no vertex (a vertex and the far triangle of its quad) are ``s / sqrt(2)`` apart,
at least ``R s / sqrt(2)`` once the cell has contracted by ``R``, so with the cap cells next
to each other never come within ``dhat`` of each other and no neighbour filter is needed.

**The stiffness ``kappa``** (:func:`default_stiffness`): chosen so that one barrier pair at
half the gap is as stiff as one boundary vertex of the film (the mean diagonal of the
energy's Hessian ``2 L`` over the boundary vertices), so contact is neither soft against
the film nor needlessly stiff for Newton. Where the film presses on itself the gap closes
further, never to zero.

**Patches** (:func:`contact_patches`): ipctk's broad phases skip pairs of one patch, which
cuts the candidates of collision detection several times over on large designs (the
film's own neighbours are most of them). A patch is a connected region of rigid cells
(it keeps its printed, flat shape, and a flat piece cannot meet itself) or a square block
of the other cells whose diagonal is a quarter turn of the tightest curl Eq. 2 allows,
``rho_min = h / (1 - R_min)``: the film cannot fold back onto itself within less than half
a turn, so two points of one block never meet.

**Candidates once per step** (:meth:`Contact.max_step`): the broad phase runs once per
Newton step, on the boxes each surface primitive sweeps from the iterate to the full step,
grown by ``dhat / 2`` (:data:`SWEEP_INFLATION`); the collision-free fraction of the step is the
narrow phase on those pairs, and the barrier at every trial shape on that step is built from
them (:meth:`Contact.evaluate`) while they are few (:data:`SWEEP_REUSE`), not from a new broad
phase: a pair closer than ``dhat`` at a shape whose every surface vertex lies in its swept box
has boxes within ``dhat`` of each other, so it is a candidate.

Without ``ipctk`` installed, :class:`Contact` raises a :class:`gdfe.GdfeError` that says how
to install it; the penetration check (:mod:`gdfe.solver.penetration`) needs nothing beyond
NumPy and SciPy.
"""

from __future__ import annotations

import dataclasses
import functools
import time

import numpy as np
import scipy.sparse as sp

from gdfe._validation import GdfeError, check_array, check_instance, check_positive
from gdfe.design import Design, Material
from gdfe.solver.energy import system_matrix
from gdfe.solver.penetration import surface_triangles
from gdfe.solver.threads import workers

__all__ = ["CONTACT_MODES", "DHAT_H", "DHAT_CELL", "STIFFNESS_SCALE", "CONTACT_THREADS", "CCD_TIGHT_INCLUSION",
           "SWEEP_INFLATION", "SWEEP_REUSE", "contact_available", "require_ipctk", "default_dhat", "default_stiffness",
           "contact_patches", "barrier", "ContactReport", "ContactState", "Contact"]

#: Values of ``contact=`` in :func:`gdfe.simulate` (see there).
CONTACT_MODES = ("auto", "on", "off")
#: ``dhat`` in film thicknesses (see the module docstring).
DHAT_H = 0.1
#: Cap of ``dhat`` in contracted cell sides.
DHAT_CELL = 0.25
#: Barrier stiffness at half the gap, in units of a boundary vertex's stiffness.
STIFFNESS_SCALE = 1.0
#: Threads of ipctk during contact solves (see :class:`Contact`).
CONTACT_THREADS = 1
#: Tolerance [mm] and iteration limit of the Tight-Inclusion CCD. ipctk's defaults (1e-6,
#: 10^7) took minutes on two parallel plates meeting face to face, the way the layers of a
#: roll meet; the result is conservative with any setting (a bound when the limit is hit).
CCD_TIGHT_INCLUSION = (1e-3, 10_000)
#: Growth of the swept boxes of a step's candidates (:meth:`Contact.max_step`), in ``dhat``: half
#: the gap (two boxes grown by ``dhat / 2`` meet when their primitives are within ``dhat``), and
#: a thousandth more for the round-off of a trial shape on the step.
SWEEP_INFLATION = 0.501
#: The barrier at a trial shape is built from the step's candidates only while they number at
#: most this many per surface primitive (vertex, edge, triangle): a long step sweeps boxes over
#: much of the surface, and then the broad phase of the shape alone is the cheaper (measured on
#: the 9 mm hinge and the 1 536-cell box: a candidate costs about a third of a primitive).
SWEEP_REUSE = 2.0

_INSTALL = "pip install 'gdfe[contact]' (or: pip install ipctk)"


def contact_available() -> bool:
    """Whether the IPC Toolkit (``ipctk``), which the contact solve needs, is installed."""
    try:
        import ipctk  # noqa: F401
    except ImportError:
        return False
    return True


def require_ipctk():
    """The ``ipctk`` module, or a :class:`gdfe.GdfeError` saying how to install it."""
    try:
        import ipctk
    except ImportError:
        raise GdfeError(f"contact: the contact solve needs the IPC Toolkit, which is not installed; "
                        f"{_INSTALL}") from None
    return ipctk


def default_dhat(design):
    """The barrier's gap ``dhat`` [mm] for ``design``: ``0.1 h``, at most ``0.25 R_min`` x the smallest cell side.

    ``R_min`` is the smallest contraction ratio of a non-rigid cell (1 if every cell is
    rigid); see the module docstring for why.
    """
    check_instance("design", design, Design)
    free = design.material != Material.RIGID
    r_min = float(design.R[free].min()) if free.any() else 1.0
    return float(min(DHAT_H * design.h, DHAT_CELL * r_min * float(np.min(design.mesh.spacing))))


def contact_patches(design):
    """The contact patch of every mesh vertex, ``(n,)`` int: surface pairs within one patch never meet.

    Each connected region of rigid cells (in the plane, through every layer) is one patch;
    the other cells are grouped in square blocks of side ``pi rho_min / (2 sqrt 2)``, a
    quarter turn of the tightest curl ``rho_min = h / (1 - R_min)`` on the diagonal (at least
    one cell). A vertex takes the patch of the first cell it belongs to.
    """
    from scipy import ndimage

    check_instance("design", design, Design)
    mesh = design.mesh
    ij = mesh.cell_ij
    nx, ny = ij.max(axis=0) + 1
    rigid = design.material == Material.RIGID
    grid = np.zeros((nx, ny), bool)
    grid[ij[rigid, 0], ij[rigid, 1]] = True
    labels, n_rigid = ndimage.label(grid)
    free = ~rigid
    shrink = float((1.0 - design.R[free]).max()) if free.any() else 0.0
    if shrink > 0.0:
        side = np.pi * (design.h / shrink) / (2.0 * np.sqrt(2.0))
        block = max(1, int(side // max(float(mesh.spacing[0]), float(mesh.spacing[1]))))
    else:
        block = max(nx, ny)
    bi, bj = ij[:, 0] // block, ij[:, 1] // block
    cell_patch = np.where(rigid, labels[ij[:, 0], ij[:, 1]],
                          n_rigid + 1 + bi * (ny // block + 1) + bj)
    patch = np.empty(mesh.n_points, np.int64)
    cells = mesh.cells[::-1]  # written last wins: the first cell of each vertex
    patch[cells.ravel()] = np.repeat(cell_patch[::-1], 8)
    return patch


def _inside(X, lo, hi, margin):
    """Whether every row of ``X`` lies in the box ``[lo - margin, hi + margin]`` of its own row."""
    return bool(np.all(X >= lo - margin) and np.all(X <= hi + margin))


def barrier(d, dhat):
    """The barrier ``b(d) = -(d^2 - dhat^2)^2 ln(d^2 / dhat^2)`` for ``0 < d < dhat``, 0 beyond [mm^4].

    The function ipctk's ``BarrierPotential`` sums (with its stiffness); here for tests and
    for :func:`default_stiffness`.
    """
    d = np.asarray(d, float)
    x, xh = d * d, dhat * dhat
    with np.errstate(divide="ignore", invalid="ignore"):
        out = -(x - xh) ** 2 * np.log(x / xh)
    return np.where(d < dhat, out, 0.0)


def _barrier_curvature(d, dhat):
    """``d^2 b / d d^2`` of :func:`barrier` at ``0 < d < dhat`` [mm^2]."""
    x, xh = d * d, dhat * dhat
    lg = np.log(x / xh)
    f1 = -2.0 * (x - xh) * lg - (x - xh) ** 2 / x
    f2 = -2.0 * lg - 4.0 * (x - xh) / x + (x - xh) ** 2 / x ** 2
    return f2 * 4.0 * x + 2.0 * f1


def default_stiffness(design, dhat):
    """The barrier stiffness ``kappa`` [mm]: one pair at ``dhat / 2`` as stiff as a boundary vertex.

    ``kappa b''(dhat / 2) = STIFFNESS_SCALE * mean(2 L_vv)`` over the boundary vertices,
    ``L`` the assembled matrix of Eq. 5 (:func:`gdfe.solver.system_matrix`).
    """
    surf = np.unique(surface_triangles(design)[0])
    Lvv = system_matrix(design).diagonal()[surf]
    return float(STIFFNESS_SCALE * 2.0 * Lvv.mean() / _barrier_curvature(0.5 * dhat, dhat))


@dataclasses.dataclass(frozen=True)
class ContactReport:
    """Whether and how a result used self-contact (:attr:`gdfe.Result.contact`).

    Attributes
    ----------
    mode : {"auto", "on", "off"}
        The ``contact=`` the solve was asked for.
    used : bool
        Whether the returned shape was solved with contact.
    available : bool
        Whether the IPC Toolkit is installed.
    reason : str
        Why contact was used (or needed and not available); empty otherwise.
    dhat_mm, stiffness : float or None
        The barrier's gap [mm] and stiffness, when contact was used.
    pairs : int
        Surface pairs within the gap in the final shape (0: nothing touches).
    barrier_energy : float
        The barrier's part of the final energy [mm^5].
    """

    mode: str
    used: bool
    available: bool
    reason: str = ""
    dhat_mm: float | None = None
    stiffness: float | None = None
    pairs: int = 0
    barrier_energy: float = 0.0

    def as_dict(self) -> dict:
        return {"mode": self.mode, "used": bool(self.used), "available": bool(self.available), "reason": self.reason,
                "dhat_mm": self.dhat_mm, "stiffness": self.stiffness, "pairs": int(self.pairs),
                "barrier_energy": float(self.barrier_energy)}


@dataclasses.dataclass(frozen=True, eq=False)
class ContactState:
    """The contact term at one shape: its pairs within the gap and its energy.

    Attributes
    ----------
    points : (s, 3) float array [mm]
        The boundary vertices (Fortran order, as ipctk takes them).
    collisions : ipctk.NormalCollisions
        The surface pairs closer than ``dhat``.
    energy : float
        ``B`` at this shape [mm^5].
    min_distance : float
        Smallest distance between the pairs within the gap [mm] (inf when there is none:
        every pair of the surface that shares no vertex is at least ``dhat`` apart).
    """

    points: np.ndarray
    collisions: object
    energy: float
    min_distance: float

    @property
    def active(self) -> int:
        """Number of surface pairs within the gap."""
        return len(self.collisions)


class Contact:
    """The self-contact term of one design: barrier energy, gradient, Hessian and CCD.

    Parameters
    ----------
    design : Design
    dhat : float, optional
        Gap [mm] below which surfaces repel (default :func:`default_dhat`).
    stiffness : float, optional
        Barrier stiffness ``kappa`` (default :func:`default_stiffness`).

    Attributes
    ----------
    dhat, stiffness : float
        (``stiffness`` is made on first use: a :class:`Contact` that only tests for crossings,
        :meth:`crosses`, never needs it.)
    surface : (s,) int array
        The boundary vertices, indices into the mesh's points.
    mesh : ipctk.CollisionMesh
        The boundary surface (its own vertex numbering, ``surface`` order), whose pairs
        within one patch are skipped.
    patches : (s,) int array
        The patch of every surface vertex (:func:`contact_patches`).
    timings : dict
        Seconds spent in the barrier (``"barrier"``) and in collision detection (``"ccd"``,
        the step's candidates included).

    Raises
    ------
    GdfeError
        If ``ipctk`` is not installed.

    Notes
    -----
    Making a :class:`Contact` sets ipctk to :data:`CONTACT_THREADS` thread(s): its parallel
    sums over pairs run in an order that changes from run to run, and where the film meets
    itself that round-off can decide which way it goes; with one thread every contact solve
    repeats exactly.
    """

    def __init__(self, design, dhat=None, stiffness=None):
        ipctk = require_ipctk()
        check_instance("design", design, Design)
        self.design = design
        self.dhat = default_dhat(design) if dhat is None else float(check_positive("dhat", dhat))
        self._stiffness = None if stiffness is None else float(check_positive("stiffness", stiffness))
        tris, _ = surface_triangles(design)
        self.surface = np.flatnonzero(np.bincount(tris.ravel(), minlength=design.mesh.n_points))  # np.unique, 30 x faster
        remap = np.full(design.mesh.n_points, -1)
        remap[self.surface] = np.arange(self.surface.size)
        faces = np.asfortranarray(remap[tris], dtype=np.int32)
        edges = np.asfortranarray(ipctk.edges(faces), dtype=np.int32)
        self.mesh = ipctk.CollisionMesh(np.asfortranarray(design.mesh.points[self.surface]), edges, faces)
        self.patches = contact_patches(design)[self.surface]
        self.mesh.can_collide = ipctk.make_vertex_patches_filter(np.ascontiguousarray(self.patches, dtype=np.int32))
        self.n = design.mesh.n_points
        self._dofs = (3 * self.surface[:, None] + np.arange(3)).ravel()
        self._ipctk = ipctk
        self._ccd = ipctk.TightInclusionCCD(*CCD_TIGHT_INCLUSION)
        ipctk.set_num_threads(CONTACT_THREADS)  # see Notes
        self.timings = {"barrier": 0.0, "ccd": 0.0}
        self._swept = None  # (lo, hi, candidates) of the last step that ran the narrow phase
        self._primitives = self.surface.size + edges.shape[0] + faces.shape[0]

    @functools.cached_property
    def stiffness(self) -> float:
        """Barrier stiffness ``kappa`` (the one given, else :func:`default_stiffness`; made on first use)."""
        return default_stiffness(self.design, self.dhat) if self._stiffness is None else self._stiffness

    @functools.cached_property
    def potential(self):
        """ipctk's ``BarrierPotential`` with :attr:`dhat` and :attr:`stiffness` (made on first use)."""
        return self._ipctk.BarrierPotential(self.dhat, self.stiffness)

    def _surface_points(self, V):
        return np.asfortranarray(np.asarray(V, float)[self.surface])

    def evaluate(self, V) -> ContactState:
        """The contact term at the shape ``V`` ``(n, 3)`` [mm] (inf where surfaces cross or touch)."""
        t0 = time.perf_counter()
        X = self._surface_points(V)
        col = self._ipctk.NormalCollisions()
        swept = self._swept
        if swept is not None and _inside(X, swept[0], swept[1], (SWEEP_INFLATION - 0.5) * self.dhat):
            col.build(swept[2], self.mesh, X, self.dhat)  # the step's candidates (module docstring)
        else:
            col.build(self.mesh, X, self.dhat)
        E, dmin = 0.0, np.inf
        if len(col):
            dmin = float(np.sqrt(max(col.compute_minimum_distance(self.mesh, X), 0.0)))
            E = float(self.potential(col, self.mesh, X)) if dmin > 0.0 else np.inf
            if not np.isfinite(E):
                E = np.inf
        self.timings["barrier"] += time.perf_counter() - t0
        return ContactState(points=X, collisions=col, energy=E, min_distance=dmin)

    def gradient(self, state) -> np.ndarray:
        """``dB/dV`` ``(n, 3)`` [mm^4] at ``state`` (zero rows off the surface)."""
        out = np.zeros((self.n, 3))
        if state.active:
            t0 = time.perf_counter()
            g = self.potential.gradient(state.collisions, self.mesh, state.points)
            out[self.surface] = np.asarray(g).reshape(-1, 3)
            self.timings["barrier"] += time.perf_counter() - t0
        return out

    def hessian(self, state, project=True):
        """The Hessian of ``B`` (3n x 3n CSR, vertex-major ``3 v + c``), or None when no pair is active.

        With ``project``, each pair's Hessian is projected onto the positive semi-definite
        cone (its negative eigenvalues clamped to zero) before it is summed; without, the
        exact Hessian.
        """
        if not state.active:
            return None
        t0 = time.perf_counter()
        proj = self._ipctk.PSDProjectionMethod.CLAMP if project else self._ipctk.PSDProjectionMethod.NONE
        H = self.potential.hessian(state.collisions, self.mesh, state.points, proj).tocoo()
        out = sp.csr_matrix((H.data, (self._dofs[H.row], self._dofs[H.col])), shape=(3 * self.n, 3 * self.n))
        self.timings["barrier"] += time.perf_counter() - t0
        return out

    def max_step(self, V0, V1, state=None) -> float:
        """The largest fraction in [0, 1] of the straight move ``V0 -> V1`` in which no face crosses another.

        Continuous collision detection of every vertex-triangle and edge-edge pair the moving
        surface sweeps: ipctk's broad phase and its Tight-Inclusion narrow phase with the
        settings :data:`CCD_TIGHT_INCLUSION`, which returns a time of first contact that is
        never late (at the iteration limit, a lower bound) and stops at 0.8 of it. With ``state``, the contact
        term at ``V0``, a move whose largest vertex displacement ``delta`` satisfies
        ``2 delta < `` the smallest gap (``state.min_distance``, at least ``dhat``) is
        taken whole without it: no two points of the surface can come closer by more than
        ``2 delta``. Otherwise the step's candidates (the boxes swept from ``V0`` to ``V1``,
        grown by :data:`SWEEP_INFLATION` ``dhat``) are kept for :meth:`evaluate` on the step
        while they are few (:data:`SWEEP_REUSE`).
        """
        X0, X1 = self._surface_points(V0), self._surface_points(V1)
        self._swept = None
        if state is not None:
            delta = float(np.sqrt(np.max(np.sum((X1 - X0) ** 2, axis=1))))
            if 2.0 * delta < min(state.min_distance, self.dhat):
                return 1.0
        t0 = time.perf_counter()
        cands = self._ipctk.Candidates()
        cands.build(self.mesh, X0, X1, SWEEP_INFLATION * self.dhat)
        a = float(cands.compute_collision_free_stepsize(self.mesh, X0, X1, narrow_phase_ccd=self._ccd))
        if len(cands) <= SWEEP_REUSE * self._primitives:
            self._swept = (np.minimum(X0, X1), np.maximum(X0, X1), cands)
        self.timings["ccd"] += time.perf_counter() - t0
        return a

    def crosses(self, V) -> bool:
        """Whether the boundary surface of the shape ``V`` ``(n, 3)`` [mm] crosses itself (the IPC Toolkit's test).

        Pairs within one patch (:func:`contact_patches`) are not tested. A yes or no does not
        depend on the order of a parallel search: the test runs on the solver's threads
        (:func:`gdfe.solver.threads.workers`) (0.72 -> 0.35 s on the 10^5-cell twist, 2 cores), the contact terms on
        :data:`CONTACT_THREADS`.
        """
        X = self._surface_points(V)
        self._ipctk.set_num_threads(workers())
        try:
            return bool(self._ipctk.has_intersections(self.mesh, X))
        finally:
            self._ipctk.set_num_threads(CONTACT_THREADS)

    def is_clear(self, V) -> bool:
        """Whether the shape ``V`` has no crossing or touching surfaces (a start the barrier accepts)."""
        if self.crosses(check_array("V", V, shape=(self.n, 3))):
            return False
        return bool(np.isfinite(self.evaluate(V).energy))

