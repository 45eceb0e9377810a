"""Boundary meshes and exact solutions for the boundary element tests (no DOLFINx)."""

from __future__ import annotations

import numpy as np

from dolfinx_feti.bem.galerkin import BoundaryMesh


def polygon(points: np.ndarray, per_side: int) -> BoundaryMesh:
    """A closed counter-clockwise polygon through ``points``, ``per_side`` elements a side."""
    k = points.shape[0]
    s = np.arange(per_side)[:, None] / per_side
    x = np.concatenate([points[i] + s * (points[(i + 1) % k] - points[i]) for i in range(k)])
    n = x.shape[0]
    elem = np.stack([np.arange(n), (np.arange(n) + 1) % n], axis=1)
    return BoundaryMesh(x, elem, np.array([0, n]), np.array([0, n]))


def batch(meshes: list[BoundaryMesh]) -> BoundaryMesh:
    """Several boundary meshes as one batch (one subdomain each)."""
    x = np.concatenate([m.x for m in meshes])
    noff = np.r_[0, np.cumsum([m.x.shape[0] for m in meshes])]
    elem = np.concatenate([m.elem + o for m, o in zip(meshes, noff, strict=False)])
    eoff = np.r_[0, np.cumsum([m.elem.shape[0] for m in meshes])]
    return BoundaryMesh(x, elem, noff, eoff)


def square(per_side: int, a: float = 0.3) -> BoundaryMesh:
    """The square [0, a]²."""
    return polygon(np.array([[0, 0], [a, 0], [a, a], [0, a]], dtype=float), per_side)


def l_shape(per_side: int, a: float = 0.2) -> BoundaryMesh:
    """An L-shaped hexagon of sides a and 2a (a re-entrant corner)."""
    pts = a * np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)
    return polygon(pts, per_side)


def disk(n: int, radius: float) -> BoundaryMesh:
    """A regular n-gon inscribed in the circle of ``radius`` about 0."""
    th = 2 * np.pi * np.arange(n) / n
    return polygon(radius * np.stack([np.cos(th), np.sin(th)], axis=1), 1)


def rigid(x: np.ndarray, bs: int) -> np.ndarray:
    """The rigid motions (constants for bs = 1) at x, node-major, not orthonormalized."""
    if bs == 1:
        return np.ones((x.shape[0], 1))
    R = np.zeros((x.shape[0], 2, 3))
    R[:, 0, 0] = R[:, 1, 1] = 1.0
    R[:, 0, 2], R[:, 1, 2] = -x[:, 1], x[:, 0]
    return R.reshape(-1, 3)


def kelvin(x: np.ndarray, x0: np.ndarray, j: int, mu: float, nu: float
           ) -> tuple[np.ndarray, np.ndarray]:
    """Kelvin's plane-strain displacement of a unit force e_j at x0, and its gradient at x."""
    r = x - x0
    rr = np.einsum("ij,ij->i", r, r)
    c = 1.0 / (8 * np.pi * mu * (1 - nu))
    e = np.eye(2)[j]
    u = c * (-(3 - 4 * nu) * 0.5 * np.log(rr)[:, None] * e + r * (r[:, j] / rr)[:, None])
    # ∂u_a/∂x_b
    g = c * (-(3 - 4 * nu) * e[None, :, None] * r[:, None, :] / rr[:, None, None]
             + (np.eye(2)[None] * r[:, j, None, None] + r[:, :, None] * e[None, None, :])
             / rr[:, None, None]
             - 2 * r[:, :, None] * r[:, None, :] * r[:, j, None, None] / rr[:, None, None] ** 2)
    return u, g


def traction_load(bm: BoundaryMesh, traction, bs: int, q: int = 12) -> np.ndarray:
    """∫ t φ_i over the boundary (P1, node-major) of a traction function t(x, normal)."""
    s, w = np.polynomial.legendre.leggauss(q)
    s, w = 0.5 * (s + 1), 0.5 * w
    X = bm.p[:, None, :] + (s[None, :] * bm.length[:, None])[..., None] * bm.tau[:, None, :]
    t = traction(X.reshape(-1, 2), np.repeat(bm.normal, q, axis=0)).reshape(-1, q, bs)
    wl = (w[None, :] * bm.length[:, None])[..., None]
    b = np.zeros((bm.x.shape[0], bs))
    np.add.at(b, bm.elem[:, 0], ((1 - s)[None, :, None] * t * wl).sum(axis=1))
    np.add.at(b, bm.elem[:, 1], (s[None, :, None] * t * wl).sum(axis=1))
    return b.ravel()
