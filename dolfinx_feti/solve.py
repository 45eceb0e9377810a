"""The solve: build the chain of transforms, run the QP solver the problem needs, map back.

The chain (:func:`.dual.dual_qp`): decompose, assemble, [eliminate Dirichlet conditions,
eliminate corners], dualize, homogenize, project; the solution of the QP goes back through it.

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

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .dual import DualQP, choose_method, dual_qp
from .errors import NotConverged
from .feti.free_motions import remove_free_motions
from .feti.precond import make_preconditioner
from .friction import FrictionSolve
from .log import Progress
from .mortar_report import mortar_warnings
from .options import PENALTY, SolverOptions, check_same_on_ranks
from .problem import ContactProblem
from .qp import (
    ConvergedReason,
    ProjectedPreconditioner,
    QPResult,
    cg,
    mpgp,
    mprgp,
    projected_operator,
    smalbe,
)
from .qp.mprgp import OPTIONS as MPRGP
from .qp.smalbe import OPTIONS as SMALBE
from .report import Report
from .solution import Solution
from .timing import Timer

#: A converged solve whose KKT residuals exceed KKT_WARN · rtol gets a warning.
KKT_WARN = 1e3


def solve(problem: ContactProblem, *, comm: MPI.Comm = MPI.COMM_WORLD,
          options: SolverOptions | Sequence[str] | None = None, **kwargs) -> Solution:
    """Solve a contact problem by FETI (Total FETI, FETI-1 or FETI-DP: option ``method``).

    Args:
        problem: The problem.
        comm: The ranks to spread the subdomains over.
        options: Solver options (:class:`SolverOptions`), or command-line tokens from which
            to read ``-feti_<name> value`` options (``options=sys.argv``: the script's command
            line, read only when passed); or give them as keyword arguments (``rtol=1e-8``,
            ...), which override both and the PETSc options database.
        **kwargs: Fields of :class:`SolverOptions`; with ``options`` given, they override its
            fields.

    Returns:
        The solution (displacement, multipliers, contact pressure, report). A solve that does
        not converge is returned with ``report.converged == False``, a negative
        ``report.converged_reason`` and its residuals (unless ``error_if_not_converged``).

    Raises:
        NotConverged: With ``error_if_not_converged``, when the solver did not converge (on
            every rank; ``error.solution`` holds what was reached).
        InputError: For a problem that is ill-posed as described (e.g. a floating body with a
            load its constraints cannot balance).
    """
    if options is None or not isinstance(options, SolverOptions):
        opts = SolverOptions.create(argv=options, **kwargs)
    else:
        opts = options.replace(**kwargs)
    check_same_on_ranks(opts, comm)
    progress = Progress(comm, opts.verbose)
    timer = Timer(progress.phase)
    report = Report()
    qp = dual_qp(problem, comm, factor=opts.factor, norm_rtol=opts.norm_rtol, timer=timer,
                 method=opts.method)
    report.warnings.extend(qp.warnings)
    feti, dec, rows, system = qp.feti, qp.dec, qp.rows, qp.system
    n_ineq = int(rows.contact.inequality.sum())
    fdata = qp.friction
    friction = None if fdata is None else FrictionSolve(fdata, rows, system.rows_local, comm)
    out = solve_qp(qp, opts, report=report, progress=progress, timer=timer, friction=friction)
    res, u, lam_all, alpha = out.result, out.u, out.lam, out.alpha

    report.converged = bool(res.converged) and bool(np.isfinite(res.gP_norm))
    report.reason = res.reason if np.isfinite(res.gP_norm) else "non-finite iterate"
    report.converged_reason = int(ConvergedReason.of(report.reason))
    report.outer_iterations = res.outer_iterations
    report.iterations = res.iterations
    report.counts = dict(res.counts)
    report.gP_rel = float(res.gP_norm / res.b_norm) if res.b_norm > 0 else float(res.gP_norm)
    e_norm = float(np.linalg.norm(feti.e))
    report.G_lambda = float(np.linalg.norm(out.G_lambda - feti.e) /
                            (e_norm if e_norm > 0 else 1.0))
    report.norm_F = qp.norm_A
    report.hessian_mults_total = feti.hessian_mults
    n_tang = 0 if fdata is None else int(fdata.rows.size)
    report.sizes = {"primal": system.primal_size[1], "dual": rows.size, "inequality": n_ineq,
                    "equality": rows.size - n_ineq - n_tang, "subdomains": dec.num_subdomains,
                    "coarse": int(feti.coarse_size), "coarse_rank": int(qp.constraint.m),
                    "ranks": comm.size}
    report.method = {"tfeti": "TFETI", "feti1": "FETI-1", "fetidp": "FETI-DP"}[qp.method]
    if qp.method != "tfeti":
        report.sizes["dual_method"] = int(feti.dual_size[1])
    report.sizes.update(qp.info)
    if not report.converged:
        report.warnings.append(f"the QP solver did not converge ({report.reason}) within "
                               f"{opts.max_it} iterations / {opts.max_outer} outer iterations")
        if n_ineq and report.G_lambda > 1e3 * opts.rtol:
            report.warnings.append(
                f"the contact forces do not balance the load (||G lambda - e|| / ||e|| = "
                f"{report.G_lambda:.1e}): a body may be pulled away from its only support; "
                "contact can push but not pull")
    progress.info(f"{report.solver}: {'converged' if report.converged else 'NOT converged'} "
                  f"({report.reason}), {report.outer_iterations} outer / {report.iterations} "
                  f"inner iterations, {report.hessian_mults} F-multiplications")
    if friction is not None:
        report.sizes["tangential"] = n_tang
        report.extra["friction"] = friction.info
        friction.destroy()
    sol = Solution(problem, system, qp.share, u, lam_all, alpha, report, comm,
                   friction=friction, surface=qp.surface)
    sol.dual = feti
    sol.check_kkt(rows.own.inequality)
    if qp.mortar:
        c, found = sol.contact, None
        surface = sol.surface  # a distributed mesh: the cells along the surfaces (rank 0)
        nodal = sol.nodal_values_on_root() if problem.mesh.part is None else \
            sol.surface_values()
        if comm.rank == 0:  # the surfaces of the whole mesh, which rank 0 holds
            mesh, node = (problem.mesh, c.node) if surface is None else \
                (surface.problem.mesh, surface.local(c.node))
            found = mortar_warnings(mesh, qp.mortar, nodal, c.spec, node, c.force)
        warn, report.extra["mortar"] = comm.bcast(found, root=0)
        report.warnings.extend(warn)
    _warn_loose_stop(report, opts.rtol)
    report.timings = timer.reduced(comm)
    report.timings["total"] = float(sum(report.timings.values()))
    report.extra["options"] = opts.to_dict()
    report.extra["history"] = res.history[-50:] if comm.rank == 0 else []
    for v in (qp.b, qp.lb, qp.lam_hat):
        v.destroy()
    if opts.error_if_not_converged and not report.converged:
        raise NotConverged(f"the solver did not converge: {report.reason} (converged reason "
                           f"{report.converged_reason}); see error.solution.report", sol)
    return sol


@dataclass
class QPSolve:
    """What :func:`solve_qp` returns.

    Attributes:
        result: The QP solver's result (its ``x`` is the homogenized iterate).
        u: The primal solution of the original problem (Dirichlet values included).
        lam: The multipliers of all rows of the original problem.
        alpha: The rigid-body amplitudes of the dualized problem's kernel.
        G_lambda: G λ of the QP's multipliers (to compare with ``e``).
    """

    result: QPResult
    u: PETSc.Vec
    lam: PETSc.Vec
    alpha: np.ndarray
    G_lambda: np.ndarray


def solve_qp(qp: DualQP, opts: SolverOptions, *, report: Report | None = None,
             progress: Progress | None = None, timer: Timer | None = None,
             friction: FrictionSolve | None = None) -> QPSolve:
    """Run the QP solver the dual QP needs and map its solution back (collective).

    Args:
        qp: The dual QP (:func:`.dual.dual_qp`, or built from a hand-made primal system).
        opts: The solver options.
        report: Gets the solver's name, warnings and the F-multiplications; a new one if None.
        progress: Progress output (none if None).
        timer: Phase timers (a new one if None).
        friction: The friction rows and their state, in the layout of ``qp.system``'s rows.
    """
    feti, ocon, ineq = qp.feti, qp.constraint, qp.ineq
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

    with timer.phase("preconditioner"):
        precond = make_preconditioner(opts.preconditioner, qp.primal, opts.factor,
                                      opts.preconditioner_scaling)
        report.warnings.extend(getattr(precond, "notes", []))
    x = qp.b.duplicate()
    x.set(0.0)
    mults0 = feti.hessian_mults
    with timer.phase("iterations"):
        def run_qp():
            return _run_qp(opts, report, progress, qp, x, n_ineq, precond, friction)
        res = run_qp() if friction is None else friction.run(run_qp, x, qp.lam_hat, ineq,
                                                             progress)
    report.hessian_mults = feti.hessian_mults - mults0

    with timer.phase("recovery"):
        lam = x.copy()
        lam.axpy(1.0, qp.lam_hat)
        at_bound = res.active if res.active is not None else np.zeros(ineq.size, dtype=bool)
        lam.array[ineq & at_bound] = 0.0  # exactly on the bound: λ = 0, not λ̂ − λ̂ rounded
        active = ~ineq | ~at_bound
        if friction is not None:  # a friction row holds as an equality where the node sticks
            friction.snap(lam, at_bound)
            active = friction.recovery_active(ineq, at_bound)
        g = feti.d.duplicate()
        feti.F.mult(lam, g)
        g.axpy(-1.0, feti.d)  # the dual gradient F λ − d
        hint = None
        if res.multiplier is not None:  # SMALBE: α = −T̃ᵀ(μ − G̃ g) from the dual KKT conditions
            hint = -ocon.transform_transpose(res.multiplier - ocon.mult(g))
        alpha = feti.rigid_amplitudes(g, active, hint)
        Glam = ocon.base.mult(lam)
        u, lam_all = qp.map_back(lam, alpha)
        # of the solutions u + z (z a free motion), the same for every method and decomposition
        remove_free_motions(qp.free_motions(ocon.null_space), qp.copy_weight, u, comm)
        if friction is not None:
            friction.relabel(qp.row_index)
    if precond is not None and hasattr(precond, "destroy"):
        precond.destroy()
    for v in (g, lam):
        v.destroy()
    return QPSolve(result=res, u=u, lam=lam_all, alpha=alpha, G_lambda=Glam)


def _run_qp(opts, report, progress, dual: DualQP, x, n_ineq, precond, friction=None):
    """The least machinery the problem needs (see the module docstring).

    With ``friction`` the start ``x`` is given (a warm start) and the friction rows are bounded.
    """
    feti, ocon, A, Pb, norm_A = dual.feti, dual.constraint, dual.A, dual.b, dual.norm_A
    if n_ineq == 0:
        report.solver = "cg"
        # When only prescribed values drive the problem, P b can be pure round-off: the floor
        # b_noise keeps CG from chasing it.
        return cg(A, Pb, x, projector=dual.projector, rtol=opts.rtol, atol=dual.b_noise,
                  max_it=opts.max_it, monitor=progress.inner, preconditioner=precond)
    lb = dual.lb
    ub = multiplier = None
    solver = mprgp
    inner = opts.of(MPRGP)
    if friction is None:
        dual.start(x)
    else:
        lb = dual.lb.copy()  # the friction rows get bounds of their own
        ub, discs, multiplier = friction.bounds(lb, dual.lam_hat)
        if discs is not None:  # MPGP: the fixed expansion only
            solver, inner = mpgp, {"gamma": inner["gamma"], "discs": discs}
    if ocon.m == 0:
        report.solver = solver.__name__
        return solver(feti.F, feti.d, x, lb=lb, ub=ub, rtol=opts.rtol, max_it=opts.max_it,
                      norm_A=norm_A, monitor=progress.inner, preconditioner=precond, **inner)
    if opts.qp == "penalty":
        # FETI-NCG_ρ: the equality G̃x = 0 replaced by the penalty ρQ; ||Gλ|| = O(1/ρ).
        report.solver = f"{solver.__name__} (dual penalty)"
        rho = opts.of(PENALTY)["rho"] * norm_A
        Arho = projected_operator(feti.F, ocon, rho=rho)
        if precond is not None:
            precond = ProjectedPreconditioner(precond, ocon, rho)
        res = solver(Arho, Pb, x, lb=lb, ub=ub, rtol=opts.rtol, max_it=opts.max_it,
                     norm_A=max(norm_A, rho), monitor=progress.inner, preconditioner=precond,
                     **inner)
        res.Dx_norm = float(np.linalg.norm(ocon.mult(x)))
        return res
    report.solver = "smalbe" if solver is mprgp else "smalbe (mpgp)"
    o = opts.of(SMALBE)  # rho and M relative to ||PFP||, eta to ||b||
    # ||G̃x|| is in units of λ, ||b|| in units of F λ: compare ||PFP|| ||G̃x||.
    return smalbe(A, Pb, ocon, x, lb=lb, ub=ub, inner=solver.__name__, multiplier=multiplier,
                  rtol=opts.rtol, eq_rtol=opts.eq_rtol or opts.rtol,
                  eq_scale=norm_A, rho=o["rho"] * norm_A, M=o["M"] * norm_A,
                  eta=None if o["eta"] is None else o["eta"] * Pb.norm(),
                  beta=o["beta"], norm_A=norm_A,
                  inner_options={**inner, "monitor": progress.inner}, preconditioner=precond,
                  max_outer=opts.max_outer, max_it=opts.max_it, monitor=progress.outer,
                  acceleration=o["acceleration"], depth=o["depth"])


def _warn_loose_stop(report: Report, rtol: float) -> None:
    """Warn when the stopping test held but the KKT residuals are far above rtol.

    The test ||g^P|| <= rtol ||b|| is relative to ||b||, which can be much larger than what
    the solution's accuracy is measured against: e.g. the gaps of contact rows far out of
    reach (an obstacle 1e6 away from a body that moves by 1e-2) enter ||b|| in full.
    """
    keys = ("dual_feasibility", "primal_feasibility", "equality", "complementarity",
            "equilibrium")
    worst = max((report.kkt.get(k, 0.0) for k in keys), default=0.0)
    if report.converged and worst > KKT_WARN * max(rtol, 1e-13):
        report.warnings.append(
            f"the stopping test held (||g^P|| <= rtol ||b||, rtol {rtol:.0e}), but the largest "
            f"KKT residual is {worst:.1e}: ||b|| is dominated by data larger than the solution "
            "(e.g. the gaps of contact rows far out of reach); lower rtol for a more accurate "
            "solution")


__all__ = ["QPSolve", "choose_method", "solve", "solve_qp"]
