"""Mortar integrals of curved 3-node segments in 2D (a second-order mesh, isoparametric P2).

A segment with dof points (a, b, e) is the parabola x(s) = Σ_k N_k(s) X_k, s ∈ [0, 1]
(:func:`.segment3.shape`). Each slave segment carries its own normal field n(s) ⊥ x'(s):

- a master node X projects onto the slave segment at the s where X − x(s) ⊥ x'(s) (the
  closest point; Newton from the chord's projection), so neighbouring master segments meet
  at one slave parameter and the slave segment is covered once;
- a slave point x(s) projects onto a master segment at the η where x_m(η) − x(s) ∥ n(s):
  (x_m(η) − x(s)) × n(s) = 0 is quadratic in η and solved exactly.

The dual basis of a curved segment depends on its Jacobian J = |x'(s)|: ψ = A N with
A = D_e M_e⁻¹, D_e = diag ∫ N_k J, M_e = ∫ N Nᵀ J, per segment. J is not a polynomial, so the
integrals use Gauss rules of 6 points on the segment and on each overlap (on straight
segments they are exact and the result equals :func:`.mortar_p2._pair_integrals`'s).
"""

from __future__ import annotations

import numpy as np

from .segment3 import dshape as _dshape
from .segment3 import shape

_GX6, _GW6 = np.polynomial.legendre.leggauss(6)
_GX6, _GW6 = 0.5 + 0.5 * _GX6, 0.5 * _GW6


def _point(X: np.ndarray, s: np.ndarray) -> np.ndarray:
    """x(s) of segments X (P, 3, 2) at one parameter per segment."""
    return np.einsum("pk,pkd->pd", shape(s), X)


def _tangent(X: np.ndarray, s: np.ndarray) -> np.ndarray:
    return np.einsum("pk,pkd->pd", _dshape(s), X)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def dual_coefficients(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A (F, 3, 3) of each segment's dual basis, and ∫ N_k J (F, 3)."""
    N = shape(_GX6)  # (q, 3)
    J = np.linalg.norm(np.einsum("qk,fkd->fqd", _dshape(_GX6), X), axis=2)  # (F, q)
    De = np.einsum("q,fq,qk->fk", _GW6, J, N)
    Me = np.einsum("q,fq,qi,qj->fij", _GW6, J, N, N)
    return De[:, :, None] * np.linalg.inv(Me), De


def _closest(X: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The parameter of the point of each segment X (P, 3, 2) closest to p (P, 2)."""
    a, b = X[:, 0], X[:, 1]
    d = b - a
    s = np.einsum("pd,pd->p", p - a, d) / np.einsum("pd,pd->p", d, d)
    dd = np.einsum("k,pkd->pd", np.array([4.0, 4.0, -8.0]), X)  # x'' (constant)
    for _ in range(8):  # Newton on (p − x(s))·x'(s) = 0; quadratic convergence from the chord
        t = _tangent(X, s)
        r = p - _point(X, s)
        f = np.einsum("pd,pd->p", r, t)
        df = -np.einsum("pd,pd->p", t, t) + np.einsum("pd,pd->p", r, dd)
        s = s - f / df
    return s


def _project(Xm: np.ndarray, p: np.ndarray, n: np.ndarray, guess: np.ndarray) -> np.ndarray:
    """η with (x_m(η) − p) × n = 0 on each master segment, the root nearest ``guess``."""
    # x_m(η) = α + β η + γ η² with the shape functions' coefficients.
    xa, xb, xe = Xm[:, 0], Xm[:, 1], Xm[:, 2]
    alpha, beta, gamma = xa, -3.0 * xa - xb + 4.0 * xe, 2.0 * xa + 2.0 * xb - 4.0 * xe
    c0, c1, c2 = _cross(alpha - p, n), _cross(beta, n), _cross(gamma, n)
    lin = -c0 / np.where(c1 == 0.0, 1.0, c1)
    small = np.abs(c2) <= 1e-12 * np.abs(c1)
    disc = np.sqrt(np.maximum(c1**2 - 4.0 * c2 * c0, 0.0))
    q = -0.5 * (c1 + np.copysign(disc, c1))  # the stable pair of roots
    r1 = q / np.where(small, 1.0, c2)
    r2 = c0 / np.where(q == 0.0, 1.0, q)
    root = np.where(np.abs(r1 - guess) < np.abs(r2 - guess), r1, r2)
    return np.where(small, lin, root)


def pair_integrals(Xs: np.ndarray, Xm: np.ndarray, A: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """M entries (P, 3, 3) of the (slave, master) segment pairs, and which overlap.

    Args:
        Xs: The slave segments' points (P, 3, 2).
        Xm: The master segments' points (P, 3, 2).
        A: The slave segments' dual coefficients (P, 3, 3).
    """
    sa = np.clip(_closest(Xs, Xm[:, 0]), 0.0, 1.0)
    sb = np.clip(_closest(Xs, Xm[:, 1]), 0.0, 1.0)
    lo, hi = np.minimum(sa, sb), np.maximum(sa, sb)
    ok = hi - lo > 1e-12
    vals = np.zeros((Xs.shape[0], 3, 3))
    for q, w in zip(_GX6, _GW6, strict=True):
        s = lo + q * (hi - lo)
        t = _tangent(Xs, s)
        J = np.linalg.norm(t, axis=1)
        n = np.stack([t[:, 1], -t[:, 0]], axis=1)  # either side: the projection is a line
        guess = (s - sa) / np.where(sb == sa, 1.0, sb - sa)
        eta = _project(Xm, _point(Xs, s), n, guess)
        psi = np.einsum("pk,pjk->pj", shape(s), A)
        vals += (w * (hi - lo) * J)[:, None, None] * psi[:, :, None] * shape(eta)[:, None, :]
    return vals, ok
