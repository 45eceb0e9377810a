"""A safeguarded 1-D search of SMALBE's dual along a stagnating residual direction.

The augmented-Lagrangian dual ``theta(mu) = min_x L(x, mu, rho)`` is concave with gradient
``D x(mu)``. Near gross sliding of friction it is almost one-dimensional: ``D x`` keeps the
direction ``d`` of the floating body's rigid mode that the few sticking rows hold only weakly,
and the plain update ``rho D x`` walks up the ridge by a fraction of a per cent of the way per
outer iteration (:mod:`.aitken` extrapolates that by at most 10). Here the step along ``d`` is
a search for the root of the directional derivative ``phi(t) = d^T D x(mu + t d)``, using only
the residual that the next outer iteration computes anyway: it grows the factor over the plain
step while ``phi`` keeps its sign (the secant of the last two values, at most doubled), and on
a sign change it puts ``mu`` at the secant root between the two points (regula falsi) and
starts over. Components of ``D x`` across ``d`` take the plain update.

Two corrections make the search work on more than a model with one slow mode:

- The start direction (a residual) still holds a few per cent of the fast modes, which a move
  by a large factor excites more than it reduces ``phi``. The residual across ``d`` after each
  move measures that part (``-H d_fast t``, ``rho H ~ I`` on fast modes), which is taken out
  of ``d`` before the next move.
- The slow subspace can have several directions (the punch on DOLFINx 0.11's medium mesh at
  0.99 𝓕N): a search that found its root leaves the residual along another slow direction,
  the next search along that one undoes part of the first, and the loop zig-zags (2 % of
  ``||D x||`` per cycle of six outer iterations there). A search started after one that
  reached its root takes the new residual made conjugate to the last direction,
  ``d = r - (r^T w / d_old^T w) d_old`` with ``w ~ H d_old`` the change of the residual over
  that search per unit of its move (a nonlinear conjugate-gradient step of Hestenes–Stiefel
  type on the dual).

A sign change below :data:`NOISE` of the last value is not trusted (the inner solves are
inexact: SMALBE stops them at ``||g^P|| <= min(M ||D x||, eta)``), nor a residual that turned
away from ``d``. ``D x`` is replicated: every rank takes the same step. Sources: the secant
method and regula falsi, and nonlinear conjugate gradients (Hestenes and Stiefel 1952; Nocedal
and Wright 2006, ch. 5); Aitken (1926) for the first factor from the measured ratio.
"""

from __future__ import annotations

import numpy as np

#: The residuals of two outer iterations count as one direction above this cosine (a search
#: starts), and a search ends once its residual's cosine with ``d`` falls below TURNED: the
#: move along ``d`` then excited other modes more than it reduced ``phi``. bench/
#: coulomb_sliding.py (F-mults of the five loads, full / half; without the conjugation):
#: TURNED 0.1: 5 444 / 6 846, 0.3: 5 288 / 6 832, 0.5: 5 234 / 7 058.
ALIGNED = 0.99
TURNED = 0.3
#: A search starts on a ratio ``q = |D x_k| / |D x_{k-1}|`` in (Q_MIN, 1]: a fast or a
#: growing residual is left to the plain update (``q = 1``: the inner solve did not move x).
Q_MIN = 0.5
#: The first factor ``1/(1 - q)`` (Aitken) is capped at FIRST; later ones at GROW times the
#: last and at CAP in all. GROW 1.5: 5 544 / 7 233, 4: 5 831 / 7 360, 2: 5 402 / 6 980
#: (before both corrections); FIRST 30 then: 5 349 / 7 082.
FIRST = 10.0
GROW = 2.0
CAP = 1.0e4
#: A sign change of ``phi`` is trusted only below ``-NOISE`` times its last value.
NOISE = 0.05
#: A search counts as having reached its root (the next one is made conjugate to it) when
#: ``phi`` fell below ROOT times its value at the search's start.
ROOT = 0.25


class DualSearch:
    """The plain update ``rho D x``, with a secant search for the root of ``phi`` along ``d``.

    ``step(Dx, plain)`` takes the residual ``D x_k`` and the plain update ``rho D x_k`` (ρ is
    their ratio) and returns the multiplier update.

    Args:
        conjugate: Make a search that follows one that reached its root conjugate to it.
    """

    def __init__(self, conjugate: bool = True) -> None:
        self.conjugate = conjugate
        self._prev: np.ndarray | None = None
        #: The search in progress: unit direction, phi at the last point, the distance of the
        #: last move along d and its factor over the plain step along d.
        self._d: np.ndarray | None = None
        self._phi = self._t = self._s = 0.0
        #: The search's start: its residual, phi there and the distance moved since.
        self._r_start: np.ndarray | None = None
        self._phi_start = self._moved = 0.0
        #: The last search that reached its root: its direction and ``w ~ H d``.
        self._conj: tuple[np.ndarray, np.ndarray] | None = None
        #: Number of moves along a search direction, secant roots taken back (overshoots),
        #: searches made conjugate.
        self.count = 0
        self.back = 0
        self.conjugated = 0

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
        d = self._start_direction(Dx, n1)
        phi = float(d @ Dx)
        if phi <= 0.0:
            return plain
        self._r_start, self._phi_start, self._moved = Dx.copy(), phi, 0.0
        return self._forward(d, phi, min(1.0 / (1.0 - q), FIRST) if q < 1.0 else GROW,
                             plain, rho)

    def _start_direction(self, Dx: np.ndarray, n1: float) -> np.ndarray:
        """The residual's direction, made conjugate to the last search that found its root."""
        conj, self._conj = self._conj, None
        if conj is not None and self.conjugate:
            d_old, w = conj
            dw = float(d_old @ w)
            if dw > 0.0:  # the dual's curvature along d_old measured as positive
                self.conjugated += 1
                d = Dx - (float(Dx @ w) / dw) * d_old
                return d / float(np.linalg.norm(d))
        return Dx / n1

    def _forward(self, d: np.ndarray, phi: float, s: float, plain: np.ndarray,
                 rho: float) -> np.ndarray:
        """Move ``s`` plain steps along ``d`` (where ``phi > 0``), the plain one across it."""
        self._d, self._phi, self._t, self._s = d, phi, s * rho * phi, s
        self._moved += self._t
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
            if phi1 <= ROOT * self._phi_start:
                self._conj = d, (self._r_start - Dx) / self._moved
            self.reset()
            self._prev = Dx.copy()
            return plain
        # phi kept its sign: the secant's factor, at most GROW times the last one
        secant = t / (rho * (phi0 - phi1)) if phi1 < phi0 else np.inf
        s = max(1.0, min(secant, GROW * s, CAP))
        # the fast part of d that the move excited, -H d_fast t ~ -d_fast t / rho, out of d
        d = d + rho * (Dx - phi1 * d) / t
        d /= float(np.linalg.norm(d))
        phi1 = float(d @ Dx)
        if phi1 <= 0.0:
            self.reset()
            self._prev = Dx.copy()
            return plain
        return self._forward(d, phi1, s, plain, rho)


__all__ = ["DualSearch"]
