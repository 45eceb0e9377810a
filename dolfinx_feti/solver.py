"""The solver object: set up once, solve many times.

As DOLFINx's ``LinearProblem`` keeps its KSP, :class:`FetiSolver` keeps everything a FETI
solve builds — the decomposition and every rank's share, the assembled and factored
subdomains, the chain of transforms (eliminate Dirichlet, eliminate corners, dualize,
homogenize, project) with the coarse factor, the preconditioner and ‖P F P‖ — and solves again
after :meth:`FetiSolver.update` has changed what depends on the load only:

    solver = df.FetiSolver(problem, comm=comm, rtol=1e-8)
    sol0 = solver.solve()
    solver.update(problem_with_more_load)   # f, c, d, e, λ̂, b and the bounds; nothing else
    sol1 = solver.solve()                   # warm-started from sol0's multipliers

:meth:`FetiSolver.update_rows` takes new constraint rows (a new contact search; a curved
obstacle that moved), :meth:`FetiSolver.update_stiffness` new stiffness matrices (a new
material, a tangent stiffness): each rebuilds what depends on them and keeps the rest.
:func:`dolfinx_feti.solve` is one set-up and one solve of this object.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import compat
from .constraints.friction_values import friction_key, with_friction_of
from .constraints.load_rows import LoadRows
from .drivers.friction import FrictionSolve
from .drivers.obstacle_motion import carried_slip
from .drivers.qp_solve import solve_qp, warn_loose_stop
from .errors import InputError, NotConverged, collective
from .fem.assembly import assemble_loads, assemble_subdomains
from .feti.preconditioner import make_preconditioner
from .log import Progress
from .options import SolverOptions, check_same_on_ranks
from .problem.changes import check_same_labels, check_same_structure
from .problem.contact_problem import ContactProblem
from .qp import ConvergedReason
from .qp.recycle import Recycle
from .results.mortar_report import mortar_warnings
from .results.report import Report
from .results.solution import Solution
from .setup.stages import DualQP, SharedProblem, qp_of_share, share_problem
from .timing import Timer

#: Starts :meth:`FetiSolver.solve` accepts besides a Solution or a Vec.
COLD = "cold"

#: How :func:`solve` solves a problem whose forms say ``solve_by = key`` (a nonlinear
#: material: ``"newton"``, registered by :mod:`dolfinx_feti.drivers.newton`); forms without
#: the attribute are solved by one FETI solve.
SOLVE_BY: dict[str, Callable] = {}


#: A load update makes room for ``mprgp_reuse`` more recycled CG directions, up to those of
#: this many load cases (qp.recycle, ``Recycle.grow``): a step's error lies in the span of the
#: earlier steps' Krylov spaces, not of the last one's. The 3D pushed block's path
#: (bench/load_path.py --case pushed3d --steps 6, FETI-DP), warm / cold median and max: room for
#: one case (80) 43 %, 48 %; two (160) 31 %, 39 %; four (320) 25 %, 39 % (history § 29). A first
#: solve, a cold one (x0="cold") and a row update keep the room of one.
CARRIED_CASES = 4


class FetiSolver:
    """A FETI contact solver set up once for a problem, solved as often as needed.

    Args:
        problem: The problem.
        comm: The ranks to spread the subdomains over.
        options: Solver options (:class:`~dolfinx_feti.SolverOptions`), or command-line tokens
            to read ``-feti_<name> value`` options from; keyword arguments override both.
        keep_meshes: Keep the DOLFINx meshes and spaces of the subdomains, so that
            :meth:`update` assembles only the new loads (False: less memory during the
            factorization; each update meshes the subdomains again).
        **kwargs: Fields of :class:`~dolfinx_feti.SolverOptions` (``rtol=1e-8``, ...).

    Attributes:
        problem: The problem of the next solve (the last one given to :meth:`update`).
        options: The solver options.
        qp: The dual QP and its chain of transforms (:class:`~dolfinx_feti.setup.stages.DualQP`).
        preconditioner: The dual preconditioner (None for ``preconditioner="none"``).
        recycle: The CG directions of the last solves on the current operator
            (:class:`~dolfinx_feti.qp.recycle.Recycle`, ``mprgp_reuse`` of them; None when 0),
            forgotten when the rows or the stiffness change and by ``solve(x0="cold")``.
        solves: Number of solves so far.
    """

    def __init__(self, problem: ContactProblem, *, comm: MPI.Comm = MPI.COMM_WORLD,
                 options: SolverOptions | Sequence[str] | None = None,
                 keep_meshes: bool = True, **kwargs) -> None:
        if getattr(problem, "mixed", None) is not None:
            raise InputError("a problem on bodies of several cell types is solved by "
                             "df.solve(problem) (one solve; FetiSolver's updates are not "
                             "implemented for it)")
        with collective(comm, "options"):  # a bad value on one rank stops every rank
            if options is None or not isinstance(options, SolverOptions):
                opts = SolverOptions.create(argv=options, **kwargs)
            else:
                opts = options.replace(**kwargs)
        check_same_on_ranks(opts, comm)  # options that differ per rank would hang the job
        self.options, self.comm, self.problem = opts, comm, problem
        self._progress = Progress(comm, opts.verbose)
        self._timer = Timer(self._progress.phase)
        self._shared: SharedProblem = share_problem(problem, comm, opts.method, self._timer)
        self._data = None if self._shared.method == "tbeti" else \
            assemble_subdomains(problem, self._shared.share, comm, self._timer, keep=keep_meshes)
        self._loads = LoadRows(self._shared.share, problem.value_size)
        self.qp: DualQP = qp_of_share(problem, self._shared, self._data, factor=opts.factor,
                                      norm_rtol=opts.norm_rtol, timer=self._timer,
                                      dual_operator=opts.dual_operator)
        self.preconditioner = None
        self._new_preconditioner()
        self._lam: PETSc.Vec | None = None
        # the predictor's data: d of the last solve's case; λ and d of the case before
        self._d_last: PETSc.Vec | None = None
        self._before: tuple[PETSc.Vec, PETSc.Vec, np.ndarray | None] | None = None
        self._new_case = False  # an update since the last solve
        self._M: float | None = None  # SMALBE's last inner precision factor, relative to ‖A‖
        self._mu: np.ndarray | None = None
        self._tangential: np.ndarray | None = None  # the friction rows' c (None: 0)
        self._normal_force: np.ndarray | None = None  # of the last friction solve
        self._normal_before: np.ndarray | None = None  # of the friction solve of the case before
        self._scales: tuple[float, float] | None = None  # the KKT test's (U, Λ) of the last solve
        # a lower bound of the KKT test's displacement scale: a Newton increment is solved
        # against the total displacement (drivers/kkt_stop.KKTStop)
        self.u_floor = 0.0
        # the last KKT check's ratio of all rows' largest force to the QP rows': the force
        # part of a warm solve's bound (drivers/kkt_stop.KKTStop's force_ratio)
        self._force_ratio = 1.0
        self.solves = 0
        # the CG directions of the last solves on this operator (qp.recycle; None: off)
        self.recycle = Recycle(opts.mprgp_reuse, deflate=opts.mprgp_deflate) \
            if opts.mprgp_reuse else None

    # --- what changes between solves ---------------------------------------------------------
    def update(self, problem: ContactProblem, *, check_stiffness: bool = False,
               slip_from: Solution | None = None) -> None:
        """Take a new load case: tractions, body forces, Dirichlet values, obstacle positions.

        See :meth:`_update` (arguments, what is recomputed); afterwards the PETSc objects let go
        of are destroyed, as after :meth:`solve`.
        """
        try:
            self._update(problem, check_stiffness, slip_from)
        finally:
            compat.garbage_cleanup(self.comm)

    def _update(self, problem: ContactProblem, check_stiffness: bool,
                slip_from: Solution | None) -> None:
        """Take a new load case: tractions, body forces, Dirichlet values, obstacle positions.

        Recomputes the load f, the right-hand sides c of the Dirichlet and obstacle rows, and
        through the chain d, e, λ̂, b and the bounds. The factorizations, G, the coarse factor,
        the preconditioner and ‖P F P‖ are kept. An obstacle whose normals change (a curved
        obstacle that moved) changes B: then the rows are updated as by :meth:`update_rows`.

        Args:
            problem: A problem on the same mesh, groups, decomposition and conditions, whose
                bilinear form is the same (checked for :class:`~dolfinx_feti.Elasticity` and
                :class:`~dolfinx_feti.Poisson`; for other forms with ``check_stiffness``, by
                assembling K again, or use :meth:`update_stiffness`).
            check_stiffness: Reassemble K and refuse the update if it changed.
            slip_from: With friction, the previous step of a load path (a Solution of this
                set-up): the friction rows act on the slip increment since it (their right-hand
                sides c_t = B_t u of that solution: a node that sticks keeps its tangential
                displacement). None: a load case from the unloaded state (c_t = 0).

        Friction coefficients and Tresca bounds (numbers) may change too.

        Raises:
            InputError: Naming what differs, for a problem whose changes cannot reuse the
                set-up (another mesh, decomposition, condition, group or material), or a new
                load that cannot be balanced.
        """
        self._refuse_boundary_elements("update")
        check_same_structure(self.problem, problem, stiffness=not check_stiffness)
        if problem.decomposition is not self.problem.decomposition:
            check_same_labels(problem.decomposition, self._shared.share, self.comm)
        if check_stiffness:
            self._check_stiffness(problem)
        self._tangential = self._slip_of(slip_from)
        if self._tangential is not None:  # the obstacles' RigidMotion carried the surfaces
            self._tangential += carried_slip(self._shared.share, self._loads.tangential,
                                             slip_from.problem, problem)
        self._new_case = True
        if self.recycle is not None:  # a row update below forgets them (and this room) again
            self.recycle.grow(min(self.recycle.k + self.recycle.base_k,
                                  CARRIED_CASES * self.recycle.base_k))
        self._new_friction_values(problem)
        f = assemble_loads(problem.forms, self._data, self._shared.share, self._timer)
        with self._timer.phase("constraints"):
            rows, moved = self._loads.rows(problem, self.comm, self._tangential)
        if moved:  # B changes with the obstacle's normals
            self.problem = problem
            self._data = replace(self._data, f=f)
            self.update_rows(rows)
            return
        with self._timer.phase("dual operators"):
            system = self.qp.system.with_rhs(f, rows.own.rhs)
            qp = self.qp.for_load(system)
        self._adopt(qp, rows)
        self._data = replace(self._data, f=f)
        self.problem = problem

    def update_rows(self, rows) -> None:
        """Take new constraint rows on the same decomposition (e.g. after a new contact search).

        Args:
            rows: This rank's rows (:class:`~dolfinx_feti.setup.share.RankRows`): the set-up's
                with new coefficients or right-hand sides, or rows of another number (a new
                contact search: the next solve then starts cold).

        B changes, so F, G, the coarse factor, ‖P F P‖ and the preconditioner are rebuilt; the
        subdomain factorizations are kept. The recycled CG directions are forgotten for rows
        of another number; for rows of the same layout (``mprgp_carry``) they are kept as
        stale pairs of the old F, which the next solve checks and uses
        (:meth:`.qp.recycle.Recycle.carry`).
        """
        self._refuse_boundary_elements("update_rows")
        old = self.qp
        self._shared = replace(self._shared, share=replace(self._shared.share, rows=rows))
        self._loads = LoadRows(self._shared.share, self.problem.value_size)
        qp = qp_of_share(self.problem, self._shared, self._data, factor=self.options.factor,
                         norm_rtol=self.options.norm_rtol, timer=self._timer,
                         factors_of=old, dual_operator=self.options.dual_operator)
        same = not self.comm.allreduce(old.b.getSizes() != qp.b.getSizes(), op=MPI.LOR)
        self._adopt(qp, rows)
        self._new_preconditioner()
        if self.recycle is not None and same and self.options.mprgp_carry:
            # rows of the same layout (a moved curved obstacle): F changed a little, the
            # directions are kept as stale pairs; the next solve checks the change (qp.recycle)
            self.recycle.carry()
        else:
            self._forget_directions()  # of another F
        self._mu = None  # the multiplier of another G̃
        self._new_case = True

    def update_stiffness(self, problem: ContactProblem | None = None, *,
                         rows=None, shift=None) -> None:
        """Reassemble and refactor the subdomains (a new material, or a new bilinear form).

        The decomposition, the shares and the rows are kept; K, f, every factorization, the
        dual operators, the coarse problem and the preconditioner are rebuilt. The kernels of
        the subdomain matrices are taken to be the rigid motions, as at set-up.

        Args:
            problem: The problem with the new forms (same mesh, groups and conditions);
                default: the current problem's forms assembled again.
            rows: This rank's rows in the set-up's layout with the right-hand sides (and
                coefficients) to solve with (a Newton step's: those of the increment); default:
                the problem's (:meth:`rows_of`).
            shift: A sparse matrix added to the assembled block-diagonal K of this rank
                (its local layout) before the factorization (e.g. Newton's augmentation on the
                active contact rows), or None.
        """
        self._refuse_boundary_elements("update_stiffness")
        if problem is not None:
            check_same_structure(self.problem, problem, stiffness=False)
        else:
            problem = self.problem
        data = assemble_subdomains(problem, self._shared.share, self.comm, self._timer,
                                   self._data.assemblers,
                                   keep=self._data.assemblers is not None)
        if shift is not None:
            data = replace(data, K=(data.K + shift).tocsr())
        if rows is None:
            rows = self.rows_of(problem)
        shared = replace(self._shared, share=replace(self._shared.share, rows=rows))
        qp = qp_of_share(problem, shared, data, factor=self.options.factor,
                         norm_rtol=self.options.norm_rtol, timer=self._timer,
                         dual_operator=self.options.dual_operator, nearby=self.qp)
        # only now, the set-up built: a failure above (a tangent that cannot be factored)
        # leaves the solver as it was, its rows with their own B (a Newton cut-back goes on
        # from it; the new rows with the old B gave rows_of rows of another layout than B)
        self.problem, self._data, self._shared = problem, data, shared
        self._loads = LoadRows(shared.share, problem.value_size)
        self._adopt(qp, rows)
        self._new_preconditioner()
        self._forget_directions()  # of another F
        self._forget_before()  # of another stiffness: no predictor
        self._M = None

    def use_friction_rows(self, fdata) -> None:
        """The friction rows of a new layout of the rows, for the next :meth:`update_stiffness`.

        A Newton step's mortar rows with friction, re-searched on the deformed surfaces
        (drivers/current_mortar.py), come in another layout: ``fdata``
        (:class:`.constraints.friction.FrictionData`) is that of the rows the next
        ``update_stiffness(rows=...)`` takes.
        """
        self._shared = replace(self._shared, friction=fdata)

    def update_rhs(self, f: np.ndarray, rows) -> None:
        """A new load ``f`` and new right-hand sides of the same rows (collective).

        Nothing is assembled and B is kept (its coefficients must be those of the set-up's
        rows): d, e, λ̂ and b are new, as in :meth:`update` (e.g. the inner iterations of a
        Newton step whose unsymmetric terms go to the right-hand sides).

        Args:
            f: The load on this rank's primal dofs.
            rows: This rank's rows in the current layout with the new right-hand sides.
        """
        self._refuse_boundary_elements("update_rhs")
        with self._timer.phase("dual operators"):
            qp = self.qp.for_load(self.qp.system.with_rhs(f, rows.own.rhs))
        self._adopt(qp, rows)

    def rows_of(self, problem: ContactProblem, tangents_follow: bool = False):
        """This rank's rows with the right-hand sides of ``problem`` (collective).

        Dirichlet values and obstacle gaps in the reference configuration, in the set-up's
        layout; ``tangents_follow``: the caller turns the friction rows of a moved curved
        obstacle itself (:meth:`.LoadRows.rows`).
        """
        with self._timer.phase("constraints"):
            rows, _ = self._loads.rows(problem, self.comm, self._tangential, tangents_follow)
        return rows

    @property
    def data(self):
        """The assembled subdomains of this rank (``fem.assembly.SubdomainData``)."""
        return self._data

    def assemble_rhs(self, problem: ContactProblem) -> np.ndarray:
        """The linear forms of ``problem`` on this rank's subdomains (collective).

        One vector assembly in the primal layout; nothing of the set-up changes.
        """
        self._refuse_boundary_elements("assemble_rhs")
        return assemble_loads(problem.forms, self._data, self._shared.share, self._timer)

    def _refuse_boundary_elements(self, what: str) -> None:
        if self._data is None:
            raise InputError(f"FetiSolver.{what}: not available for method='tbeti' (its "
                             "boundary element subdomains are set up per problem); create a "
                             "new FetiSolver")

    def _slip_of(self, sol: Solution | None) -> np.ndarray | None:
        """B_t u of ``sol`` on this rank's tangential rows (None without ``sol``)."""
        if sol is None or self.qp.friction is None:
            return None
        if not isinstance(sol, Solution) or sol.feti.B.getSize() != self.qp.system.B.getSize():
            raise InputError("slip_from: a Solution of this solver's set-up expected")
        Bu = sol.feti.B.createVecLeft()
        sol.feti.B.mult(sol.u_vec, Bu)
        out = Bu.array_r[self._loads.tangential].copy()
        Bu.destroy()
        return out

    def _new_friction_values(self, problem: ContactProblem) -> None:
        """Take the friction coefficients and Tresca bounds of ``problem`` (if they changed)."""
        old = self.problem
        if self.qp.friction is None or [friction_key(c) for c in old.contact] == \
                [friction_key(c) for c in problem.contact]:
            return
        fdata = with_friction_of(self.qp.friction, old, problem, self._shared.share.rows)
        self.qp.friction = fdata
        self._shared = replace(self._shared, friction=fdata)

    def _adopt(self, qp: DualQP, rows) -> None:
        """Make ``qp`` (with ``rows``) the current QP; keep what the set-up found."""
        old = self.qp
        qp.rows = rows
        qp.share = replace(old.share, rows=rows) if old.share.rows is not rows else old.share
        self._shared = replace(self._shared, share=qp.share)
        self.qp = qp
        # rows of another number (a new contact search): the last multipliers start nothing
        if self._lam is not None and self.comm.allreduce(
                self._lam.getSizes() != qp.b.getSizes(), op=MPI.LOR):
            self._lam.destroy()
            self._lam = None
            self._forget_before()  # the secant predictor's history is of the old rows too
            if self._d_last is not None:
                self._d_last.destroy()
                self._d_last = None

    def _forget_directions(self) -> None:
        # the operator changed: recycled directions of the old one would change the answer
        if self.recycle is not None:
            self.recycle.clear()

    def _new_preconditioner(self) -> None:
        if self.preconditioner is not None and hasattr(self.preconditioner, "destroy"):
            self.preconditioner.destroy()
        opts = self.options
        with self._timer.phase("preconditioner"):
            self.preconditioner = make_preconditioner(
                opts.preconditioner, self.qp.primal, opts.factor, opts.preconditioner_scaling,
                explicit=self.qp.feti.operator == "explicit")

    def _check_stiffness(self, problem: ContactProblem) -> None:
        """Refuse forms whose stiffness differs from the set-up's (one assembly of K)."""
        data = assemble_subdomains(problem, self._shared.share, self.comm, Timer(),
                                   self._data.assemblers)
        diff = abs(data.K - self._data.K).max() if data.K.nnz else 0.0
        scale = abs(self._data.K).max() if self._data.K.nnz else 1.0
        changed = self.comm.allreduce(bool(diff > 1e-12 * scale), op=MPI.LOR)
        if changed:
            raise InputError("update: the new problem's bilinear form gives another stiffness "
                             "matrix; use FetiSolver.update_stiffness(problem)")

    # --- the solve -------------------------------------------------------------------------
    def solve(self, x0: Solution | PETSc.Vec | str | None = None) -> Solution:
        """Solve the current problem (collective).

        See :meth:`_solve`; afterwards the PETSc objects the solve let go of are destroyed
        (:func:`~dolfinx_feti.compat.garbage_cleanup`), so memory stays flat over many solves.
        """
        try:
            return self._solve(x0)
        finally:
            compat.garbage_cleanup(self.comm)

    def _solve(self, x0) -> Solution:
        """Solve the current problem (collective).

        Args:
            x0: Where the QP solver starts: None for the last solve's multipliers (a warm
                start; the default start on the first solve), ``"cold"`` for the default
                start (λ = λ̂ where feasible, and no recycled CG directions of earlier solves:
                :mod:`~dolfinx_feti.qp.recycle`), a :class:`~dolfinx_feti.Solution` of this
                problem's set-up for its multipliers, or a Vec of multipliers of the QP's rows.
                With Coulomb friction a warm start's fixed point starts from the slip bounds
                of the last solve's normal forces (scaled by the same load factor).

        Returns:
            The solution (displacement, multipliers, contact pressure, report). A solve that
            does not converge is returned with ``report.converged == False``, a negative
            ``report.converged_reason`` and its residuals (unless ``error_if_not_converged``).
            Its report's timings are those of this solve and of the set-up or updates since
            the previous one.

        Raises:
            NotConverged: With ``error_if_not_converged``, when the solver did not converge.
        """
        opts, qp, comm, progress = self.options, self.qp, self.comm, self._progress
        timer, self._timer = self._timer, Timer(progress.phase)
        report = Report()
        report.warnings.extend(qp.warnings)
        rows, system = qp.rows, qp.system
        fdata = qp.friction
        friction = None if fdata is None else FrictionSolve(fdata, rows, system.rows_local, comm)
        mults0 = qp.feti.hessian_mults
        start, scale, omega, g0 = self._start(x0)
        if friction is not None and start is not None:
            normal, predicted = self._normal_start(scale, omega) if x0 is None else (None, False)
            friction.start_from(normal, predicted)
        mu, mu_kind = self._mu_start(scale, omega, start) if x0 is None and start is not None \
            else (None, None)
        start_mults = qp.feti.hessian_mults - mults0
        warm_opts = opts.replace(smalbe_M=self._M) if mu is not None and self._M else opts
        # a warm Coulomb solve of a load path takes the last solve's KKT scales before its
        # first Tresca step: before them U is max|b_i| / scale_i (the gaps of rows far out of
        # reach, 42x the displacement on the 2D Coulomb path), so that step's length bound
        # is void, and the rescale after it costs a recovery (history § 37). Not under Newton
        # (u_floor > 0): the last increment's ‖Δu‖ is not the next one's scale
        scales = self._scales if x0 is None and start is not None and fdata is not None and \
            fdata.coulomb and self.u_floor == 0 else None
        out = solve_qp(qp, warm_opts, report=report, progress=progress, timer=timer,
                       friction=friction, preconditioner=self.preconditioner, x0=start,
                       multiplier0=mu, u_floor=self.u_floor, recycle=self.recycle,
                       scales=scales, force_ratio=self._force_ratio if x0 is None and
                       start is not None and self._mprgp_alone() else 1.0, g0=g0)
        report.hessian_mults += start_mults  # the warm start's line search
        report.extra["warm_start_scale"] = scale if start is not None else None
        report.extra["warm_start_secant"] = omega
        report.extra["warm_start_multiplier"] = mu_kind
        for v in (start, g0):
            if v is not None:
                v.destroy()
        new_case = self._new_case
        self._remember(out)
        if fdata is not None and fdata.coulomb:
            self._scales = (out.u.norm(PETSc.NormType.INFINITY), self._lam.norm())
        if friction is not None:
            if new_case:  # another solve of the same case only replaces the last
                self._normal_before = self._normal_force
            self._normal_force = friction.normal_force
        sol = self._solution(out, report, friction)
        warn_loose_stop(report, opts.rtol)
        report.timings = timer.reduced(comm)
        report.timings["total"] = float(sum(report.timings.values()))
        report.extra["options"] = opts.to_dict()
        report.extra["history"] = out.result.history[-50:] if comm.rank == 0 else []
        report.extra["solve"] = self.solves
        self.solves += 1
        if opts.error_if_not_converged and not report.converged:
            raise NotConverged(f"the solver did not converge: {report.reason} (converged reason "
                               f"{report.converged_reason}); see error.solution.report", sol)
        return sol

    def _start(self, x0) -> tuple[PETSc.Vec | None, float, float | None, PETSc.Vec | None]:
        """The QP iterate to start from (None: the default start), its scale and secant step.

        The scale and the step as :meth:`.DualQP.warm_start` returns them, and the start's
        gradient where MPRGP runs alone (no coarse space, no friction: its first product is
        that gradient, which the warm start's product gives; None otherwise).
        """
        if isinstance(x0, str):
            if x0 != COLD:
                raise InputError(f"x0 must be None, {COLD!r}, a Solution or a Vec, got {x0!r}")
            self._forget_directions()  # a cold solve repeats a first solve: nothing recycled
            return None, 1.0, None, None
        lam = self._lam if x0 is None else x0
        if isinstance(lam, Solution):
            if lam.feti.B.getSize() != self.qp.system.B.getSize():
                raise InputError("x0: a Solution of another problem (its rows differ)")
            full = lam.lam
            lam = self.qp.b.duplicate()
            lam.array[:] = full.array_r[self.qp.row_index]
        if lam is None:
            return None, 1.0, None, None
        if lam.getSizes() != self.qp.b.getSizes():
            raise InputError(f"x0: {lam.getSize()} multipliers for a QP of {self.qp.b.getSize()} "
                             "rows")
        x = self.qp.b.duplicate()
        earlier = (*self._before[:2], self._d_last) if x0 is None and self._new_case and \
            self._before is not None else None
        g = x.duplicate() if self._mprgp_alone() else None
        scale, omega, have = self.qp.warm_start(lam, x, earlier, g)
        if lam is not x0 and lam is not self._lam:
            lam.destroy()
        if g is not None and not have:
            g.destroy()
            g = None
        return x, scale, omega, g

    def _mu_start(self, scale: float, omega: float | None, start: PETSc.Vec
                  ) -> tuple[np.ndarray | None, str | None]:
        """SMALBE's multiplier of a warm start and how it was found.

        ``"secant"``: the extrapolation of the last two multipliers, where the start is the
        secant predictor (a load path from its third case); ``"scaled"``: the last one times
        the load factor; after new rows (another G̃: no last μ), without friction,
        ``"estimate"``: the least-squares multiplier the start implies
        (:meth:`.DualQP.multiplier_estimate`, one F-multiplication), else None (SMALBE starts
        from zero). The estimate is not taken where a last μ exists: it is exact at the
        solution but only as good as the start's set of rows at the bound, and on a new load
        of the 2D Hertz case it saved F-multiplications at rtol 1e-6 and 1e-10 and cost some
        at 1e-8 (docs/benchmarks.md § 11).
        """
        before = None if self._before is None else self._before[2]
        if omega is not None and self._mu is not None and before is not None and \
                before.shape == self._mu.shape:
            return self._mu + omega * (self._mu - before), "secant"
        if self._mu is not None:
            return self._mu * scale, "scaled"
        if self.qp.friction is None and self._smalbe_runs():
            return self.qp.multiplier_estimate(start), "estimate"
        return None, None

    def _normal_start(self, scale: float, omega: float | None
                      ) -> tuple[np.ndarray | None, bool]:
        """The normal forces a warm Coulomb solve's slip bounds start from, and if predicted.

        Where the start is the secant predictor (``omega``: a load path from its third case),
        the last two cases' normal forces extrapolated as λ is (predicted); else the last
        one's scaled by the load factor; None (g = ∞) without a last friction solve.
        """
        last, before = self._normal_force, self._normal_before
        if last is None:
            return None, False
        if omega is not None and before is not None and before.shape == last.shape:
            return last + omega * (last - before), True
        return last * scale, False

    def _mprgp_alone(self) -> bool:
        """Whether the QP is solved by MPRGP alone on F: no coarse space, no friction.

        There the iterate stays in ker G̃ (there is none) and the projected gradient is the
        violation B u − c exactly, so the KKT bound measured against the last solve's force
        ratio is the exact residual (bench/first_warm.py: equal to 2 digits on the 3D pushed
        block); under SMALBE the term of ‖G̃x‖ is not in it, and the calibrated bound made
        four of eight warm steps of the 2D Hertz path by FETI-DP fail their first check (one
        F-multiplication more each) where FETI-1's saved one in five.
        """
        return self.qp.constraint.m == 0 and self.qp.friction is None

    def _smalbe_runs(self) -> bool:
        """Whether the QP has a coarse space and inequality rows (SMALBE takes a multiplier)."""
        qp = self.qp
        return qp.constraint.m > 0 and self.comm.allreduce(int(qp.ineq.sum())) > 0

    def _remember(self, out) -> None:
        """Keep λ = λ̂ + x and SMALBE's multiplier of this solve as the next one's start.

        The last solve of the load case before is kept too, with ``d`` of both cases (the
        warm start's predictor, :meth:`.DualQP.warm_start`); another solve of the same case
        only replaces the last.
        """
        if self._lam is not None:
            if self._new_case and self._d_last is not None:
                self._forget_before()
                self._before = (self._lam, self._d_last, self._mu)
            else:
                self._lam.destroy()
                if self._d_last is not None:
                    self._d_last.destroy()
        self._lam = self.qp.multipliers(out.x)
        self._d_last = self.qp.feti.d.copy()
        self._new_case = False
        # SMALBE-M only lowers M; a warm solve continues from where the last one left it.
        # Not after Coulomb's fixed point with the Krylov recycling: each of its Tresca
        # solves starts SMALBE from the same M and lowers it, so the last one's M, carried,
        # ratchets down along a path (‖A‖/4 → ‖A‖/32 over the 2D Coulomb path's 8 steps)
        # and every Tresca solve of the next case runs its inner solves tighter. Started
        # from the options' M, as a cold solve is, SMALBE takes more outer iterations whose
        # inner solves start from the recycled directions (1.4 F-multiplications per outer
        # iteration against 4.5): the path's warm steps 24 % fewer. Without the recycling
        # each of them starts CG afresh (8.9 against 15.9 per outer iteration, but 3x as
        # many): 70 % more, so there M is carried (docs/benchmarks_history.md § 37)
        last = out.result.history[-1] if out.result.history else {}
        restart = self.recycle is not None and self.qp.friction is not None and \
            self.qp.friction.coulomb
        self._M = last["M"] / self.qp.norm_A if "M" in last and self.qp.norm_A > 0 and \
            not restart else None
        mu = out.result.multiplier
        self._mu = None if mu is None else np.array(mu, dtype=float)
        self._force_ratio = out.force_ratio

    def _forget_before(self) -> None:
        self._normal_before = None  # Coulomb's predictor goes with λ's
        if self._before is not None:
            for v in self._before[:2]:
                v.destroy()
            self._before = None

    def _solution(self, out, report: Report, friction) -> Solution:
        """The Solution of a QP solve, with its report filled (collective)."""
        qp, comm, opts = self.qp, self.comm, self.options
        res, feti, rows, system = out.result, qp.feti, qp.rows, qp.system
        n_ineq = int(rows.contact.inequality.sum())
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
        n_tang = 0 if qp.friction is None else int(qp.friction.rows.size)
        report.sizes = {"primal": system.primal_size[1], "dual": rows.size,
                        "inequality": n_ineq, "equality": rows.size - n_ineq - n_tang,
                        "subdomains": qp.dec.num_subdomains, "coarse": int(feti.coarse_size),
                        "coarse_rank": int(qp.constraint.m), "ranks": comm.size}
        report.method = {"tfeti": "TFETI", "feti1": "FETI-1", "fetidp": "FETI-DP",
                         "tbeti": "TBETI"}[qp.method]
        if qp.method != "tfeti":
            report.sizes["dual_method"] = int(feti.dual_size[1])
        report.sizes.update(qp.info)
        report.extra["dual_operator"] = getattr(feti, "operator", "implicit")
        if not report.converged:
            report.warnings.append(f"the QP solver did not converge ({report.reason}) within "
                                   f"{opts.max_it} iterations / {opts.max_outer} outer "
                                   "iterations")
            # a Coulomb fixed point out of steps is not a body pulled off its support
            if n_ineq and report.G_lambda > 1e3 * opts.rtol and \
                    report.reason != "coulomb_max_steps":
                report.warnings.append(
                    f"the contact forces do not balance the load (||G lambda - e|| / ||e|| = "
                    f"{report.G_lambda:.1e}): a body may be pulled away from its only support; "
                    "contact can push but not pull")
        self._progress.info(
            f"{report.solver}: {'converged' if report.converged else 'NOT converged'} "
            f"({report.reason}), {report.outer_iterations} outer / {report.iterations} inner "
            f"iterations, {report.hessian_mults} F-multiplications")
        if friction is not None:
            report.sizes["tangential"] = n_tang
            report.extra["friction"] = friction.info
            friction.destroy()
        sol = Solution(self.problem, system, qp.share, out.u, out.lam, out.alpha, report, comm,
                       friction=friction, surface=qp.surface)
        sol.dual = feti
        sol.check_kkt(rows.own.inequality)
        if qp.mortar:
            self._mortar_report(sol, report)
        return sol

    def _mortar_report(self, sol: Solution, report: Report) -> None:
        """The mortar checks (rank 0 holds the surfaces), on every rank's report."""
        comm, qp = self.comm, self.qp
        c, found = sol.contact, None
        surface = sol.surface  # the cells at the surfaces the rows came from (rank 0)
        nodal = sol.surface_values()  # collective; rank 0 has the values at their points
        if comm.rank == 0:
            found = mortar_warnings(surface.problem.mesh, qp.mortar, nodal, c.spec,
                                    surface.local(c.node), c.force)
        warn, report.extra["mortar"] = comm.bcast(found, root=0)
        report.warnings.extend(warn)

    def destroy(self) -> None:
        """Free the PETSc objects the solver holds (collective); it cannot solve again.

        The chain, the factorizations and the preconditioner go; its Solutions stay valid,
        without their ``dual`` operators.
        """
        if self.preconditioner is not None and hasattr(self.preconditioner, "destroy"):
            self.preconditioner.destroy()
            self.preconditioner = None
        self._forget_before()
        for v in (self._lam, self._d_last):
            if v is not None:
                v.destroy()
        self._lam = self._d_last = None
        if self.qp is not None:
            self.qp.destroy()
            self.qp = None
        compat.garbage_cleanup(self.comm)


def solve(problem: ContactProblem, *, comm: MPI.Comm = MPI.COMM_WORLD,
          options: SolverOptions | Sequence[str] | None = None, **kwargs) -> Solution:
    """Solve a contact problem by FETI (option ``method``; by default FETI-1 or FETI-DP).

    The default ``method="auto"`` takes the method of least measured time
    (:func:`~dolfinx_feti.setup.method_rule.method_by_time`). One set-up and one solve of a
    :class:`FetiSolver`; to solve again on the same set-up (load cases, load steps) keep the
    solver instead.

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
    if getattr(problem, "mixed", None) is not None:  # bodies of several cell types
        from .drivers.mixed_solve import solve_mixed

        return solve_mixed(problem, comm=comm, options=options, **kwargs)
    by = getattr(problem.forms, "solve_by", None)
    if by is not None:
        if by not in SOLVE_BY:
            raise InputError(f"the forms ask to be solved by {by!r}, which is not registered "
                             f"(known: {sorted(SOLVE_BY)})")
        return SOLVE_BY[by](problem, comm=comm, options=options, **kwargs)
    solver = FetiSolver(problem, comm=comm, options=options, keep_meshes=False, **kwargs)
    try:
        sol = solver.solve()
    except NotConverged as e:
        e.solution.dual = None
        raise
    finally:
        solver.destroy()
    sol.dual = None  # the operators went with the solver: keep a FetiSolver for them
    return sol


__all__ = ["COLD", "SOLVE_BY", "FetiSolver", "solve"]
