"""Mortar integrals on bilinear quadrilateral facets (of hexahedra): the reference-element parts.

A facet of a first-order hexahedron is a bilinear quadrilateral, in general warped (its four
vertices need not lie in a plane) and not a parallelogram. Its vertices are taken in the
tensor order of the reference square, ``(0, 0), (1, 0), (0, 1), (1, 1)``, with the shape
functions

    N_0 = (1 − ξ)(1 − η),  N_1 = ξ(1 − η),  N_2 = (1 − ξ)η,  N_3 = ξη.

Dual basis (Wohlmuth 2000; Popp, Gitterle, Gee and Wall 2010): ψ_i = Σ_l A_il N_l with
A = D M_e⁻¹, M_e = ∫ N Nᵀ dA the facet's own mass matrix and D = diag(∫ N_i dA), so that
∫ ψ_i N_j dA = δ_ij ∫ N_j dA on the facet. ψ is computed per facet from its geometry (the
surface Jacobian enters M_e), not taken from a parallelogram formula, so warped and
trapezoidal facets are biorthogonal too.

Overlap of a slave facet with a master facet: both are projected onto the slave facet's plane
(through its vertex centroid, normal to the cross product of its diagonals) along that
normal; the master's projection is clipped by the slave's (Sutherland–Hodgman), the polygon cut
into triangles about its centroid and integrated with a 7-point rule of degree 5 (Radon). The
projection of a bilinear facet is the bilinear map of the projected vertices, so a point of the
plane has exact reference coordinates on either facet (:func:`inverse_bilinear`, Newton's
method) and the slave surface's area element is the plane's times J_s/J_plane. The integrand
ψ_j N_k is a polynomial (of degree 4) where both facets are parallelograms in the plane, so
the integrals are exact there; elsewhere they carry the rule's (small) error, as in Popp et
al.'s integration cells.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .clipping import clip_polygons, fan_quadrature

#: Cyclic vertex order of a quadrilateral given in tensor order.
CYCLIC = np.array([0, 1, 3, 2])

# Gauss–Legendre on [0, 1], 6 points: exact for degree 11 per variable (M_e of a planar facet
# has degree 3 per variable; a warped facet's area element, a square root, is integrated to
# ~1e-10 for a vertex 0.3 facet sizes out of plane).
_G, _GW = np.polynomial.legendre.leggauss(6)
_G, _GW = 0.5 * (_G + 1.0), 0.5 * _GW
SQUARE_X = np.stack(np.meshgrid(_G, _G, indexing="ij"), axis=-1).reshape(-1, 2)
SQUARE_W = np.outer(_GW, _GW).ravel()



def collapsed_gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A rule of n² points on the reference triangle, from Gauss's on the square (Duffy).

    Exact for polynomials of degree 2n − 2; weights relative to the triangle's area (sum 1).
    """
    g, w = np.polynomial.legendre.leggauss(n)
    g, w = 0.5 * (g + 1.0), 0.5 * w
    u, v = np.meshgrid(g, g, indexing="ij")
    wu, wv = np.meshgrid(w, w, indexing="ij")
    points = np.stack([u.ravel(), (v * (1.0 - u)).ravel()], axis=1)
    return points, 2.0 * (wu * wv * (1.0 - u)).ravel()


# 25 points, exact for degree 8: ψ_j N_k (degree 4) on parallelograms, and the rational
# integrand of trapezoidal facets to ~1e-7 relative where a vertex is moved by 0.3 h.
TRI_X, TRI_W = collapsed_gauss(5)


def shape(xi: np.ndarray) -> np.ndarray:
    """Bilinear shape functions at reference points ``xi`` (..., 2), shape (..., 4)."""
    s, t = xi[..., 0], xi[..., 1]
    return np.stack([(1 - s) * (1 - t), s * (1 - t), (1 - s) * t, s * t], axis=-1)


