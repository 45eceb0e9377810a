"""Conjugate gradients, optionally preconditioned and projected onto ``Im P`` (FETI)."""

from __future__ import annotations

import math
from collections.abc import Callable

from petsc4py import PETSc

from .equality import Projector
from .precond import Preconditioner
from .result import QPResult


def cg(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, *, projector: Projector | None = None,
       rtol: float = 1e-6, atol: float = 0.0, max_it: int = 1000,
       monitor: Callable[[int, float, str], None] | None = None,
       preconditioner=None) -> QPResult:
    """Minimize ``1/2 x^T A x - b^T x`` (over ``Im P`` when a projector is given).

    With a projector ``P`` the start is replaced by ``P x`` and every residual is projected, so
    the iterates stay in ``Im P``: this solves ``P A P x = P b`` for an ``A`` that is positive
    semidefinite and positive definite on ``Im P`` (consistent there).

    With a preconditioner ``M^{-1}`` (an approximate inverse of ``A``, symmetric positive
    definite on ``Im P``) this is PCG with the preconditioned residual ``z = P M^{-1} P r``
    (the projected preconditioner of classical FETI; ``z = M^{-1} r`` without a projector):
    ``p_0 = z_0``, ``a_k = r_k^T z_k / p_k^T A p_k``, ``p_{k+1} = z_{k+1} + (r_{k+1}^T z_{k+1} /
    r_k^T z_k) p_k``. Each iteration applies ``M^{-1}`` once (``counts['precond']``, equal to
    the number of iterations); a non-positive ``r^T z`` ends the solve with ``'breakdown'``.

    Stopping test: ``||r_k|| <= max(rtol * ||P b||, atol)`` where ``r_k`` is the recursively
    updated projected residual ``P (b - A x_k)`` (``P = I`` without a projector), the
    *un*preconditioned residual with or without a preconditioner, so the test means the same
    thing in both cases. The recursion drifts from the true residual only by rounding; no
    extra multiplication is spent to recompute it.

    Args:
        A: Symmetric operator.
        b: Right-hand side.
        x: Start, overwritten with the solution.
        projector: Optional orthogonal projector ``P``.
        rtol: Relative tolerance (relative to ``||P b||``).
        atol: Absolute tolerance.
        max_it: Maximum number of iterations.
        monitor: Called as ``monitor(it, residual_norm, kind)`` with ``kind`` ``'init'`` or
            ``'cg'``.
        preconditioner: Optional ``M^{-1}``: a PETSc Mat or PC, an object with ``mult(x, y)``
            or a callable ``f(x, y)`` (see :mod:`.precond`).

    Returns:
        The result; ``reason`` is ``'rtol'``/``'atol'``, ``'max_it'`` or ``'breakdown'``
        (``p^T A p <= 0``, ``r^T z <= 0`` or a non-finite value). ``counts`` has ``'cg'`` and,
        with a preconditioner, ``'precond'``.
    """
    if rtol < 0 or atol < 0 or max_it < 0:
        raise ValueError("cg: rtol, atol and max_it must be non-negative")
    prec = None if preconditioner is None else Preconditioner(preconditioner)
    r, p, Ap = x.duplicate(), x.duplicate(), x.duplicate()
    z = r if prec is None else x.duplicate()
    if projector is not None:
        projector.apply(x, x)
        projector.apply(b, r)
        b_norm = r.norm()
    else:
        b_norm = b.norm()
    if not math.isfinite(b_norm):
        raise ValueError("cg: b has non-finite entries")
    tol = max(rtol * b_norm, atol)
    A.mult(x, r)
    mults = 1
    r.aypx(-1.0, b)
    if projector is not None:
        projector.apply(r, r)
    rr = r.dot(r)
    if not math.isfinite(rr):
        raise ValueError("cg: the initial residual has non-finite entries (x or A)")
    history: list[dict] = []
    it, kind, reason = 0, "init", "max_it"
    rz = rr
    while True:
        rnorm = math.sqrt(rr)
        history.append({"it": it, "kind": kind, "r": rnorm})
        if monitor is not None:
            monitor(it, rnorm, kind)
        if not math.isfinite(rnorm):
            reason = "breakdown"
            break
        if rnorm <= tol:
            reason = "rtol" if rtol * b_norm >= atol else "atol"
            break
        if it >= max_it:
            break
        if prec is not None:
            prec.apply(r, z)
            if projector is not None:
                projector.apply(z, z)
            rz_new = r.dot(z)
            if not (rz_new > 0.0 and math.isfinite(rz_new)):
                reason = "breakdown"  # M^{-1} is not positive definite on Im P
                break
        else:
            rz_new = rr
        if it == 0:
            z.copy(p)
        else:
            p.aypx(rz_new / rz, z)
        rz = rz_new
        A.mult(p, Ap)
        mults += 1
        pAp = p.dot(Ap)
        if not pAp > 0.0:
            reason = "breakdown"
            break
        a = rz / pAp
        x.axpy(a, p)
        r.axpy(-a, Ap)
        if projector is not None:
            # Re-projecting keeps r in Im P despite rounding (and A p need not lie in Im P).
            projector.apply(r, r)
        rr = r.dot(r)
        it += 1
        kind = "cg"
    counts = {"cg": it}
    if prec is not None:
        counts["precond"] = prec.count
    return QPResult(x=x, converged=reason in ("rtol", "atol"), reason=reason, iterations=it,
                    hessian_mults=mults, counts=counts, gP_norm=rnorm, b_norm=b_norm,
                    history=history)
