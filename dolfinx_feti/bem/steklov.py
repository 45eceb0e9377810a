"""The discrete Steklov–Poincaré operator and the representation formula inside a subdomain.

Symmetric Galerkin form (Steinbach 2008, Langer & Steinbach 2003):

    S = D + (½M + K)ᵀ V⁻¹ (½M + K) = D + YᵀY,   Y = L⁻¹(½M + K),   V = L Lᵀ,

symmetric by construction and positive semidefinite, with the kernel of the continuous
operator: the constants (Laplace) or the rigid motions (Lamé), exactly up to round-off since
the inner integrals are in closed form (D kills them through ∂_s, ½M + K through the angle sum
of the double layer).

Inside, u(x) = ∫ G t − ∫ ∂G/∂n_y u with t = V⁻¹(½M + K) u: the map from the boundary values to
the values at interior points is one dense matrix per subdomain.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ..errors import SolveError
from .galerkin import BoundaryMesh, point_fields
from .operators import Operators, layers, mass_and_derivative


def steklov(op: Operators, label: str = "subdomain") -> np.ndarray:
    """S = D + (½M + K)ᵀ V⁻¹ (½M + K) of one subdomain."""
    try:
        L = scipy.linalg.cholesky(op.V, lower=True)
    except np.linalg.LinAlgError:
        raise SolveError(f"TBETI: the single layer matrix of {label} is not positive definite") \
            from None
    Y = scipy.linalg.solve_triangular(L, 0.5 * op.M + op.K, lower=True)
    return op.D + Y.T @ Y


def neumann_map(op: Operators) -> np.ndarray:
    """V⁻¹(½M + K): the Neumann data (P0) of given Dirichlet data (P1)."""
    return scipy.linalg.cho_solve(scipy.linalg.cho_factor(op.V, lower=True),
                                  0.5 * op.M + op.K)


def interior_maps(bm: BoundaryMesh, ops: list[Operators], X: np.ndarray, sub: np.ndarray,
                  bs: int, mu=None, nu=None) -> list[np.ndarray]:
    """Per subdomain, the matrix from its boundary values to its values at points ``X``.

    ``X`` are scaled points (as ``bm``), ``sub`` their subdomain (ascending); ``bs`` 1
    (Laplace) or 2 (Lamé, with ``mu``, ``nu`` per subdomain). Rows follow the points.
    """
    if np.any(np.diff(sub) < 0):
        raise ValueError("interior_maps: the points must be sorted by subdomain")
    fields = ("ln", "dl") if bs == 1 else ("ln", "rr", "dl", "edl")
    _, _, f = point_fields(bm, X, sub, fields)
    ne = np.diff(bm.elem_off)
    count = np.bincount(sub, minlength=bm.count)
    poff = np.r_[0, np.cumsum(count * ne)]  # the pairs, point by point, so by subdomain
    out = []
    for s in range(bm.count):  # dense per-subdomain algebra
        m, n = int(count[s]), int(ne[s])
        g = {k: v[poff[s]:poff[s + 1]].reshape(m, n, *v.shape[1:]) for k, v in f.items()}
        _, C = mass_and_derivative(bm, s)
        single, double = layers(g, bm, s, C, *(() if bs == 1 else (float(mu[s]), float(nu[s]))))
        out.append(single @ neumann_map(ops[s]) - double)
    return out


__all__ = ["interior_maps", "neumann_map", "steklov"]
