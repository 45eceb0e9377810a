"""Large-deformation contact by Newton: each step an exact-constraint FETI contact QP.

At the iterate u_k (total displacement from the reference configuration) the increment Δu
solves the contact QP of the linearization

    min ½ Δuᵀ K_t(u_k) Δu − Δuᵀ r(u_k)   s.t.   B_E Δu = c_E − B_E u_k,
                                                 B_I Δu <= g(u_k)

with r = f_ext − f_int the residual of the hyperelastic forms (:mod:`.fem.hyperelastic`) and
g(u_k) the gaps of the current configuration. Its multipliers are the total constraint forces
λ_{k+1} (at Δu = 0 the QP's KKT conditions are those of the nonlinear problem). One
:class:`~dolfinx_feti.FetiSolver` serves every step: ``update_stiffness`` with the tangent,
the residual and the rows' new right-hand sides refactors the subdomains and keeps the
decomposition, the shares and the rows' layout; each QP starts from the last multipliers.

The choices:

- **Method.** The tangent of a stressed floating subdomain has the translations in its
  kernel but not the rotations (its internal forces, balanced by interface forces, turn with
  it), and may be indefinite. So Newton runs FETI-DP by default (``method="fetidp"``, corners
  assembled, Dirichlet conditions eliminated): K̃_t is the tangent of whole bodies held by
  their Dirichlet conditions, definite wherever the equilibrium is stable. A body with no
  Dirichlet condition (held by contact only) leaves K̃_t singular with a kernel that is not
  the rigid motions: it is refused by name, as is a subdomain FETI-DP's corners leave free
  to turn. An augmentation κ Σ b_r b_rᵀ on the active obstacle rows keeps the QP convex where
  a compressed free surface makes the bare tangent indefinite (docs/large_deformation.md).
  TFETI (``method="tfeti"``) may be asked for: the
  set-up's check K K⁺ K = K on the reference kernels then refuses a prestressed floating
  subdomain whose rotations left the kernel.
- **Gaps.** Every obstacle row takes the gap and the normal of its node's current position
  (for a plane exactly c − B u_k), with the obstacle's curvature term in the tangent near the
  solution; node-to-node pairs the normal of the deformed master surface and the gap of the
  current positions; mortar contact the search and the integrals redone on every iterate's
  surfaces (:mod:`.current_mortar`, the rows' layout may change); ties keep their rows of the
  reference surfaces (they glue material points); friction on rigid obstacles and on
  node-to-node pairs acts on the slip increment of the load step in the current tangents
  (:mod:`.newton_friction`); friction on mortar pairs on the slip of each slave node
  relative to the master material it is paired with, since the last converged step
  (:mod:`.mortar_friction`).
- **Line search** by backtracking on the merit φ(u) = (‖r(u) − Bᵀλ_{k+1}‖² + κ²‖v(u)‖²)^½, v
  the violation of the equality rows and the penetration of the inequality rows (physical
  lengths), κ the stiffness scale max_i Σ_j |K_ij|; a trial with a non-finite residual (a
  cell turned inside out: J <= 0) is halved.
- **Stop** when the KKT residuals of the nonlinear problem in physical units
  (:func:`.kkt_stop.kkt_residuals`, equilibrium r(u) − Bᵀλ against max(‖r at the start of
  the step‖, ‖Bᵀλ‖)) and the last increment (‖Δu‖∞ against ‖u‖∞) are all below
  ``newton_rtol`` (the increment against its square root: converging quadratically, the next
  one would be of the order of its square). The Newton history (residuals, steps, QP
  iterations, F-multiplications, seconds) is the report's ``extra["newton"]``.
- **Increments** are solved to an accuracy tied to Newton's residual (a forcing term,
  :meth:`NewtonSolver._forcing`: the QP's rtol and Coulomb's fixed point tightened near the
  solution, never loosened), so the stop can be met with the QPs' Krylov recycling on.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError, NotConverged, SolveError
from ..fem.hyperelastic import NewtonState
from ..options import SolverOptions
from ..problem.contact_problem import ContactProblem, Mortar, NodeToNode, RigidObstacle
from ..results.solution import Solution
from ..solver import COLD, SOLVE_BY, FetiSolver
from .current_mortar import DeformedMortar, check_mortar
from .current_rows import CurrentRows, rows_with_rhs
from .kkt_stop import kkt_residuals
from .mortar_step import exact_step, gap_change
from .newton_friction import IncrementalSlip
from .qp_solve import UNMET_KKT


def _met(kkt: dict[str, float], rtol: float) -> bool:
    """Whether Newton's KKT residuals are within ``rtol``.

    Coulomb's |g − 𝓕λ_N| is left out: the fixed point bounds it by its own tolerance.
    """
    return max((v for key, v in kkt.items() if key != "coulomb_bound"), default=0.0) <= rtol


#: An increment's QP measures its lengths against at least this fraction of ‖u‖∞ (the total
#: displacement): against ‖Δu‖∞ alone the KKT test's bound falls below the round-off of the
#: QP near the solution and it runs to its budget (3D friction: 10 000 F-multiplications per
#: Newton iteration, drivers/kkt_stop.KKTStop).
U_FLOOR = 1e-2

INF = PETSc.NormType.INFINITY

#: The forcing term's floor, a fraction of ``newton_rtol``: no increment is asked for more
#: (NewtonSolver._forcing).
QP_FLOOR = 0.1
#: Near the solution an increment QP is asked for this fraction of the iterate's largest
#: KKT residual (an inexact Newton forcing term, Eisenstat & Walker 1996), if below the
#: user's accuracies. 0.1 only halved Newton's residual per iteration on
#: problems/ironing_path.toml near the solution (one more iteration than without recycling);
#: 0.01 takes it below ``newton_rtol`` at once.
FORCING = 0.01

#: The obstacles' curvature term enters the tangent once the relative residual is below this.
CURVATURE_FROM = 1e-3


class StepFailed(SolveError):
    """A Newton step that cannot go on (a tangent that cannot be factored): cut back."""


@dataclass(frozen=True)
class NewtonOptions:
    """Options of the Newton loop (keyword arguments ``newton_rtol``, ``newton_max_it``, ...).

    Attributes:
        rtol: Bound on every KKT residual of the nonlinear problem (its square root on
            ‖Δu‖∞/‖u‖∞); near the solution the increments are asked for down to 0.1 of it
            (:meth:`NewtonSolver._forcing`).
        max_it: Newton iterations per load step.
        max_backtracks: Halvings of the step in the line search.
        mortar_derivatives: Mortar rows: the Newton step with their derivatives (inner QPs
            mixed by Anderson, :mod:`.mortar_step`: quadratic on curved surfaces, where the
            frozen rows converge linearly; asked for, as the flat blocks compressed 40 % fail
            with it: an indefinite tangent at their first iterate, docs/large_deformation.md);
            False: D, M and the normals frozen at the iterate.
    """

    rtol: float = 1e-9
    max_it: int = 25
    max_backtracks: int = 12
    mortar_derivatives: bool = False

    @classmethod
    def pop(cls, kwargs: dict) -> NewtonOptions:
        """Take ``newton_<field>`` out of ``kwargs``."""
        vals = {k: kwargs.pop(f"newton_{k}") for k in ("rtol", "max_it", "max_backtracks",
                                                        "mortar_derivatives")
                if f"newton_{k}" in kwargs}
        opts = cls(**vals)
        if not (0 < opts.rtol < 1) or opts.max_it < 1 or opts.max_backtracks < 0:
            raise InputError(f"Newton options out of range: {opts}")
        return opts


def _check_obstacle(c: RigidObstacle, problem: ContactProblem) -> None:
    """Rigid obstacles: current gaps and normals, any degree; friction in 2D and 3D."""


def _check_pair(c: NodeToNode, problem: ContactProblem) -> None:
    """Node-to-node pairs: degree 1, a vector problem; friction in 2D and 3D."""
    if c.gap is not None or problem.value_size == 1:
        raise InputError("large-deformation contact: node-to-node contact takes its gap "
                         "from the geometry (no gap override, a vector problem)")
    if problem.degree != 1:
        raise InputError("large-deformation contact: node-to-node contact of degree-1 "
                         "meshes only")


#: The contact conditions the Newton driver takes, each with its check: the rows of the current
#: configuration exist for these (drivers/current_rows.py). A new one is an entry here.
NEWTON_CONDITIONS = {RigidObstacle: _check_obstacle, NodeToNode: _check_pair,
                     Mortar: check_mortar}


def check_newton_problem(problem: ContactProblem) -> None:
    """Refuse by name what the Newton driver does not handle."""
    for c in problem.contact:
        check = NEWTON_CONDITIONS.get(type(c))
        if check is None:
            raise InputError(
                f"large-deformation contact: {type(c).__name__} is not supported by the Newton "
                "driver yet (rigid obstacles, node-to-node and mortar contact only)")
        check(c, problem)
    rubbing = {bool(c.mortar) for c in problem.contact
               if getattr(c, "friction", None) is not None}
    if len(rubbing) > 1:  # re-searched mortar rows move the other rows' local indices
        raise InputError("large-deformation contact: friction on mortar pairs together with "
                         "friction on rigid obstacles or node-to-node pairs is not supported "
                         "by the Newton driver (one kind of friction contact)")
    if not problem.dirichlet:
        raise InputError("large-deformation contact: every body needs a Dirichlet condition "
                         "(a body held by contact only leaves the tangent singular with a "
                         "kernel that is not its rigid motions)")


class _Nonlinear:
    """The system kkt_residuals reads: B, c = c0, and the equilibrium of the forms."""

    def __init__(self, B: PETSc.Mat, c: PETSc.Vec, r: np.ndarray, scale: float,
                 comm: MPI.Comm) -> None:
        self.B, self.c, self.comm, self._r, self._scale = B, c, comm, r, scale

    def residuals(self, u: PETSc.Vec, lam: PETSc.Vec) -> dict[str, float]:
        w = self.B.createVecRight()
        self.B.multTranspose(lam, w)
        res = math.sqrt(self.comm.allreduce(float(np.sum((self._r - w.array_r) ** 2)),
                                            op=MPI.SUM))
        ref = max(self._scale, w.norm(), 1e-300)
        w.destroy()
        return {"equilibrium": res / ref}


class NewtonSolver:
    """Newton over one FETI set-up for a hyperelastic contact problem (collective).

    Args:
        problem: The first problem (its forms a :class:`~dolfinx_feti.Hyperelastic`).
        comm: The ranks.
        options: Solver options of the QPs (as for :func:`dolfinx_feti.solve`).
        newton: The Newton options.
        **kwargs: Fields of :class:`~dolfinx_feti.SolverOptions`; ``method`` defaults to
            ``"fetidp"`` (module docstring).
    """

    def __init__(self, problem: ContactProblem, *, comm: MPI.Comm = MPI.COMM_WORLD,
                 options: SolverOptions | Sequence[str] | None = None,
                 newton: NewtonOptions | None = None, **kwargs) -> None:
        check_newton_problem(problem)
        named = isinstance(options, SolverOptions) or (
            options is not None and any(str(a).startswith("-feti_method") for a in options))
        if not named:
            kwargs.setdefault("method", "fetidp")
        self.comm, self.newton = comm, newton or NewtonOptions()
        self.state = NewtonState()
        self.solver = FetiSolver(self._at_state(problem), comm=comm, options=options,
                                 keep_meshes=True, **kwargs)
        # the user's accuracies, an increment's at most (_tighten): the QPs' options and the
        # Coulomb fixed point's rtol of the friction data it was read from
        self._qp_options = self.solver.options
        self._fp: tuple[object, float] | None = None
        if self.solver.qp.method == "fetidp" and int(self.solver.qp.feti.coarse_size) > 0:
            self.solver.destroy()
            raise InputError("large-deformation contact: a body floats in FETI-DP's K̃ (no "
                             "Dirichlet condition stops some of its rigid motions); the tangent "
                             "of a stressed floating body has no known kernel: hold every "
                             "body by a Dirichlet condition")
        steps = self.solver.qp.steps
        free = [int(self.solver.data.local_subs[i]) for i, R in
                enumerate(getattr(steps[-1], "kernels_rr", []) if steps else []) if R.shape[1]]
        free = sorted(set().union(*comm.allgather(free)))
        if free:
            self.solver.destroy()
            raise InputError(
                f"large-deformation contact: subdomains {free} are held by too few corners in "
                "FETI-DP (they may turn about them): the kernel of a prestressed tangent is not "
                "a rigid motion. Decompose so that every subdomain has at least two corners "
                "(gdim of them in 3D) or a Dirichlet condition of its own (e.g. more parts), "
                "or one subdomain per body (ByTags)")
        B = self.solver.qp.system.B
        self.u = B.createVecRight()
        self.u.zeroEntries()
        self._fresh = True  # the set-up's tangent and rows are those of u = 0
        self._cold = False
        self._lam: PETSc.Vec | None = None  # the last QP's multipliers: the active rows
        data = self.solver.data
        self._kappa = comm.allreduce(
            float(abs(data.K).sum(axis=1).max()) if data.K.shape[0] else 0.0, op=MPI.MAX)
        self.rows = CurrentRows(self.solver, comm, self._kappa)
        # mortar contact: the search and the integrals redone on every iterate's surfaces
        self.mortar = DeformedMortar(self.solver, problem, comm) if any(
            c.mortar for c in problem.contact) else None
        if self.mortar is not None:
            self.mortar.quiet()
            self.mortar.consistent = self.newton.mortar_derivatives
            if self.mortar.friction and self.newton.mortar_derivatives:
                self.solver.destroy()
                raise InputError("large-deformation contact: newton_mortar_derivatives=True "
                                 "is not built with friction on mortar pairs (the tangential "
                                 "rows' derivatives); use the frozen rows (the default)")
        self.slip = None if self.solver.qp.friction is None else \
            IncrementalSlip(self.solver, comm)
        self.rows.friction = self.slip

    def _at_state(self, problem: ContactProblem) -> ContactProblem:
        forms = problem.forms
        if getattr(forms, "with_state", None) is None:
            raise InputError("the Newton driver needs forms with a state (a df.Hyperelastic)")
        return replace(problem, forms=forms.with_state(self.state))

    def destroy(self) -> None:
        """Free the set-up."""
        self.solver.destroy()
        self.u.destroy()

    # --- pieces ------------------------------------------------------------------------------
    def _residual(self, problem: ContactProblem, u: np.ndarray) -> np.ndarray:
        """r(u) = f_ext − f_int(u) on this rank (one vector assembly)."""
        self.state.set(self.solver.data, u)
        return self.solver.assemble_rhs(problem)

    def _factor(self, problem, rows, lam, curved: bool, k: int) -> None:
        """The tangent at the current iterate with the augmentation, refactored."""
        try:
            self.solver.update_stiffness(problem, rows=rows,
                                         shift=self.rows.augmentation(lam, curved))
        except SolveError as e:  # K K⁺ K = K fails: a singular or indefinite tangent
            raise StepFailed(f"Newton iteration {k}: the tangent stiffness cannot be "
                             f"factored ({e}): a singular or indefinite tangent") from e
        if self.mortar is not None:
            self.mortar.quiet()

    def _merit(self, problem, u: PETSc.Vec, BTlam: np.ndarray, rows0, c0: np.ndarray,
               shift: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        try:
            r = self._residual(problem, u.array_r)
        except InputError:  # non-finite: a cell turned inside out (J <= 0) at this trial
            return math.inf, None
        rhs = self.rows.at(problem, rows0, c0, u)[0]
        v = self.rows.violation(rhs if shift is None else rhs + shift, rows0.own)
        s = float(np.sum((r - BTlam) ** 2)) + self._kappa ** 2 * float(np.sum(v ** 2))
        s = self.comm.allreduce(s, op=MPI.SUM)
        return (math.sqrt(s) if np.isfinite(s) else math.inf), r

    # --- one load step ------------------------------------------------------------------------
    def step(self, problem: ContactProblem) -> tuple[Solution, bool]:
        """Newton from the current state to the equilibrium of ``problem`` (collective).

        Returns:
            The solution at the last iterate (total displacement, constraint forces, the
            Newton history in ``report.extra["newton"]``) and whether Newton converged. On
            failure the state is left where the failure happened (see :meth:`reset`).
        """
        comm, opts, solver = self.comm, self.newton, self.solver
        check_newton_problem(problem)
        current = self._at_state(problem)
        if self.slip is not None:
            self.slip.begin(self.u, problem)
        if self.mortar is not None:  # the origin of the mortar pairs' slip (friction)
            self.mortar.begin(self.u)
        rows0 = solver.rows_of(current, tangents_follow=True)
        c0 = rows0.own.rhs.copy()
        r = self._residual(current, self.u.array_r)
        r_scale = math.sqrt(comm.allreduce(float(r @ r), op=MPI.SUM))
        history: list[dict] = []
        converged = False
        lam = None
        for k in range(opts.max_it):
            t0 = time.perf_counter()
            rows, rows0, c0, start, curved, active = self._linearize(
                current, rows0, c0, lam, history, k)
            qp, inner = self._increment(current, rows, start, curved, active, history, k)
            du, lam = qp.u_vec, qp.lam
            self._lam = lam
            if qp.report.reason == "unbounded":  # the dual of an indefinite K̃_t
                history.append(self._record(k, math.nan, 0.0, qp, t0, {}))
                c_now = self.rows.c_at(current, rows0, c0, self.u)
                return self._indefinite(problem, qp, c_now, r, r_scale, history, k), False
            alpha, r, r_k = self._line_search(current, qp, rows, rows0, c0, inner, r_scale)
            if alpha is None:
                history.append(self._record(k, math.nan, 0.5 ** (opts.max_backtracks + 1),
                                            qp, t0, {}))
                c_now = self.rows.c_at(current, rows0, c0, self.u)
                return self._solution(problem, qp, c_now, r_k, r_scale, history, False), False
            self.u.axpy(alpha, du)
            self.state.set(solver.data, self.u.array_r)
            du_rel = alpha * du.norm(INF) / max(self.u.norm(INF), 1e-300)
            c_now = self.rows.c_at(current, rows0, c0, self.u)
            kkt = self._kkt(c_now, r, r_scale, lam, rows0.own, qp.friction)
            history.append(self._record(k, du_rel, alpha, qp, t0, kkt))
            if self.mortar is not None:
                history[-1]["inner_qps"] = inner
            if self._solved(current, qp, kkt, du_rel, c_now, r, r_scale, history):
                converged = True
                break
        sol = self._solution(problem, qp, c_now, r, r_scale, history, converged)
        if converged and self.slip is not None:
            self.slip.converged(problem)
        return sol, converged

    def _linearize(self, current, rows0, c0, lam, history, k) -> tuple:
        """The rows at the iterate (a new mortar layout maybe) and the tangent factored.

        Returns the rows, the reference rows and their right-hand side (new ones after a
        mortar relayout), the start in a new layout, whether the obstacles' curvature term
        is in the tangent, and the multipliers that chose the active rows of that term.
        """
        comm, solver = self.comm, self.solver
        self.state.set(solver.data, self.u.array_r)
        rhs, coef, normal = self.rows.at(current, rows0, c0, self.u, keep=True)
        rows = rows_with_rhs(rows0, rhs, comm, coef, normal)
        start, curved, active = None, False, None  # start: the last multipliers, new layout
        if self.mortar is not None:  # new mortar rows: maybe another layout
            old, last = solver.qp.rows, lam if lam is not None else self._lam
            rows, rows0, c0 = self.mortar.relayout(current, rows, c0, self.u)
            if self.mortar.friction:  # the friction rows of the new layout
                solver.use_friction_rows(self.mortar.friction_rows(rows))
            self.mortar.linearization(current, self.u, old, last)
            if last is not None and not self._cold:
                start = self.mortar.warm_start(old, last, rows)
        same = rows.own.size == solver.qp.rows.own.size and np.array_equal(
            rows.own.rhs, solver.qp.rows.own.rhs)
        if not (self._fresh and k == 0 and comm.allreduce(same, op=MPI.LAND)):
            # (else the set-up is the linearization at u = 0 with these rows)
            active = lam if lam is not None else self._lam
            # the obstacles' curvature term (−λ ∂n/∂y) near the solution only: far from
            # it an overshooting λ would make the tangent indefinite
            curved = bool(history) and history[-1]["residual"] < CURVATURE_FROM
            self._factor(current, rows, active, curved, k)
        self._fresh = False
        return rows, rows0, c0, start, curved, active

    def _increment(self, current, rows, start, curved, active, history, k) -> tuple:
        """The increment's contact QP solved; returns it and the number of inner QPs."""
        solver = self.solver
        x0 = None if self._cold else self._start(start)
        # the increment to the accuracy of the total displacement (KKTStop's u_floor),
        # with two digits to spare for the equilibrium (K of the increment's error)
        solver.u_floor = U_FLOOR * self.u.norm(INF)
        self._tighten(self._forcing(history))
        qp = solver.solve(COLD if self._cold else x0)
        if x0 is not None:
            x0.destroy()
        self._cold = False
        if qp.report.reason == "unbounded" and curved:  # once more without the term
            self._factor(current, rows, active, False, k)
            qp = solver.solve(COLD)
        elif not qp.report.converged and qp.report.reason != "unbounded" and \
                solver.recycle is not None:
            # once more cold, without the recycled CG directions: bench/ironing.py's step 44
            # had one Tresca solve of Coulomb's fixed point (inner rtol 5e-11) run MPRGP
            # with them to its 5 000 iterations; cold it converged in 122 F-multiplications.
            # Its cause (deflated CG blind to the gradient an inexact Galerkin step left in
            # span W) is now caught in the solver (qp/mpgp_steps.py, DEFLATE_DESCENT); kept
            # as a safety net: it costs nothing unless a recycled solve fails
            spent = qp.report.hessian_mults
            qp = solver.solve(COLD)
            qp.report.hessian_mults += spent
            qp.report.extra["cold_retry"] = True
        if self.mortar is not None and self.mortar.derived and \
                qp.report.converged:  # the rows' derivatives: inner QPs (mortar_step.py)
            last_du = history[-1]["du_rel"] if history else 1.0
            return exact_step(solver, self.mortar, qp, rows, self._start,
                              eta=min(0.1, last_du),
                              floor=0.1 * self.newton.rtol * self.u.norm(INF))
        return qp, 0

    def _forcing(self, history: list[dict]) -> float:
        """The accuracy the next increment is asked for (inf: the user's; collective data).

        Newton's residual after a step is the increment's error (its QP's rtol, its Coulomb
        fixed point's tolerance) plus what the tangent leaves out: an increment solved to the
        user's rtol above ``newton_rtol`` can leave every iterate above Newton's stop while
        passing its own tests (problems/ironing_path.toml: rtol 1e-8, Coulomb's 1e-6,
        ``newton_rtol`` 1e-9: with the Krylov recycling the iteration cycled at the
        equilibrium residual 5.4e-9 between two increments that each passed their KKT test
        and ended their fixed point at another point within its tolerance). So the next
        increment is asked for :data:`FORCING` times the iterate's largest KKT residual
        (Eisenstat & Walker 1996), down to :data:`QP_FLOOR` ``newton_rtol``: Newton's stop
        can then be met, and no increment is solved less accurately than the user asked.
        """
        kkt = history[-1]["kkt"] if history else {}
        worst = max((v for key, v in kkt.items() if key != "coulomb_bound"), default=math.nan)
        if not math.isfinite(worst):
            return math.inf
        return max(QP_FLOOR * self.newton.rtol, FORCING * worst)

    def _tighten(self, eta: float) -> None:
        """The increment's QP rtol and Coulomb fixed point's rtol: the user's, or ``eta``."""
        solver = self.solver
        rtol = min(self._qp_options.rtol, eta)
        if rtol != solver.options.rtol:
            solver.options = self._qp_options.replace(rtol=rtol)
        fdata = solver.qp.friction
        if fdata is None or not fdata.coulomb:
            return
        if self._fp is None or self._fp[0] is not fdata:  # new friction data: the user's
            self._fp = (fdata, float(fdata.rtol))
        fdata.rtol = min(self._fp[1], eta)

    def _indefinite(self, problem, qp, c_now, r, r_scale, history, k) -> Solution:
        """The solution at an indefinite tangent, with the reason and what to do."""
        sol = self._solution(problem, qp, c_now, r, r_scale, history, False)
        sol.report.reason = "indefinite tangent"
        sol.report.warnings.append(
            f"Newton iteration {k}: the tangent stiffness K̃_t is indefinite (the QP is "
            "unbounded): an instability of the structure, or of subdomains joined only "
            "at corners under compression; take smaller load steps (solve_path) or "
            "fewer subdomains")
        return sol

    def _line_search(self, current, qp, rows, rows0, c0, inner, r_scale) -> tuple:
        """Backtracking on the merit function along the increment.

        Returns the step length (None if none was accepted), the residual at the accepted
        point and the residual at the iterate.
        """
        comm = self.comm
        w = self.solver.qp.system.B.createVecRight()
        self.solver.qp.system.B.multTranspose(qp.lam, w)
        BTlam = w.array_r.copy()
        w.destroy()
        phi0, r_k = self._merit(current, self.u, BTlam, rows0, c0)
        # below this the merit is round-off (of the forces and of K u)
        floor = 1e3 * np.finfo(float).eps * (math.sqrt(comm.allreduce(
            float(BTlam @ BTlam), op=MPI.SUM)) + self._kappa * self.u.norm() + r_scale)
        # the mortar rows' linearized gap moves with G, not B (mortar_step.py)
        gap = gap_change(self.mortar, rows, qp.u_vec) if inner else None
        alpha, trial = 1.0, self.u.duplicate()
        try:
            for _ in range(self.newton.max_backtracks + 1):
                trial.waxpy(alpha, qp.u_vec, self.u)
                phi, r = self._merit(current, trial, BTlam, rows0, c0,
                                     None if gap is None else alpha * gap)
                if phi <= max((1 - 1e-4 * alpha) * phi0, floor):
                    return alpha, r, r_k
                alpha *= 0.5
            return None, r, r_k
        finally:
            trial.destroy()

    def _solved(self, current, qp, kkt, du_rel, c_now, r, r_scale, history) -> bool:
        """Whether Newton may stop at this iterate (history's last KKT made exact)."""
        rtol = self.newton.rtol
        # quadratic convergence: the next increment would be of the order du_rel²
        if not (_met(kkt, rtol) and du_rel <= math.sqrt(rtol) and
                qp.report.converged and self.rows.dropped <= rtol):
            return False
        # mortar rows: checked again with the search and the integrals of u itself
        exact = kkt if self.mortar is None else self.mortar.kkt_at(
            current, self.u, qp.lam, c_now, r, r_scale, friction=qp.friction)
        if exact is None or not _met(exact, rtol):
            return False
        history[-1]["kkt"] = {key: float(v) for key, v in exact.items()}
        return True

    def _start(self, full: np.ndarray | None) -> PETSc.Vec | None:
        """The QP's start from multipliers of all rows (None: the solver's last ones)."""
        if full is None:
            return None
        x0 = self.solver.qp.b.duplicate()
        x0.array[:] = full[self.solver.qp.row_index]
        return x0

    def _kkt(self, c0, r, r_scale, lam, own, friction=None) -> dict[str, float]:
        system = self.solver.qp.system
        c = system.B.createVecLeft()
        c.array[:] = c0
        kkt, _ = kkt_residuals(_Nonlinear(system.B, c, r, r_scale, self.comm), own.scale,
                               own.kind, own.inequality, self.u, lam, friction=friction)
        c.destroy()
        return kkt

    def _record(self, k, du_rel, alpha, qp, t0, kkt) -> dict:
        return {"iteration": k, "step": float(alpha), "du_rel": float(du_rel),
                "residual": float(kkt.get("equilibrium", math.nan)),
                "kkt": {key: float(v) for key, v in kkt.items()},
                "normal_dropped": float(self.rows.dropped),
                "qp_converged": bool(qp.report.converged), "qp_reason": qp.report.reason,
                "qp_rtol": float(self.solver.options.rtol),
                "coulomb_rtol": None if self._fp is None else float(self._fp[0].rtol),
                "qp_cold_retry": bool(qp.report.extra.get("cold_retry", False)),
                "hessian_mults": int(qp.report.hessian_mults),
                "seconds": self.comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)}

    def _solution(self, problem, qp: Solution, c0, r, r_scale, history, converged
                  ) -> Solution:
        """The Solution of the iterate.

        u the total displacement, λ the constraint forces, the contact data of the current
        configuration.
        """
        solver = self.solver
        system = solver.qp.system.with_rhs(r, c0)
        report = qp.report
        report.converged = bool(converged)
        report.reason = "newton converged" if converged else "newton did not converge"
        report.extra["newton"] = history
        report.extra["newton_iterations"] = len(history)
        report.hessian_mults = int(sum(h["hessian_mults"] for h in history))
        # the last increment's QP: its KKT test is not the solution's (Newton's is, below)
        report.warnings = [w for w in report.warnings if not w.startswith(UNMET_KKT)]
        u, lam = self.u.copy(), qp.lam.copy()
        sol = Solution(problem, system, solver.qp.share, u, lam, qp.alpha, report, self.comm,
                       friction=qp.friction)
        report.kkt, report.max_penetration = kkt_residuals(
            _Nonlinear(system.B, system.c, r, r_scale, self.comm), solver.qp.rows.own.scale,
            solver.qp.rows.own.kind, solver.qp.rows.own.inequality, u, lam,
            friction=qp.friction)
        if self.mortar is not None:
            self.mortar.report(sol)
        return sol

    def save(self) -> np.ndarray:
        """The current displacement (local), for :meth:`reset`."""
        return self.u.array_r.copy()

    def reset(self, u: np.ndarray) -> None:
        """Go back to a saved displacement (a load step's cut-back)."""
        self.u.array[:] = u
        self.state.set(self.solver.data, self.u.array_r)
        self._cold = True  # the failed iterate's multipliers are no start
        self._lam = None


