"""Extrapolation of a slowly converging SMALBE outer loop along a fixed direction (Aitken).

Near gross sliding of friction the equality residual ``D x`` of SMALBE's outer loop keeps its
direction (the floating body's rigid mode that the few sticking rows hold only weakly) and
shrinks by a fraction of a per cent per outer iteration: the plain updates ``rho D x_k`` form
a geometric series of ratio ``q`` whose sum ``rho D x_k / (1 - q)`` is the update that the
next hundreds of outer iterations would add up to (Aitken's extrapolation of a linearly
converging sequence). Source: Aitken, Proc. Roy. Soc. Edinburgh 46 (1926).
"""

from __future__ import annotations

import numpy as np

#: The largest factor of the extrapolated step over the plain one. bench/coulomb_sliding.py
#: (the full punch at 0.9 𝓕N): 10: 1 556, 30: 2 193 F-multiplications (2 712 without).
CAP = 10.0
#: The residuals of two outer iterations count as one direction above this cosine.
ALIGNED = 0.99
#: Only a ratio ``q = |D x_k| / |D x_{k-1}|`` in (Q_MIN, 1) is extrapolated: a fast or a
#: growing residual is left to the plain update.
Q_MIN = 0.5


class Aitken:
    """The plain update ``rho D x``, multiplied by ``min(1/(1 - q), CAP)`` on a slow loop.

    Applied when two successive residuals are aligned (cosine > :data:`ALIGNED`) and the ratio
    of their norms is in (:data:`Q_MIN`, 1); the pair is then forgotten, so the next
    extrapolation needs two new plain steps (an overshoot shows as a turned residual and is
    not extrapolated). ``D x`` is replicated: every rank takes the same step.
    """

    def __init__(self) -> None:
        self._prev: np.ndarray | None = None
        #: Number of extrapolated steps.
        self.count = 0

    def reset(self) -> None:
        """Forget the last residual."""
        self._prev = None

    def step(self, Dx: np.ndarray, plain: np.ndarray) -> np.ndarray:
        """The update from the residual ``Dx`` and the plain update ``plain``."""
        prev, self._prev = self._prev, Dx.copy()
        if prev is None:
            return plain
        n0, n1 = float(np.linalg.norm(prev)), float(np.linalg.norm(Dx))
        if n0 == 0.0 or n1 == 0.0:
            return plain
        cos, q = float(prev @ Dx) / (n0 * n1), n1 / n0
        if cos <= ALIGNED or not Q_MIN < q < 1.0:
            return plain
        self._prev = None
        self.count += 1
        return plain * min(1.0 / (1.0 - q), CAP)


__all__ = ["Aitken"]