def tangents(P: np.ndarray, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """∂x/∂ξ and ∂x/∂η of facets with vertices ``P`` (F, 4, d) at points ``xi`` (F, Q, 2)."""
    s, t = xi[..., 0:1], xi[..., 1:2]
    a, b = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    c = P[:, 3] - P[:, 1] - P[:, 2] + P[:, 0]
    return a[:, None] + t * c[:, None], b[:, None] + s * c[:, None]


def area_element(P: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """|∂x/∂ξ × ∂x/∂η| (3D facets) or |det| (2D quadrilaterals) at ``xi`` (F, Q, 2)."""
    x_s, x_t = tangents(P, xi)
    if P.shape[2] == 2:
        return np.abs(x_s[..., 0] * x_t[..., 1] - x_s[..., 1] * x_t[..., 0])
    return np.linalg.norm(np.cross(x_s, x_t), axis=-1)


def dual_basis(P: np.ndarray, basis=shape) -> tuple[np.ndarray, np.ndarray]:
    """Dual-basis coefficients and lumped areas of quadrilateral facets.

    Args:
        P: Vertices (F, 4, 3) in tensor order.
        basis: The functions on the facet (:func:`shape`, or the 9 biquadratic ones).

    Returns:
        ``(A, D)``: A (F, k, k) with ψ_i = Σ_l A_il N_l, and D (F, k) = ∫ N_i dA.
    """
    F = P.shape[0]
    xi = np.broadcast_to(SQUARE_X, (F, *SQUARE_X.shape))
    w = SQUARE_W * area_element(P, xi)  # (F, Q)
    N = basis(SQUARE_X)  # (Q, k)
    Me = np.einsum("fq,qi,qj->fij", w, N, N)
    D = Me.sum(axis=2)
    return D[:, :, None] * np.linalg.inv(Me), D


def inverse_bilinear(P: np.ndarray, p: np.ndarray, tol: float = 1e-13,
                     max_iter: int = 30) -> np.ndarray:
    """Reference coordinates of points in planar quadrilaterals, by Newton's method.

    The first step, from the centre, is exact for parallelograms: only the other
    quadrilaterals iterate on.

    Args:
        P: Vertices (F, 4, 2) in tensor order.
        p: Points (F, Q, 2); each row's points are mapped by its quadrilateral.
        tol: Stop when every update is below ``tol`` (reference units).
        max_iter: At most this many iterations (convergence is quadratic from the centre
            of a convex quadrilateral: about 5).

    Returns:
        ξ (F, Q, 2) with x(ξ) = p.
    """
    a, b = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    c = P[:, 3] - P[:, 1] - P[:, 2] + P[:, 0]
    xi = np.full(p.shape, 0.5)
    _newton_step(xi, P[:, 0], a, b, c, p)
    size = np.abs(a).sum(axis=1) + np.abs(b).sum(axis=1)
    bent = np.flatnonzero(np.abs(c).sum(axis=1) > 1e-12 * size)
    if bent.size == 0:
        return xi
    sub = xi[bent]
    for _ in range(max_iter):  # a few Newton steps, each over all points at once
        step = _newton_step(sub, P[bent, 0], a[bent], b[bent], c[bent], p[bent])
        if step < tol:
            break
    xi[bent] = sub
    return xi


def _newton_step(xi, p0, a, b, c, p) -> float:
    """One Newton step for x(ξ) = p0 + aξ + bη + cξη = p, in place; returns the largest update."""
    s, t = xi[..., 0], xi[..., 1]
    res = [p0[:, None, d] + s * a[:, None, d] + t * b[:, None, d] + s * t * c[:, None, d]
           - p[..., d] for d in range(2)]
    j_s = [a[:, None, d] + t * c[:, None, d] for d in range(2)]
    j_t = [b[:, None, d] + s * c[:, None, d] for d in range(2)]
    det = j_s[0] * j_t[1] - j_s[1] * j_t[0]
    det = np.where(det == 0.0, 1.0, det)
    ds = (j_t[1] * res[0] - j_t[0] * res[1]) / det
    dt = (j_s[0] * res[1] - j_s[1] * res[0]) / det
    xi[..., 0] -= ds
    xi[..., 1] -= dt
    return max(np.abs(ds).max(initial=0.0), np.abs(dt).max(initial=0.0))


def plane_frame(P: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Origin and in-plane unit vectors (t1, t2) with (t1, t2, n) right-handed, per facet."""
    origin = P.mean(axis=1)
    e = P[:, 1] - P[:, 0]
    e = e - np.einsum("ij,ij->i", e, n)[:, None] * n
    t1 = e / np.linalg.norm(e, axis=1)[:, None]
    return origin, t1, np.cross(n, t1)


def inverse_affine(P: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Reference coordinates of points in planar triangles (F, 3, 2): x = P0 + ξ e1 + η e2."""
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    det = np.where(det == 0.0, 1.0, det)[:, None]
    d = p - P[:, None, 0]
    return np.stack([(d[..., 0] * e2[:, None, 1] - d[..., 1] * e2[:, None, 0]) / det,
                     (e1[:, None, 0] * d[..., 1] - e1[:, None, 1] * d[..., 0]) / det], axis=-1)


def triangle_shape(xi: np.ndarray) -> np.ndarray:
    """Linear shape functions of a triangle at reference points ``xi`` (..., 2), (..., 3)."""
    return np.stack([1.0 - xi[..., 0] - xi[..., 1], xi[..., 0], xi[..., 1]], axis=-1)


@dataclass(frozen=True)
class FacetKind:
    """What the overlap integrals need of a kind of flat-mapped facet.

    Attributes:
        cyclic: The facet's vertices in their order around it.
        reference: ``reference(P, p)``: reference coordinates (F, Q, 2) of points ``p``
            (F, Q, 2) of planar facets with vertices ``P`` (F, nv, 2).
        shape: The facet's functions at reference points (..., 2) → (..., k).
    """

    cyclic: np.ndarray
    reference: Callable[[np.ndarray, np.ndarray], np.ndarray]
    shape: Callable[[np.ndarray], np.ndarray]


#: A bilinear quadrilateral (tensor order) and a linear triangle.
QUADRILATERAL = FacetKind(CYCLIC, inverse_bilinear, shape)
TRIANGLE = FacetKind(np.arange(3), inverse_affine, triangle_shape)


def pair_integrals(x: np.ndarray, slave: np.ndarray, ns: np.ndarray, A: np.ndarray,
                   master: np.ndarray, i: np.ndarray, j: np.ndarray, basis=shape,
                   slave_points: np.ndarray | None = None,
                   master_points: np.ndarray | None = None,
                   kinds: tuple[FacetKind, FacetKind] | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """M entries of (slave facet, master facet) pairs of quadrilaterals (or triangles).

    Args:
        x: Node coordinates (N, 3).
        slave: Slave facets (F_s, 4), tensor order.
        ns: The slave facets' outward unit normals (F_s, 3).
        A: The slave facets' dual-basis coefficients (F_s, k, k) (:func:`dual_basis`).
        master: Master facets (F_m, 4), tensor order.
        i: Slave facet of each candidate pair.
        j: Master facet of each candidate pair.
        basis: The k functions on either facet (the geometry stays bilinear).
        slave_points: The points of ``basis`` on each slave facet (F_s, k); the vertices
            when None.
        master_points: The same on each master facet.
        kinds: The (slave, master) facet kinds, when not both quadrilaterals with ``basis``
            (a triangle against a quadrilateral: bodies of different cell types).

    Returns:
        ``(rows, cols, vals, pairs)``: slave node, master node and value of each entry of M,
        and the number of pairs with a non-empty overlap.
    """
    quad = FacetKind(CYCLIC, inverse_bilinear, basis)
    sk, mk = kinds if kinds is not None else (quad, quad)
    Ps, Pm = x[slave[i]], x[master[j]]
    origin, t1, t2 = plane_frame(Ps, ns[i])

    def plane(p):
        d = p - origin[:, None]
        return np.stack([np.einsum("ikl,il->ik", d, t1), np.einsum("ikl,il->ik", d, t2)], axis=2)

    S, Mp = plane(Ps), plane(Pm)
    Sc = S[:, sk.cyclic]
    twice_area = (Sc[..., 0] * np.roll(Sc[..., 1], -1, axis=1)
                  - np.roll(Sc[..., 0], -1, axis=1) * Sc[..., 1]).sum(axis=1)
    Sc = np.where((twice_area < 0)[:, None, None], Sc[:, ::-1], Sc)  # the clipper must be ccw
    nm = len(mk.cyclic)
    poly, count = clip_polygons(Mp[:, mk.cyclic], np.full(i.size, nm), Sc)
    idx = np.flatnonzero(count >= 3)
    poly, count = poly[idx], count[idx]
    first, pair, q, w = fan_quadrature(poly, count, TRI_X, TRI_W)  # w: the plane's area
    on = idx[pair]  # the (slave, master) pair of each triangle
    xs = sk.reference(S[on], q)
    xm = mk.reference(Mp[on], q)
    # A warped slave facet: its area element relative to that of its projection on the plane
    # (a triangle is flat).
    height = np.abs(np.einsum("ikl,il->ik", Ps - origin[:, None], ns[i])).max(axis=1)
    warped = np.flatnonzero(height[on] > 1e-12 * np.abs(S[on]).max(axis=(1, 2)))
    if warped.size:
        w[warped] *= area_element(Ps[on[warped]], xs[warped]) / \
            np.maximum(area_element(S[on[warped]], xs[warped]), 1e-300)
    psi = sk.shape(xs) @ np.swapaxes(A[i[on]], 1, 2)  # (T, Q, k): ψ_l = Σ_i A_li N_i
    vals = np.swapaxes(w[:, :, None] * psi, 1, 2) @ mk.shape(xm)  # (T, k, km): Σ_q w ψ_l N_k
    ks, km = A.shape[1], mk.shape(np.zeros(2)).size
    vals = np.add.reduceat(vals, first, axis=0) if pair.size else np.zeros((0, ks, km))
    keep = np.abs(vals).sum(axis=(1, 2)) > 0.0
    si, mj = i[idx[keep]], j[idx[keep]]
    sp_ = slave if slave_points is None else slave_points
    mp_ = master if master_points is None else master_points
    rows = np.repeat(sp_[si], km, axis=1).ravel()
    cols = np.tile(mp_[mj], (1, ks)).ravel()
    return rows, cols, vals[keep].ravel(), int(keep.sum())
