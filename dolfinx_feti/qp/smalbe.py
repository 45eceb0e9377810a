"""SMALBE-M: semimonotonic augmented Lagrangians for bound and equality constraints (Dostál).

Minimizes ``f(x) = 1/2 x^T A x - b^T x`` subject to ``x`` in a constraint set (bounds, discs)
and ``D x = 0``, with an inner solver (an :class:`.mpgp.MPGP` object: MPRGP on bounds, MPGP
with discs) on the augmented Lagrangian ``L(x, mu, rho) = f(x) + mu^T D x + rho/2 ||D x||^2``.
See ALGORITHMS.md section 5 and Dostál, *Optimal Quadratic Programming Algorithms* (2009),
chapter 6. The penalty ``rho`` stays fixed; the inner precision factor ``M`` adapts.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from petsc4py import PETSc

from ..parallel.reduce import any_rank
from ..validation import Choice, Integer, Maybe, Option, OptionSet, Real
from .aitken import Aitken
from .anderson import Anderson
from .dual_search import DualSearch
from .equality import EqualityConstraint, penalized_operator
from .mpgp import MPGP
from .mprgp import MPRGP
from .norm import estimate_norm
from .precond import Preconditioner, ProjectedPreconditioner
from .problem import QP
from .result import QPResult
from .solver import QPSolver

_RESERVED = ("lb", "ub", "rtol", "atol", "stop", "b_norm", "g", "g_valid", "max_it",
             "preconditioner")
PRECONDITIONER_FORMS = ("projected", "plain")
ACCELERATIONS = ("auto", "none", "anderson", "aitken", "search")
#: The extrapolations of a slow outer loop along ``D x`` by acceleration name.
EXTRAPOLATIONS = {"aitken": Aitken, "search": DualSearch}
#: The inner solvers of :func:`smalbe` by name.
INNER = {"mprgp": MPRGP, "mpgp": MPGP}

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
    acceleration=Option("auto", Choice(*ACCELERATIONS), "'none' (the plain multiplier "
                        "update μ += ρDx of the theory), 'anderson' (Anderson acceleration of "
                        "that update, memory reset when the active set changes), 'aitken' "
                        "(the plain update extrapolated where the residual keeps its direction "
                        "and shrinks slowly), 'search' (a safeguarded secant search of the dual "
                        "along that direction, the factor growing while the residual keeps its "
                        "sign) or 'auto' ('search' when the constraint set has discs, i.e. 3D "
                        "friction, else 'anderson')"),
    depth=Option(3, Integer(ge=1, le=100), "the memory of the Anderson acceleration (number "
                 "of past updates)"),
    rho_growth=Option(None, Maybe(Real(ge=1)), "ρ is multiplied by this (up to rho_max) after "
                      "an outer iteration that cut ||Dx|| by less than half (None or 1: ρ "
                      "fixed, SMALBE-M)"),
    rho_max=Option(100.0, Real(gt=0), "the largest ρ of rho_growth, relative to ||A||"))

#: An outer iteration whose ||Dx|| is above this fraction of the one before counts as slow
#: (``rho_growth``).
SLOW_OUTER = 0.5


@dataclass(frozen=True)
class Absolute:
    """A value of ``rho``, ``M`` or ``eta`` taken as it is, not relative to ``||A||``/``||b||``.

    PERMON's ``QPS_ARG_DIRECT`` (against ``QPS_ARG_MULTIPLE``, the options' units):
    ``SMALBE(rho=Absolute(5.0))`` penalizes with 5, whatever ``||A||``.
    """

    value: float


class SMALBE(QPSolver):
    """SMALBE-M for a QP with an equality constraint, owning its inner solver (collective).

    Outer iteration ``k``:

    1. The inner solver on ``L(., mu_k, rho)`` (Hessian ``A + rho D^T D``, linear term
       ``b - D^T mu_k``, the QP's constraint set), warm-started, until
       ``||g^P(x, mu_k, rho)|| <= min(M ||D x||, eta)`` or the final test.
    2. Final test: ``||g^P(x, mu_k, rho)|| <= rtol ||b||`` and
       ``eq_scale ||D x|| <= eq_rtol ||b||``.
       Because ``grad_x L(x, mu_k, rho) = A x - b + D^T (mu_k + rho D x)``, the first condition
       is the KKT residual of the *un*-augmented Lagrangian with the updated multiplier; the
       returned ``multiplier`` is that one.
    3. ``mu_{k+1} = mu_k + rho D x`` (or its Anderson-accelerated version, see ``acceleration``).
    4. ``M <- M / beta`` if ``L(x_k, mu_k, rho) < L(x_{k-1}, mu_{k-1}, rho) + rho/2 ||D x_k||^2``
       (the augmented Lagrangian did not increase enough).

    ``D`` (the QP's ``eq``) must have orthonormal rows; then for ``A = P A P`` (``P`` the
    projector onto ``ker D``, as in FETI where ``A = P F P``) the inner Hessian has norm
    ``max(||A||, rho)`` exactly, which sets the inner ``alpha_bar``. For an ``A`` that does not
    commute with ``D^T D`` pass ``inner_norm_A=norm_A + rho`` (a valid upper bound).

    The inner gradient is carried over between outer iterations (the change of ``mu`` changes
    it by ``D^T (mu_{k+1} - mu_k)``), so an outer iteration costs no extra multiplication.

    Preconditioning: the QP's ``preconditioner`` approximates ``A^{-1}`` (in FETI, e.g. the
    lumped or Dirichlet preconditioner of ``F``) and the inner solver preconditions in face
    with

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
        inner: The inner solver (an :class:`.mpgp.MPGP`, e.g. :class:`.mprgp.MPRGP` on
            bounds, ``MPGP()`` with discs); its own tolerances are replaced by SMALBE's tests.
            Default: ``MPRGP(options_prefix=options_prefix)``.
        rtol: Relative tolerance of the projected gradient.
        eq_rtol: Relative tolerance of the constraint; default ``rtol``.
        eq_scale: Scales ``||D x||`` in the final test. ``D x`` and ``b`` have different units
            (in FETI: multipliers vs. gradients); ``eq_scale = ||A||`` makes the test
            unit-consistent. Default 1 (the test of the theory).
        max_outer: Maximum number of outer iterations.
        max_it: Budget of inner iterations over all outer iterations.
        rho: Penalty relative to ``||A||`` (option ``-<prefix>smalbe_rho``), or
            :class:`Absolute`.
        M: Initial inner precision factor relative to ``||A||``, or :class:`Absolute`.
        eta: Inner precision cap relative to ``||b||`` (None: 0.1), or :class:`Absolute`.
        beta: Divisor of ``M`` (> 1).
        acceleration: ``'none'``: step 3 as above. ``'anderson'``: Anderson acceleration of
            the fixed point ``mu -> mu + rho D x(mu)`` (type II, least squares over the last
            ``depth`` differences), its memory cleared whenever the active set of the inner
            result changes. Not covered by SMALBE's theory (the step 4 test and the stopping
            test are unchanged, and the returned multiplier is always the plain update of the
            final ``x``, i.e. the KKT multiplier). ``'aitken'``: the plain update, multiplied
            by ``min(1/(1 - q), 10)`` when ``D x`` kept its direction and shrank by the ratio
            ``q`` in (0.5, 1) (:class:`.aitken.Aitken`). ``'search'``: along the direction ``d``
            of such a residual, a secant search for the root of ``d^T D x(mu + t d)`` (the
            factor over the plain step doubled while the sign holds, the secant root on a
            sign change; the plain update across ``d``; ``d`` corrected by the residual across
            it and made conjugate to the last search that found its root:
            :class:`.dual_search.DualSearch`). ``'auto'`` (default): ``'search'`` when the
            QP's set is curved (discs: 3D friction), else ``'anderson'``. With discs near
            gross sliding Anderson's steps threw the multiplier far off on some loads (‖Dx‖ up
            to 1e5, no convergence in 20 000 iterations on the coarse half punch of
            tests/drivers/test_friction_symmetry.py at 0.7 and 0.99 𝓕N, tipped over by
            changing CURVATURE_SCALE by 2 %); the plain update converged on all, and its slow
            outer loops (‖Dx‖ −0.3 % per outer iteration over 150 of them on the punch at
            0.9 𝓕N) are what the extrapolation and the search cut (bench/coulomb_sliding.py,
            docs/benchmarks.md § 24).
        depth: Memory of the Anderson acceleration.
        rho_growth: After an outer iteration that left ``||D x||`` above :data:`SLOW_OUTER`
            times the one before, ``rho`` is multiplied by this, up to ``rho_max`` (None or 1:
            ``rho`` fixed). Near gross sliding of friction the multiplier update contracts
            ``||D x||`` by a few per cent per outer iteration at the default ``rho``: the few
            free (sticking) rows must carry the equality. A larger ``rho`` contracts it faster,
            at the price of a stiffer inner problem where it is not needed; growing it only on
            slow iterations keeps the easy cases at the default. The inner operator, its
            preconditioner and the carried gradient are updated with ``rho`` (no extra
            multiplication); the Anderson memory is cleared and the step-4 test skipped once.
            Not covered by SMALBE-M's theory, which keeps ``rho`` fixed (Dostál 2009 keeps
            such a growth for the SMALBE variant that adapts ``rho`` instead of ``M``). Off by
            default: on the punch's fine mesh, with the curvature scaling of MPGP's
            preconditioner in face, the stiffer inner problems cost more than the outer
            iterations saved (bench/coulomb_sliding.py ``--rho-growth 2``).
        rho_max: The cap of ``rho_growth``, relative to ``||A||`` (or :class:`Absolute`).
        inner_norm_A: ``||A + rho D^T D||`` for the inner solver; default ``max(||A||, rho)``.
        preconditioner_form: ``'projected'`` or ``'plain'``, see above.
        monitor: Called as ``monitor(k, record)`` after each outer iteration with the record
            that is appended to ``history``.
        options_prefix: Read the declared options (:data:`OPTIONS`) as
            ``-<options_prefix>smalbe_<name>`` (e.g. ``'feti_'``); keywords given here override
            them. None: the database is not read.

    Raises:
        ValueError: For an invalid option (an InputError naming it for the declared ones).
        TypeError: For an inner solver that cannot be one (``inner_capable`` false).
    """

    options: ClassVar[OptionSet] = OPTIONS
    name: ClassVar[str] = "smalbe"

    def __init__(self, inner: MPGP | None = None, *, rtol: float = 1e-6,
                 eq_rtol: float | None = None, eq_scale: float = 1.0, max_outer: int = 100,
                 max_it: int = 10000, rho: float | Absolute | None = None,
                 M: float | Absolute | None = None, eta: float | Absolute | None = None,
                 beta: float | None = None, acceleration: str | None = None,
                 depth: int | None = None, rho_growth: float | None = None,
                 rho_max: float | Absolute | None = None, inner_norm_A: float | None = None,
                 preconditioner_form: str = "projected",
                 monitor: Callable[[int, dict], None] | None = None,
                 options_prefix: str | None = None) -> None:
        scaled = {"rho": rho, "M": M, "eta": eta, "rho_max": rho_max}
        absolute = {k: float(v.value) for k, v in scaled.items() if isinstance(v, Absolute)}
        scaled = {k: None if k in absolute else v for k, v in scaled.items()}
        self._set_options(options_prefix, beta=beta, acceleration=acceleration, depth=depth,
                          rho_growth=rho_growth, **scaled)
        for k, v in absolute.items():
            setattr(self, k, v)
        #: The names among rho, M, eta that hold absolute values.
        self.absolute = frozenset(absolute)
        if preconditioner_form not in PRECONDITIONER_FORMS:
            raise ValueError(f"smalbe: preconditioner_form must be one of "
                             f"{PRECONDITIONER_FORMS}, got {preconditioner_form!r}")
        if rtol < 0 or max_outer < 1 or max_it < 0 or not eq_scale > 0:
            raise ValueError("smalbe: need beta > 1, rtol >= 0, max_outer >= 1, max_it >= 0, "
                             "eq_scale > 0")
        if inner is not None and not getattr(inner, "inner_capable", False):
            raise TypeError(f"smalbe: {type(inner).__name__} cannot be the inner solver (it "
                            "takes no warm start and stopping test: use MPGP or MPRGP)")
        self.inner = inner if inner is not None else MPRGP(options_prefix=options_prefix)
        self.rtol, self.eq_rtol, self.eq_scale = rtol, rtol if eq_rtol is None else eq_rtol, \
            eq_scale
        self.max_outer, self.max_it, self.inner_norm_A = max_outer, max_it, inner_norm_A
        self.preconditioner_form, self.monitor = preconditioner_form, monitor

    def penalties(self, norm_A: float, b_norm: float) -> tuple[float, float, float]:
        """``(rho, M, eta)`` in absolute units for ``||A||`` and ``||b||``."""
        def value(k: str, scale: float, default: float) -> float:
            v = getattr(self, k)
            if k in self.absolute:
                return v
            return (default if v is None else v) * scale
        return value("rho", norm_A, 1.1), value("M", norm_A, 1.0), value("eta", b_norm, 0.1)

    def rho_cap(self, norm_A: float) -> float:
        """The largest ``rho`` of ``rho_growth`` in absolute units."""
        return self.rho_max if "rho_max" in self.absolute else self.rho_max * norm_A

    def solve(self, qp: QP, x: PETSc.Vec, *, multiplier: np.ndarray | None = None,
              test=None) -> QPResult:
        """Minimize ``qp`` (which must have ``eq``) from ``x`` (collective).

        Args:
            qp: The QP: ``A`` symmetric positive semidefinite, positive definite on
                ``ker D``; ``eq`` the constraint ``D`` with orthonormal rows (e.g. from
                ``orthonormalize``).
            x: Start (projected onto the set), overwritten with the solution.
            multiplier: Initial ``mu`` (replicated array of length ``D.m``); default zeros.
            test: A :class:`.stopping.MaxGradientTest` that replaces the final test of step
                2: the projected gradient of the Lagrangian passes ``test`` and
                ``||D x|| <= test.eq_tol``.

        Returns:
            The result, with ``multiplier``, ``outer_iterations`` and one history record per
            outer iteration: ``k``, ``inner_iterations``, ``hessian_mults``, ``gP``, ``Dx``,
            ``M`` (used in this inner solve), ``M_next``, ``rho``, ``L``
            (``L(x_k, mu_k, rho)``), ``L_prev``, ``L_increase_ok`` (the step-4 test held;
            None at ``k = 0``), ``M_decreased``, ``inner_reason``. ``reason`` is
            ``'converged'``, ``'max_it'``, ``'max_outer'`` or the inner failure
            (``'unbounded'``, ``'breakdown'``); ``converged_reason`` the signed code.
            With ``test``, each record also holds ``test_gP`` (the test's weighted gradient
            at the last inner iterate), ``test_tol`` and ``eq_tol`` (its two bounds).

        Raises:
            ValueError: For a QP without equality constraint, non-finite ``b``, non-positive
                penalties or a multiplier of the wrong shape.
        """
        if qp.eq is None:
            raise ValueError("smalbe: the QP has no equality constraint; solve it by the "
                             "inner solver alone")
        return _SMALBESolve(self, qp, x, multiplier, test).run()


class _SMALBESolve:
    """The state of one SMALBE solve: the multiplier, the inner QP, the outer records."""

    def __init__(self, solver: SMALBE, qp: QP, x: PETSc.Vec,
                 multiplier: np.ndarray | None, test=None) -> None:
        self.s, self.x, self.D, self.test = solver, x, qp.eq, test
        self.b_norm = b_norm = qp.b.norm()
        if not math.isfinite(b_norm):
            raise ValueError("smalbe: b has non-finite entries")
        self.mults = 0
        self.counts = {"cg": 0, "expansion": 0, "proportioning": 0, "norm": 0}
        norm_A = qp.norm_A
        if norm_A is None:
            est = estimate_norm(qp.A, x)
            norm_A, self.mults, self.counts["norm"] = est.value, est.iterations, est.iterations
        rho, self.M, eta = solver.penalties(norm_A, b_norm)
        # A zero b (e.g. a body resting on an obstacle with no load) leaves eta = 0: the inner
        # solves are then exact, which x = 0 (g = 0) satisfies at once.
        if not (rho > 0 and self.M > 0 and (eta > 0 or (eta == 0 and b_norm == 0))):
            raise ValueError(f"smalbe: need rho, M, eta > 0 (got {rho}, {self.M}, {eta}); "
                             "eta = 0 only for a zero b")
        self.rho, self.rho0, self.eta = rho, rho, eta
        self.growth = solver.rho_growth or 1.0
        self.rho_cap = max(solver.rho_cap(norm_A), rho)
        self.norm_A, self.qp = norm_A, qp
        self.tol_g = solver.rtol * b_norm
        self.tol_e = solver.eq_rtol * b_norm / solver.eq_scale
        self.mu = np.zeros(self.D.m) if multiplier is None else \
            np.array(multiplier, dtype=np.float64)
        if self.mu.shape != (self.D.m,):
            raise ValueError(f"smalbe: multiplier has shape {self.mu.shape}, expected "
                             f"({self.D.m},)")
        self.inner_qp = self._inner_qp(qp, norm_A)
        self.g, self.tmp = qp.b.duplicate(), qp.b.duplicate()
        self.g_valid = False
        acceleration = solver.acceleration
        if acceleration == "auto":
            curved = getattr(qp.constraints, "curved", False)
            acceleration = "search" if curved else "anderson"
        self.anderson = Anderson(solver.depth) if acceleration == "anderson" else None
        #: The extrapolation of a slow outer loop along D x ('aitken', 'search') or None.
        extrapolation = EXTRAPOLATIONS.get(acceleration)
        self.extrapolation = None if extrapolation is None else extrapolation()
        self.prev_active: np.ndarray | None = None
        self.history: list[dict] = []
        self.total_it, self.L_prev = 0, None
        self.dx_prev = math.inf

    def _inner_qp(self, qp: QP, norm_A: float) -> QP:
        """The QP of the augmented Lagrangian: ``A + rho D^T D``, ``b - D^T mu``, the set."""
        s, rho = self.s, self.rho
        inner_norm = s.inner_norm_A if s.inner_norm_A is not None else max(norm_A, rho)
        H = penalized_operator(qp.A, self.D, rho)
        self.prec, inner_prec = None, None
        if qp.preconditioner is not None:
            self.prec = Preconditioner(qp.preconditioner)  # counts the applications of M^{-1}
            self.counts["precond"] = 0
            inner_prec = (ProjectedPreconditioner(self.prec, self.D, rho)
                          if s.preconditioner_form == "projected" else self.prec)
        bk = qp.b.duplicate()
        self.D.mult_transpose(self.mu, bk)
        bk.aypx(-1.0, qp.b)  # b - D^T mu
        return qp.child(A=H, b=bk, eq=None, norm_A=inner_norm, preconditioner=inner_prec,
                        operator_key=(qp.A, float(rho)))

    def run(self) -> QPResult:
        """The outer loop; the result. The inner QP's operator and vectors are freed after it.

        (A shell Mat holds its Python context: without ``destroy`` neither is ever freed.)
        """
        try:
            reason = "max_outer"
            for k in range(self.s.max_outer):
                M_k = self.M
                res = self._inner_solve(M_k)
                reason = self._outer_update(k, M_k, res)
                if reason is not None:
                    break
            else:
                reason = "max_outer"
            return self._result(reason, res)
        finally:
            for obj in (self.inner_qp.A, self.inner_qp.b, self.g, self.tmp):
                obj.destroy()

    def _inner_solve(self, M_k: float) -> QPResult:
        """The inner solve of one outer iteration; its counts added to SMALBE's."""
        D, eta, tol_g, tol_e = self.D, self.eta, self.tol_g, self.tol_e

        def inner_stop(gP: float, xv: PETSc.Vec, gv: PETSc.Vec) -> bool:
            dxv = float(np.linalg.norm(D.mult(xv)))
            return gP <= min(M_k * dxv, eta) or (self.test is None and gP <= tol_g and
                                                 dxv <= tol_e)

        final_test = None
        if self.test is not None:  # the caller's final test, checked first (reason 'rtol')
            def final_test(gPa: np.ndarray, xv: PETSc.Vec) -> bool:
                # both parts evaluated at every iterate: ``test.last`` is then the weighted
                # gradient of the last one, which the history records against its bound
                passed = self.test(gPa, xv)
                return float(np.linalg.norm(D.mult(xv))) <= self.test.eq_tol and passed

        res = self.s.inner.solve(self.inner_qp, self.x, stop=inner_stop, rtol=0.0, atol=0.0,
                                 max_it=self.s.max_it - self.total_it, b_norm=self.b_norm,
                                 g=self.g, g_valid=self.g_valid, test=final_test)
        self.g_valid = True
        self.total_it += res.iterations
        self.mults += res.hessian_mults
        for key, value in res.counts.items():
            self.counts[key] = self.counts.get(key, 0) + value
        return res

    def _outer_update(self, k: int, M_k: float, res: QPResult) -> str | None:
        """Record the outer iteration, adapt M, update the multiplier; the reason to stop."""
        rho = self.rho
        self.Dx = Dx = self.D.mult(self.x)
        self.dx = dx = float(np.linalg.norm(Dx))
        L, L_prev = res.objective, self.L_prev
        increase_ok = None if L_prev is None else bool(L >= L_prev + 0.5 * rho * dx * dx)
        if increase_ok is False:
            self.M /= self.s.beta
        record = {"k": k, "inner_iterations": res.iterations,
                  "hessian_mults": res.hessian_mults, "gP": res.gP_norm, "Dx": dx, "M": M_k,
                  "M_next": self.M, "rho": rho, "L": L, "L_prev": L_prev,
                  "L_increase_ok": increase_ok, "M_decreased": increase_ok is False,
                  "inner_reason": res.reason}
        if self.test is not None:  # where the caller's bounds stand (which one binds)
            record.update(test_gP=self.test.last, test_tol=self.test.tol,
                          eq_tol=self.test.eq_tol)
        self.history.append(record)
        if self.s.monitor is not None:
            self.s.monitor(k, record)
        final = res.reason == "rtol" if self.test is not None else \
            res.gP_norm <= self.tol_g and dx <= self.tol_e
        self._update_multiplier(Dx, res, final)
        self.L_prev = L
        if final:
            return "converged"
        if self.growth > 1.0 and dx > SLOW_OUTER * self.dx_prev and self.rho < self.rho_cap:
            self._grow_rho(min(self.rho * self.growth, self.rho_cap))
        self.dx_prev = dx
        return None if res.converged else res.reason

    def _grow_rho(self, rho: float) -> None:
        """Raise ρ: the inner operator and preconditioner anew, ``g += (ρ' − ρ) DᵀD x``.

        The multiplier and ``b − Dᵀμ`` are unchanged; the Anderson memory (a map of the old
        ρ) is cleared and the step-4 test, whose L is of the old ρ, skipped once.
        """
        old, s = self.inner_qp, self.s
        self.D.mult_transpose(self.D.mult(self.x), self.tmp)
        self.g.axpy(rho - self.rho, self.tmp)
        inner_norm = max(self.norm_A, rho) if s.inner_norm_A is None else \
            s.inner_norm_A + rho - self.rho0
        if isinstance(old.preconditioner, ProjectedPreconditioner):
            old.preconditioner.rho = rho
        self.rho = rho
        self.inner_qp = old.child(A=penalized_operator(self.qp.A, self.D, rho),
                                  operator_key=(self.qp.A, float(rho)),
                                  norm_A=inner_norm)
        old.A.destroy()
        if self.anderson is not None:
            self.anderson.reset()
        if self.extrapolation is not None:
            self.extrapolation.reset()
        self.L_prev = None

    def _update_multiplier(self, Dx: np.ndarray, res: QPResult, final: bool) -> None:
        """``mu += rho D x`` (accelerated unless final), and ``b - D^T mu``, ``g`` with it.

        Updated even at the end: the KKT multiplier of the final x is ``mu_k + rho D x``
        (the plain update, whatever the acceleration).
        """
        step = self.rho * Dx
        if not final and self.anderson is not None:
            # A new active set is a new affine map: the secant memory of the old one misleads.
            comm = self.x.getComm().tompi4py()
            if self.prev_active is None or any_rank(
                    comm, bool(np.any(res.active != self.prev_active))):
                self.anderson.reset()
            step = self.anderson.step(self.mu, step)
            self.prev_active = res.active.copy()
        elif not final and self.extrapolation is not None:
            step = self.extrapolation.step(Dx, step)
        self.mu += step
        self.D.mult_transpose(step, self.tmp)
        self.inner_qp.b.axpy(-1.0, self.tmp)
        self.g.axpy(1.0, self.tmp)

    def _result(self, reason: str, res: QPResult) -> QPResult:
        rho, Dx, dx, mu = self.rho, self.Dx, self.dx, self.mu
        f = res.objective - float(np.dot(mu - rho * Dx, Dx)) - 0.5 * rho * dx * dx
        if self.prec is not None:
            self.counts["precond"] = self.prec.count
        return QPResult(x=self.x, converged=reason == "converged", reason=reason,
                        iterations=self.total_it, outer_iterations=len(self.history),
                        hessian_mults=self.mults, counts=self.counts, gP_norm=res.gP_norm,
                        Dx_norm=dx, b_norm=self.b_norm, active=res.active,
                        active_count=res.active_count, history=self.history, multiplier=mu,
                        objective=f)


