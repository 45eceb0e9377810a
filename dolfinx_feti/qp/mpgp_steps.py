"""One MPGP solve: the iterate, its gradient, the work vectors and the steps that move them.

:class:`.mpgp.MPGP` is set up once; each ``solve`` makes an :class:`MPGPSolve` (the state of
that solve) and runs its loop. The steps are the methods: the split of the gradient, the
stopping test, the proportioning test, the CG direction in the face (preconditioned in face),
the CG step (turning disc pairs along their circles), the expansion (its variant an object of
:mod:`.expansion`, chosen when the solver was made) and the proportioning step. The algorithm
and its variants are described in :mod:`.mpgp`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from petsc4py import PETSc

from ..parallel.reduce import any_rank, count, sum_array, sum_scalar
from .box import Box, check_finite
from .discs import SeparableSet
from .precond import Preconditioner
from .problem import QP
from .recycle import galerkin_step
from .result import QPResult
from .start import Counter, feasible_start, step_length

if TYPE_CHECKING:
    from .mpgp import MPGP

# z^T phi below this fraction of ||z|| ||phi|| means that the preconditioned free gradient is
# no descent direction (M^{-1} singular or not positive there): the step falls back to phi.
_DESCENT_RTOL = 1e-12
# p^T A p below this fraction of ||A|| p^T p is treated as zero curvature: rounding makes the
# curvature of a PSD operator along a null direction tiny but positive, not zero.
CURVATURE_RTOL = 1e-14
# The curvature term ξ/r of a rotating disc pair is compared with this fraction of ||A|| (a
# stand-in for the diagonal of A, which the preconditioner does not expose) in the scaling of
# the preconditioner in face: bench/coulomb_sliding.py, the punch at 0.7 𝓕N, h = 0.15/0.25:
# 0.005: 2 417, 0.02: 1 514, 0.05: 1 434, 0.1: 1 678 F-multiplications (11 618 unscaled).
CURVATURE_SCALE = 0.05
# A step along the circles is rejected when it raises the energy by more than this times
# Σ|x||g| (the round-off level of the energy differences).
_ENERGY_NOISE = 64 * np.finfo(float).eps
# A CG step that turns pairs moves x by x0 - t p plus the pull-back c onto the circles; g is
# updated by -t A p and the product A c deferred while the deferred pull-backs d satisfy
# ||A|| |d| <= DRIFT_RTOL ||g^P|| (a fresh gradient then, and always before a stopping test
# is passed): one multiplication per such step instead of two. bench/coulomb_sliding.py, the
# half punch at 0.9 𝓕N with SMALBE's Anderson acceleration: 3 588 → 2 093 F-multiplications
# (0.01: 2 004, 0.5: 1 935).
DRIFT_RTOL = 0.1
# A deflated CG direction p keeps the descent g^T p = g^T r of its undeflated r (z or phi) only
# while the gradient is orthogonal to the recycled directions W; below this fraction of g^T r
# the free gradient lies mostly in span W, which the deflated directions cannot reduce (the
# Galerkin step that started the face was inexact: a Gram matrix W^T A W of condition 1e10
# leaves ~1e-6 of W^T g). bench/ironing.py at h = 0.15, step 44 (with mprgp_project false):
# ||g^P|| stood at 1.25e-12 (|W^T phi| 9.3e-13) for 4 997 CG steps of length ~0 until max_it.
# The face's CG then goes on undeflated (counts['undeflated']).
DEFLATE_DESCENT = 0.5
# A face started by a Galerkin step on stale pairs whose deflation loses the descent
# (DEFLATE_DESCENT: the gradient lies in span W, which the inexact step could not clear) takes
# the Galerkin step on them again, at most this many times a face, before CG goes on
# undeflated. The 4-step moving sphere of tests/drivers/test_krylov_recycle.py on DOLFINx
# 0.11's mesh, with the lengths-only gradient bound: 0 refinements 34, 42, 64
# F-multiplications per warm step, 1: 31, 35, 70, 3: 31, 24, 26 (10: the same); with the
# force bound, which asks the runs for more accuracy, 3: 58, 48, 54 and 10: 58, 32, 34
# (0.5.2's mesh 37, 32, 36 and 37, 26, 29; the sphere S3's path unchanged, 49, 34, 45, 37).
STALE_REFINES = 10


class MPGPSolve:
    """The state of one MPGP solve of ``qp`` from ``x`` (collective; see :meth:`.MPGP.solve`).

    Raises:
        ValueError: For a variant the constraint set does not allow, non-finite data or an
            invalid step length.
        TypeError: For a preconditioner of no accepted kind.
    """

    def __init__(self, solver: MPGP, qp: QP, x: PETSc.Vec, *, stop, b_norm: float | None,
                 g: PETSc.Vec | None, g_valid: bool, rtol: float, atol: float,
                 max_it: int, test=None) -> None:
        name = solver.name
        self.solver, self.x, self.b = solver, x, qp.b
        self.rtol, self.atol, self.max_it = rtol, atol, max_it
        self.comm = x.getComm().tompi4py()
        S = qp.constraints if qp.constraints is not None else Box(None, None, x)
        self.S: Box | SeparableSet = S
        solver.expansion_step.check(name, S.curved)
        self.line_search = solver.proportioning == "line" and not S.curved
        self.tangent = S.curved and solver.face == "tangent"
        use = qp.preconditioner is not None and solver.preconditioning == "face"
        self.prec = Preconditioner(qp.preconditioner) if use else None
        check_finite(self.comm, f"{name}: b", qp.b.array_r)
        check_finite(self.comm, f"{name}: the start x", x.array_r)
        self.mult = Counter(qp.A)
        self.counts = {"cg": 0, "expansion": 0, "proportioning": 0, "norm": 0}
        if solver.expansion_step.rejects:
            self.counts["rejected"] = 0
        if self.prec is not None:
            self.counts["precond"] = 0
        self.alpha_bar, self.scale_A = step_length(name, self.mult, x, self.counts,
                                                   solver.alpha_bar, qp.norm_A)
        self.b_norm = qp.b.norm() if b_norm is None else b_norm
        self.stop, self.test = stop, test
        self.g = feasible_start(name, S.project, self.mult, x, qp.b, g, g_valid, self.comm)
        self.phi, self.beta, self.p, self.Ap = (x.duplicate() for _ in range(4))
        self.Hp = x.duplicate() if self.tangent else self.Ap  # (A + curvature) p on circles
        self.z = self.phi if self.prec is None else x.duplicate()
        self.w = x.duplicate() if self.prec is not None and self.tangent else None
        self.history: list[dict] = []
        self.it, self.kind = 0, "init"
        self.cg_pending = False  # p holds a CG direction to be continued (else restart)
        self.pHp = 1.0
        n = x.getLocalSize()
        self.rot = np.zeros(n, dtype=bool)  # disc entries turning along their circle
        self.curv = np.zeros(n)
        # x − (the straight steps): the pull-backs onto the circles whose A-product g lacks
        self.drift = np.zeros(n) if self.tangent else None
        self.drift_norm = 0.0
        self.gP = math.inf
        # Krylov recycling (flat sets only: on circles the face is not a subspace)
        self.recycle = solver.recycle if not S.curved else None
        self.basis = None  # the recycled directions of this face; deflation on when set
        self.recycled = False  # this face started with the Galerkin step
        # a stale basis's deflation lost the descent: refine by Galerkin steps (STALE_REFINES)
        self.refine, self.refined = False, 0
        if self.recycle is not None:
            self.recycle.bind(qp.operator_key or (qp.A,))
            if self.recycle.stale and not self.recycle.checked:
                self._check_carried()

    # --- the loop --------------------------------------------------------------------------
    def run(self) -> QPResult:
        """Iterate until a stopping test holds; the result."""
        while True:
            phi_a, phi2, beta2, gP, active = self.split()
            self.gP = gP
            reason = self.stopping(gP)
            if reason is not None and self.drift_norm > 0.0:
                self.history.pop()  # tested again on the exact gradient
                self.fresh_gradient()
                continue
            if reason is not None:
                break
            self.it += 1
            kind = None
            if self.proportional(phi_a, beta2):
                kind = self.face_step(active, phi2)
            if kind is None:  # not proportional, or a turning CG step was rejected
                kind = self.proportioning(beta2)
            if kind == "unbounded":
                reason = kind
                break
            self.kind, self.cg_pending = kind, kind == "cg"
            self.recycled = kind == "recycle" or (self.recycled and kind == "cg")
            if not self.recycled:
                self.basis = None
            self.counts[kind] = self.counts.get(kind, 0) + 1  # 'recycle' only once taken
        if self.recycle is not None:
            self.recycle.commit(self.comm)
        return self.result(reason, gP, active)

    def split(self) -> tuple[np.ndarray, float, float, float, np.ndarray]:
        """Split ``g`` into ``phi`` and ``beta``: ``(phi, ||phi||², ||beta||², ||g^P||, active)``.

        With curved faces the tangential gradient of turning pairs counts as free.
        """
        x, g = self.x, self.g
        phi_a, beta_a, active = self.S.split(x.array_r, g.array_r)
        if self.tangent:  # pairs on their circle pushed outwards: their tangential part is free
            rot, self.curv = self.S.rotating(x.array_r, g.array_r)
            self.rot = rot
            phi_a[rot] = beta_a[rot]
            beta_a[rot] = 0.0
        self.phi.array[:] = phi_a
        self.beta.array[:] = beta_a
        phi2, beta2 = self.phi.dot(self.phi), self.beta.dot(self.beta)
        return phi_a, phi2, beta2, math.sqrt(phi2 + beta2), active

    def stopping(self, gP: float) -> str | None:
        """Record the iterate; the reason to stop, or None."""
        monitor, rtol, atol = self.solver.monitor, self.rtol, self.atol
        self.history.append({"it": self.it, "kind": self.kind, "gP": gP})
        if monitor is not None:
            monitor(self.it, gP, self.kind)
        if not math.isfinite(gP):
            return "breakdown"
        if self.test is not None:  # the caller's test replaces the relative one
            if self.test(self.phi.array_r + self.beta.array_r, self.x):
                return "rtol"
        elif gP <= max(rtol * self.b_norm, atol):
            return "rtol" if rtol * self.b_norm >= atol else "atol"
        if self.stop is not None and self.stop(gP, self.x, self.g):
            return "stop"
        if self.it >= self.max_it:
            return "max_it"
        return None

    def proportional(self, phi_a: np.ndarray, beta2: float) -> bool:
        """The proportioning test ``||beta||² <= Gamma² phi~^T phi``."""
        phit_a = self.S.reduced_free(self.x.array_r, phi_a, self.alpha_bar)
        phit_phi = sum_scalar(self.comm, float(np.dot(phit_a, phi_a)))
        gamma = self.solver.gamma
        return beta2 <= gamma * gamma * phit_phi

    # --- the steps in the face -------------------------------------------------------------
    def face_step(self, active: np.ndarray, phi2: float) -> str | None:
        """A CG step, or an expansion where it leaves the set.

        Returns its kind, ``'unbounded'``, or None when a turning CG step was rejected (a
        proportioning step follows).
        """
        x, p, Ap, rot = self.x, self.p, self.Ap, self.rot
        if self.recycle is not None and not self.cg_pending and not self.recycled and \
                self.galerkin(active):
            return "recycle"
        self.direction(active & ~rot, phi2)  # entries fixed in this face: active, not turning
        if self.refine:  # stale deflation lost the descent: the Galerkin step again
            self.refine = False
            self.refined += 1
            if self.galerkin(active, self.basis):
                return "recycle"
            self.basis, self.cg_pending = None, False
            self.direction(active & ~rot, phi2)
        self.mult(p, Ap)
        if self.tangent:
            self.Hp.array[:] = Ap.array_r + self.curv * p.array_r
            moves = any_rank(self.comm, bool(np.any(p.array_r[rot] != 0.0)))
            pf = p.array_r.copy()
            pf[rot] = 0.0  # rotating pairs follow their circle: no limit on the step
        else:
            moves, pf = False, p.array_r
        pHp, gp = p.dot(self.Hp), self.g.dot(p)
        self.pHp = pHp
        t_f = self.S.max_step(x.array_r, pf)
        positive = pHp > CURVATURE_RTOL * self.scale_A * p.dot(p)
        if not positive and self.basis is not None:
            # a deflated direction is a difference of nearly equal vectors when the free
            # gradient lies almost in the recycled space: its curvature is rounding, not A's
            self.basis, self.cg_pending = None, False
            return self.face_step(active, phi2)
        if self.recycle is not None:
            self.recycle.record(p.array_r, Ap.array_r)
        t_cg = gp / pHp if positive else math.inf
        if t_cg <= t_f and math.isfinite(t_cg):
            return self.cg_step(t_cg, moves)
        if not math.isfinite(t_f):
            return "unbounded"
        if moves:
            # To the boundary along p (turning pairs), then a projected free-gradient step.
            x.array[:] = self.S.step(x.array_r, p.array_r, t_f)
            self.fresh_gradient()
            self.projected_step(self.alpha_bar)
            return "expansion"
        step = self.solver.expansion_step
        if self.recycled and self.stop is None and \
                self.solver.galerkin_expansion is not None and self.recycle.project_pays():
            # a face started from the recycled space, in a solve that no outer iteration cuts
            # short (SMALBE's inner solves keep their own step: GalerkinExpansion), while the
            # projection's record says it pays
            step = self.solver.galerkin_expansion
        ok = step.expand(self, t_cg, t_f, gp, pHp, positive)
        return "expansion" if ok else "unbounded"

    def direction(self, fixed: np.ndarray, phi2: float) -> None:
        """The CG direction ``p`` in the face from the (preconditioned) free gradient.

        Preconditioning in face: ``z = D_F M^{-1} D_F phi`` (``phi = D_F g`` already), kept if
        a descent direction. With curved faces the face's Hessian is ``A + C`` (``C`` the
        curvature terms ξ/r of the rotating pairs, :meth:`.discs.SeparableSet.rotating`), which
        ``M^{-1} ≈ A^{-1}`` does not see: ξ is the pair's slip and r its slip bound, a nodal
        force, so C/||A|| grows like 1/h and reached 140 on the punch near gross sliding.
        ``z = S M^{-1} S phi`` with ``S = diag(1/sqrt(1 + c_i/(κ ||A||)))`` (κ =
        :data:`CURVATURE_SCALE`), the symmetric Jacobi-like scaling of ``(A + C)^{-1}``;
        ``S = I`` off the rotating pairs. ``p = r - (r^T H p / p^T H p) p`` continues the
        conjugate direction, else ``p = r``; lost descent (the face changed under rounding)
        restarts.
        """
        x, p, phi, z, S = self.x, self.p, self.phi, self.z, self.S
        r = phi
        if self.prec is not None:
            if self.tangent:  # every rank applies M^{-1} once either way (collective)
                s = 1.0 / np.sqrt(1.0 + self.curv / (CURVATURE_SCALE * self.scale_A))
                self.w.array[:] = phi.array_r * s
                self.prec.apply(self.w, z)
                z.array[:] = z.array_r * s
            else:
                self.prec.apply(phi, z)
            z.array[fixed] = 0.0
            if self.tangent:
                z.array[:] = S.tangential(x.array_r, z.array_r, self.rot)
            if z.dot(phi) > _DESCENT_RTOL * math.sqrt(phi2 * z.dot(z)):
                r = z
        if not self.cg_pending:
            r.copy(p)
            self._deflate(p, r)
            return
        p.aypx(-r.dot(self.Hp) / self.pHp, r)
        self._deflate(p, r)
        if self.tangent:  # the face: interior blocks and the tangents of rotating pairs
            pa = S.tangential(x.array_r, p.array_r, self.rot)
            pa[fixed] = 0.0
            p.array[:] = pa
        if not self.g.dot(p) > 0.0:
            r.copy(p)

    def galerkin(self, active: np.ndarray, basis=None) -> bool:
        """The Galerkin step on the recycled directions of this face (:mod:`.recycle`).

        ``x <- x + t d``, ``g <- g + t A d`` (no product), ``d`` the Galerkin correction on
        the stored directions that vanish on the active entries, ``t`` its minimizing length
        cut at the boundary. On stale pairs (:meth:`.recycle.Recycle.carry`) ``c`` comes from
        the old Gram matrix and ``A d`` is multiplied (one product); the pair ``(d, A d)``
        then replaces the stale column of the largest weight (:meth:`.recycle.Recycle.swap`).
        With ``deflate`` (and an uncut step) the face's CG directions are then kept
        A-conjugate to them. Returns whether ``x`` moved. ``basis``: the face's (a stale
        one's refinement, :meth:`_deflate`), else the store's for ``active``.
        """
        if basis is None:
            self.refined = 0
            basis = self.recycle.basis(active, self.comm)
        if basis is None:
            return False
        xa, ga = self.x.array_r, self.g.array_r
        dAd = basis.galerkin(ga)
        if dAd is None:
            return False
        d, Ad = dAd
        if basis.stale:  # A W of the old operator: the step's own product (p is free here)
            self.p.array[:] = d
            self.mult(self.p, self.Ap)
            Ad = self.Ap.array_r.copy()
            # the exact pair replaces the stale column of the largest weight (the span kept):
            # the stale store turns exact where this solve's errors lie
            if self.recycle.swap(basis.c, d, Ad, self.comm):
                basis = self.recycle.basis(active, self.comm)
        ts = galerkin_step(self.S, xa, ga, d, Ad, self.comm)
        if ts is None:
            return False
        t, t_min = ts
        self.x.array[:] = self.S.step(xa, -d, t)
        self.g.array[:] = ga + t * Ad
        self.recycle.stats["steps"] += 1
        self.recycle.stats["directions"] += basis.m
        self.basis = basis if self.recycle.deflate and t >= t_min else None
        return True

    def _check_carried(self) -> None:
        """The guard of a store carried across a change of the operator (one product)."""
        w, _ = self.recycle.newest()
        self.p.array[:] = w
        self.mult(self.p, self.Ap)
        self.recycle.check(self.Ap.array_r, self.comm)

    def _deflate(self, p: PETSc.Vec, r: PETSc.Vec) -> None:
        """Make ``p`` A-conjugate to the face's recycled directions (deflated CG).

        With the gradient orthogonal to them, deflation keeps ``g^T p = g^T r``; where it
        loses more than :data:`DEFLATE_DESCENT` of it, the gradient lies in their span (the
        Galerkin step was inexact) and the deflated operator cannot reduce it: the basis is
        dropped for the rest of this face and CG restarts from ``r`` (one dot product more).
        """
        if self.basis is None:
            return
        p.array[:] = self.basis.conjugate(p.array_r)
        gp, gr = sum_array(self.comm, np.array([float(self.g.array_r @ p.array_r),
                                                 float(self.g.array_r @ r.array_r)]))
        if gp < DEFLATE_DESCENT * gr and self.basis.stale and self.refined < STALE_REFINES:
            self.refine = True
            return
        if gp < DEFLATE_DESCENT * gr:
            self.basis, self.cg_pending = None, False
            self.counts["undeflated"] = self.counts.get("undeflated", 0) + 1
            r.copy(p)

    def cg_step(self, t_cg: float, moves: bool) -> str | None:
        """The feasible CG step ``x <- x - t_cg p``: ``'cg'``, or None if rejected.

        Along the circles when pairs turn, kept unless the energy increased (else None,
        counted in ``counts['rejected']``).
        """
        x, p = self.x, self.p
        if not moves:
            x.array[:] = self.S.step(x.array_r, p.array_r, t_cg)
            self.g.axpy(-t_cg, self.Ap)
            return "cg"
        if self.turn(t_cg):
            return "cg"
        self.counts["rejected"] = self.counts.get("rejected", 0) + 1
        return None

    def turn(self, t: float) -> bool:
        """A CG step that turns disc pairs along their circles: x <- P(x - t p).

        The gradient follows as ``g - t A p``, the product with the pull-back onto the circles
        (``c = x1 - (x0 - t p)``) deferred while the deferred products move g by at most
        :data:`DRIFT_RTOL` ||g^P|| (:meth:`_defer`); else a fresh gradient. Kept unless the
        energy increased: f(x1) - f(x0) = ½ (x1 - x0)ᵀ(g0 + g1) for a quadratic, without the
        cancellation of f(x1) - f(x0); the rounding of x on the circles, where g is large,
        moves f by ~ eps Σ|x||g|: tolerated. The deferred products err that difference by at
        most ½ |x1 - x0| ||A|| (|d0| + |d1|) (d the pull-backs not yet multiplied): a step
        the bound leaves in doubt is decided on a fresh gradient. On rejection x, g and the
        deferred pull-backs are restored.
        """
        x, g = self.x, self.g
        x0, g0 = x.array_r.copy(), g.copy()
        drift0 = None if self.drift is None else (self.drift.copy(), self.drift_norm)
        x.array[:] = self.S.step(x.array_r, self.p.array_r, t)
        deferred = self.drift is not None and self._defer(x0, t)
        if not deferred:
            self.fresh_gradient()
        n0 = 0.0 if drift0 is None else drift0[1]
        while True:
            xa, ga = x.array_r, g.array_r
            df, noise, dx2 = sum_array(self.comm, np.array([
                0.5 * float(np.dot(xa - x0, g0.array_r + ga)),
                float(np.abs(x0) @ np.abs(g0.array_r) + np.abs(xa) @ np.abs(ga)),
                float(np.dot(xa - x0, xa - x0))]))
            n1 = 0.0 if self.drift is None else self.drift_norm
            err = 0.5 * math.sqrt(dx2) * self.scale_A * (n0 + n1)
            if df + err <= _ENERGY_NOISE * noise:
                g0.destroy()
                return True
            if not deferred:
                break
            deferred = False  # in doubt: decide on the fresh gradient
            self.fresh_gradient()
        if drift0 is not None:  # g0 lacks the products of the pull-backs before this step
            self.drift[:], self.drift_norm = drift0
        x.array[:] = x0
        g0.copy(g)
        g0.destroy()
        return False

    def _defer(self, x0: np.ndarray, t: float) -> bool:
        """``g -= t A p`` for a step that turned pairs, the pull-back's product deferred.

        Returns False (nothing done) when the pull-backs not yet multiplied would move g by
        more than :data:`DRIFT_RTOL` ||g^P|| (bounded by ||A|| times their norm).
        """
        c = self.x.array_r - (x0 - t * self.p.array_r)
        d = self.drift + c
        nd = math.sqrt(sum_scalar(self.comm, float(d @ d)))
        if self.scale_A * nd > DRIFT_RTOL * self.gP:
            return False
        self.drift[:] = d
        self.drift_norm = nd
        self.g.axpy(-t, self.Ap)
        return True

    # --- what the expansions are made of ---------------------------------------------------
    def energy(self) -> float:
        """``f(x) = 1/2 x^T (A x - b) - 1/2 b^T x`` from the gradient (no product)."""
        return 0.5 * (self.x.dot(self.g) - self.x.dot(self.b))

    def fresh_gradient(self) -> None:
        """``g = A x - b`` (one product)."""
        self.mult(self.x, self.g)
        self.g.axpy(-1.0, self.b)
        if self.drift is not None:
            self.drift[:] = 0.0
            self.drift_norm = 0.0

    def half_step(self, t_f: float) -> None:
        """To the boundary along ``p``: ``x <- x - t_f p``, ``g <- g - t_f A p``."""
        self.x.array[:] = self.S.step(self.x.array_r, self.p.array_r, t_f)
        self.g.axpy(-t_f, self.Ap)

    def projected_step(self, step: float) -> None:
        """``x <- P(x - step phi(x))`` with a fresh gradient."""
        xa = self.x.array_r
        phi_a = self.S.split(xa, self.g.array_r)[0]
        self.x.array[:] = self.S.project(xa - step * phi_a)
        self.fresh_gradient()

    # --- the proportioning step and the result ---------------------------------------------
    def proportioning(self, beta2: float) -> str:
        """The proportioning step: ``'proportioning'``, or ``'unbounded'``.

        The gradient projection ``x <- P(x - alpha_bar g)`` (MPGP's), or on a flat set with
        ``proportioning='line'`` the exact line search along ``beta`` cut at the opposite
        bound (MPRGP's).
        """
        x, g, beta, S = self.x, self.g, self.beta, self.S
        if not self.line_search:
            x.array[:] = S.project(x.array_r - self.alpha_bar * g.array_r)
            self.fresh_gradient()
            return "proportioning"
        self.mult(beta, self.Ap)
        bAb = beta.dot(self.Ap)
        t_f = S.max_step(x.array_r, beta.array_r)
        positive = bAb > CURVATURE_RTOL * self.scale_A * beta2
        t = min(beta2 / bAb if positive else math.inf, t_f)
        if not math.isfinite(t):
            return "unbounded"
        x.array[:] = S.step(x.array_r, beta.array_r, t)
        g.axpy(-t, self.Ap)
        return "proportioning"

    def result(self, reason: str, gP: float, active: np.ndarray) -> QPResult:
        """The record of the solve."""
        if self.prec is not None:
            self.counts["precond"] = self.prec.count
        active_count = count(self.comm, int(np.count_nonzero(active)))
        return QPResult(x=self.x, converged=reason in ("rtol", "atol", "stop"), reason=reason,
                        iterations=self.it, hessian_mults=self.mult.n, counts=self.counts,
                        gP_norm=gP, b_norm=self.b_norm, active=active,
                        active_count=active_count, history=self.history,
                        objective=self.energy())


__all__ = ["CURVATURE_RTOL", "CURVATURE_SCALE", "DEFLATE_DESCENT", "STALE_REFINES",
           "MPGPSolve"]
