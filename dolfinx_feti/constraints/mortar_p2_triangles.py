"""Mortar coupling of quadratic (6-node) triangular facets in 3D: P2 tetrahedra.

The vertex functions of a 6-node triangle integrate to zero over it, so no dual basis with
positive weights exists for the plain Lagrange functions. Popp, Wohlmuth, Gee and Wall (2012)
change the basis of the slave surface first (:mod:`.quadratic_triangles`):

    Ñ_v = N_v + α Σ_{edges e ∋ v} N_e,        Ñ_e = (1 − 2α) N_e,        α = 1/5,

with ∫ Ñ_v = 2|T|/15 and ∫ Ñ_e = |T|/5 per facet, and build the dual basis on it:
ψ = A Ñ with A = D_e M_e⁻¹, D_e = diag ∫ Ñ, M_e = ∫ Ñ Ñᵀ. On a flat facet both are
proportional to |T|, so A is one constant 6 × 6 matrix, and ∫ ψ_j Ñ_k = δ_jk ∫ Ñ_k.

The mortar integrals are those of linear mortar (:mod:`.mortar`) with these functions:

    D_j  = ∫_Γs Ñ_j,        M_jl = ∫_{Γs ∩ π(Γm)} ψ_j N_l^m∘π

(the master side keeps its plain Lagrange functions N^m). The slave displacement is
u = Σ Ñ_k ũ_k, so the row of slave point j reads ũ_j − Σ_l (M_jl / C_j) u_l: it is written at
the dof points like a linear mortar row, then its slave entry at an edge point is expressed in
u (ũ_e = (u_e − α(u_a + u_b)) / (1 − 2α), :func:`.quadratic_triangles.transform_rows` with
``own_only``). On straight-sided facets the gap of an edge point in the new basis is the gap
at the edge's midpoint, the point itself, so the weighted gaps are those of the dof points.

Overlaps: the master triangle projected onto the slave facet's plane along its normal is
clipped by the slave triangle (:mod:`.clipping`), the polygon cut into a fan of triangles
about its centroid; the projection of a flat master facet is affine, so ψ_j N_l∘π is a
polynomial of degree 4 there and a collapsed Gauss rule of 9 points (exact for degree 4)
integrates M exactly. Everything runs over all pairs at once (loops over the at most 6
vertices of an overlap polygon and the points of the rule only).
"""

from __future__ import annotations

import numpy as np

from ..mesh.dofpoints import DofPoints, facet_weights
from ..mesh.topology import surface_points
from .clipping import clip_polygons, fan_quadrature
from .mortar import MortarCoupling, search
from .mortar_quad import collapsed_gauss
from .quadratic_triangles import ALPHA, EDGES

#: Rule on the reference triangle, exact for degree 4 (weights relative to the area).
RULE_X, RULE_W = collapsed_gauss(3)
#: ∫ Ñ_k / |T| of the transformed basis: vertices, then edge points.
WEIGHTS = facet_weights("tetrahedron", 2)


def shape(lam: np.ndarray) -> np.ndarray:
    """The 6-node Lagrange functions at barycentric coordinates ``lam`` (..., 3) → (..., 6)."""
    vertex = lam * (2.0 * lam - 1.0)
    edge = np.stack([4.0 * lam[..., a] * lam[..., b] for a, b in EDGES], axis=-1)
    return np.concatenate([vertex, edge], axis=-1)


def transformation() -> np.ndarray:
    """T (6, 6) with Ñ = T N on every facet (Popp, Wohlmuth, Gee and Wall 2012)."""
    T = np.eye(6)
    for e, (a, b) in enumerate(EDGES):
        T[a, 3 + e] = T[b, 3 + e] = ALPHA
        T[3 + e, 3 + e] = 1.0 - 2.0 * ALPHA
    return T


def dual_coefficients() -> np.ndarray:
    """C (6, 6) with ψ = C N (the plain functions): C = A T, A = D_e M_e⁻¹ (per unit area)."""
    lam = np.c_[1.0 - RULE_X.sum(axis=1), RULE_X]
    Nt = shape(lam) @ transformation().T  # Ñ at the rule's points; M_e has degree 4: exact
    Me = np.einsum("q,qi,qj->ij", RULE_W, Nt, Nt)
    return np.diag(WEIGHTS) @ np.linalg.inv(Me) @ transformation()


_C = dual_coefficients()


def triangle_points(points: DofPoints, tri: np.ndarray) -> np.ndarray:
    """The dof points (vertices, then edge points in :data:`EDGES` order) of triangles (F, 3)."""
    e = np.stack([points.lookup(1, np.sort(tri[:, [a, b]], axis=1)) for a, b in EDGES], axis=1)
    if np.any(e < 0):
        raise ValueError("facets that belong to no cell")
    return np.c_[tri, e]


