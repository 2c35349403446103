"""Target surfaces of 2-D inverse design: analytic ones and triangle meshes, placed on the film.

The film shrinks isotropically in its plane, so the mid-surface of a folded film is, cell by
cell, a scaled copy of the flat print: its metric is ``lambda(p)^2 (dx^2 + dy^2)`` with
``lambda = 1 - c_mid``, where ``c_mid`` is the mean of the two faces' contractions. A target
surface is therefore described through *conformal coordinates* ``u`` (mm): a map ``X(u)`` onto
the surface whose metric is ``f(u)^2 |du|^2``. The film point ``p`` (mm, from the film's centre)
goes to ``u = sigma p``, so the fold must contract its mid-surface by ``1 - sigma f(sigma p)``,
and bend with the surface's second fundamental form. Every surface has conformal coordinates;
the analytic targets use closed forms:

- ``dome``: a sphere of radius ``R`` (default the film's size) through stereographic coordinates,
  ``X = (4R^2 u, 2R |u|^2) / (4R^2 + |u|^2)``, ``f = 4R^2 / (4R^2 + |u|^2)``, bending towards the top face;
- ``saddle``: Enneper's minimal surface scaled to the principal radii ``+-R`` at its centre
  (to leading order ``z = (x^2 - y^2) / (2R)``), ``f = 1 + |u|^2 / A^2`` with ``A = 2R``;
- ``cylinder``: radius ``R`` about an axis along y (default half the film's size), ``f = 1``;
- ``twist``: a helicoid strip about x twisting by ``angle`` (default pi) along the folded strip,
  ``X = (v_1, sinh v_2 cos v_1, sinh v_2 sin v_1) / tau`` with ``v = tau u``, ``f = cosh(tau u_2)``;
  the film is a strip ``size x width`` (default ``width = size / 4``).

For an analytic target the scale ``sigma`` is chosen by the design (:func:`gdfe.inverse2d.scale_for`):
the patch of the surface the film covers is the image of the film. A triangle mesh (OBJ, STL,
PLY; :func:`load_target`) is a fixed patch: it is flattened by least-squares conformal maps
(Levy et al. 2002, written here from its equations), its flat outline becomes the film's
outline scaled to the film's size, and ``sigma`` follows from that size.

Lengths in mm, angles in rad.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from gdfe._validation import GdfeError, check_array, check_choice, check_file, check_number, check_positive
from gdfe.physical_ranges import MAX_CONTRACTION

__all__ = ["Target", "ANALYTIC", "MESH_SUFFIXES", "dome", "saddle", "cylinder", "twist", "mesh_target",
           "load_target", "make_target", "read_triangle_mesh", "conformal_flattening"]

#: The analytic targets, by name.
ANALYTIC = ("dome", "saddle", "cylinder", "twist")
#: Triangle-mesh files a target may be read from.
MESH_SUFFIXES = (".obj", ".stl", ".ply")

_FD = 1e-4  # relative step of the numerical derivatives of a map, times the film's size


@dataclasses.dataclass(frozen=True, eq=False)
class Target:
    """A target surface with conformal coordinates, and the film that is to fold into it.

    Attributes
    ----------
    name : str
    kind : str
        ``"dome"``, ``"saddle"``, ``"cylinder"``, ``"twist"`` or ``"mesh"``.
    film_size : (2,) float array [mm]
        The film's flat rectangle (x, y), centred at the origin (its bounding box, for a mesh).
    params : dict
        The surface's parameters (``radius_mm``, ``angle_rad``, ...), for reports.
    maps : callable
        ``maps(sigma) -> (surface, factor)``: ``surface(u)`` takes conformal coordinates
        ``(k, 2)`` [mm] to points ``(k, 3)`` [mm], ``factor(u)`` is its metric factor ``f``
        ``(k,)`` (``|dX| = f |du|``). Only the twist depends on ``sigma`` (its angle is over
        the folded strip).
    curvature : callable or None
        ``curvature(u)``: the second fundamental form per unit length, ``(k, 2, 2)`` [1/mm],
        in the frame of the film's axes, positive where the surface bends towards the film's
        top face; None: from the surface by central differences.
    sigma : float or None
        Scale from film to conformal coordinates, ``u = sigma p``, where the target fixes it
        (a mesh); None: the design chooses it (:func:`gdfe.inverse2d.scale_for`).
    film_mask : callable or None
        ``film_mask(p)`` ``(k, 2)`` -> bool: where the film is (a mesh's outline); None: the rectangle.
    family : callable or None
        ``family(t)``: the same kind of target with its curvature scaled by ``t`` (a dome of
        radius ``R / t``), for the closest reachable target; None for a mesh.
    source : str
        Where it came from (a file, or the formula).
    note : str
        What is known to limit the fold of this kind of target (said with a design that misses it).
    """

    name: str
    kind: str
    film_size: np.ndarray
    params: dict
    maps: object
    curvature: object = None
    sigma: float | None = None
    film_mask: object = None
    family: object = None
    source: str = ""
    note: str = ""

    def point(self, p, sigma):
        """Target points ``(k, 3)`` [mm] of film points ``p`` ``(k, 2)`` [mm] at scale ``sigma``."""
        return self.maps(sigma)[0](sigma * np.asarray(p, float))

    def metric_factor(self, p, sigma):
        """``lambda = sigma f(sigma p)`` ``(k,)``: the mid-surface's length ratio, fold to film, at ``p``."""
        return sigma * self.maps(sigma)[1](sigma * np.asarray(p, float))

    def second_form(self, p, sigma):
        """Second fundamental form per unit length of the target at film points ``p``, ``(k, 2, 2)`` [1/mm].

        In the frame of the film's axes (the conformal frame is a rotation and scaling of it),
        positive where the surface bends towards the film's top face.
        """
        u = sigma * np.asarray(p, float)
        if self.curvature is not None:
            return self.curvature(u)
        return _second_form(self.maps(sigma)[0], u, _FD * float(np.max(self.film_size)))

    def summary(self) -> dict:
        return {"name": self.name, "kind": self.kind, "film_mm": [float(v) for v in self.film_size],
                "params": dict(self.params), "source": self.source}


def _second_form(surface, u, eps):
    """``II / f^2`` by central differences of ``surface`` at ``u`` ``(k, 2)`` -> ``(k, 2, 2)``."""
    ex, ey = np.array([eps, 0.0]), np.array([0.0, eps])
    X0 = surface(u)
    Xu = (surface(u + ex) - surface(u - ex)) / (2 * eps)
    Xv = (surface(u + ey) - surface(u - ey)) / (2 * eps)
    n = np.cross(Xu, Xv)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    Xuu = (surface(u + ex) - 2 * X0 + surface(u - ex)) / eps**2
    Xvv = (surface(u + ey) - 2 * X0 + surface(u - ey)) / eps**2
    Xuv = (surface(u + ex + ey) - surface(u + ex - ey) - surface(u - ex + ey) + surface(u - ex - ey)) / (4 * eps**2)
    f2 = 0.5 * (np.einsum("ij,ij->i", Xu, Xu) + np.einsum("ij,ij->i", Xv, Xv))
    II = np.empty((len(u), 2, 2))
    II[:, 0, 0] = np.einsum("ij,ij->i", Xuu, n) / f2
    II[:, 1, 1] = np.einsum("ij,ij->i", Xvv, n) / f2
    II[:, 0, 1] = II[:, 1, 0] = np.einsum("ij,ij->i", Xuv, n) / f2
    return II


def _film(size, width=None):
    size = check_positive("size", size)
    w = size if width is None else check_positive("width", width)
    return np.array([size, w], float)


def _fixed(surface, factor):
    return lambda sigma: (surface, factor)


def dome(size, radius=None):
    """A spherical cap of radius ``radius`` [mm] (default ``size``), for a square film of side ``size`` [mm]."""
    film = _film(size)
    R = float(film[0] if radius is None else check_positive("radius", radius))

    def surface(u):
        q = np.einsum("ij,ij->i", u, u)
        den = 4 * R * R + q
        return np.column_stack([4 * R * R * u / den[:, None], 2 * R * q / den])

    def factor(u):
        return 4 * R * R / (4 * R * R + np.einsum("ij,ij->i", u, u))

    def curvature(u):
        return np.broadcast_to(np.eye(2) / R, (len(u), 2, 2)).copy()

    return Target(name="dome", kind="dome", film_size=film, params={"radius_mm": R}, maps=_fixed(surface, factor),
                  curvature=curvature, family=lambda t: dome(film[0], R / t),
                  source=f"sphere of radius {R:g} mm (stereographic coordinates)")


def saddle(size, radius=None):
    """Enneper's surface with principal radii ``+-radius`` [mm] at its centre (default ``size``); square film."""
    film = _film(size)
    R = float(film[0] if radius is None else check_positive("radius", radius))
    A = 2.0 * R

    def surface(u):
        a, b = u[:, 0] / A, u[:, 1] / A
        return A * np.column_stack([a - a**3 / 3 + a * b * b, b - b**3 / 3 + a * a * b, a * a - b * b])

    def factor(u):
        return 1.0 + np.einsum("ij,ij->i", u, u) / (A * A)

    return Target(name="saddle", kind="saddle", film_size=film, params={"radius_mm": R},
                  maps=_fixed(surface, factor), family=lambda t: saddle(film[0], R / t),
                  source=f"Enneper's minimal surface, principal radii +-{R:g} mm at its centre")


def cylinder(size, radius=None):
    """A cylinder of radius ``radius`` [mm] (default ``size / 2``) about an axis along y; square film."""
    film = _film(size)
    R = float(0.5 * film[0] if radius is None else check_positive("radius", radius))

    def surface(u):
        return np.column_stack([R * np.sin(u[:, 0] / R), u[:, 1], R * (1 - np.cos(u[:, 0] / R))])

    def factor(u):
        return np.ones(len(u))

    def curvature(u):
        out = np.zeros((len(u), 2, 2))
        out[:, 0, 0] = 1.0 / R
        return out

    return Target(name="cylinder", kind="cylinder", film_size=film, params={"radius_mm": R},
                  maps=_fixed(surface, factor), curvature=curvature, family=lambda t: cylinder(film[0], R / t),
                  source=f"cylinder of radius {R:g} mm, axis along y")


def twist(size, angle=None, width=None):
    """A helicoid strip: a film ``size x width`` [mm] (default ``width = size / 4``) twisting by ``angle``
    [rad] (default pi) about its length, end to end."""
    size = check_positive("size", size)
    film = _film(size, 0.25 * size if width is None else width)
    theta = float(math.pi if angle is None else check_number("angle", angle, minimum=0.0, include_minimum=False,
                                                            what="a positive angle in rad"))
    _check_twist_metric(theta, *film)

    def maps(sigma):
        tau = theta / (sigma * film[0])  # per mm of the folded strip: the angle is end to end

        def surface(u):
            v1, v2 = tau * u[:, 0], tau * u[:, 1]
            return np.column_stack([v1, np.sinh(v2) * np.cos(v1), np.sinh(v2) * np.sin(v1)]) / tau

        def factor(u):
            return np.cosh(tau * u[:, 1])

        return surface, factor

    return Target(name="twist", kind="twist", film_size=film, params={"angle_rad": theta, "width_mm": float(film[1])},
                  maps=maps, family=lambda t: twist(size, theta * t, film[1]),
                  source=f"helicoid strip twisting by {theta:g} rad end to end", note=TWIST_NOTE)


def _check_twist_metric(theta, length, width):
    """Refuse a twist no shrink film can reach: its edges longer than its middle line by more than any film shrinks.

    In the film's conformal coordinates the helicoid's length ratio is ``cosh(theta y / length)``
    at ``y`` across the strip, whatever the scale; isotropic shrink gives at most
    ``1 / (1 - MAX_CONTRACTION)`` (:data:`gdfe.physical_ranges.MAX_CONTRACTION`).
    """
    a = 0.5 * theta * width / length
    ratio = math.cosh(a) if a < 700.0 else math.inf
    needs = f"{ratio:.3g} times" if math.isfinite(ratio) else "more than 1e300 times"
    limit = 1.0 / (1.0 - MAX_CONTRACTION)
    if ratio <= limit:
        return
    largest = 2.0 * math.acosh(limit) * length / width
    hint = (f"; {theta:g} degrees is {math.radians(theta):.4g} rad" if math.radians(theta) <= largest else "")
    raise GdfeError(f"angle: a twist of {theta:g} rad end to end of a {length:g} x {width:g} mm strip needs its "
                    f"edges {needs} as long as its middle line (cosh(angle x width / (2 x length)), the "
                    f"film's conformal coordinates), and a shrink film gives at most {limit:.3g} (a free shrink of "
                    f"{MAX_CONTRACTION:.0%}); expected at most {largest:.4g} rad for this strip{hint}")


#: Why a twist is beyond isotropic shrink (measured by ``gdfe study inverse2d``).
TWIST_NOTE = ("a helicoid's curvature is a pure twist (zero mean curvature) and isotropic shrink bends a cell alike "
              "in every direction: the placement's estimate, both faces alike, folds untwisted, and the twist has to "
              "come from one-sided coats varying over the strip, which a strip narrow for its thickness resists (the "
              "distance falls with the strip's size: gdfe study inverse2d)")


#: The analytic target builders, by name: ``builder(size, **params)``.
_BUILDERS = {"dome": dome, "saddle": saddle, "cylinder": cylinder, "twist": twist}


def make_target(target, size, radius=None, angle=None, width=None):
    """A :class:`Target` from a name (:data:`ANALYTIC`) or the path of a triangle mesh.

    Parameters
    ----------
    target : str or Path
        ``"dome"``, ``"saddle"``, ``"cylinder"``, ``"twist"``, or an OBJ/STL/PLY file.
    size : float [mm]
        The film's size: the side of the square film, the length of the twist's strip, the
        largest side of a mesh's flattened outline.
    radius : float [mm], optional
        Dome, saddle, cylinder: the radius of curvature.
    angle : float [rad], optional
        Twist: the angle end to end.
    width : float [mm], optional
        Twist: the strip's width.
    """
    if isinstance(target, str) and target in _BUILDERS:
        kw = {"dome": {"radius": radius}, "saddle": {"radius": radius}, "cylinder": {"radius": radius},
              "twist": {"angle": angle, "width": width}}[target]
        unused = [k for k, v in (("radius", radius), ("angle", angle), ("width", width)) if v is not None and k not in kw]
        if unused:
            raise GdfeError(f"{unused[0]}: not a parameter of the {target} target (it takes "
                            f"{', '.join(kw) or 'none'})")
        return _BUILDERS[target](size, **kw)
    if isinstance(target, (str, Path)) and Path(target).suffix.lower() in MESH_SUFFIXES:
        for k, v in (("radius", radius), ("angle", angle), ("width", width)):
            if v is not None:
                raise GdfeError(f"{k}: a mesh target has no parameters, got {k}={v:g}")
        return load_target(target, size)
    raise GdfeError(f"target: expected one of {', '.join(repr(a) for a in ANALYTIC)} or a triangle mesh "
                    f"({'/'.join(s[1:].upper() for s in MESH_SUFFIXES)}), got {target!r}")


# -- triangle meshes ------------------------------------------------------------------------------------------
def read_triangle_mesh(path):
    """Vertices ``(n, 3)`` and triangles ``(t, 3)`` of an OBJ, STL or PLY file (through meshio).

    Quadrilaterals are split; duplicated vertices (an STL's) are merged.
    """
    path = check_file("target", path, suffixes=MESH_SUFFIXES, what="triangle mesh")
    from gdfe.io import read_mesh

    mesh = read_mesh(path, "a readable triangle mesh")
    tris = []
    for block in mesh.cells:
        if block.type == "triangle":
            tris.append(block.data)
        elif block.type == "quad":
            q = block.data
            tris += [q[:, [0, 1, 2]], q[:, [0, 2, 3]]]
    if not tris:
        raise GdfeError(f"{path.name}: expected triangles, got {', '.join(b.type for b in mesh.cells) or 'no cells'}")
    V = check_array(f"{path.name}: vertices", np.asarray(mesh.points, float)[:, :3], shape=(-1, 3))
    T = np.concatenate(tris).astype(np.int64)
    # merge coincident vertices (an STL stores every triangle's corners)
    scale = float(np.ptp(V, axis=0).max()) or 1.0
    key = np.round(V / (1e-9 * scale)).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    V, T = V[first], inverse.ravel()[T]
    T = T[(T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 0] != T[:, 2])]
    used = np.unique(T)
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    return V[used], remap[T]


