"""Conjugate gradients, optionally projected onto ``Im P`` (FETI's natural coarse space)."""

from __future__ import annotations

import math
from collections.abc import Callable

from petsc4py import PETSc

from .equality import Projector
from .result import QPResult


def cg(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, *, projector: Projector | None = None,
       rtol: float = 1e-6, atol: float = 0.0, max_it: int = 1000,
       monitor: Callable[[int, float, str], None] | None = None) -> QPResult:
    """Minimize ``1/2 x^T A x - b^T x`` (over ``Im P`` when a projector is given).

    With a projector ``P`` the start is replaced by ``P x`` and every residual is projected, so
    the iterates stay in ``Im P``: this solves ``P A P x = P b`` for an ``A`` that is positive
    semidefinite and positive definite on ``Im P`` (consistent there).

    Stopping test: ``||r_k|| <= max(rtol * ||P b||, atol)`` where ``r_k`` is the recursively
    updated projected residual ``P (b - A x_k)`` (``P = I`` without a projector). The
    recursion drifts from the true residual only by rounding; no extra multiplication is
    spent to recompute it.

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

    Returns:
        The result; ``reason`` is ``'rtol'``/``'atol'``, ``'max_it'`` or ``'breakdown'``
        (``p^T A p <= 0`` or a non-finite value).
    """
    if rtol < 0 or atol < 0 or max_it < 0:
        raise ValueError("cg: rtol, atol and max_it must be non-negative")
    r, p, Ap = x.duplicate(), x.duplicate(), x.duplicate()
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
    r.copy(p)
    history: list[dict] = []
    it, kind, reason = 0, "init", "max_it"
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
        A.mult(p, Ap)
        mults += 1
        pAp = p.dot(Ap)
        if not pAp > 0.0:
            reason = "breakdown"
            break
        a = rr / pAp
        x.axpy(a, p)
        r.axpy(-a, Ap)
        if projector is not None:
            # Re-projecting keeps r in Im P despite rounding (and A p need not lie in Im P).
            projector.apply(r, r)
        rr_new = r.dot(r)
        p.aypx(rr_new / rr, r)
        rr = rr_new
        it += 1
        kind = "cg"
    return QPResult(x=x, converged=reason in ("rtol", "atol"), reason=reason, iterations=it,
                    hessian_mults=mults, counts={"cg": it}, gP_norm=rnorm, b_norm=b_norm,
                    history=history)
