"""Vectorised element kernels: small strain, and total Lagrangian with eigenstrain (neo-Hookean, the
default of :func:`reference_fem.solve_nonlinear`, or St Venant-Kirchhoff).

St Venant-Kirchhoff model (per quadrature point, reference gradient ``F = I + grad u``): the film's free
stretch ``F* = diag(1 + eps*)`` is split off multiplicatively, ``F = F_e F*``, so with
``G = F*^-1`` (diagonal) the elastic Green strain is

    E_e = (G F^T F G - I) / 2 = G E G + (G^2 - I) / 2,

the stored energy per reference volume is ``W = J* (lambda/2 tr(E_e)^2 + mu E_e:E_e)`` with
``J* = det F*``, and the first Piola stress is ``P = F S`` with ``S = J* G S_e G``,
``S_e = lambda tr(E_e) I + 2 mu E_e``. The consistent tangent is

    dP/dF = delta_ik S_JL + J* [lambda B_iJ B_kL + mu ((F G^2 F^T)_ik (G^2)_JL + B_iL B_kJ)],
    B = F G^2,

assembled per pair of basis functions with batched ``einsum`` contractions over the quadrature points.

Neo-Hookean model (the default): the same split ``F_e = F G``, with the energy and tangent
written in :func:`neohookean_state`.

Small-strain model: ``sigma = C : (eps(u) - eps*)``; its stiffness is the tangent above at
``F = G = I``, ``S = 0`` and its load is ``int grad(phi) : C : eps* dV``.

All loops run over chunks of elements; inside a chunk everything is one batched ``einsum`` /
``matmul``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from gdfe._validation import GdfeError

_ELEMENTS = {"hex1": ("ElementHex1", 2), "hex2": ("ElementHex2", 4), "hexs2": ("ElementHexS2", 4)}
_CHUNK_BUDGET = 4.0e6  # doubles per chunk for the (elements, qp, basis, basis) arrays


class Discretisation:
    """Basis data of a :class:`~reference_fem.mesh.LayeredStrip` for one element type.

    Attributes
    ----------
    X : (N, 3) float array [mm]
        Reference positions of the scalar degrees of freedom (nodes, and for quadratic elements
        edge, face and cell midpoints).
    dphi : (n_el, n_qp, n_bf, 3) float array [1/mm]
        Reference gradients of the scalar basis functions at the quadrature points.
    w : (n_el, n_qp) float array [mm^3]
        Quadrature weights times Jacobian.
    edofs : (n_el, n_bf) int array
        Scalar dofs of each element; vector dof ``3 * edofs + component``.
    """

    def __init__(self, strip, element="hex2"):
        import skfem

        if element not in _ELEMENTS:
            raise GdfeError(f"element: expected one of {', '.join(map(repr, sorted(_ELEMENTS)))}, got {element!r}")
        name, intorder = _ELEMENTS[element]
        basis = skfem.CellBasis(strip.mesh, getattr(skfem, name)(), intorder=intorder)
        self.element = element
        self.N = int(basis.N)
        self.X = np.ascontiguousarray(basis.doflocs.T)
        nbf = basis.Nbfun
        self.dphi = np.ascontiguousarray(
            np.stack([basis.basis[a][0].grad for a in range(nbf)]).transpose(2, 3, 0, 1)
        )
        self.w = np.ascontiguousarray(basis.dx)
        self.edofs = np.ascontiguousarray(basis.element_dofs.T)
        self.n_el, self.n_qp, self.n_bf = self.dphi.shape[:3]
        vdofs = (3 * self.edofs[:, :, None] + np.arange(3)).reshape(self.n_el, 3 * nbf)
        self.vdofs = vdofs
        n = 3 * nbf
        self._rows = np.repeat(vdofs, n, axis=1).ravel()
        self._cols = np.tile(vdofs, (1, n)).ravel()
        self._pattern = None
        self.chunk = max(1, int(_CHUNK_BUDGET // (self.n_qp * nbf * nbf)))

    @property
    def ndofs(self) -> int:
        return 3 * self.N

    def chunks(self):
        for s in range(0, self.n_el, self.chunk):
            yield slice(s, min(s + self.chunk, self.n_el))

    def sparse(self, Ke) -> sp.csr_matrix:
        """Assemble element matrices ``(n_el, 3 n_bf, 3 n_bf)`` into a global CSR matrix."""
        if self._pattern is None:
            # sorted unique (row, col) keys are the CSR order; remember where each entry goes
            keys = self._rows.astype(np.int64) * self.ndofs + self._cols
            uniq, inverse = np.unique(keys, return_inverse=True)
            rows = uniq // self.ndofs
            indptr = np.searchsorted(rows, np.arange(self.ndofs + 1))
            self._pattern = (inverse, (uniq % self.ndofs).astype(np.int32), indptr, uniq.size)
        inverse, indices, indptr, nnz = self._pattern
        data = np.bincount(inverse, weights=Ke.ravel(), minlength=nnz)
        return sp.csr_matrix((data, indices, indptr), shape=(self.ndofs, self.ndofs))

    def vector(self, fe) -> np.ndarray:
        """Assemble element vectors ``(n_el, n_bf, 3)`` into a global ``(3 N,)`` vector."""
        return np.bincount(self.vdofs.ravel(), weights=fe.reshape(self.n_el, -1).ravel(),
                           minlength=self.ndofs)


def element_fields(strip, material, disc, scale=1.0):
    """Per-element Lamé constants, inverse free stretch and volume ratio.

    Returns
    -------
    lam, mu : (n_el,) float arrays [MPa]
    G : (n_el, 3) float array
        ``1 / (1 + scale * eps*)`` in the film, 1 elsewhere.
    eps : (n_el, 3) float array
        ``scale * eps*`` in the film, 0 elsewhere.
    """
    from .mesh import FILM

    film = np.asarray(strip.ply) == FILM
    la, ma = material.lame("active")
    lp, mp = material.lame("passive")
    lam = np.where(film, la, lp)
    mu = np.where(film, ma, mp)
    eps = np.zeros((disc.n_el, 3))
    eps[film] = scale * np.asarray(material.eigenstrain_xyz)
    return lam, mu, 1.0 / (1.0 + eps), eps


def _bmm(X, Y):
    """``out[c] = X[c]^T Y[c]`` for stacks ``X (c, q, m)``, ``Y (c, q, n)``."""
    return np.einsum("cqx,cqy->cxy", X, Y, optimize=True)


def _tangent(dphi, w, F, S, g, lam, mu, jst):
    """Element tangent ``int grad(phi_a) . dP/dF . grad(phi_b) dV``: shape ``(c, a, 3, b, 3)``.

    With ``B = F G^2`` and ``V_ai = B_iJ dphi_aJ`` the material part is
    ``J* [lambda V_ai V_bk + mu (V_ak V_bi + (F G^2 F^T)_ik dphi_a . G^2 . dphi_b)]``; the
    geometric part is ``delta_ik dphi_a . S . dphi_b`` (omitted when ``S`` is None).
    """
    c, q, a = dphi.shape[:3]
    g2 = (g * g)[:, None, None, :]  # (c, 1, 1, 3)
    B = F * g2
    V = np.einsum("cqiJ,cqaJ->cqai", B, dphi).reshape(c, q, 3 * a)
    wj = w * jst[:, None]
    P = _bmm(V * wj[:, :, None], V).reshape(c, a, 3, a, 3)
    K = lam[:, None, None, None, None] * P + mu[:, None, None, None, None] * P.transpose(0, 1, 4, 3, 2)
    H = np.einsum("cqiM,cqkM->cqik", B, F).reshape(c, q, 9) * (wj * mu[:, None])[:, :, None]
    gab = np.einsum("cqaJ,cqbJ->cqab", dphi * g2, dphi).reshape(c, q, a * a)
    K += _bmm(H, gab).reshape(c, 3, 3, a, a).transpose(0, 3, 1, 4, 2)
    if S is not None:
        Sd = np.einsum("cqJL,cqbL->cqbJ", S * w[:, :, None, None], dphi)
        Kg = np.einsum("cqaJ,cqbJ->cab", dphi, Sd, optimize=True)
        for i in range(3):
            K[:, :, i, :, i] += Kg
    return K


def linear_system(disc, lam, mu, eps):
    """Small-strain stiffness and eigenstrain load.

    Returns
    -------
    K : (3N, 3N) csr_matrix [N/mm]
    f : (3N,) float array [N]
        ``int grad(phi) : C : eps* dV``: the equivalent nodal forces of the eigenstrain.
    """
    n = 3 * disc.n_bf
    Ke = np.empty((disc.n_el, n, n))
    fe = np.empty((disc.n_el, disc.n_bf, 3))
    for s in disc.chunks():
        dphi, w = disc.dphi[s], disc.w[s]
        c = dphi.shape[0]
        F = np.broadcast_to(np.eye(3), (c, disc.n_qp, 3, 3))
        Ke[s] = _tangent(dphi, w, F, None, np.ones((c, 3)), lam[s], mu[s], np.ones(c)).reshape(c, n, n)
        sig = lam[s][:, None] * eps[s].sum(axis=1)[:, None] + 2 * mu[s][:, None] * eps[s]  # diagonal
        fe[s] = np.einsum("cq,cqai,ci->cai", w, dphi, sig)
    return disc.sparse(Ke), disc.vector(fe)


def svk_state(disc, u, lam, mu, G, *, tangent=True):
    """Energy, internal force and (optionally) tangent of the eigenstrained SVK solid.

    Parameters
    ----------
    disc : Discretisation
    u : (3N,) float array [mm]
        Displacement, vector dof ``3 * dof + component``.
    lam, mu : (n_el,) float arrays [MPa]
    G : (n_el, 3) float array
        Inverse free stretch per element.
    tangent : bool
        Also assemble the tangent stiffness.

    Returns
    -------
    energy : float [N mm]
    f : (3N,) float array [N]
        Internal force ``int P : grad(phi) dV`` (the residual; there are no external loads).
    K : (3N, 3N) csr_matrix [N/mm] or None
    """
    return _state(disc, u, lam, mu, G, tangent, _svk_chunk)


def neohookean_state(disc, u, lam, mu, G, *, tangent=True):
    """Energy, internal force and (optionally) tangent of the eigenstrained neo-Hookean solid.

    ``psi(F_e) = mu/2 (F_e : F_e - 3) - mu ln J_e + lambda/2 (ln J_e)^2`` per unit volume of the
    stress-free (shrunk) state, so ``W = J* psi(F G)`` per reference volume and
    ``P = J* [mu (F_e - F_e^-T) + lambda ln J_e F_e^-T] G``. The tangent, with
    ``W_ai = (F_e^-T G grad phi_a)_i``, is
    ``J* [mu delta_ik (G grad phi_a).(G grad phi_b) + lambda W_ai W_bk + (mu - lambda ln J_e) W_ak W_bi]``.
    A configuration with ``J_e <= 0`` anywhere has infinite energy.

    Parameters and returns as :func:`svk_state`.
    """
    return _state(disc, u, lam, mu, G, tangent, _neohookean_chunk)


def _state(disc, u, lam, mu, G, tangent, chunk):
    """Energy, internal force and tangent of an eigenstrained solid, assembled chunk by chunk.

    ``chunk(dphi, w, F, lam, mu, g, jst, tangent)`` is the material law on one chunk of ``c``
    elements, with ``F = I + grad u`` of shape ``(c, n_qp, 3, 3)``, ``g`` the chunk's rows of ``G``
    and ``jst`` its ``J*``. It returns the chunk's energy, first Piola stress ``P`` ``(c, n_qp, 3, 3)``
    and element tangents ``(c, 3 n_bf, 3 n_bf)`` (None without ``tangent``), or None where the
    configuration is not admissible: then the energy is infinite, the force NaN and there is no tangent.
    """
    n = 3 * disc.n_bf
    U = u.reshape(-1, 3)
    Jst = np.prod(1.0 / G, axis=1)
    energy = 0.0
    fe = np.empty((disc.n_el, disc.n_bf, 3))
    Ke = np.empty((disc.n_el, n, n)) if tangent else None
    for s in disc.chunks():
        dphi, w = disc.dphi[s], disc.w[s]
        F = np.einsum("cai,cqaJ->cqiJ", U[disc.edofs[s]], dphi)
        F[..., 0, 0] += 1.0
        F[..., 1, 1] += 1.0
        F[..., 2, 2] += 1.0
        out = chunk(dphi, w, F, lam[s], mu[s], G[s], Jst[s], tangent)
        if out is None:
            return np.inf, np.full(disc.ndofs, np.nan), None
        e, P, K = out
        energy += e
        fe[s] = np.einsum("cq,cqiL,cqaL->cai", w, P, dphi)
        if tangent:
            Ke[s] = K
    return energy, disc.vector(fe), (disc.sparse(Ke) if tangent else None)


def _svk_chunk(dphi, w, F, lam, mu, g, jst, tangent):
    """The SVK law on one chunk of elements (see :func:`_state`)."""
    c, n = dphi.shape[0], 3 * dphi.shape[2]
    gg = (g[:, :, None] * g[:, None, :])[:, None]  # (c, 1, 3, 3): G_J G_L
    Ee = 0.5 * (gg * np.einsum("cqiJ,cqiL->cqJL", F, F) - np.eye(3))
    tr = np.trace(Ee, axis1=-2, axis2=-1)
    l_, m_, j_ = lam[:, None], mu[:, None], jst[:, None]
    Se = 2 * m_[..., None, None] * Ee
    for i in range(3):
        Se[..., i, i] += l_ * tr
    S = j_[..., None, None] * gg * Se
    energy = float(np.sum(w * j_ * (0.5 * l_ * tr**2 + m_ * np.einsum("cqJL,cqJL->cq", Ee, Ee))))
    P = np.einsum("cqiJ,cqJL->cqiL", F, S)
    K = _tangent(dphi, w, F, S, g, lam, mu, jst).reshape(c, n, n) if tangent else None
    return energy, P, K


def _neohookean_chunk(dphi, w, F, lam, mu, g, jst, tangent):
    """The neo-Hookean law on one chunk of elements (see :func:`_state`); None where ``J_e <= 0``."""
    c, n_qp, n_bf = dphi.shape[:3]
    n = 3 * n_bf
    g = g[:, None, None, :]  # (c, 1, 1, 3)
    Fe = F * g
    Je = np.linalg.det(Fe)
    if np.any(~(Je > 0)):
        return None
    lnJ = np.log(Je)
    Finv = np.linalg.inv(Fe)
    FinvT = np.swapaxes(Finv, -1, -2)
    l_, m_, j_ = lam[:, None], mu[:, None], jst[:, None]
    I1 = np.einsum("cqiJ,cqiJ->cq", Fe, Fe)
    energy = float(np.sum(w * j_ * (0.5 * m_ * (I1 - 3) - m_ * lnJ + 0.5 * l_ * lnJ**2)))
    Pe = m_[..., None, None] * (Fe - FinvT) + (l_ * lnJ)[..., None, None] * FinvT
    P = j_[..., None, None] * Pe * g
    if not tangent:
        return energy, P, None
    dt = dphi * g
    W = np.einsum("cqJi,cqaJ->cqai", Finv, dt).reshape(c, n_qp, n)
    wj = w * j_
    K = _bmm(W * (wj * l_)[:, :, None], W).reshape(c, n_bf, 3, n_bf, 3)
    K += _bmm(W * (wj * (m_ - l_ * lnJ))[:, :, None], W).reshape(
        c, n_bf, 3, n_bf, 3).transpose(0, 1, 4, 3, 2)
    Kd = np.einsum("cqaJ,cqbJ->cab", dt * (wj * m_)[:, :, None, None], dt, optimize=True)
    for i in range(3):
        K[:, :, i, :, i] += Kd
    return energy, P, K.reshape(c, n, n)


#: The hyperelastic laws by name: ``state(disc, u, lam, mu, G, tangent=...)`` of each.
STATES = {"svk": svk_state, "neohookean": neohookean_state}