def _cross2(a, b):
    """The z component of the cross product of 2-D vectors ``(k, 2)``."""
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def _boundary_edges(T):
    """Directed boundary edges ``(b, 2)`` of a triangle mesh (edges used by one triangle)."""
    E = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    key = np.sort(E, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return E[counts[inv.ravel()] == 1]


def conformal_flattening(V, T):
    """Least-squares conformal map of a disc-like triangle mesh to the plane (Levy et al. 2002).

    Minimises ``sum_t A_t |grad u_2 - rot90(grad u_1)|^2``, the departure of the map from a
    conformal one, over the flat coordinates ``u`` with two boundary vertices held (the two
    farthest apart); the result is scaled to the mesh's area and turned so that its principal
    axes are the coordinate axes.

    Returns
    -------
    (n, 2) float array [mm]
        Flat coordinates of every vertex, with the orientation of the triangles kept.
    """
    V = np.asarray(V, float)
    T = np.asarray(T)
    n = len(V)
    B = _boundary_edges(T)
    if len(B) == 0:
        raise GdfeError("target: expected a surface patch with a boundary (a disc), got a closed surface")
    # local orthonormal frame of every triangle
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    e1 = b - a
    nrm = np.cross(e1, c - a)
    area2 = np.linalg.norm(nrm, axis=1)
    if np.any(area2 <= 1e-14 * float(np.max(area2))):
        raise GdfeError("target: the mesh has degenerate (zero-area) triangles")
    x1 = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
    y1 = np.cross(nrm / area2[:, None], x1)
    P = np.stack([np.zeros((len(T), 2)),
                  np.column_stack([np.einsum("ij,ij->i", b - a, x1), np.zeros(len(T))]),
                  np.column_stack([np.einsum("ij,ij->i", c - a, x1), np.einsum("ij,ij->i", c - a, y1)])], axis=1)
    # W_j = (x_{j+2} - x_{j+1}) + i (y_{j+2} - y_{j+1}); row t of the complex system: sum_j W_j U_j / sqrt(2A)
    W = np.stack([P[:, (j + 2) % 3] - P[:, (j + 1) % 3] for j in range(3)], axis=1)
    s = 1.0 / np.sqrt(area2)  # 1 / sqrt(2 A)
    Wr, Wi = W[..., 0] * s[:, None], W[..., 1] * s[:, None]
    rows = np.repeat(np.arange(len(T)), 3)
    cols = T.ravel()
    Mr = sp.csr_matrix((Wr.ravel(), (rows, cols)), shape=(len(T), n))
    Mi = sp.csr_matrix((Wi.ravel(), (rows, cols)), shape=(len(T), n))
    # real form of M U = 0 with U = u1 + i u2: [Mr -Mi; Mi Mr] [u1; u2]
    A = sp.bmat([[Mr, -Mi], [Mi, Mr]]).tocsc()
    bv = np.unique(B)
    D = np.linalg.norm(V[bv][:, None] - V[bv][None], axis=2) if len(bv) <= 4000 else None
    if D is not None:
        i0, i1 = np.unravel_index(np.argmax(D), D.shape)
        p0, p1 = bv[i0], bv[i1]
    else:
        p0 = bv[0]
        p1 = bv[int(np.argmax(np.linalg.norm(V[bv] - V[p0], axis=1)))]
    pinned = np.array([p0, p1, p0 + n, p1 + n])
    dist = float(np.linalg.norm(V[p1] - V[p0]))
    values = np.array([0.0, dist, 0.0, 0.0])
    free = np.setdiff1d(np.arange(2 * n), pinned)
    rhs = -A[:, pinned] @ values
    Af = A[:, free]
    from scipy.sparse.linalg import spsolve

    x = np.zeros(2 * n)
    x[pinned] = values
    x[free] = spsolve((Af.T @ Af).tocsc(), Af.T @ rhs)
    U = np.column_stack([x[:n], x[n:]])
    # orientation: the flat triangles must keep the mesh's orientation
    ua, ub, uc = U[T[:, 0]], U[T[:, 1]], U[T[:, 2]]
    signed = _cross2(ub - ua, uc - ua)
    if np.sum(signed) < 0:
        U[:, 1] = -U[:, 1]
        signed = -signed
    if np.any(signed <= 0):
        raise GdfeError(f"target: the conformal flattening folds {int(np.sum(signed <= 0))} triangles over; "
                        "expected a disc-like patch without very thin triangles")
    scale = math.sqrt(0.5 * float(area2.sum()) / (0.5 * float(signed.sum())))
    U = (U - U.mean(axis=0)) * scale
    _, _, Vt = np.linalg.svd(U - U.mean(axis=0), full_matrices=False)
    if np.linalg.det(Vt) < 0:
        Vt[1] = -Vt[1]
    return U @ Vt.T


class _Interpolant:
    """Barycentric interpolation of vertex values over a flat triangle mesh (nearest triangle outside)."""

    def __init__(self, U, T):
        from scipy.spatial import cKDTree

        self.U, self.T = U, T
        self.tree = cKDTree(U[T].mean(axis=1))
        a, b, c = U[T[:, 0]], U[T[:, 1]], U[T[:, 2]]
        self.a = a
        M = np.stack([b - a, c - a], axis=2)  # (t, 2, 2): columns b - a, c - a
        self.Minv = np.linalg.inv(M)

    def locate(self, p, k=12):
        """Triangle ``(q,)`` and barycentric coordinates ``(q, 3)`` of points ``p`` ``(q, 2)``, and whether inside."""
        p = np.asarray(p, float)
        k = min(k, len(self.T))
        _, cand = self.tree.query(p, k=k)
        cand = cand.reshape(len(p), -1)
        vw = np.einsum("qkij,qkj->qki", self.Minv[cand], p[:, None, :] - self.a[cand])
        bary = np.concatenate([1.0 - vw.sum(axis=2, keepdims=True), vw], axis=2)
        worst = bary.min(axis=2)  # >= 0 inside
        j = np.argmax(worst, axis=1)
        rows = np.arange(len(p))
        tri = cand[rows, j]
        b = bary[rows, j]
        inside = worst[rows, j] >= -1e-9
        bc = np.clip(b, 0.0, None)
        bc /= bc.sum(axis=1, keepdims=True)
        return tri, np.where(inside[:, None], b, bc), inside

    def __call__(self, values, p):
        tri, b, _ = self.locate(p)
        vals = np.asarray(values)[self.T[tri]]  # (q, 3, ...)
        return np.einsum("qj,qj...->q...", b, vals)


def _vertex_areas(V, T):
    A = 0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]), axis=1)
    return np.bincount(T.ravel(), np.repeat(A / 3.0, 3), minlength=len(V)), A


