"""Box constraints ``l <= x <= u`` on the local part of a distributed vector.

All work here is elementwise NumPy on local arrays; the only communication is the global
minimum in :meth:`Box.max_step` and the validation in the constructor. Infinite bounds are
handled by IEEE arithmetic (``x - (-inf) = inf``), never by special cases.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc


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
    if comm.allreduce(bad, op=MPI.LOR):
        raise ValueError(f"{what} has non-finite entries")


class Box:
    """Local view of ``l <= x <= u`` with the operations MPRGP needs.

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

    def project(self, xa: np.ndarray) -> np.ndarray:
        """Return the projection of a local array onto the box."""
        return np.clip(xa, self.l, self.u)

    def split(self, xa: np.ndarray, ga: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(phi, beta, active)``: free and chopped gradient, and the at-a-bound mask.

        ``beta`` is ``min(g, 0)`` at a lower bound and ``max(g, 0)`` at an upper bound; an entry
        with ``l = u`` cannot move and contributes to neither.
        """
        at_l = xa <= self.l
        at_u = xa >= self.u
        active = at_l | at_u
        phi = np.where(active, 0.0, ga)
        beta = np.where(at_l & ~at_u, np.minimum(ga, 0.0),
                        np.where(at_u & ~at_l, np.maximum(ga, 0.0), 0.0))
        return phi, beta, active

    def reduced_free(self, xa: np.ndarray, phi: np.ndarray, alpha: float) -> np.ndarray:
        """Reduced free gradient: the largest part of ``phi`` with ``x - alpha phi~`` feasible.

        ``x - alpha * phi~`` equals ``P_box(x - alpha * phi)``.
        """
        return np.where(phi > 0, np.minimum((xa - self.l) / alpha, phi),
                        np.where(phi < 0, np.maximum((xa - self.u) / alpha, phi), 0.0))

    def _ratios(self, xa: np.ndarray, pa: np.ndarray) -> np.ndarray:
        """Step length at which each entry of ``x - t p`` meets its bound (inf if never)."""
        ratios = np.full(xa.shape, np.inf)
        down = pa > 0
        up = pa < 0
        ratios[down] = (xa[down] - self.l[down]) / pa[down]
        ratios[up] = (xa[up] - self.u[up]) / pa[up]
        return ratios

    def max_step(self, xa: np.ndarray, pa: np.ndarray) -> float:
        """Largest ``t >= 0`` with ``x - t p`` feasible, over all ranks (inf if unbounded)."""
        local = float(self._ratios(xa, pa).min(initial=np.inf))
        return max(self.comm.allreduce(local, op=MPI.MIN), 0.0)

    def step(self, xa: np.ndarray, pa: np.ndarray, t: float) -> np.ndarray:
        """Return ``x - t p`` with the entries that reach a bound set exactly to it.

        Entries whose bound-hitting step is ``<= t`` are snapped (so the active set is exact
        despite rounding); the final clip removes rounding overshoots elsewhere.
        """
        ratios = self._ratios(xa, pa)
        new = xa - t * pa
        hit = ratios <= t
        new[hit & (pa > 0)] = self.l[hit & (pa > 0)]
        new[hit & (pa < 0)] = self.u[hit & (pa < 0)]
        return self.project(new)
