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
    """

    result: QPResult
    x: PETSc.Vec
    u: PETSc.Vec
    lam: PETSc.Vec
    alpha: np.ndarray
    G_lambda: np.ndarray


#: ``qp="penalty"`` under the KKT test: after a failed check ρ grows by twice the largest
#: residual over rtol (the residuals fall like 1/ρ), within these factors.
PENALTY_GROWTH = (10.0, 1e4)


def solve_qp(qp: DualQP, opts: SolverOptions, *, report: Report | None = None,
             progress: Progress | None = None, timer: Timer | None = None,
             friction: FrictionSolve | None = None, preconditioner=None,
             x0: PETSc.Vec | None = None, multiplier0: np.ndarray | None = None) -> QPSolve:
    """Run the QP solver the dual QP needs and map its solution back (collective).

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
    """
    feti, ineq = qp.feti, qp.ineq
    comm = feti.comm
    report = Report() if report is None else report
    progress = Progress(comm, 0) if progress is None else progress
    timer = Timer() if timer is None else timer
    n_ineq = comm.allreduce(int(ineq.sum()))
    # the QP's rows are a subset of the problem's (FETI-1 and FETI-DP remove some)
    qp_row = np.full(qp.system.dual_size[0], -1, dtype=np.int64)
    qp_row[qp.row_index] = np.arange(qp.row_index.size)
    if friction is not None:
        friction.relabel(qp_row)

    own_precond = preconditioner is None
    if own_precond:
        with timer.phase("preconditioner"):
            preconditioner = make_preconditioner(opts.preconditioner, qp.primal, opts.factor,
                                                 opts.preconditioner_scaling,
                                                 explicit=feti.operator == "explicit")
    precond = preconditioner
    report.warnings.extend(getattr(precond, "notes", []))
    x = qp.b.duplicate()
    if x0 is None:
        x.set(0.0)
        if friction is None and n_ineq:
            qp.start(x)
    else:
        x0.copy(x)
    mults0 = feti.hessian_mults
    kkt_test = opts.stop_test == "kkt"
    penalty = opts.qp == "penalty"
    rho_factor = 1.0  # qp="penalty": ρ grows by PENALTY_GROWTH after a failed check
    stop = KKTStop(qp, opts.rtol) if kkt_test else None
    runs: list[QPResult] = []
    check_mults = kplus = 0
    done = False

    def rescale(res: QPResult) -> None:
        # the scales of the KKT test from the first friction step's solution (one recovery)
        nonlocal kplus
        if stop is None or stop.checks or kplus:
            return
        u1, lam1, _, _ = _recover(qp, res, x, friction)
        friction.relabel(qp_row)
        lam_qp1 = qp.multipliers(x)
        stop.rescale(u1, lam_qp1)
        kplus += 1
        for v in (u1, lam1, lam_qp1):
            v.destroy()

    while True:
        used = sum(r.iterations for r in runs)
        with timer.phase("iterations"):
            def run_qp(mu=multiplier0, used=used, loosen=1.0, rho_factor=rho_factor):
                # loosen: Coulomb's early fixed-point steps are solved to loosen·rtol
                o = opts if loosen == 1.0 or stop is not None else \
                    opts.replace(rtol=opts.rtol * loosen)
                return _run_qp(o, report, progress, qp, x, n_ineq, precond, friction, mu,
                               max_it=opts.max_it - used,
                               test=None if stop is None else stop.make_test(loosen),
                               rho_factor=rho_factor)
            res = run_qp() if friction is None else friction.run(
                run_qp, x, qp.lam_hat, ineq, progress, opts.rtol, rescale)
        runs.append(res)
        m0 = feti.hessian_mults
        with timer.phase("recovery"):
            u, lam_all, alpha, Glam = _recover(qp, res, x, friction)
        kplus += 1
        if stop is None or not res.converged:
            break
        with timer.phase("stopping test"):
            scale, kind, ineq_all = row_data(qp)
            kkt, _ = kkt_residuals(qp.system, scale, kind, ineq_all, u, lam_all,
                                   friction=friction)
            lam_qp = qp.multipliers(x)
            done = stop.accept(kkt, u, lam_qp, res.Dx_norm)
            lam_qp.destroy()
        used = sum(r.iterations for r in runs)
        if done or stop.stalled or stop.checks >= MAX_CHECKS or used >= opts.max_it:
            if not done:
                worst = max(kkt.values())
                why = "more iterations did not lower it: the round-off floor of this dual " \
                    "problem (e.g. eps times the gaps of contact rows far out of reach)" \
                    if stop.stalled else f"after {stop.checks} checks"
                report.warnings.append(
                    f"the KKT residuals did not all reach rtol {opts.rtol:.0e}: the largest is "
                    f"{worst:.1e} ({why})")
            break
        if penalty:
            # the penalty leaves ‖G̃x‖ = O(1/ρ), and with it the balance of the floating
            # subdomains and the gluing: the residuals fall like 1/ρ, not with the gradient
            rho_factor *= min(PENALTY_GROWTH[1], max(PENALTY_GROWTH[0],
                                                     2.0 * max(kkt.values()) / opts.rtol))
        check_mults += feti.hessian_mults - m0
        progress.info(f"stopping test: KKT residuals above rtol ({max(kkt.values()):.1e}); "
                      "continuing")
        u.destroy()
        lam_all.destroy()
        multiplier0 = res.multiplier
        if friction is not None:  # back to the QP's rows (the recovery left the problem's)
            friction.relabel(qp_row)
    res = _merge(runs)
    report.hessian_mults = m0 - mults0  # the iterations and the checks before the last
    report.stopping = {"test": "kkt" if stop is not None else "dual",
                       "met": None if stop is None else done,
                       "checks": 0 if stop is None else stop.checks,
                       "check_hessian_mults": check_mults, "check_kplus_solves": kplus - 1,
                       "history": [] if stop is None else stop.history}
    if own_precond and precond is not None and hasattr(precond, "destroy"):
        precond.destroy()
    return QPSolve(result=res, x=x, u=u, lam=lam_all, alpha=alpha, G_lambda=Glam)


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
              progress: Progress | None = None) -> QPSolver:
    """The QP solver the dual QP needs, the least machinery first (the module docstring).

    Args:
        opts: The solver options (each solver's own under its prefix: ``opts.of(...)``).
        dual: The dual QP (its coarse space decides between MPRGP alone and SMALBE).
        n_ineq: Number of inequality rows of the whole problem (none: projected CG).
        discs: Whether friction puts the tangential multipliers in discs (MPGP, 3D).
        progress: Monitors of the inner and outer iterations.
    """
    inner_mon = None if progress is None else progress.inner
    if n_ineq == 0:
        # When only prescribed values drive the problem, P b can be pure round-off: the floor
        # b_noise keeps CG from chasing it.
        return CG(rtol=opts.rtol, atol=dual.b_noise, max_it=opts.max_it, monitor=inner_mon)
    mprgp_opts = opts.of(MPRGP_OPTIONS)
    inner = MPGP(gamma=mprgp_opts["gamma"], rtol=opts.rtol, max_it=opts.max_it,
                 monitor=inner_mon) if discs else \
        MPRGP(rtol=opts.rtol, max_it=opts.max_it, monitor=inner_mon, **mprgp_opts)
    if dual.constraint.m == 0 or opts.qp == "penalty":
        return inner
    # rho and M relative to ||PFP||, eta to ||b||; ||G̃x|| is in units of λ, ||b|| in units
    # of F λ: compare ||PFP|| ||G̃x||.
    return SMALBE(inner, rtol=opts.rtol, eq_rtol=opts.eq_rtol or opts.rtol,
                  eq_scale=dual.norm_A, max_outer=opts.max_outer, max_it=opts.max_it,
                  monitor=None if progress is None else progress.outer,
                  **opts.of(SMALBE_OPTIONS))


def _run_qp(opts, report, progress, dual: DualQP, x, n_ineq, precond, friction=None,
            multiplier0=None, max_it=None, test=None, rho_factor=1.0):
    """Build the QP of this solve (bounds, friction) and run the solver it needs.

    With ``friction`` the start ``x`` is given (a warm start) and the friction rows are bounded.
    ``max_it`` is what is left of the budget of iterations (default ``opts.max_it``), ``test``
    the stopping test that replaces the solver's relative one (:class:`.kkt_stop.KKTStop`),
    ``rho_factor`` a factor on the dual penalty's ρ (``qp="penalty"``).
    """
    if max_it is not None:
        opts = opts.replace(max_it=max(int(max_it), 1))
    feti, ocon, norm_A = dual.feti, dual.constraint, dual.norm_A
    lb, ub, discs, multiplier = dual.lb, None, None, multiplier0
    if friction is not None and n_ineq:
        lb = dual.lb.copy()  # the friction rows get bounds of their own
        ub, discs, multiplier = friction.bounds(lb, dual.lam_hat)
    solver = qp_solver(opts, dual, n_ineq, discs is not None, progress)
    report.solver = solver.name if not isinstance(solver, SMALBE) else \
        f"smalbe{' (mpgp)' if discs is not None else ''}"
    if isinstance(solver, CG):
        return solver.solve(QP(dual.A, dual.b, eq=ocon, preconditioner=precond), x, test=test)
    if ocon.m == 0:
        return solver.solve(QP.create(feti.F, feti.d, lb=lb, ub=ub, discs=discs,
                                      norm_A=norm_A, preconditioner=precond), x, test=test)
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


__all__ = ["KKT_WARN", "QPSolve", "qp_solver", "solve_qp", "warn_loose_stop"]
