"""SMALBE-M: semimonotonic augmented Lagrangians for bound and equality constraints (Dostál).

Minimizes ``f(x) = 1/2 x^T A x - b^T x`` subject to ``lb <= x <= ub`` and ``D x = 0``, with an
inner MPRGP on the augmented Lagrangian ``L(x, mu, rho) = f(x) + mu^T D x + rho/2 ||D x||^2``.
See ALGORITHMS.md section 5 and Dostál, *Optimal Quadratic Programming Algorithms* (2009),
chapter 6. The penalty ``rho`` stays fixed; the inner precision factor ``M`` adapts.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..validation import Choice, Integer, Maybe, Option, OptionSet, Real
from .equality import EqualityConstraint, penalized_operator
from .mprgp import mprgp
from .norm import estimate_norm
from .precond import Preconditioner, ProjectedPreconditioner
from .result import QPResult

_RESERVED = ("lb", "ub", "rtol", "atol", "stop", "b_norm", "g", "g_valid", "max_it",
             "preconditioner")
PRECONDITIONER_FORMS = ("projected", "plain")
ACCELERATIONS = ("none", "anderson")

#: SMALBE's options: ``-feti_smalbe_<name>``, ``SolverOptions.smalbe_<name>``. ``rho`` and
#: ``M`` are relative to ||A||, ``eta`` to ||b|| (the caller scales them).
OPTIONS = OptionSet(
    "smalbe", "SMALBE-M (bounds and equalities, inner MPRGP/MPGP)",
    rho=Option(1.1, Real(gt=0), "the penalty ρ relative to ||A||"),
    M=Option(1.0, Real(gt=0), "the initial inner precision factor M relative to ||A|| (the "
             "reference value 100 stalls the outer loop; 1 needs the fewest F-multiplications "
             "on B1, 2D Hertz and the 3D blocks: docs/solvers.md)"),
    eta=Option(None, Maybe(Real(gt=0)), "the inner precision cap η relative to ||b|| (None: "
               "0.1)"),
    beta=Option(2.0, Real(gt=1), "the divisor of M"),
    acceleration=Option("anderson", Choice(*ACCELERATIONS), "'none' (the plain multiplier "
                        "update μ += ρDx of the theory) or 'anderson' (Anderson acceleration of "
                        "that update, memory reset when the active set changes)"),
    depth=Option(3, Integer(ge=1, le=100), "the memory of the Anderson acceleration (number "
                 "of past updates)"))


def smalbe(A: PETSc.Mat, b: PETSc.Vec, D: EqualityConstraint, x: PETSc.Vec, *, lb=None,
           ub=None, rtol: float = 1e-6, eq_rtol: float | None = None, rho: float | None = None,
           M: float | None = None, eta: float | None = None, beta: float = 2.0,
           norm_A: float | None = None, inner: str = "mprgp",
           inner_options: dict[str, Any] | None = None, max_outer: int = 100,
           max_it: int = 10000, monitor: Callable[[int, dict], None] | None = None,
           eq_scale: float = 1.0, multiplier: np.ndarray | None = None,
           preconditioner=None, preconditioner_form: str = "projected",
           acceleration: str = "none", depth: int = 5) -> QPResult:
    """Solve ``min f(x)`` s.t. ``lb <= x <= ub``, ``D x = 0`` by SMALBE-M (collective).

    Outer iteration ``k``:

    1. MPRGP on ``L(., mu_k, rho)`` (Hessian ``A + rho D^T D``, linear term ``b - D^T mu_k``),
       warm-started, until ``||g^P(x, mu_k, rho)|| <= min(M ||D x||, eta)`` or the final test.
    2. Final test: ``||g^P(x, mu_k, rho)|| <= rtol ||b||`` and
       ``eq_scale ||D x|| <= eq_rtol ||b||``.
       Because ``grad_x L(x, mu_k, rho) = A x - b + D^T (mu_k + rho D x)``, the first condition
       is the KKT residual of the *un*-augmented Lagrangian with the updated multiplier; the
       returned ``multiplier`` is that one.
    3. ``mu_{k+1} = mu_k + rho D x`` (or its Anderson-accelerated version, see ``acceleration``).
    4. ``M <- M / beta`` if ``L(x_k, mu_k, rho) < L(x_{k-1}, mu_{k-1}, rho) + rho/2 ||D x_k||^2``
       (the augmented Lagrangian did not increase enough).

    ``D`` must have orthonormal rows; then for ``A = P A P`` (``P`` the projector onto
    ``ker D``, as in FETI where ``A = P F P``) the inner Hessian has norm ``max(||A||, rho)``
    exactly, which sets the inner ``alpha_bar``. For an ``A`` that does not commute with
    ``D^T D`` pass ``inner_options={'norm_A': norm_A + rho}`` (a valid upper bound).

    The inner gradient is carried over between outer iterations (the change of ``mu`` changes
    it by ``D^T (mu_{k+1} - mu_k)``), so an outer iteration costs no extra multiplication.

    Preconditioning: ``preconditioner`` approximates ``A^{-1}`` (in FETI, e.g. the lumped or
    Dirichlet preconditioner of ``F``) and the inner MPRGP preconditions in face with

    - ``preconditioner_form='projected'`` (default): ``P M^{-1} P + rho^{-1} D^T D``
      (:class:`.ProjectedPreconditioner`). This assumes ``A = P A P`` (``A`` maps ``ker D``
      into itself and vanishes on ``Im D^T``, as ``P F P`` does): then the inner Hessian is
      ``P A P`` on ``ker D`` and ``rho I`` on ``Im D^T``, and the operator is exact on
      ``Im D^T`` and the classical projected preconditioner on ``ker D``. For another ``A``
      it is still symmetric positive (semi)definite, hence safe, but not that inverse;
    - ``'plain'``: ``M^{-1}`` as given, which must then approximate
      ``(A + rho D^T D)^{-1}`` itself.

    ``counts['precond']`` sums the applications of ``M^{-1}`` over all inner solves.

    Args:
        A: Symmetric positive semidefinite Hessian, positive definite on ``ker D``.
        b: Linear term.
        D: Equality constraint with orthonormal rows (e.g. from ``orthonormalize``).
        x: Start (projected onto the box), overwritten with the solution.
        lb: Lower bound (Vec, scalar or None).
        ub: Upper bound (Vec, scalar or None).
        rtol: Relative tolerance of the projected gradient.
        eq_rtol: Relative tolerance of the constraint; default ``rtol``.
        rho: Penalty; default ``1.1 ||A||``.
        M: Initial inner precision factor; default ``100 ||A||``.
        eta: Inner absolute precision cap; default ``0.1 ||b||``.
        beta: Divisor of ``M`` (> 1).
        norm_A: ``||A||``; default a Lanczos estimate (counted in ``hessian_mults``).
        inner: Inner solver: ``'mprgp'`` (bounds ``lb``, ``ub``) or ``'mpgp'``
            (:func:`.mpgp.mpgp`: bounds and disc constraints, given as
            ``inner_options={'discs': ...}``).
        inner_options: Extra keyword arguments of the inner solver (``gamma``, ``expansion``,
            ``alpha``, ``alpha_bar``, ``norm_A``, ``monitor``; ``discs`` for MPGP).
        max_outer: Maximum number of outer iterations.
        max_it: Budget of inner iterations over all outer iterations.
        monitor: Called as ``monitor(k, record)`` after each outer iteration with the record
            that is appended to ``history``.
        eq_scale: Scales ``||D x||`` in the final test. ``D x`` and ``b`` have different units
            (in FETI: multipliers vs. gradients); ``eq_scale = ||A||`` makes the test
            unit-consistent. Default 1 (the test of the theory).
        multiplier: Initial ``mu`` (replicated array of length ``D.m``); default zeros.
        preconditioner: Optional ``M^{-1}`` (a PETSc Mat or PC, an object with ``mult(x, y)``
            or a callable ``f(x, y)``).
        preconditioner_form: ``'projected'`` or ``'plain'``, see above.
        acceleration: ``'none'``: step 3 as above. ``'anderson'``: Anderson acceleration of
            the fixed point ``mu -> mu + rho D x(mu)`` (type II, least squares over the last
            ``depth`` differences), its memory cleared whenever the active set of the inner
            result changes. Not covered by SMALBE's theory (the step 4 test and the stopping
            test are unchanged, and the returned multiplier is always the plain update of the
            final ``x``, i.e. the KKT multiplier).
        depth: Memory of the Anderson acceleration.

    Returns:
        The result, with ``multiplier``, ``outer_iterations`` and one history record per outer
        iteration: ``k``, ``inner_iterations``, ``hessian_mults``, ``gP``, ``Dx``, ``M`` (used
        in this inner solve), ``M_next``, ``rho``, ``L`` (``L(x_k, mu_k, rho)``), ``L_prev``,
        ``L_increase_ok`` (the step-4 test held; None at ``k = 0``), ``M_decreased``,
        ``inner_reason``. ``reason`` is ``'converged'``, ``'max_it'``, ``'max_outer'`` or the
        inner failure (``'unbounded'``, ``'breakdown'``).
    """
    if inner not in ("mprgp", "mpgp"):
        raise ValueError(f"smalbe: inner solver {inner!r} is not available ('mprgp', 'mpgp')")
    if inner == "mpgp":
        from .mpgp import mpgp as inner_solver
    else:
        inner_solver = mprgp
    opts = dict(inner_options or {})
    bad = sorted(set(opts) & set(_RESERVED))
    if bad:
        raise ValueError(f"smalbe: inner_options may not set {bad} (SMALBE controls them; "
                         "pass a preconditioner as smalbe(preconditioner=...))")
    if acceleration not in ACCELERATIONS or depth < 1:
        raise ValueError(f"smalbe: acceleration must be one of {ACCELERATIONS} and depth >= 1, "
                         f"got {acceleration!r}, {depth}")
    if preconditioner_form not in PRECONDITIONER_FORMS:
        raise ValueError(f"smalbe: preconditioner_form must be one of {PRECONDITIONER_FORMS}, "
                         f"got {preconditioner_form!r}")
    if not beta > 1.0 or rtol < 0 or max_outer < 1 or max_it < 0 or not eq_scale > 0:
        raise ValueError("smalbe: need beta > 1, rtol >= 0, max_outer >= 1, max_it >= 0, "
                         "eq_scale > 0")
    eq_rtol = rtol if eq_rtol is None else eq_rtol
    b_norm = b.norm()
    if not math.isfinite(b_norm):
        raise ValueError("smalbe: b has non-finite entries")
    mults = 0
    counts = {"cg": 0, "expansion": 0, "proportioning": 0, "norm": 0}
    if norm_A is None:
        est = estimate_norm(A, x)
        norm_A, mults, counts["norm"] = est.value, est.iterations, est.iterations
    rho = 1.1 * norm_A if rho is None else float(rho)
    M = 100.0 * norm_A if M is None else float(M)
    eta = 0.1 * b_norm if eta is None else float(eta)
    # A zero b (e.g. a body resting on an obstacle with no load) leaves eta = 0: the inner
    # solves are then exact, which x = 0 (g = 0) satisfies at once.
    if not (rho > 0 and M > 0 and (eta > 0 or (eta == 0 and b_norm == 0))):
        raise ValueError(f"smalbe: need rho, M, eta > 0 (got {rho}, {M}, {eta}); "
                         "eta = 0 only for a zero b")
    opts.setdefault("norm_A", max(norm_A, rho))
    H = penalized_operator(A, D, rho)
    if preconditioner is not None:
        prec = Preconditioner(preconditioner)  # counts the applications of M^{-1}
        counts["precond"] = 0
        opts["preconditioner"] = (ProjectedPreconditioner(prec, D, rho)
                                  if preconditioner_form == "projected" else prec)
    tol_g, tol_e = rtol * b_norm, eq_rtol * b_norm / eq_scale

    mu = np.zeros(D.m) if multiplier is None else np.array(multiplier, dtype=np.float64)
    if mu.shape != (D.m,):
        raise ValueError(f"smalbe: multiplier has shape {mu.shape}, expected ({D.m},)")
    bk, g, tmp = b.duplicate(), b.duplicate(), b.duplicate()
    D.mult_transpose(mu, bk)
    bk.aypx(-1.0, b)  # b - D^T mu
    g_valid = False
    anderson = _Anderson(depth) if acceleration == "anderson" else None
    prev_active, comm = None, x.getComm().tompi4py()
    history: list[dict] = []
    total_it, L_prev, reason = 0, None, "max_outer"
    res = None
    dx = math.nan
    for k in range(max_outer):
        M_k = M

        def inner_stop(gP: float, xv: PETSc.Vec, gv: PETSc.Vec, M_k: float = M_k) -> bool:
            dxv = float(np.linalg.norm(D.mult(xv)))
            return gP <= min(M_k * dxv, eta) or (gP <= tol_g and dxv <= tol_e)

        res = inner_solver(H, bk, x, lb=lb, ub=ub, rtol=0.0, atol=0.0, stop=inner_stop,
                    max_it=max_it - total_it, b_norm=b_norm, g=g, g_valid=g_valid, **opts)
        g_valid = True
        total_it += res.iterations
        mults += res.hessian_mults
        for key, value in res.counts.items():
            counts[key] = counts.get(key, 0) + value
        Dx = D.mult(x)
        dx = float(np.linalg.norm(Dx))
        L = res.objective
        increase_ok = None if L_prev is None else bool(L >= L_prev + 0.5 * rho * dx * dx)
        if increase_ok is False:
            M /= beta
        record = {"k": k, "inner_iterations": res.iterations,
                  "hessian_mults": res.hessian_mults, "gP": res.gP_norm, "Dx": dx, "M": M_k,
                  "M_next": M, "rho": rho, "L": L, "L_prev": L_prev, "L_increase_ok": increase_ok,
                  "M_decreased": increase_ok is False, "inner_reason": res.reason}
        history.append(record)
        if monitor is not None:
            monitor(k, record)
        # Update mu even at the end: the KKT multiplier of the final x is mu_k + rho D x.
        step = rho * Dx
        if res.gP_norm <= tol_g and dx <= tol_e:
            pass  # the final multiplier: the plain update (KKT), whatever the acceleration
        elif anderson is not None:
            # A new active set is a new affine map: the secant memory of the old one misleads.
            if prev_active is None or comm.allreduce(
                    bool(np.any(res.active != prev_active)), op=MPI.LOR):
                anderson.reset()
            step = anderson.step(mu, step)
            prev_active = res.active.copy()
        mu += step
        D.mult_transpose(step, tmp)
        bk.axpy(-1.0, tmp)
        g.axpy(1.0, tmp)
        L_prev = L
        if res.gP_norm <= tol_g and dx <= tol_e:
            reason = "converged"
            break
        if not res.converged:
            reason = res.reason
            break
    f = res.objective - float(np.dot(mu - rho * Dx, Dx)) - 0.5 * rho * dx * dx
    if preconditioner is not None:
        counts["precond"] = prec.count
    return QPResult(x=x, converged=reason == "converged", reason=reason, iterations=total_it,
                    outer_iterations=len(history), hessian_mults=mults, counts=counts,
                    gP_norm=res.gP_norm, Dx_norm=dx, b_norm=b_norm, active=res.active,
                    active_count=res.active_count, history=history, multiplier=mu,
                    objective=f)


class _Anderson:
    """Anderson acceleration (type II) of the fixed point ``mu -> mu + rho D x(mu)``.

    Once the active set has settled the map is affine in ``mu`` and its contraction
    ``(I + rho S)^{-1}`` (``S`` the dual Schur complement on the free set) has only a few
    eigenvalues away from 0 (one or two on B1), so a short secant memory removes them in a few
    outer iterations where the plain update needs tens. ``mu`` and the residuals are
    replicated and identical on every rank, so every rank takes the same step.
    """

    def __init__(self, depth: int) -> None:
        self.depth = depth
        self._mu: list[np.ndarray] = []  # mu_k
        self._f: list[np.ndarray] = []   # f_k = rho D x_k (the plain step)

    def reset(self) -> None:
        """Forget the history."""
        self._mu.clear()
        self._f.clear()

    def step(self, mu: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Return the accelerated ``mu_{k+1} - mu_k`` from ``mu_k`` and the plain step ``f``."""
        self._mu.append(mu.copy())
        self._f.append(f.copy())
        if len(self._f) > self.depth + 1:
            self._mu.pop(0)
            self._f.pop(0)
        if len(self._f) < 2:
            return f
        dF = np.diff(np.array(self._f), axis=0).T           # columns f_i+1 - f_i
        dG = dF + np.diff(np.array(self._mu), axis=0).T     # G(mu) = mu + f
        gamma = np.linalg.lstsq(dF, f, rcond=1e-10)[0]
        return f - dG @ gamma
