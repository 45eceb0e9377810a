"""The dual solve: run the QP solver the dual QP needs and map its solution back.

The chain (:func:`.dual.dual_qp`): decompose, assemble, [eliminate Dirichlet conditions,
eliminate corners], dualize, homogenize, project; the solution of the QP goes back through it
(:meth:`.dual.DualQP.map_back`). :class:`~dolfinx_feti.FetiSolver` calls :func:`solve_qp` once
per solve on the chain it keeps.

Solver choice (the least machinery the problem needs):
- no inequality rows: projected CG on P F P;
- inequalities and a coarse space (always in Total FETI; in FETI-1 and FETI-DP when a body or
  a subdomain floats): SMALBE-M with inner MPRGP on P F P;
- inequalities and no coarse space (FETI-DP or FETI-1 with every body held): MPRGP alone on F.
With friction (:mod:`.friction`) the tangential multipliers get box bounds (2D: MPRGP with upper
bounds) or disc bounds (3D: MPGP, also as SMALBE's inner solver); Coulomb friction repeats the
solve in a fixed point on the slip bounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from ..feti.chain import DualQP
from ..feti.free_motions import remove_free_motions
from ..feti.preconditioner import make_preconditioner
from ..log import Progress
from ..options import PENALTY, SolverOptions
from ..qp import (
    CG,
    MPGP,
    MPRGP,
    QP,
    SMALBE,
    ProjectedPreconditioner,
    QPResult,
    QPSolver,
    projected_operator,
)
from ..qp.mprgp import OPTIONS as MPRGP_OPTIONS
from ..qp.recycle import Recycle
from ..qp.smalbe import OPTIONS as SMALBE_OPTIONS
from ..results.report import Report
from ..timing import Timer
from .friction import FrictionSolve
from .kkt_stop import KEYS, MAX_CHECKS, KKTStop, kkt_residuals, row_data

#: A converged solve whose KKT residuals exceed KKT_WARN · rtol gets a warning.
KKT_WARN = 1e3


@dataclass
class QPSolve:
    """What :func:`solve_qp` returns.

    Attributes:
        result: The QP solver's result.
        x: The homogenized iterate the solver returned (λ = λ̂ + x).
        u: The primal solution of the original problem (Dirichlet values included).
        lam: The multipliers of all rows of the original problem.
        alpha: The rigid-body amplitudes of the dualized problem's kernel.
        G_lambda: G λ of the QP's multipliers (to compare with ``e``).
        force_ratio: The ratio of the largest force of all rows to the QP rows' at the last
            KKT check (:meth:`.KKTStop.measure`; 1 without the KKT test), for the bound of a
            next warm solve.
    """

    result: QPResult
    x: PETSc.Vec
    u: PETSc.Vec
    lam: PETSc.Vec
    alpha: np.ndarray
    G_lambda: np.ndarray
    force_ratio: float = 1.0


#: ``qp="penalty"`` under the KKT test: after a failed check ρ grows by twice the largest
#: residual over rtol (the residuals fall like 1/ρ), within these factors.
PENALTY_GROWTH = (10.0, 1e4)

#: Under the KKT test a run after a failed check gets at most CONTINUE_BUDGET times the
#: (outer) iterations of all runs before it, and at least CONTINUE_MIN: the check moves the
#: bound by the factor the residuals missed rtol by, which a converging iteration covers in
#: fewer. A run that spends it has met the round-off floor of the dual gradient, below which
#: the bound asks for what no iteration reaches (finding 8's obstacle 1e6 away on 2 ranks:
#: 1 000 outer iterations of one inner step each, then max_outer); the check after it decides.
CONTINUE_BUDGET, CONTINUE_MIN = 1.0, 20


def solve_qp(qp: DualQP, opts: SolverOptions, *, report: Report | None = None,
             progress: Progress | None = None, timer: Timer | None = None,
             friction: FrictionSolve | None = None, preconditioner=None,
             x0: PETSc.Vec | None = None, multiplier0: np.ndarray | None = None,
             u_floor: float = 0.0, recycle: Recycle | None = None,
             scales: tuple[float, float] | None = None, force_ratio: float = 1.0,
             g0: PETSc.Vec | None = None) -> QPSolve:
    """Run the QP solver the dual QP needs and map its solution back (collective).

    Under the KKT stopping test a converged run is recovered and checked in physical units; a
    failed check continues the solve warm from where it stopped (:class:`_KKTRuns`).

    Args:
        qp: The dual QP (:func:`.dual.dual_qp`, or built from a hand-made primal system).
        opts: The solver options.
        report: Gets the solver's name, warnings and the F-multiplications; a new one if None.
        progress: Progress output (none if None).
        timer: Phase timers (a new one if None).
        friction: The friction rows and their state, in the layout of ``qp.system``'s rows.
        preconditioner: The dual preconditioner to use; None builds the one ``opts`` names
            (and frees it after the solve).
        x0: The start (a homogenized iterate, feasible for the bounds); None for the default
            start :meth:`.dual.DualQP.start`. Not used with friction (it starts cold).
        multiplier0: SMALBE's start for the multiplier of G̃ x = 0 (e.g. an earlier solve's
            ``result.multiplier`` on the same G̃); None for zeros.
        u_floor: A lower bound of the KKT test's displacement scale (:class:`.KKTStop`).
        recycle: The store of recycled CG directions the MPRGP solves use and keep
            (:mod:`dolfinx_feti.qp.recycle`; the owner clears it when the operator changes);
            None: a new one per run when ``opts.mprgp_reuse`` (reuse within the run only).
        scales: The KKT test's scales (U, Λ) of an earlier solve of a case near this one (a
            warm step of a load path), taken before the first run (:meth:`.KKTStop.rescale`).
        force_ratio: The KKT bound's ratio of all rows' largest force to the QP rows'
            (:class:`.KKTStop`; a warm solve passes the last solve's ``force_ratio``).
        g0: The gradient A x0 − b at ``x0`` (:meth:`.DualQP.warm_start`), taken by the first
            run of MPRGP alone (no coarse space, no friction) instead of its first product.
    """
    report = Report() if report is None else report
    timer = Timer() if timer is None else timer
    own_precond = preconditioner is None
    if own_precond:
        with timer.phase("preconditioner"):
            preconditioner = make_preconditioner(opts.preconditioner, qp.primal, opts.factor,
                                                 opts.preconditioner_scaling,
                                                 explicit=qp.feti.operator == "explicit")
    report.warnings.extend(getattr(preconditioner, "notes", []))
    runs = _KKTRuns(qp, opts, report, Progress(qp.feti.comm, 0) if progress is None else
                    progress, timer, friction, preconditioner, x0, multiplier0, u_floor,
                    recycle, scales, force_ratio, g0)
    out = runs.solve()
    if own_precond and preconditioner is not None and hasattr(preconditioner, "destroy"):
        preconditioner.destroy()
    return out


def _qp_rows(qp: DualQP) -> np.ndarray:
    """Local row of the QP of each local row of the problem (-1: removed by FETI-1/FETI-DP)."""
    qp_row = np.full(qp.system.dual_size[0], -1, dtype=np.int64)
    qp_row[qp.row_index] = np.arange(qp.row_index.size)
    return qp_row


def _start(qp: DualQP, x0: PETSc.Vec | None, n_ineq: int,
           friction: FrictionSolve | None) -> PETSc.Vec:
    """The first iterate: a copy of ``x0``, or the default start (friction sets its own)."""
    x = qp.b.duplicate()
    if x0 is None:
        x.set(0.0)
        if friction is None and n_ineq:
            qp.start(x)
    else:
        x0.copy(x)
    return x


#: How the warning of a KKT test that ended above rtol begins (a driver that judges the
#: solution by its own test, as Newton does for its increments' QPs, leaves it out).
UNMET_KKT = "the KKT residuals did not all reach rtol"


def _unmet_warning(kkt: dict, rtol: float, stop: KKTStop) -> str:
    """The warning of a KKT test that ended without every residual below rtol."""
    why = "more iterations did not lower it: the round-off floor of this dual problem " \
        "(e.g. eps times the gaps of contact rows far out of reach)" \
        if stop.stalled else f"after {stop.checks} checks"
    return (f"{UNMET_KKT} {rtol:.0e}: the largest is "
            f"{max(kkt.values()):.1e} ({why})")


def _penalty_growth(kkt: dict, rtol: float) -> float:
    """Factor on ρ after a failed KKT check of ``qp="penalty"``.

    The penalty leaves ‖G̃x‖ = O(1/ρ), and with it the balance of the floating subdomains and
    the gluing: the residuals fall like 1/ρ, not with the gradient.
    """
    return min(PENALTY_GROWTH[1], max(PENALTY_GROWTH[0], 2.0 * max(kkt.values()) / rtol))


class _KKTRuns:
    """The runs of the QP solver of one :func:`solve_qp` and the KKT checks between them."""

    def __init__(self, qp: DualQP, opts: SolverOptions, report: Report, progress: Progress,
                 timer: Timer, friction: FrictionSolve | None, precond,
                 x0: PETSc.Vec | None, multiplier0: np.ndarray | None, u_floor: float = 0.0,
                 recycle: Recycle | None = None, scales: tuple[float, float] | None = None,
                 force_ratio: float = 1.0, g0: PETSc.Vec | None = None):
        self.qp, self.opts, self.report, self.progress, self.timer = \
            qp, opts, report, progress, timer
        self.friction, self.precond, self.multiplier0 = friction, precond, multiplier0
        self.recycle = recycle
        self.n_ineq = qp.feti.comm.allreduce(int(qp.ineq.sum()))
        # the QP's rows are a subset of the problem's (FETI-1 and FETI-DP remove some)
        self.qp_row = _qp_rows(qp)
        if friction is not None:
            friction.relabel(self.qp_row)
        self.x = _start(qp, x0, self.n_ineq, friction)
        # the start's gradient, for the first run only (then the iterate has moved)
        self.g0 = g0 if x0 is not None and friction is None else None
        self.stop = KKTStop(qp, opts.rtol, u_floor, force_ratio) \
            if opts.stop_test == "kkt" else None
        self.scaled = self.stop is not None and scales is not None
        if self.scaled:
            self.stop.take_scales(*scales)
        self.rho_factor = 1.0  # qp="penalty": ρ grows by PENALTY_GROWTH after a failed check
        self.runs: list[QPResult] = []
        self.check_mults = self.kplus = 0
        self.done = False

    def solve(self) -> QPSolve:
        """Run, recover and check until the test holds or gives up; the last recovery."""
        feti, stop = self.qp.feti, self.stop
        mults0 = feti.hessian_mults
        while True:
            res = self.run()
            if self.budget_spent(res):  # the check decides: met, stalled or another run
                res.converged, res.reason = True, "stop"
            m0 = feti.hessian_mults
            with self.timer.phase("recovery"):
                u, lam_all, alpha, Glam = _recover(self.qp, res, self.x, self.friction)
            self.kplus += 1
            if stop is None or not res.converged:
                break
            with self.timer.phase("stopping test"):
                kkt = self.check(u, lam_all, res)
            if self.finished(kkt):
                break
            self.continue_after(kkt, res)
            self.check_mults += feti.hessian_mults - m0
            u.destroy()
            lam_all.destroy()
        res = _merge(self.runs)
        self.report.hessian_mults = m0 - mults0  # the iterations and the checks before the last
        self.report.stopping = self.record()
        return QPSolve(result=res, x=self.x, u=u, lam=lam_all, alpha=alpha, G_lambda=Glam,
                       force_ratio=stop.measured if stop is not None else 1.0)

    def run(self) -> QPResult:
        """One run of the QP solver (with Coulomb friction: its fixed point) from ``x``."""
        with self.timer.phase("iterations"):
            def run_qp(mu=self.multiplier0, loosen=1.0, rho_factor=self.rho_factor):
                return self._run_qp(mu, loosen, rho_factor)
            res = run_qp() if self.friction is None else self.friction.run(
                run_qp, self.x, self.qp.lam_hat, self.qp.ineq, self.progress, self.opts.rtol,
                self._rescale)
        self.runs.append(res)
        return res

    def budget(self) -> tuple[int, int]:
        """(max_it, max_outer) of the next run.

        All that is left, or after a failed check :data:`CONTINUE_BUDGET` times what the runs
        before used (not with friction, whose fixed point runs the QP solver itself).
        """
        opts = self.opts
        used = sum(r.iterations for r in self.runs)
        max_it, max_outer = opts.max_it - used, opts.max_outer
        if self.runs and self.stop is not None and self.friction is None:
            outer = sum(r.outer_iterations for r in self.runs)
            max_it = min(max_it, max(CONTINUE_MIN, int(CONTINUE_BUDGET * used)))
            max_outer = min(max_outer, max(CONTINUE_MIN, int(CONTINUE_BUDGET * outer)))
        return max_it, max_outer

    def budget_spent(self, res: QPResult) -> bool:
        """Whether a run after a failed check stopped at :meth:`budget`, not at the options'."""
        if len(self.runs) < 2 or self.stop is None or self.friction is not None:
            return False
        used = sum(r.iterations for r in self.runs)
        return (res.reason == "max_it" and used < self.opts.max_it) or \
            (res.reason == "max_outer" and res.outer_iterations < self.opts.max_outer)

    def _run_qp(self, mu, loosen: float, rho_factor: float) -> QPResult:
        # loosen: Coulomb's early fixed-point steps are solved to loosen·rtol
        opts, stop = self.opts, self.stop
        o = opts if loosen == 1.0 or stop is not None else opts.replace(rtol=opts.rtol * loosen)
        max_it, max_outer = self.budget()
        if max_outer != opts.max_outer:
            o = o.replace(max_outer=max_outer)
        g0, self.g0 = self.g0, None
        return _run_qp(o, self.report, self.progress, self.qp, self.x, self.n_ineq,
                       self.precond, self.friction, mu, max_it=max_it, recycle=self.recycle,
                       test=None if stop is None else stop.make_test(loosen),
                       rho_factor=rho_factor, g0=g0)

    def _rescale(self, res: QPResult) -> None:
        # the scales of the KKT test from the first friction step's solution (one recovery)
        stop = self.stop
        # (not when the solve started from an earlier solve's scales: they are as good as
        # this step's, and the recovery is an F and a K⁺ application)
        if stop is None or stop.checks or self.kplus or self.scaled:
            return
        u1, lam1, _, _ = _recover(self.qp, res, self.x, self.friction)
        self.friction.relabel(self.qp_row)
        lam_qp1 = self.qp.multipliers(self.x)
        stop.rescale(u1, lam_qp1)
        self.kplus += 1
        for v in (u1, lam1, lam_qp1):
            v.destroy()

    def check(self, u: PETSc.Vec, lam_all: PETSc.Vec, res: QPResult) -> dict:
        """The KKT residuals of the recovered solution; sets :attr:`done` when they hold."""
        scale, kind, ineq_all = row_data(self.qp)
        kkt, _ = kkt_residuals(self.qp.system, scale, kind, ineq_all, u, lam_all,
                               friction=self.friction, u_floor=self.stop.u_floor)
        lam_qp = self.qp.multipliers(self.x)
        self.done = self.stop.accept(kkt, u, lam_qp, res.Dx_norm)
        self.stop.measure(lam_all, scale)
        lam_qp.destroy()
        return kkt

    def finished(self, kkt: dict) -> bool:
        """Whether to stop after this check (met, stalled, out of checks or iterations)."""
        stop = self.stop
        used = sum(r.iterations for r in self.runs)
        if not (self.done or stop.stalled or stop.checks >= MAX_CHECKS
                or used >= self.opts.max_it):
            return False
        if not self.done:
            self.report.warnings.append(_unmet_warning(kkt, self.opts.rtol, stop))
        return True

    def continue_after(self, kkt: dict, res: QPResult) -> None:
        """Prepare the next run after a failed check: ρ, SMALBE's multiplier, the rows."""
        if self.opts.qp == "penalty":
            self.rho_factor *= _penalty_growth(kkt, self.opts.rtol)
        self.progress.info(f"stopping test: KKT residuals above rtol ({max(kkt.values()):.1e});"
                           " continuing")
        self.multiplier0 = res.multiplier
        if self.friction is not None:  # back to the QP's rows (the recovery left the problem's)
            self.friction.relabel(self.qp_row)

    def record(self) -> dict:
        """The report's ``stopping`` entry."""
        stop = self.stop
        return {"test": "kkt" if stop is not None else "dual",
                "met": None if stop is None else self.done,
                "checks": 0 if stop is None else stop.checks,
                "check_hessian_mults": self.check_mults,
                "check_kplus_solves": self.kplus - 1,
                "history": [] if stop is None else stop.history}


def _recover(qp: DualQP, res: QPResult, x: PETSc.Vec, friction: FrictionSolve | None):
    """(u, λ of all rows, α, Gλ) of the QP iterate ``x`` (collective; ``x`` unchanged).

    One F application (the dual gradient for α) and one K⁺ application (u).
    """
    feti, ocon, ineq, comm = qp.feti, qp.constraint, qp.ineq, qp.feti.comm
    at_bound = res.active if res.active is not None else np.zeros(ineq.size, dtype=bool)
    lam = qp.hom.map_back(x, at_bound)
    active = ~ineq | ~at_bound
    if friction is not None:  # a friction row holds as an equality where the node sticks
        friction.snap(lam, at_bound)
        active = friction.recovery_active(ineq, at_bound)
    g = feti.d.duplicate()
    feti.F.mult(lam, g)
    g.axpy(-1.0, feti.d)  # the dual gradient F λ − d
    alpha = feti.rigid_amplitudes(g, active, qp.proj.map_back(res.multiplier, g))
    Glam = ocon.base.mult(lam)
    u, lam_all = qp.map_back(lam, alpha)
    # of the solutions u + z (z a free motion), the same for every method and decomposition
    remove_free_motions(qp.free_motions(ocon.null_space), qp.copy_weight, u, comm)
    if friction is not None:
        friction.relabel(qp.row_index)
    for v in (g, lam):
        v.destroy()
    return u, lam_all, alpha, Glam


def _merge(runs: list[QPResult]) -> QPResult:
    """The last run's result with the iterations, counts and histories of all runs."""
    res = runs[-1]
    if len(runs) == 1:
        return res
    counts: dict[str, int] = {}
    for r in runs:
        for k, v in r.counts.items():
            counts[k] = counts.get(k, 0) + v
    res.iterations = sum(r.iterations for r in runs)
    res.outer_iterations = sum(r.outer_iterations for r in runs)
    res.hessian_mults = sum(r.hessian_mults for r in runs)
    res.counts = counts
    res.history = [h for r in runs for h in r.history]
    return res


def qp_solver(opts: SolverOptions, dual: DualQP, n_ineq: int, discs: bool = False,
              progress: Progress | None = None, recycle: Recycle | None = None) -> QPSolver:
    """The QP solver the dual QP needs, the least machinery first (the module docstring).

    Args:
        opts: The solver options (each solver's own under its prefix: ``opts.of(...)``).
        dual: The dual QP (its coarse space decides between MPRGP alone and SMALBE).
        n_ineq: Number of inequality rows of the whole problem (none: projected CG).
        discs: Whether friction puts the tangential multipliers in discs (MPGP, 3D).
        progress: Monitors of the inner and outer iterations.
        recycle: The recycled CG directions MPRGP uses and keeps (None: its own, if any).
    """
    inner_mon = None if progress is None else progress.inner
    if n_ineq == 0:
        # When only prescribed values drive the problem, P b can be pure round-off: the floor
        # b_noise keeps CG from chasing it.
        return CG(rtol=opts.rtol, atol=dual.b_noise, max_it=opts.max_it, monitor=inner_mon)
    mprgp_opts = opts.of(MPRGP_OPTIONS)
    inner = MPGP(gamma=mprgp_opts["gamma"], rtol=opts.rtol, max_it=opts.max_it,
                 monitor=inner_mon) if discs else \
        MPRGP(rtol=opts.rtol, max_it=opts.max_it, monitor=inner_mon, recycle=recycle,
              **mprgp_opts)
    if dual.constraint.m == 0 or opts.qp == "penalty":
        return inner
    # rho and M relative to ||PFP||, eta to ||b||; ||G̃x|| is in units of λ, ||b|| in units
    # of F λ: compare ||PFP|| ||G̃x||.
    return SMALBE(inner, rtol=opts.rtol, eq_rtol=opts.eq_rtol or opts.rtol,
                  eq_scale=dual.norm_A, max_outer=opts.max_outer, max_it=opts.max_it,
                  monitor=None if progress is None else progress.outer,
                  **opts.of(SMALBE_OPTIONS))


def unused_on_discs(opts: SolverOptions) -> str | None:
    """The warning for MPRGP options set away from their defaults that MPGP on discs ignores.

    MPGP on friction discs (3D) implements the fixed expansion step only and does not recycle;
    as PETSc reports options that were set and not used, a choice that is not honoured is
    said rather than dropped (the problem is solved all the same).
    """
    declared = MPRGP_OPTIONS.options
    unused = [f"mprgp_{k}={getattr(opts, MPRGP_OPTIONS.key(k))!r}" for k in ("expansion", "alpha")
              if getattr(opts, MPRGP_OPTIONS.key(k)) != declared[k].default]
    if not unused:
        return None
    return (f"{', '.join(unused)} not used: MPGP on the friction discs (3D) takes the fixed "
            "expansion step")


def _run_qp(opts, report, progress, dual: DualQP, x, n_ineq, precond, friction=None,
            multiplier0=None, max_it=None, test=None, rho_factor=1.0, recycle=None, g0=None):
    """Build the QP of this solve (bounds, friction) and run the solver it needs.

    With ``friction`` the start ``x`` is given (a warm start) and the friction rows are bounded.
    ``max_it`` is what is left of the budget of iterations (default ``opts.max_it``), ``test``
    the stopping test that replaces the solver's relative one (:class:`.kkt_stop.KKTStop`),
    ``rho_factor`` a factor on the dual penalty's ρ (``qp="penalty"``), ``g0`` the gradient
    A x − b at ``x`` if known (used by MPRGP alone, whose QP it is; else ignored).
    """
    if max_it is not None:
        opts = opts.replace(max_it=max(int(max_it), 1))
    feti, ocon, norm_A = dual.feti, dual.constraint, dual.norm_A
    lb, ub, discs, multiplier = dual.lb, None, None, multiplier0
    if friction is not None and n_ineq:
        lb = dual.lb.copy()  # the friction rows get bounds of their own
        ub, discs, multiplier = friction.bounds(lb, dual.lam_hat)
    solver = qp_solver(opts, dual, n_ineq, discs is not None, progress, recycle)
    if discs is not None:
        note = unused_on_discs(opts)
        if note and note not in report.warnings:
            report.warnings.append(note)
    report.solver = solver.name if not isinstance(solver, SMALBE) else \
        f"smalbe{' (mpgp)' if discs is not None else ''}"
    if isinstance(solver, CG):
        return solver.solve(QP(dual.A, dual.b, eq=ocon, preconditioner=precond), x, test=test)
    if ocon.m == 0:
        known = g0 is not None and discs is None and not isinstance(solver, CG)
        return solver.solve(QP.create(feti.F, feti.d, lb=lb, ub=ub, discs=discs,
                                      norm_A=norm_A, preconditioner=precond), x, test=test,
                            g=g0 if known else None, g_valid=known)
    if opts.qp == "penalty":
        # FETI-NCG_ρ: the equality G̃x = 0 replaced by the penalty ρQ; ||Gλ|| = O(1/ρ).
        report.solver = f"{solver.name} (dual penalty)"
        rho = opts.of(PENALTY)["rho"] * norm_A * rho_factor
        Arho = projected_operator(feti.F, ocon, rho=rho)
        if precond is not None:
            precond = ProjectedPreconditioner(precond, ocon, rho)
        res = solver.solve(QP.create(Arho, dual.b, lb=lb, ub=ub, discs=discs,
                                     norm_A=max(norm_A, rho), preconditioner=precond), x,
                           test=test)
        Arho.destroy()  # a shell holds its context until destroyed
        res.Dx_norm = float(np.linalg.norm(ocon.mult(x)))
        return res
    return solver.solve(QP.create(dual.A, dual.b, lb=lb, ub=ub, discs=discs, eq=ocon,
                                  norm_A=norm_A, preconditioner=precond), x,
                        multiplier=multiplier, test=test)


def warn_loose_stop(report: Report, rtol: float) -> None:
    """Warn when the dual stopping test held but the KKT residuals are far above rtol.

    The dual test ||g^P|| <= rtol ||b|| (``stop_test="dual"``) is relative to ||b||, which can
    be much larger than what the solution's accuracy is measured against: e.g. the gaps of
    contact rows far out of reach (an obstacle 1e6 away from a body that moves by 1e-2) enter
    ||b|| in full. The KKT test bounds the residuals themselves and warns on its own.
    """
    if report.stopping.get("test") == "kkt":
        return
    worst = max((report.kkt.get(k, 0.0) for k in KEYS), default=0.0)
    if report.converged and worst > KKT_WARN * max(rtol, 1e-13):
        report.warnings.append(
            f"the stopping test held (||g^P|| <= rtol ||b||, rtol {rtol:.0e}), but the largest "
            f"KKT residual is {worst:.1e}: ||b|| is dominated by data larger than the solution "
            "(e.g. the gaps of contact rows far out of reach); use stop_test='kkt' (the "
            "default: every KKT residual <= rtol) or lower rtol")


__all__ = ["KKT_WARN", "QPSolve", "UNMET_KKT", "qp_solver", "solve_qp", "warn_loose_stop"]
