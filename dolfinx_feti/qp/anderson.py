"""Anderson acceleration (type II) of SMALBE's multiplier update (a fixed point in ``mu``).

Sources: Anderson, J. ACM 12 (1965); Walker & Ni, SIAM J. Numer. Anal. 49 (2011).
"""

from __future__ import annotations

import numpy as np


class Anderson:
    """Anderson acceleration (type II) of the fixed point ``mu -> mu + rho D x(mu)``.

    Once the active set has settled the map is affine in ``mu`` and its contraction
    ``(I + rho S)^{-1}`` (``S`` the dual Schur complement on the free set) has only a few
    eigenvalues away from 0 (one or two on B1), so a short secant memory removes them in a few
    outer iterations where the plain update needs tens. ``mu`` and the residuals are
    replicated and identical on every rank, so every rank takes the same step.
    """

    def __init__(self, depth: int) -> None:
        self.depth = depth
        self._mu: list[np.ndarray] = []  # mu_k
        self._f: list[np.ndarray] = []   # f_k = rho D x_k (the plain step)

    def reset(self) -> None:
        """Forget the history."""
        self._mu.clear()
        self._f.clear()

    def step(self, mu: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Return the accelerated ``mu_{k+1} - mu_k`` from ``mu_k`` and the plain step ``f``."""
        self._mu.append(mu.copy())
        self._f.append(f.copy())
        if len(self._f) > self.depth + 1:
            self._mu.pop(0)
            self._f.pop(0)
        if len(self._f) < 2:
            return f
        dF = np.diff(np.array(self._f), axis=0).T           # columns f_i+1 - f_i
        dG = dF + np.diff(np.array(self._mu), axis=0).T     # G(mu) = mu + f
        gamma = np.linalg.lstsq(dF, f, rcond=1e-10)[0]
        return f - dG @ gamma


__all__ = ["Anderson"]
