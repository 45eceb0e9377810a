"""Conjugate gradients, optionally preconditioned and projected onto ``Im P`` (FETI)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import ClassVar

from petsc4py import PETSc

from ..validation import OptionSet
from .equality import Projector
from .precond import Preconditioner
from .problem import QP
from .result import QPResult
from .solver import QPSolver


class CG(QPSolver):
    """CG for ``min 1/2 x^T A x - b^T x`` s.t. ``D x = 0`` (the QP's ``eq``, optional).

    With an equality constraint ``D`` (orthonormal rows, ``P = I - D^T D``) the start is
    replaced by ``P x`` and every residual is projected, so the iterates stay in
    ``Im P = ker D``: this solves ``P A P x = P b`` for an ``A`` that is positive semidefinite
    and positive definite on ``Im P`` (consistent there).

    With the QP's preconditioner ``M^{-1}`` (an approximate inverse of ``A``, symmetric
    positive definite on ``Im P``) this is PCG with the preconditioned residual
    ``z = P M^{-1} P r`` (the projected preconditioner of classical FETI; ``z = M^{-1} r``
    without a constraint): ``p_0 = z_0``, ``a_k = r_k^T z_k / p_k^T A p_k``,
    ``p_{k+1} = z_{k+1} + (r_{k+1}^T z_{k+1} / r_k^T z_k) p_k``. Each iteration applies
    ``M^{-1}`` once (``counts['precond']``, equal to the number of iterations); a non-positive
    ``r^T z`` ends the solve with ``'breakdown'``.

    Stopping test: ``||r_k|| <= max(rtol * ||P b||, atol)`` where ``r_k`` is the recursively
    updated projected residual ``P (b - A x_k)`` (``P = I`` without a constraint), the
    *un*preconditioned residual with or without a preconditioner, so the test means the same
    thing in both cases. The recursion drifts from the true residual only by rounding; no
    extra multiplication is spent to recompute it.

    Args:
        rtol: Relative tolerance (relative to ``||P b||``).
        atol: Absolute tolerance.
        max_it: Maximum number of iterations.
        monitor: Called as ``monitor(it, residual_norm, kind)`` with ``kind`` ``'init'`` or
            ``'cg'``.
        options_prefix: Where to read declared options (CG declares none: its tolerances
            are those of the caller, e.g. ``-feti_rtol``).

    Raises:
        ValueError: For a negative ``rtol``, ``atol`` or ``max_it``.
    """

    options: ClassVar[OptionSet] = OptionSet("cg", "conjugate gradients (no inequality)")
    name: ClassVar[str] = "cg"

    def __init__(self, *, rtol: float = 1e-6, atol: float = 0.0, max_it: int = 1000,
                 monitor: Callable[[int, float, str], None] | None = None,
                 options_prefix: str | None = None) -> None:
        if rtol < 0 or atol < 0 or max_it < 0:
            raise ValueError("cg: rtol, atol and max_it must be non-negative")
        self._set_options(options_prefix)
        self.rtol, self.atol, self.max_it, self.monitor = rtol, atol, max_it, monitor

    def solve(self, qp: QP, x: PETSc.Vec, *, test=None) -> QPResult:
        """Minimize ``qp`` from ``x`` (overwritten with the solution; collective).

        Args:
            qp: The QP (no inequality constraint).
            x: The start.
            test: A test of the projected residual that replaces ``||r|| <= max(rtol ||P b||,
                atol)`` (:class:`.stopping.MaxGradientTest`); its success is reported as
                ``'rtol'``.

        Returns:
            The result; ``reason`` is ``'rtol'``/``'atol'``, ``'max_it'`` or ``'breakdown'``
            (``p^T A p <= 0``, ``r^T z <= 0`` or a non-finite value). ``counts`` has ``'cg'``
            and, with a preconditioner, ``'precond'``.

        Raises:
            ValueError: For a QP with inequality constraints, or non-finite ``b`` or initial
                residual.
        """
        if qp.constraints is not None:
            raise ValueError("cg: the QP has inequality constraints; solve it by MPRGP, MPGP "
                             "or SMALBE")
        return _CGSolve(self, qp, x, test).run()


class _CGSolve:
    """The state of one CG solve."""

    def __init__(self, solver: CG, qp: QP, x: PETSc.Vec, test=None) -> None:
        self.solver, self.A, self.x, self.test = solver, qp.A, x, test
        pre = qp.preconditioner
        self.prec = None if pre is None else Preconditioner(pre)
        self.projector = None if qp.eq is None else Projector(qp.eq)
        self.r, self.p, self.Ap = x.duplicate(), x.duplicate(), x.duplicate()
        self.z = self.r if self.prec is None else x.duplicate()
        self.b_norm = self._start(qp.b)
        self.tol = max(solver.rtol * self.b_norm, solver.atol)

    def _project(self, v: PETSc.Vec) -> None:
        if self.projector is not None:
            self.projector.apply(v, v)

    def _start(self, b: PETSc.Vec) -> float:
        """Project the start, set ``r = P (b - A x)``; ``||P b||``."""
        x, r = self.x, self.r
        if self.projector is not None:
            self.projector.apply(x, x)
            self.projector.apply(b, r)
            b_norm = r.norm()
        else:
            b_norm = b.norm()
        if not math.isfinite(b_norm):
            raise ValueError("cg: b has non-finite entries")
        self.A.mult(x, r)
        self.mults = 1
        r.aypx(-1.0, b)
        self._project(r)
        self.rr = r.dot(r)
        if not math.isfinite(self.rr):
            raise ValueError("cg: the initial residual has non-finite entries (x or A)")
        return b_norm

    def run(self) -> QPResult:
        """Iterate until a stopping test holds; the result."""
        s = self.solver
        history: list[dict] = []
        it, kind, reason, rz = 0, "init", "max_it", self.rr
        while True:
            rnorm = math.sqrt(self.rr)
            history.append({"it": it, "kind": kind, "r": rnorm})
            if s.monitor is not None:
                s.monitor(it, rnorm, kind)
            if not math.isfinite(rnorm):
                reason = "breakdown"
                break
            if self.test is not None:  # the caller's test replaces the relative one
                if self.test(self.r.array_r, self.x):
                    reason = "rtol"
                    break
            elif rnorm <= self.tol:
                reason = "rtol" if s.rtol * self.b_norm >= s.atol else "atol"
                break
            if it >= s.max_it:
                break
            rz = self._step(it, rz)
            if rz is None:
                reason = "breakdown"
                break
            it += 1
            kind = "cg"
        counts = {"cg": it}
        if self.prec is not None:
            counts["precond"] = self.prec.count
        return QPResult(x=self.x, converged=reason in ("rtol", "atol"), reason=reason,
                        iterations=it, hessian_mults=self.mults, counts=counts, gP_norm=rnorm,
                        b_norm=self.b_norm, history=history)

    def _step(self, it: int, rz: float) -> float | None:
        """One (preconditioned) CG step; the new ``r^T z``, or None on a breakdown."""
        r, z, p, Ap, x = self.r, self.z, self.p, self.Ap, self.x
        if self.prec is not None:
            self.prec.apply(r, z)
            self._project(z)
            rz_new = r.dot(z)
            if not (rz_new > 0.0 and math.isfinite(rz_new)):
                return None  # M^{-1} is not positive definite on Im P
        else:
            rz_new = self.rr
        if it == 0:
            z.copy(p)
        else:
            p.aypx(rz_new / rz, z)
        self.A.mult(p, Ap)
        self.mults += 1
        pAp = p.dot(Ap)
        if not pAp > 0.0:
            return None
        a = rz_new / pAp
        x.axpy(a, p)
        r.axpy(-a, Ap)
        # Re-projecting keeps r in Im P despite rounding (and A p need not lie in Im P).
        self._project(r)
        self.rr = r.dot(r)
        return rz_new


def cg(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, *, projector: Projector | None = None,
       rtol: float = 1e-6, atol: float = 0.0, max_it: int = 1000,
       monitor: Callable[[int, float, str], None] | None = None,
       preconditioner=None) -> QPResult:
    """Minimize ``1/2 x^T A x - b^T x`` (over ``Im P`` when a projector is given).

    The function form of :class:`CG`: ``CG(...).solve(QP(A, b, eq=projector.con,
    preconditioner=preconditioner), x)``; see there.
    """
    solver = CG(rtol=rtol, atol=atol, max_it=max_it, monitor=monitor)
    eq = None if projector is None else projector.con
    return solver.solve(QP(A, b, eq=eq, preconditioner=preconditioner), x)


__all__ = ["CG", "cg"]