def solve_newton(problem: ContactProblem, *, comm: MPI.Comm = MPI.COMM_WORLD,
                 options: SolverOptions | Sequence[str] | None = None, **kwargs) -> Solution:
    """Solve a hyperelastic contact problem by Newton from the unloaded state (collective).

    What :func:`dolfinx_feti.solve` runs for forms with ``solve_by = "newton"``. Keyword
    arguments ``newton_rtol``, ``newton_max_it``, ``newton_max_backtracks``
    (:class:`NewtonOptions`); the rest are :class:`~dolfinx_feti.SolverOptions` of the QPs.

    Raises:
        NotConverged: With ``error_if_not_converged``, when Newton did not converge.
    """
    newton = NewtonOptions.pop(kwargs)
    raise_if = bool(kwargs.get("error_if_not_converged", False))
    run = NewtonSolver(problem, comm=comm, options=options, newton=newton, **kwargs)
    try:
        sol, ok = run.step(problem)
    finally:
        run.destroy()
    sol.dual = None
    if raise_if and not ok:
        raise NotConverged("Newton did not converge; see error.solution.report.extra['newton']",
                           sol)
    return sol


SOLVE_BY["newton"] = solve_newton

__all__ = ["CURVATURE_FROM", "NewtonOptions", "NewtonSolver", "StepFailed", "rows_with_rhs",
           "solve_newton"]