def _mean_curvature(V, T, normals):
    """Mean curvature at every vertex from the cotangent Laplacian, positive towards ``normals``;
    boundary vertices take the mean of their interior neighbours'."""
    n = len(V)
    rows, cols, vals = [], [], []
    for j in range(3):
        i0, i1, i2 = T[:, j], T[:, (j + 1) % 3], T[:, (j + 2) % 3]
        e1, e2 = V[i1] - V[i0], V[i2] - V[i0]
        cot = np.einsum("ij,ij->i", e1, e2) / np.maximum(np.linalg.norm(np.cross(e1, e2), axis=1), 1e-300)
        rows += [i1, i2]
        cols += [i2, i1]
        vals += [cot, cot]
    L = sp.csr_matrix((np.concatenate(vals) * 0.5, (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    lap = L @ V - np.asarray(L.sum(axis=1)).ravel()[:, None] * V  # sum_j w_ij (x_j - x_i)
    area, _ = _vertex_areas(V, T)
    H = np.einsum("ij,ij->i", lap, normals) / (2.0 * np.maximum(area, 1e-300))
    bnd = np.zeros(n, bool)
    bnd[np.unique(_boundary_edges(T))] = True
    if bnd.any() and (~bnd).any():
        A = sp.csr_matrix((np.ones(3 * len(T) * 2), (np.concatenate([T[:, [0, 1, 2]].ravel(), T[:, [1, 2, 0]].ravel()]),
                                                     np.concatenate([T[:, [1, 2, 0]].ravel(), T[:, [0, 1, 2]].ravel()]))),
                          shape=(n, n))
        A.data[:] = 1.0
        inner = (~bnd).astype(float)
        for _ in range(3):  # the boundary's values from the interior, ring by ring
            s = A @ (H * inner)
            c = A @ inner
            take = bnd & (c > 0) & (inner == 0)
            H[take] = s[take] / c[take]
            inner[take] = 1.0
    return H


def mesh_target(V, T, size, name="mesh", source=""):
    """A :class:`Target` from a disc-like triangle mesh ``V`` ``(n, 3)`` [mm], ``T`` ``(t, 3)``.

    The mesh is flattened conformally (:func:`conformal_flattening`); the film is its flat
    outline scaled so that the outline's largest side is ``size`` [mm], which fixes ``sigma``.
    """
    size = check_positive("size", size)
    V = check_array("vertices", V, shape=(-1, 3), min_size=3)
    T = np.asarray(T, np.int64)
    if T.ndim != 2 or T.shape[1] != 3 or T.min() < 0 or T.max() >= len(V):
        raise GdfeError(f"triangles: expected a (t, 3) array of vertex indices, got shape {T.shape}")
    U = conformal_flattening(V, T)
    extent = np.ptp(U, axis=0)
    sigma = float(extent.max() / size)
    centre = 0.5 * (U.max(axis=0) + U.min(axis=0))
    U = U - centre
    interp = _Interpolant(U, T)
    area3, _ = _vertex_areas(V, T)
    area2, _ = _vertex_areas(np.column_stack([U, np.zeros(len(U))]), T)
    f_vertex = np.sqrt(area3 / np.maximum(area2, 1e-300))
    fn = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    vn = np.zeros_like(V)
    for j in range(3):
        np.add.at(vn, T[:, j], fn)
    vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-300)
    H = _mean_curvature(V, T, vn)

    def surface(u):
        return interp(V, u)

    def factor(u):
        return interp(f_vertex, u)

    def curvature(u):
        return np.einsum("q,ij->qij", interp(H, u), np.eye(2))

    def film_mask(p):
        return interp.locate(sigma * np.asarray(p, float))[2]

    film = extent / sigma
    return Target(name=name, kind="mesh", film_size=film, params={"vertices": int(len(V)), "triangles": int(len(T))},
                  maps=_fixed(surface, factor), curvature=curvature, sigma=sigma, film_mask=film_mask,
                  source=source or "triangle mesh")


def load_target(path, size):
    """A :class:`Target` from an OBJ, STL or PLY triangle mesh [mm] and the film's size [mm]."""
    from gdfe._validation import check_surface_mesh

    path = Path(path)
    V, T = read_triangle_mesh(path)
    check_surface_mesh(f"target {path.name}", V, T)
    return mesh_target(V, T, size, name=path.stem, source=str(path))
