"""A dense reference solver for ``min ½xᵀSx − dᵀx`` over intervals and discs (no FETI, no MPGP).

Semismooth Newton on the natural residual F(x) = x − P(x − γ(Sx − d)), γ = 1/‖S‖₂, with the
generalized Jacobian of the projection, an Armijo line search on ½‖F‖² and a projected gradient
step as fallback; quadratically convergent near the solution, so it ends at ‖F‖ ~ 1e-15.
Used as the independent reference of the MPGP unit tests and of the friction tests (where S is
the dense dual Schur complement of the undecomposed problem).
"""

from __future__ import annotations

import numpy as np


class ConeSet:
    """``l <= x <= u`` on entries, ``||x[I_k] − c_k|| <= r_k`` on disjoint index pairs."""

    def __init__(self, lb: np.ndarray, ub: np.ndarray, pairs: np.ndarray | None = None,
                 centre: np.ndarray | None = None, radius: np.ndarray | None = None) -> None:
        self.l, self.u = np.asarray(lb, dtype=float), np.asarray(ub, dtype=float)
        self.I = np.zeros((0, 2), dtype=int) if pairs is None else np.asarray(pairs).reshape(-1, 2)
        k = self.I.shape[0]
        self.c = np.zeros((k, 2)) if centre is None else np.asarray(centre, dtype=float)
        self.r = np.zeros(k) if radius is None else np.asarray(radius, dtype=float)

    def project(self, y: np.ndarray) -> np.ndarray:
        x = np.clip(y, self.l, self.u)
        if self.I.size:
            Y = y[self.I] - self.c
            n = np.linalg.norm(Y, axis=1)
            s = np.ones_like(n)
            out = n > self.r
            s[out] = self.r[out] / n[out]
            x[self.I] = self.c + Y * s[:, None]
        return x

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        """An element of the generalized Jacobian of the projection at y."""
        D = np.diag(((y > self.l) & (y < self.u)).astype(float))
        for k, (i, j) in enumerate(self.I):
            w = y[[i, j]] - self.c[k]
            n = np.linalg.norm(w)
            if n <= self.r[k]:
                B = np.eye(2)
            else:
                w = w / n
                B = (self.r[k] / n) * (np.eye(2) - np.outer(w, w))
            D[np.ix_([i, j], [i, j])] = B
        return D


def solve(S: np.ndarray, d: np.ndarray, cs: ConeSet, tol: float = 1e-15,
          max_it: int = 500) -> np.ndarray:
    """The minimizer (S symmetric positive definite)."""
    S = np.asarray(S, dtype=float)
    n = d.size
    gamma = 1.0 / np.linalg.norm(S, 2)
    scale = max(np.abs(d).max(), 1e-300) * gamma

    def residual(x):
        y = x - gamma * (S @ x - d)
        return x - cs.project(y), y

    x = cs.project(np.zeros(n))
    for _ in range(max_it):
        F, y = residual(x)
        nF = np.linalg.norm(F)
        if nF <= tol * scale * np.sqrt(n):
            return x
        J = np.eye(n) - cs.jacobian(y) @ (np.eye(n) - gamma * S)
        try:
            dx = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            dx = None
        t, accepted = 1.0, False
        while dx is not None and t > 1e-10:
            if np.linalg.norm(residual(x + t * dx)[0]) <= (1.0 - 1e-4 * t) * nF:
                x, accepted = x + t * dx, True
                break
            t *= 0.5
        if not accepted:  # projected gradient step: decreases the objective
            x = cs.project(x - gamma * (S @ x - d))
    raise RuntimeError("the semismooth Newton reference did not converge")


def natural_residual(S: np.ndarray, d: np.ndarray, cs: ConeSet, x: np.ndarray) -> float:
    """‖x − P(x − γ(Sx − d))‖ / (γ ‖d‖): zero exactly at the minimizer."""
    gamma = 1.0 / np.linalg.norm(S, 2)
    return float(np.linalg.norm(x - cs.project(x - gamma * (S @ x - d)))
                 / (gamma * max(np.linalg.norm(d), 1e-300)))
