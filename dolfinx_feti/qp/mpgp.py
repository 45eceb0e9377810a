"""MPGP: modified proportioning with gradient projections for separable convex constraints.

Minimizes ``f(x) = 1/2 x^T A x - b^T x`` over a product of simple convex sets: every entry of
``x`` lies in an interval ``l_i <= x_i <= u_i`` (infinite bounds allowed), except the entries
grouped in pairs by :class:`Discs`, each pair in a disc ``||(x_i, x_j) - c|| <= r``. This is
the dual of 3D contact with Tresca friction (a disc per contact node on the two tangential
multipliers). Source: Dostál, Kozubek et al., MPGP for separable convex constraints (Dostál,
Kozubek, Sadowská, Vondrák, *Scalable Algorithms for Contact Problems*, 2016, chapter on
MPGP); the algorithm is MPRGP (:mod:`.mprgp`) with the box replaced by the set:

- a block (an entry, or a disc pair) is *active* when it lies on the boundary of its set, with
  outward unit normal n (for an entry at its lower bound n = -1, at its upper bound n = +1,
  for a disc pair n = (x - c)/||x - c||);
- free gradient φ = g on the blocks that are not active, 0 on the active ones;
- chopped gradient β = g - min(nᵀg, 0) n on the active blocks (the part of g that is not in
  the normal cone -N(x): g + N(x) ∋ 0 is the KKT condition), 0 on the others; the projected
  gradient is gᴾ = φ + β and vanishes exactly at the solution;
- reduced free gradient φ̃ = (x - P(x - ᾱ φ))/ᾱ;
- proportional iterate (‖β‖² <= Γ² φ̃ᵀφ): a CG step in the face if it stays feasible, else an
  expansion: the largest feasible step along the CG direction, then ``x <- P(x - ᾱ φ(x))``;
- otherwise a proportioning step, the gradient projection ``x <- P(x - ᾱ g(x))`` (a line
  search along β, as MPRGP does, leaves a curved boundary at once).

For interval constraints only it solves the same problems as :func:`.mprgp.mprgp` (with a
different proportioning step).

Curved faces (``face='tangent'``, the default; ``face='interior'`` is the algorithm above as
published). A disc pair on its circle whose gradient pushes it outwards (nᵀg <= 0) is at a
minimum in the normal direction and can only turn along the circle; with the plain definition
its tangential gradient counts in β, and only gradient projection steps of length ᾱ move it,
which converges slowly when many contact nodes slip (measured: 5–40× the frictionless number of
F-multiplications on the 3D blocks of ``demos/demo_tresca3d.py``). With ``'tangent'`` such a
pair belongs to the face: its tangential gradient counts in φ, the CG direction is kept
tangent to its circle, the step length is that of the model with the Hessian of the Lagrangian
on the circle, ``A + (ξ/r) I`` (ξ = −nᵀg the normal force; the exact second-order model of the
energy along the projected step), and the step ``x <- P(x - t p)`` goes along the circle (the
projection maps the tangent back to the circle). Such a step takes a fresh gradient (a second
multiplication) and is kept unless the energy increased beyond round-off, else a gradient
projection step follows. The expansion and proportioning steps and the stopping test are
unchanged (gᴾ = φ + β is the same vector). Measured: 3–6× fewer multiplications on the 3D
blocks (see docs/friction.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .box import Box, check_finite
from .precond import Preconditioner
from .result import QPResult
from .start import Counter, feasible_start, step_length

# A disc pair is on its circle when ||x - c|| >= (1 - _ON_CIRCLE) r: projections and snapped
# steps put it there up to a few ulps. The projection leaves alone a pair outside by less than
# _OUTSIDE r (a rounding error of an earlier projection), so that it is idempotent.
_ON_CIRCLE = 1e-12
_OUTSIDE = 1e-14
_DESCENT_RTOL = 1e-12
# A step along the circles is rejected when it raises the energy by more than this times
# Σ|x||g| (the round-off level of the energy differences).
_ENERGY_NOISE = 64 * np.finfo(float).eps
_CURVATURE_RTOL = 1e-14


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
        return max(self.comm.allreduce(local, op=MPI.MIN), 0.0)

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


def mpgp(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, *, lb=None, ub=None,
         discs: Discs | None = None, rtol: float = 1e-6, atol: float = 0.0, gamma: float = 1.0,
         alpha_bar: float | None = None, norm_A: float | None = None, max_it: int = 10000,
         stop: Callable[[float, PETSc.Vec, PETSc.Vec], bool | None] | None = None,
         monitor: Callable[[int, float, str], None] | None = None,
         b_norm: float | None = None, g: PETSc.Vec | None = None, g_valid: bool = False,
         preconditioner=None, expansion: str = "fixed", alpha: str = "fixed",
         face: str = "tangent") -> QPResult:
    """Solve ``min 1/2 x^T A x - b^T x`` s.t. ``lb <= x <= ub`` and the discs, by MPGP.

    Collective. The arguments and the result are those of :func:`.mprgp.mprgp` (so SMALBE can
    use either as its inner solver), plus ``discs`` and ``face`` (``'tangent'`` or
    ``'interior'``, see the module docstring); ``expansion`` and ``alpha`` exist for that
    compatibility and only ``'fixed'`` is implemented. ``result.active`` marks the entries of
    the blocks on their boundary (both entries of a disc pair on its circle).

    Hessian multiplications: 1 for the initial gradient (0 when ``g_valid``), 1 per CG step (2
    when it turns pairs along their circles), 2 per expansion (3 when its first half turns
    pairs), 1 per proportioning step, 3 per rejected turning step (``counts['rejected']``) and
    its proportioning step, plus the norm estimate when neither ``alpha_bar`` nor ``norm_A`` is
    given.

    Raises:
        ValueError: For invalid bounds or discs, non-finite data, or invalid parameters.
    """
    comm = x.getComm().tompi4py()
    if expansion != "fixed" or alpha != "fixed":
        raise ValueError(f"mpgp: only the fixed expansion is implemented, got "
                         f"expansion={expansion!r}, alpha={alpha!r}")
    if not gamma > 0 or rtol < 0 or atol < 0 or max_it < 0:
        raise ValueError("mpgp: need gamma > 0 and non-negative rtol, atol, max_it")
    if face not in ("tangent", "interior"):
        raise ValueError(f"mpgp: face must be 'tangent' or 'interior', got {face!r}")
    tangent = face == "tangent"
    prec = None if preconditioner is None else Preconditioner(preconditioner)
    S = SeparableSet(lb, ub, discs, x)
    check_finite(comm, "mpgp: b", b.array_r)
    check_finite(comm, "mpgp: the start x", x.array_r)
    mult = Counter(A)
    counts = {"cg": 0, "expansion": 0, "proportioning": 0, "norm": 0}
    if prec is not None:
        counts["precond"] = 0
    alpha_bar, scale_A = step_length("mpgp", mult, x, counts, alpha_bar, norm_A)
    if b_norm is None:
        b_norm = b.norm()

    g = feasible_start("mpgp", S.project, mult, x, b, g, g_valid, comm)

    phi, beta, p, Ap = x.duplicate(), x.duplicate(), x.duplicate(), x.duplicate()
    Hp = x.duplicate()  # (A + curvature) p
    z = phi if prec is None else x.duplicate()
    history: list[dict] = []
    it, kind, reason = 0, "init", "max_it"
    cg_pending = False
    pHp = 1.0
    rot = np.zeros(x.getLocalSize(), dtype=bool)
    curv = np.zeros(x.getLocalSize())
    while True:
        phi_a, beta_a, active = S.split(x.array_r, g.array_r)
        if tangent:  # pairs on their circle pushed outwards: their tangential part is free
            rot, curv = S.rotating(x.array_r, g.array_r)
            phi_a[rot] = beta_a[rot]
            beta_a[rot] = 0.0
        phi.array[:] = phi_a
        beta.array[:] = beta_a
        phi2, beta2 = phi.dot(phi), beta.dot(beta)
        gP = math.sqrt(phi2 + beta2)
        history.append({"it": it, "kind": kind, "gP": gP})
        if monitor is not None:
            monitor(it, gP, kind)
        if not math.isfinite(gP):
            reason = "breakdown"
            break
        if gP <= max(rtol * b_norm, atol):
            reason = "rtol" if rtol * b_norm >= atol else "atol"
            break
        if stop is not None and stop(gP, x, g):
            reason = "stop"
            break
        if it >= max_it:
            reason = "max_it"
            break
        it += 1
        phit_a = S.reduced_free(x.array_r, phi_a, alpha_bar)
        phit_phi = comm.allreduce(float(np.dot(phit_a, phi_a)))
        proportional = beta2 <= gamma * gamma * phit_phi
        if proportional:
            fixed = active & ~rot  # entries that do not move in this face
            r = phi
            if prec is not None:
                prec.apply(phi, z)
                z.array[fixed] = 0.0
                if tangent:
                    z.array[:] = S.tangential(x.array_r, z.array_r, rot)
                if z.dot(phi) > _DESCENT_RTOL * math.sqrt(phi2 * z.dot(z)):
                    r = z
            if cg_pending:
                p.aypx(-r.dot(Hp) / pHp, r)
                if tangent:  # the face: interior blocks and the tangents of rotating pairs
                    pa = S.tangential(x.array_r, p.array_r, rot)
                    pa[fixed] = 0.0
                    p.array[:] = pa
                if not g.dot(p) > 0.0:
                    r.copy(p)
            else:
                r.copy(p)
            mult(p, Ap)
            Hp.array[:] = Ap.array_r + curv * p.array_r
            pHp, gp = p.dot(Hp), g.dot(p)
            moves = comm.allreduce(bool(np.any(p.array_r[rot] != 0.0)), op=MPI.LOR)
            pf = p.array_r.copy()
            pf[rot] = 0.0  # rotating pairs follow their circle: no limit on the step
            t_f = S.max_step(x.array_r, pf)
            positive = pHp > _CURVATURE_RTOL * scale_A * p.dot(p)
            t_cg = gp / pHp if positive else math.inf
            if t_cg <= t_f and math.isfinite(t_cg):
                if not moves:
                    x.array[:] = S.step(x.array_r, p.array_r, t_cg)
                    g.axpy(-t_cg, Ap)
                    kind, cg_pending = "cg", True
                    counts["cg"] += 1
                    continue
                # A step along the circles (the tangent step, projected back): a fresh
                # gradient, kept unless the energy increased. f(x1) - f(x0) = ½ (x1 - x0)ᵀ(g0 +
                # g1) for a quadratic, without the cancellation of f(x1) - f(x0); the rounding
                # of x on the circles, where g is large, moves f by ~ eps Σ|x||g|: tolerated.
                x0, g0 = x.array_r.copy(), g.copy()
                x.array[:] = S.step(x.array_r, p.array_r, t_cg)
                mult(x, g)
                g.axpy(-1.0, b)
                xa, ga = x.array_r, g.array_r
                df, noise = comm.allreduce(np.array([
                    0.5 * float(np.dot(xa - x0, g0.array_r + ga)),
                    float(np.abs(x0) @ np.abs(g0.array_r) + np.abs(xa) @ np.abs(ga))]))
                if df <= _ENERGY_NOISE * noise:
                    kind, cg_pending = "cg", True
                    counts["cg"] += 1
                    continue
                x.array[:] = x0
                g0.copy(g)
                counts["rejected"] = counts.get("rejected", 0) + 1
                proportional = False  # fall back to a gradient projection step
            else:
                if not math.isfinite(t_f):
                    reason = "unbounded"
                    break
                # Expansion: to the boundary along p, then a projected free-gradient step.
                x.array[:] = S.step(x.array_r, p.array_r, t_f)
                if moves:
                    mult(x, g)
                    g.axpy(-1.0, b)
                else:
                    g.axpy(-t_f, Ap)
                phi_h = S.split(x.array_r, g.array_r)[0]
                x.array[:] = S.project(x.array_r - alpha_bar * phi_h)
                mult(x, g)
                g.axpy(-1.0, b)
                kind, cg_pending = "expansion", False
                counts["expansion"] += 1
        if not proportional:
            # Proportioning: the gradient projection step with the full gradient.
            x.array[:] = S.project(x.array_r - alpha_bar * g.array_r)
            mult(x, g)
            g.axpy(-1.0, b)
            kind, cg_pending = "proportioning", False
            counts["proportioning"] += 1

    if prec is not None:
        counts["precond"] = prec.count
    active_count = comm.allreduce(int(np.count_nonzero(active)))
    objective = 0.5 * (x.dot(g) - x.dot(b))
    return QPResult(x=x, converged=reason in ("rtol", "atol", "stop"), reason=reason,
                    iterations=it, hessian_mults=mult.n, counts=counts, gP_norm=gP,
                    b_norm=b_norm, active=active, active_count=active_count, history=history,
                    objective=objective)
