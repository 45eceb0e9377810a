"""A safeguarded 1-D search of SMALBE's dual along a stagnating residual direction.

The augmented-Lagrangian dual ``theta(mu) = min_x L(x, mu, rho)`` is concave with gradient
``D x(mu)``. Near gross sliding of friction it is almost one-dimensional: ``D x`` keeps the
direction ``d`` of the floating body's rigid mode that the few sticking rows hold only weakly,
and the plain update ``rho D x`` walks up the ridge by a fraction of a per cent of the way per
outer iteration (:mod:`.aitken` extrapolates that by at most 10). Here the step along ``d`` is
a search for the root of the directional derivative ``phi(t) = d^T D x(mu + t d)``, using only
the residual that the next outer iteration computes anyway: it grows the factor over the plain
step while ``phi`` keeps its sign (the secant of the last two values, at most doubled), and on
a sign change it puts ``mu`` at the secant root between the two points (the regula falsi of
the bracket) and starts over. Components of ``D x`` across ``d`` take the plain update. The
start direction (a residual) still holds a few per cent of the fast modes, which a move by a
large factor excites more than it reduces ``phi``; the residual across ``d`` after each move
measures that part, which is taken out of ``d`` before the next move (on a linear model with
the slow contraction 0.998, tests/qp/test_qp_dual_search.py: 34 outer iterations with the
correction, 464 without, Aitken's 1 891). A sign change below
:data:`NOISE` of the last value is not trusted (the inner solves are inexact: SMALBE stops them
at ``||g^P|| <= min(M ||D x||, eta)``), nor a residual that turned away from ``d``.
Sources: the secant and regula falsi methods for a monotone 1-D equation (e.g. Nocedal and
Wright 2006, ch. 3 and 11); Aitken (1926) for the first factor from the measured ratio.
"""

from __future__ import annotations

import numpy as np

#: The residuals of two outer iterations count as one direction above this cosine (a search
#: starts), and a search ends once its residual's cosine with ``d`` falls below TURNED: the
#: move along ``d`` then excited other modes more than it reduced ``phi``. bench/
#: coulomb_sliding.py (F-mults of the five loads, full / half): TURNED 0.1: 5 444 / 6 846,
#: 0.3: 5 288 / 6 832, 0.5: 5 234 / 7 058 (with the direction's correction).
ALIGNED = 0.99
TURNED = 0.3
#: A search starts on a ratio ``q = |D x_k| / |D x_{k-1}|`` in (Q_MIN, 1]: a fast or a
#: growing residual is left to the plain update (``q = 1``: the inner solve did not move x).
Q_MIN = 0.5
#: The first factor ``1/(1 - q)`` (Aitken) is capped at FIRST; later ones at GROW times the
#: last and at CAP in all.
FIRST = 10.0
#: GROW 1.5: 5 544 / 7 233, 4: 5 831 / 7 360, 2: 5 402 / 6 980 (before the direction's
#: correction); FIRST 30 then: 5 349 / 7 082.
GROW = 2.0
CAP = 1.0e4
#: A sign change of ``phi`` is trusted only below ``-NOISE`` times its last value.
NOISE = 0.05


class DualSearch:
    """The plain update ``rho D x``, with a secant search for the root of ``phi`` along ``d``.

    ``step(Dx, plain)`` takes the residual ``D x_k`` and the plain update ``rho D x_k`` (ρ is
    their ratio) and returns the multiplier update. ``D x`` is replicated: every rank takes the
    same step.
    """

    def __init__(self) -> None:
        self._prev: np.ndarray | None = None
        #: The search in progress: unit direction, phi at the last point, the distance of the
        #: last move along d and the factor of that move over the plain step along d.
        self._d: np.ndarray | None = None
        self._phi = self._t = self._s = 0.0
        #: Number of extrapolated steps (forward), secant roots taken back (overshoots).
        self.count = 0
        self.back = 0

    def reset(self) -> None:
        """Forget the last residual and the search."""
        self._prev, self._d = None, None

    def step(self, Dx: np.ndarray, plain: np.ndarray) -> np.ndarray:
        """The update from the residual ``Dx`` and the plain update ``plain``."""
        n1 = float(np.linalg.norm(Dx))
        if n1 == 0.0:
            self.reset()
            return plain
        rho = float(np.linalg.norm(plain)) / n1
        if self._d is not None:
            return self._continue(Dx, n1, plain, rho)
        prev, self._prev = self._prev, Dx.copy()
        if prev is None:
            return plain
        n0 = float(np.linalg.norm(prev))
        cos, q = float(prev @ Dx) / (n0 * n1), n1 / n0
        if cos <= ALIGNED or not Q_MIN < q <= 1.0:
            return plain
        s = min(1.0 / (1.0 - q), FIRST) if q < 1.0 else GROW
        return self._forward(Dx / n1, n1, s, plain, rho)

    def _forward(self, d: np.ndarray, phi: float, s: float, plain: np.ndarray,
                 rho: float) -> np.ndarray:
        """Move ``s`` plain steps along ``d`` (where ``phi > 0``), the plain one across it."""
        self._d, self._phi, self._t, self._s = d, phi, s * rho * phi, s
        self.count += 1
        return plain + (s - 1.0) * rho * phi * d

    def _continue(self, Dx: np.ndarray, n1: float, plain: np.ndarray,
                  rho: float) -> np.ndarray:
        """The next point of the search from ``phi`` at the last one."""
        d, phi0, t, s = self._d, self._phi, self._t, self._s
        phi1 = float(d @ Dx)
        if phi1 < -NOISE * phi0:  # overshot: the secant root between the two points
            self.back += 1
            self.reset()
            root = t * phi0 / (phi0 - phi1)
            return plain - phi1 * rho * d - (t - root) * d
        if phi1 < TURNED * n1:  # at the root within the inner accuracy, or turned away
            self.reset()
            self._prev = Dx.copy()
            return plain
        # phi kept its sign: the secant's factor, at most GROW times the last one
        secant = t / (rho * (phi0 - phi1)) if phi1 < phi0 else np.inf
        s = max(1.0, min(secant, GROW * s, CAP))
        # The residual across d after a move t along d is mostly that move's excitation of
        # the fast modes that d still holds, -H d_fast t ~ -d_fast t / rho (rho H ~ I on
        # them): taking it out of d is a step of power iteration on the slow mode per move.
        d = d + rho * (Dx - phi1 * d) / t
        d /= float(np.linalg.norm(d))
        phi1 = float(d @ Dx)
        if phi1 <= 0.0:
            self.reset()
            self._prev = Dx.copy()
            return plain
        return self._forward(d, phi1, s, plain, rho)


__all__ = ["DualSearch"]
