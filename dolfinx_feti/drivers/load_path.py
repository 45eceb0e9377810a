"""Load paths and load cases on one set-up of a :class:`~dolfinx_feti.FetiSolver`.

A load path solves ``problem_at(t)`` for each pseudo-time ``t`` in order, carrying the state
from step to step: the multipliers (a warm start), Coulomb's slip bounds, and with friction
the tangential displacement of every contact node (the friction rows act on the slip increment
of the step, so a node that sticks keeps its tangential displacement and loading then unloading
leaves tangential tractions locked in). Small deformation, no inertia: every step is a static
problem on the reference geometry; what changes with t is what :meth:`FetiSolver.update` takes
(tractions, body forces, Dirichlet values, rigid obstacles' positions, friction values).

Load cases are independent problems on one set-up, each from the unloaded state (no slip
history); the set-up is paid once and its cost shared over the cases.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..errors import InputError, collective
from ..log import Progress
from ..options import SolverOptions
from ..problem.contact_problem import ContactProblem
from ..results.solution import Solution
from ..solver import COLD, FetiSolver
from .path_output import History, PathOutput, setup_seconds

#: How :func:`solve_path` steps a problem whose forms say ``solve_by = key`` (a nonlinear
#: material: ``"newton"``, registered by :mod:`dolfinx_feti.drivers.newton`).
PATH_BY: dict[str, Callable] = {}


def check_times(times: Sequence[float]) -> np.ndarray:
    """The pseudo-times as an array, refused unless finite and strictly increasing."""
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise InputError("solve_path: times must be a non-empty sequence of numbers")
    if not np.all(np.isfinite(t)):
        raise InputError("solve_path: times must be finite")
    if np.any(np.diff(t) <= 0):
        raise InputError("solve_path: times must increase strictly (a path is solved in order)")
    return t


def problem_at_time(problem_at: Callable[[float], ContactProblem], t: float) -> ContactProblem:
    """``problem_at(t)``, refused unless a ContactProblem."""
    p = problem_at(float(t))
    if not isinstance(p, ContactProblem):
        raise InputError(f"solve_path: problem_at({t:g}) returned {type(p).__name__}, not a "
                         "ContactProblem")
    return p


def solve_path(problem_at: Callable[[float], ContactProblem], times: Sequence[float], *,
               comm: MPI.Comm = MPI.COMM_WORLD,
               options: SolverOptions | Sequence[str] | None = None,
               xdmf: str | Path | None = None, history: str | Path | None = None,
               progress: bool = True, **kwargs) -> list[Solution]:
    """Solve a quasistatic load path on one set-up (collective).

    The first step starts from the unloaded, stress-free state; each later step reuses the
    set-up (factorizations, G, the coarse factor, the preconditioner, ‖F‖), starts from the
    last step's multipliers, and with friction acts on the slip increment of the step.

    Args:
        problem_at: ``problem_at(t)`` → the problem at pseudo-time ``t``: the same mesh, groups,
            decomposition and conditions at every t (see :meth:`FetiSolver.update` for what
            may change).
        times: The pseudo-times, strictly increasing.
        comm: The ranks to spread the subdomains over.
        options: Solver options, or command-line tokens (as for :func:`dolfinx_feti.solve`).
        xdmf: Write the displacement and the contact fields (pressure; with friction the
            tangential traction and the stick/slip state) of every step to this XDMF file, with
            the step's time (None: no file).
        history: Write the per-step history (iterations, F-multiplications, times, contact
            forces, stick/slip counts; of a hyperelastic path also the Newton history, sub-steps
            and cut-backs) to this JSON file (None: no file).
        progress: One line per step on rank 0 (through the ``dolfinx_feti`` logger).
        **kwargs: Fields of :class:`~dolfinx_feti.SolverOptions`.

    Returns:
        One :class:`~dolfinx_feti.Solution` per time; ``report.extra["step"]`` and
        ``report.extra["time"]`` say which. A step that does not converge is kept (its report
        says so; the next steps start from it) unless ``error_if_not_converged``.

    Raises:
        InputError: For bad times, or a ``problem_at(t)`` whose set-up differs (named).
        NotConverged: With ``error_if_not_converged``, at the first step that does not.
    """
    t = check_times(times)
    first = None
    with collective(comm):  # user code: a failure on one rank stops every rank
        first = problem_at_time(problem_at, t[0])
    by = getattr(first.forms, "solve_by", None)
    if by is not None:
        if by not in PATH_BY:
            raise InputError(f"solve_path: the forms ask to be solved by {by!r}, which is not "
                             f"registered (known: {sorted(PATH_BY)})")
        return PATH_BY[by](problem_at, t, first, comm=comm, options=options,
                           progress=progress, xdmf=xdmf, history=history, **kwargs)
    line = Progress(comm, 1 if progress else 0)
    out = PathOutput(xdmf, history, comm)
    solver, sols = None, []
    try:
        for k, tk in enumerate(t):
            problem = first if k == 0 else None
            if k:
                with collective(comm):  # user code: a failure on one rank stops every rank
                    problem = problem_at_time(problem_at, tk)
            if solver is None:
                out.check(problem)
                solver = FetiSolver(problem, comm=comm, options=options, **kwargs)
            else:
                solver.update(problem, slip_from=sols[-1])
            sol = solver.solve()
            sol.report.extra.update({"step": k, "time": float(tk)})
            sols.append(sol)
            record = History.record(sol)
            line.info(_step_line(k, t.size, tk, record))
            out.write(sol, float(tk), record)
        out.close()
    finally:
        out.abort()
        if solver is not None:
            solver.destroy()
    return sols


def _step_line(k: int, n: int, t: float, r: dict) -> str:
    force = ", ".join(f"{v:.4g}" for v in r["contact_force"])
    return (f"step {k + 1}/{n} t = {t:g}: {'converged' if r['converged'] else 'NOT converged'}, "
            f"{r['hessian_mults']} F-multiplications, set-up {r['setup_time']:.3f} s, "
            f"solve {r['solve_time']:.3f} s, contact force ({force})")


def solve_cases(problems: Sequence[ContactProblem], *, comm: MPI.Comm = MPI.COMM_WORLD,
                options: SolverOptions | Sequence[str] | None = None, warm: bool = True,
                progress: bool = True, **kwargs) -> list[Solution]:
    """Solve independent load cases on one set-up, each from the unloaded state (collective).

    Args:
        problems: The load cases: the same mesh, groups, decomposition and conditions.
        comm: The ranks to spread the subdomains over.
        options: Solver options, or command-line tokens (as for :func:`dolfinx_feti.solve`).
        warm: Start each case's iterations from the last case's multipliers (the answer does
            not depend on the start); False: from the default start, as a single solve.
        progress: One line per case on rank 0.
        **kwargs: Fields of :class:`~dolfinx_feti.SolverOptions`.

    Returns:
        One Solution per case. Each report's ``extra["case"]`` holds the case's index, the
        number of cases, its own seconds, and the amortized seconds per case (the set-up and
        every case's solve over the number of cases).
    """
    if len(problems) == 0:
        raise InputError("solve_cases: no load cases given")
    line = Progress(comm, 1 if progress else 0)
    solver, sols = None, []
    wall = time.perf_counter()
    try:
        for k, problem in enumerate(problems):
            if solver is None:
                solver = FetiSolver(problem, comm=comm, options=options, **kwargs)
            else:
                solver.update(problem)  # no slip history: from the unloaded state
            sol = solver.solve(None if warm else COLD)
            sols.append(sol)
            line.info(f"case {k + 1}/{len(problems)}: "
                      f"{'converged' if sol.report.converged else 'NOT converged'}, "
                      f"{sol.report.hessian_mults} F-multiplications, "
                      f"{sol.report.timings.get('total', math.nan):.3f} s")
    finally:
        if solver is not None:
            solver.destroy()
    wall = comm.allreduce(time.perf_counter() - wall, op=MPI.MAX)
    n = len(sols)
    setup = setup_seconds(sols[0])
    for k, sol in enumerate(sols):
        sol.report.extra["case"] = {
            "index": k, "cases": n, "seconds": sol.report.timings.get("total", math.nan),
            "setup_seconds": setup_seconds(sol), "first_setup_seconds": setup,
            "amortized_seconds": wall / n,
            "amortized_hessian_mults": sum(s.report.hessian_mults for s in sols) / n}
    return sols


__all__ = ["PATH_BY", "check_times", "problem_at_time", "solve_cases", "solve_path"]