def smalbe(A: PETSc.Mat, b: PETSc.Vec, D: EqualityConstraint, x: PETSc.Vec, *, lb=None,
           ub=None, rtol: float = 1e-6, eq_rtol: float | None = None, rho: float | None = None,
           M: float | None = None, eta: float | None = None, beta: float = 2.0,
           norm_A: float | None = None, inner: str = "mprgp",
           inner_options: dict[str, Any] | None = None, max_outer: int = 100,
           max_it: int = 10000, monitor: Callable[[int, dict], None] | None = None,
           eq_scale: float = 1.0, multiplier: np.ndarray | None = None,
           preconditioner=None, preconditioner_form: str = "projected",
           acceleration: str = "none", depth: int = 5, rho_growth: float | None = None,
           rho_max: float | None = None) -> QPResult:
    """Solve ``min f(x)`` s.t. ``lb <= x <= ub``, ``D x = 0`` by SMALBE-M (collective).

    The function form of :class:`SMALBE` (see there for the algorithm and the result), with
    ``rho``, ``M``, ``eta``, ``rho_max`` absolute (defaults ``1.1 ||A||``, ``100 ||A||``,
    ``0.1 ||b||``, ``100 ||A||``).

    ``inner`` is ``'mprgp'`` (:class:`.mprgp.MPRGP`, bounds ``lb``, ``ub``) or ``'mpgp'``
    (:class:`.mpgp.MPGP`: bounds and disc constraints, given as
    ``inner_options={'discs': ...}``); ``inner_options`` are the keyword arguments of the inner
    solver's constructor (``gamma``, ``expansion``, ``alpha``, ``alpha_bar``, ``face``,
    ``monitor``), ``discs`` (the QP's) and ``norm_A`` (SMALBE's ``inner_norm_A``). ``norm_A``
    is ``||A||`` (default a Lanczos estimate, counted in ``hessian_mults``), ``preconditioner``
    the QP's ``M^{-1}``; the others are :class:`SMALBE`'s and :meth:`SMALBE.solve`'s.
    """
    if inner not in INNER:
        raise ValueError(f"smalbe: inner solver {inner!r} is not available ('mprgp', 'mpgp')")
    opts = dict(inner_options or {})
    bad = sorted(set(opts) & set(_RESERVED))
    if bad:
        raise ValueError(f"smalbe: inner_options may not set {bad} (SMALBE controls them; "
                         "pass a preconditioner as smalbe(preconditioner=...))")
    discs, inner_norm_A = opts.pop("discs", None), opts.pop("norm_A", None)
    if acceleration not in ACCELERATIONS or depth < 1:
        raise ValueError(f"smalbe: acceleration must be one of {ACCELERATIONS} and depth >= 1, "
                         f"got {acceleration!r}, {depth}")
    solver = SMALBE(
        INNER[inner](**opts), rtol=rtol, eq_rtol=eq_rtol, eq_scale=eq_scale,
        max_outer=max_outer, max_it=max_it, rho=1.1 if rho is None else Absolute(rho),
        M=100.0 if M is None else Absolute(M), eta=None if eta is None else Absolute(eta),
        beta=beta, acceleration=acceleration, depth=depth, rho_growth=rho_growth,
        rho_max=None if rho_max is None else Absolute(rho_max), inner_norm_A=inner_norm_A,
        preconditioner_form=preconditioner_form, monitor=monitor)
    qp = QP.create(A, b, lb=lb, ub=ub, discs=discs, eq=D, norm_A=norm_A,
                   preconditioner=preconditioner)
    return solver.solve(qp, x, multiplier=multiplier)


__all__ = ["ACCELERATIONS", "INNER", "OPTIONS", "PRECONDITIONER_FORMS", "SMALBE", "Absolute",
           "smalbe"]