def _barycentric(p: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of plane points p (P, Q, 2) in triangles T (P, 3, 2)."""
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    d = p - T[:, None, 0]
    l1 = (d[..., 0] * e2[:, None, 1] - d[..., 1] * e2[:, None, 0]) / det[:, None]
    l2 = (e1[:, None, 0] * d[..., 1] - e1[:, None, 1] * d[..., 0]) / det[:, None]
    return np.stack([1.0 - l1 - l2, l1, l2], axis=-1)


def pair_integrals(x: np.ndarray, slave: np.ndarray, ns: np.ndarray, master: np.ndarray,
                   i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M (P, 6, 6) of (slave, master) triangle pairs: Σ over the overlap of ψ_j N_l^m∘π.

    Args:
        x: Vertex coordinates (N, 3).
        slave: Slave triangles (F_s, 3) (vertices in the order of their dof points).
        ns: The slave triangles' outward unit normals.
        master: Master triangles (F_m, 3).
        i: Slave triangle of each candidate pair.
        j: Master triangle of each candidate pair.

    Returns:
        ``(vals, i, j)`` of the pairs with a non-empty overlap.
    """
    a = x[slave[i, 0]]
    t1 = x[slave[i, 1]] - a
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    t2 = np.cross(ns[i], t1)

    def plane(p):
        d = p - a[:, None]
        return np.stack([np.einsum("ikl,il->ik", d, t1), np.einsum("ikl,il->ik", d, t2)], axis=2)

    S, Mp = plane(x[slave[i]]), plane(x[master[j]])
    ccw = (S[:, 1, 0] - S[:, 0, 0]) * (S[:, 2, 1] - S[:, 0, 1]) - \
        (S[:, 1, 1] - S[:, 0, 1]) * (S[:, 2, 0] - S[:, 0, 0]) > 0.0
    clip = np.where(ccw[:, None, None], S, S[:, ::-1])  # the clipper must be counter-clockwise
    e1, e2 = Mp[:, 1] - Mp[:, 0], Mp[:, 2] - Mp[:, 0]
    m_area = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    poly, count = clip_polygons(Mp, np.full(i.size, 3), clip)
    s1, s2 = S[:, 1] - S[:, 0], S[:, 2] - S[:, 0]
    s_area = np.abs(s1[:, 0] * s2[:, 1] - s1[:, 1] * s2[:, 0])
    idx = np.flatnonzero((count >= 3) & (m_area > 1e-12 * s_area))  # a master seen edge-on: none
    poly, count = poly[idx], count[idx]
    first, pair, q, w = fan_quadrature(poly, count, RULE_X, RULE_W)
    on = idx[pair]
    psi = shape(_barycentric(q, S[on])) @ _C.T  # (T, Q, 6)
    Nm = shape(_barycentric(q, Mp[on]))
    vals = np.einsum("tq,tqj,tql->tjl", w, psi, Nm)
    vals = np.add.reduceat(vals, first, axis=0) if pair.size else np.zeros((0, 6, 6))
    keep = np.abs(vals).sum(axis=(1, 2)) > 0.0
    return vals[keep], i[idx[keep]], j[idx[keep]]


def triangle6_coupling(x: np.ndarray, cells: np.ndarray, slave: np.ndarray,
                       master: np.ndarray, points: DofPoints,
                       search_distance: float | None = None, cell_type: str | None = None,
                       self_contact: bool = False) -> MortarCoupling:
    """The mortar coupling of two surfaces of 6-node triangles (see :func:`.mortar_coupling`).

    Args:
        x: Vertex coordinates (N, 3) (a first-order mesh: straight-sided facets).
        cells: Tetrahedra (to orient the facets' outward normals).
        slave: Slave facets as vertex triples.
        master: Master facets as vertex triples.
        points: The dof points of the degree-2 space (the vertices first).
        search_distance: As for :func:`.mortar.mortar_coupling`.
        cell_type: The cells' type ("tetrahedron").
        self_contact: One surface as slave and master (:mod:`.self_contact`).

    Returns:
        The coupling over dof points: ``slave_nodes`` and the columns of ``M`` are dof points;
        ``D`` the integrals of the transformed basis Ñ (the rows are in ũ on the slave side).
    """
    found = search(x, cells, slave, master, search_distance, cell_type, self_contact)
    slave, ns, master, i, j = found.slave, found.ns, found.master, found.i, found.j
    sp_ = triangle_points(points, slave)
    mp_ = triangle_points(points, master)
    nodes, normals, D = surface_points(x, cells, slave, sp_, WEIGHTS, cell_type)
    vals, i, j = pair_integrals(x, slave, ns, master, i, j)
    r = np.repeat(sp_[i], 6, axis=1).ravel()
    c = np.tile(mp_[j], (1, 6)).ravel()
    return found.coupling(nodes, normals, D, (r, c, vals.ravel()), points.num_points, i.size)
