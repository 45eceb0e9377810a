"""Box constraints ``l <= x <= u`` on the local part of a distributed vector.

All work here is elementwise NumPy on local arrays, restricted to the entries with a finite
bound (the others are never touched); the only communication is the global minimum in
:meth:`Box.max_step` and the validation in the constructor. A one-sided bound is handled by
IEEE arithmetic (``x - (-inf) = inf``), never by special cases.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..parallel.reduce import any_rank, min_scalar


def _local_bound(bound, x: PETSc.Vec, default: float) -> np.ndarray:
    if bound is None:
        return np.full(x.getLocalSize(), default)
    if isinstance(bound, PETSc.Vec):
        if bound.getSizes() != x.getSizes():
            raise ValueError(f"bound layout {bound.getSizes()} differs from x {x.getSizes()}")
        return np.array(bound.array_r, dtype=np.float64)
    return np.full(x.getLocalSize(), float(bound))


def check_finite(comm: MPI.Comm, what: str, *arrays: np.ndarray) -> None:
    """Raise ValueError on every rank if any local array holds a non-finite entry anywhere."""
    bad = any(not np.all(np.isfinite(a)) for a in arrays)
    if any_rank(comm, bad):
        raise ValueError(f"{what} has non-finite entries")


class Box:
    """Local view of ``l <= x <= u`` with the operations MPRGP needs (a flat constraint set).

    Args:
        lb: Lower bound: a Vec laid out like ``x``, a scalar, or None (``-inf``).
        ub: Upper bound, likewise (None means ``+inf``).
        x: A Vec with the layout of the unknowns.

    Raises:
        ValueError: (on every rank) for NaN bounds, ``lb > ub``, ``lb = +inf`` or ``ub = -inf``.
    """

    def __init__(self, lb, ub, x: PETSc.Vec) -> None:
        self.comm = x.getComm().tompi4py()
        self.l = _local_bound(lb, x, -np.inf)
        self.u = _local_bound(ub, x, np.inf)
        problems = []
        if np.isnan(self.l).any() or np.isnan(self.u).any():
            problems.append("a bound is NaN")
        if (self.l > self.u).any():
            problems.append("lb > ub somewhere (empty feasible set)")
        if (self.l == np.inf).any() or (self.u == -np.inf).any():
            problems.append("lb = +inf or ub = -inf somewhere (empty feasible set)")
        # Every rank must raise together, otherwise the others hang in the next collective.
        problems = sorted(set(sum(self.comm.allgather(problems), [])))
        if problems:
            raise ValueError("infeasible or invalid bounds: " + "; ".join(problems))
        # The work is done on the bounded entries only: in FETI most rows (the gluing ones)
        # are unbounded, and on them every box operation is the identity.
        bounded = np.flatnonzero(np.isfinite(self.l) | np.isfinite(self.u))
        self._sel = slice(None) if bounded.size == self.l.size else bounded
        self._l, self._u = self.l[self._sel], self.u[self._sel]

    #: A box has no curved boundary (see :class:`.discs.SeparableSet`).
    curved = False

    def project(self, xa: np.ndarray) -> np.ndarray:
        """Return the projection of a local array onto the box."""
        out = np.array(xa, dtype=np.float64)
        sel = self._sel
        out[sel] = np.clip(xa[sel], self._l, self._u)
        return out

    def split(self, xa: np.ndarray, ga: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(phi, beta, active)``: free and chopped gradient, and the at-a-bound mask.

        ``beta`` is ``min(g, 0)`` at a lower bound and ``max(g, 0)`` at an upper bound; an entry
        with ``l = u`` cannot move and contributes to neither.
        """
        sel, xs, gs = self._sel, xa[self._sel], ga[self._sel]
        at_l = xs <= self._l
        at_u = xs >= self._u
        act = at_l | at_u
        phi = np.array(ga, dtype=np.float64)
        phi[sel] = np.where(act, 0.0, gs)
        beta = np.zeros_like(phi)
        beta[sel] = np.where(at_l & ~at_u, np.minimum(gs, 0.0),
                             np.where(at_u & ~at_l, np.maximum(gs, 0.0), 0.0))
        active = np.zeros(phi.shape, dtype=bool)
        active[sel] = act
        return phi, beta, active

    def reduced_free(self, xa: np.ndarray, phi: np.ndarray, alpha: float) -> np.ndarray:
        """Reduced free gradient: the largest part of ``phi`` with ``x - alpha phi~`` feasible.

        ``x - alpha * phi~`` equals ``P_box(x - alpha * phi)``.
        """
        sel, xs, ps = self._sel, xa[self._sel], phi[self._sel]
        out = np.array(phi, dtype=np.float64)
        out[sel] = np.where(ps > 0, np.minimum((xs - self._l) / alpha, ps),
                            np.where(ps < 0, np.maximum((xs - self._u) / alpha, ps), 0.0))
        return out

    def _ratios(self, xa: np.ndarray, pa: np.ndarray) -> np.ndarray:
        """Step lengths at which the bounded entries of ``x - t p`` meet their bounds.

        ``inf`` where an entry never does; the unbounded entries are left out.
        """
        xs, ps = xa[self._sel], pa[self._sel]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(ps > 0, (xs - self._l) / ps,
                            np.where(ps < 0, (xs - self._u) / ps, np.inf))

    def max_step(self, xa: np.ndarray, pa: np.ndarray) -> float:
        """Largest ``t >= 0`` with ``x - t p`` feasible, over all ranks (inf if unbounded)."""
        local = float(self._ratios(xa, pa).min(initial=np.inf))
        return max(min_scalar(self.comm, local), 0.0)

    def step(self, xa: np.ndarray, pa: np.ndarray, t: float) -> np.ndarray:
        """Return ``x - t p`` with the entries that reach a bound set exactly to it.

        Entries whose bound-hitting step is ``<= t`` are snapped (so the active set is exact
        despite rounding); the final clip removes rounding overshoots elsewhere.
        """
        sel, ps = self._sel, pa[self._sel]
        hit = self._ratios(xa, pa) <= t
        new = xa - t * pa
        ns = new[sel]
        ns = np.where(hit & (ps > 0), self._l, np.where(hit & (ps < 0), self._u, ns))
        new[sel] = np.clip(ns, self._l, self._u)
        return new
