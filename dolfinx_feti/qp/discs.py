"""Disc constraints and the set {l <= x <= u} ∩ discs that MPGP works on.

A constraint set gives the MPGP loop (:mod:`.mpgp`) what it needs: the projection, the split of
the gradient into free and chopped parts, the reduced free gradient, the largest feasible step
and the snapped step; :class:`.box.Box` is the set of bounds alone. A disc pair on its circle
is active with outward normal n = (x − c)/||x − c||; its chopped gradient is the part of g not
in the normal cone. Curved sets also give the *rotating* pairs (on the circle and pushed
outwards) and the tangential projection, for the faces that follow the circles.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..parallel.reduce import min_scalar
from .box import Box

# A disc pair is on its circle when ||x - c|| >= (1 - _ON_CIRCLE) r: projections and snapped
# steps put it there up to a few ulps. The projection leaves alone a pair outside by less than
# _OUTSIDE r (a rounding error of an earlier projection), so that it is idempotent.
_ON_CIRCLE = 1e-12
_OUTSIDE = 1e-14


class Discs:
    """Disc constraints ``||(x[i], x[j]) - c|| <= r`` on pairs of *local* entries.

    Args:
        index: (k, 2) local indices (into the rank's part of ``x``) of the pairs; an entry may
            belong to one pair at most.
        centre: (k, 2) centres.
        radius: (k,) radii, >= 0 (``inf``: no constraint; 0: the entry pair is fixed at c).
    """

    def __init__(self, index, centre, radius) -> None:
        self.index = np.asarray(index, dtype=np.int64).reshape(-1, 2)
        self.centre = np.asarray(centre, dtype=np.float64).reshape(-1, 2)
        self.radius = np.asarray(radius, dtype=np.float64).ravel()
        if not (self.centre.shape == self.index.shape and self.radius.size == self.index.shape[0]):
            raise ValueError("Discs: index (k, 2), centre (k, 2) and radius (k,) must agree")

    @property
    def size(self) -> int:
        """Number of discs on this rank."""
        return self.index.shape[0]


class SeparableSet:
    """Local view of the set ``{l <= x <= u} ∩ discs`` with the operations MPGP needs.

    Args:
        lb, ub: Bounds as for :class:`.box.Box`; they must be infinite on disc entries.
        discs: :class:`Discs` or None.
        x: A Vec with the layout of the unknowns.

    Raises:
        ValueError: (on every rank) for invalid bounds or discs.
    """

    def __init__(self, lb, ub, discs: Discs | None, x: PETSc.Vec) -> None:
        self.box = Box(lb, ub, x)
        self.comm = self.box.comm
        d = discs if discs is not None else Discs(np.zeros((0, 2)), np.zeros((0, 2)), [])
        n = x.getLocalSize()
        problems = []
        flat = d.index.ravel()
        if flat.size and (flat.min() < 0 or flat.max() >= n):
            problems.append("a disc index is out of the local range")
        elif np.unique(flat).size != flat.size:
            problems.append("an entry belongs to two discs")
        elif flat.size and (np.isfinite(self.box.l[flat]).any()
                            or np.isfinite(self.box.u[flat]).any()):
            problems.append("finite lb/ub on a disc entry")
        if np.isnan(d.radius).any() or (d.radius < 0).any() or not np.isfinite(d.centre).all():
            problems.append("a disc radius is negative or NaN, or a centre is not finite")
        problems = sorted(set(sum(self.comm.allgather(problems), [])))
        if problems:
            raise ValueError("invalid disc constraints: " + "; ".join(problems))
        self.I, self.c, self.r = d.index, d.centre, d.radius
        self.finite = np.isfinite(self.r)
        #: Whether any rank has a disc: the set's boundary is curved somewhere.
        self.curved = bool(self.comm.allreduce(self.I.size > 0, op=MPI.LOR))

    # --- the discs alone -------------------------------------------------------------------
    def _rel(self, xa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions relative to the centres and their norms."""
        Y = xa[self.I] - self.c
        return Y, np.linalg.norm(Y, axis=1)

    def _on_circle(self, nrm: np.ndarray) -> np.ndarray:
        return self.finite & (nrm >= (1.0 - _ON_CIRCLE) * np.where(self.finite, self.r, 0.0))

    def _disc_ratios(self, xa: np.ndarray, pa: np.ndarray) -> np.ndarray:
        """Largest t >= 0 with the disc pair of x - t p inside its disc (inf if never)."""
        Y, nrm = self._rel(xa)
        P = pa[self.I]
        a = np.einsum("ij,ij->i", P, P)
        bq = np.einsum("ij,ij->i", Y, P)
        r = np.where(self.finite, self.r, 0.0)
        cq = np.minimum(nrm * nrm - r * r, 0.0)  # <= 0 inside (rounding clipped)
        disc = np.sqrt(np.maximum(bq * bq - a * cq, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            # the positive root of a t² − 2 bq t + cq = 0, in its stable form
            t = np.where(bq >= 0, (bq + disc) / a, -cq / (disc - bq))
        t = np.where((a > 0) & self.finite, t, np.inf)
        return np.where(np.isnan(t), 0.0, np.maximum(t, 0.0))

    # --- what MPGP calls -------------------------------------------------------------------
    def project(self, xa: np.ndarray) -> np.ndarray:
        """Return the projection of a local array onto the set."""
        out = self.box.project(xa)
        if self.I.size:
            Y, nrm = self._rel(out)
            with np.errstate(divide="ignore", invalid="ignore"):
                s = np.where(nrm > self.r * (1.0 + _OUTSIDE), self.r / nrm, 1.0)
            out[self.I] = self.c + Y * s[:, None]
        return out

    def split(self, xa: np.ndarray, ga: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(phi, beta, active)``: free and chopped gradient, and the active mask."""
        phi, beta, active = self.box.split(xa, ga)
        if self.I.size:
            Y, nrm = self._rel(xa)
            on = self._on_circle(nrm)
            G = ga[self.I]
            with np.errstate(divide="ignore", invalid="ignore"):
                nvec = np.where(nrm[:, None] > 0, Y / nrm[:, None], 0.0)
            ng = np.einsum("ij,ij->i", nvec, G)
            chopped = G - np.minimum(ng, 0.0)[:, None] * nvec
            chopped[on & (nrm <= 0)] = 0.0  # radius 0: the normal cone is the whole plane
            Ion = self.I[on]
            phi[Ion] = 0.0
            beta[Ion] = chopped[on]
            active[Ion] = True
        return phi, beta, active

    def rotating(self, xa: np.ndarray, ga: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotating entries and their curvature terms.

        The rotating entries are those of the disc pairs on their circle pushed outwards
        (nᵀg <= 0, r > 0); the curvature term of each is ξ/r (ξ = −nᵀg >= 0 the normal force;
        zero elsewhere). On such a pair the minimization goes on along the circle, where the
        Hessian of the Lagrangian restricted to the tangent is ``A + (ξ/r) I``.
        """
        rot = np.zeros(xa.size, dtype=bool)
        curv = np.zeros(xa.size)
        if self.I.size:
            Y, nrm = self._rel(xa)
            on = self._on_circle(nrm) & (nrm > 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                nvec = np.where(nrm[:, None] > 0, Y / nrm[:, None], 0.0)
            ng = np.einsum("ij,ij->i", nvec, ga[self.I])
            sel = on & (ng <= 0.0)
            rot[self.I[sel]] = True
            curv[self.I[sel]] = np.repeat(-ng[sel] / self.r[sel], 2).reshape(-1, 2)
        return rot, curv

    def tangential(self, xa: np.ndarray, va: np.ndarray, rot: np.ndarray) -> np.ndarray:
        """``v`` with its normal component removed on the disc pairs marked in ``rot``."""
        out = va.copy()
        if self.I.size:
            sel = rot[self.I[:, 0]]
            Y, nrm = self._rel(xa)
            nvec = Y[sel] / nrm[sel, None]
            V = va[self.I[sel]]
            out[self.I[sel]] = V - np.einsum("ij,ij->i", V, nvec)[:, None] * nvec
        return out

    def reduced_free(self, xa: np.ndarray, phi: np.ndarray, alpha: float) -> np.ndarray:
        """Reduced free gradient: ``x - alpha * phi~ = P(x - alpha * phi)``."""
        out = self.box.reduced_free(xa, phi, alpha)
        if self.I.size:
            trial = xa.copy()
            trial[self.I] -= alpha * phi[self.I]
            proj = self.project(trial)
            out[self.I] = (xa[self.I] - proj[self.I]) / alpha
        return out

    def max_step(self, xa: np.ndarray, pa: np.ndarray) -> float:
        """Largest ``t >= 0`` with ``x - t p`` feasible, over all ranks (inf if unbounded)."""
        local = float(self.box._ratios(xa, pa).min(initial=np.inf))
        if self.I.size:
            local = min(local, float(self._disc_ratios(xa, pa).min(initial=np.inf)))
        return max(min_scalar(self.comm, local), 0.0)

    def step(self, xa: np.ndarray, pa: np.ndarray, t: float) -> np.ndarray:
        """Return ``x - t p`` with the blocks that reach their boundary put exactly on it."""
        new = self.box.step(xa, pa, t)
        if self.I.size:
            hit = self._disc_ratios(xa, pa) <= t
            Y = xa[self.I] - t * pa[self.I] - self.c
            nrm = np.linalg.norm(Y, axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                s = np.where(hit & (nrm > 0), self.r / nrm, 1.0)
            new[self.I] = self.c + Y * s[:, None]
        return self.project(new)
