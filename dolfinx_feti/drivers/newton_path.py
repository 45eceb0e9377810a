"""Load paths of hyperelastic problems: Newton per step on one set-up, automatic cut-back.

What :func:`dolfinx_feti.solve_path` runs for forms with ``solve_by = "newton"`` (registered
in :data:`.load_path.PATH_BY`); the Newton iteration itself is :mod:`.newton`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..errors import NotConverged, SolveError, collective
from ..log import Progress
from ..options import SolverOptions
from ..problem.contact_problem import ContactProblem
from ..results.solution import Solution
from .load_path import PATH_BY, problem_at_time
from .newton import NewtonOptions, NewtonSolver, StepFailed
from .path_output import History, PathOutput


def solve_path_newton(problem_at: Callable[[float], ContactProblem], times: np.ndarray,
                      first: ContactProblem, *, comm: MPI.Comm = MPI.COMM_WORLD,
                      options: SolverOptions | Sequence[str] | None = None,
                      progress: bool = True, max_cutbacks: int = 8,
                      xdmf: str | Path | None = None, history: str | Path | None = None,
                      **kwargs) -> list[Solution]:
    """A load path of a hyperelastic problem, one Newton solve per step (collective).

    What :func:`dolfinx_feti.solve_path` runs for forms with ``solve_by = "newton"``. Each
    step starts from the last converged state. A step whose Newton iteration fails (no
    convergence within ``newton_max_it``, a line search that finds no decrease, an indefinite
    tangent) is cut back: the state goes back to the last converged one and the interval is
    halved (``problem_at`` at the intermediate times), at most ``max_cutbacks`` times per
    step; the sub-steps then go on at the halved interval to the step's end. The
    unloaded state is taken to be t = 0 (the first step's cut-back starts there if
    ``times[0] > 0``). ``xdmf`` and ``history`` write the files of
    :func:`dolfinx_feti.solve_path` (the total displacement and the contact fields of every
    step; per step the record of :class:`.path_output.History` with the Newton history).

    Returns:
        One Solution per time; ``report.extra`` holds ``step``, ``time``, ``substeps`` (the
        times solved on the way, cut-backs included) and ``cutbacks``. A step that fails
        after every cut-back is returned not converged and ends the path (or raises
        NotConverged with ``error_if_not_converged``).
    """
    newton = NewtonOptions.pop(kwargs)
    raise_if = bool(kwargs.get("error_if_not_converged", False))
    line = Progress(comm, 1 if progress else 0)
    out = PathOutput(xdmf, history, comm)
    out.check(first)
    run = NewtonSolver(first, comm=comm, options=options, newton=newton, **kwargs)
    sols: list[Solution] = []
    t_done = 0.0 if times[0] > 0 else None
    try:
        for k, tk in enumerate(times):
            sol, substeps, cuts = _path_step(run, problem_at, first if k == 0 else None,
                                             t_done, float(tk), max_cutbacks, comm)
            sol.report.extra.update({"step": k, "time": float(tk), "substeps": substeps,
                                     "cutbacks": cuts})
            sol.dual = None
            sols.append(sol)
            line.info(f"step {k + 1}/{times.size} t = {tk:g}: "
                      f"{'converged' if sol.report.converged else 'NOT converged'}, "
                      f"{len(substeps)} sub-step(s), {cuts} cut-back(s), "
                      f"{sol.report.extra['newton_iterations']} Newton iterations")
            out.write(sol, float(tk), newton_record(sol))
            if not sol.report.converged:
                if raise_if:
                    raise NotConverged(f"solve_path: Newton failed at t = {tk:g} after {cuts} "
                                       "cut-backs", sol)
                break
            t_done = float(tk)
        out.close()
    finally:
        out.abort()
        run.destroy()
    return sols


def newton_record(sol: Solution) -> dict:
    """The history record of a Newton step.

    :meth:`.path_output.History.record` with the Newton iterations (residuals, steps, QP
    counts, seconds), the sub-steps and the cut-backs.
    """
    rec = History.record(sol)
    ex = sol.report.extra
    rec.update({"newton_iterations": int(ex["newton_iterations"]),
                "newton_seconds": float(sum(h["seconds"] for h in ex["newton"])),
                "substeps": [float(t) for t in ex.get("substeps", [])],
                "cutbacks": int(ex.get("cutbacks", 0)), "newton": ex["newton"]})
    return rec


def _path_step(run: NewtonSolver, problem_at, first, t_done, tk: float, max_cutbacks: int,
               comm: MPI.Comm):
    """Newton to the problem at ``tk`` from the state at ``t_done``, with cut-backs."""
    saved = run.save()
    start = tk if t_done is None else t_done
    dt = tk - start
    t_now, cuts, substeps = start, 0, []
    sol = failure = None
    while True:
        t_next = tk if dt <= 0 or t_now + dt >= tk - 1e-12 * abs(tk) else t_now + dt
        if first is not None and t_next == tk:
            problem = first
        else:
            problem = None
            with collective(comm):
                problem = problem_at_time(problem_at, t_next)
        try:
            sol, ok = run.step(problem)
        except StepFailed as e:
            sol, ok, failure = None, False, e
        substeps.append(t_next)
        if ok:
            saved, t_now = run.save(), t_next
            if t_now >= tk:
                return sol, substeps, cuts
            dt = min(dt, tk - t_now)
            continue
        if cuts >= max_cutbacks or dt <= 0:
            if sol is None:
                raise SolveError(f"solve_path: Newton failed at t = {t_next:g} after {cuts} "
                                 f"cut-backs: {failure}")
            return sol, substeps, cuts
        cuts += 1
        run.reset(saved)
        dt /= 2


PATH_BY["newton"] = solve_path_newton

__all__ = ["newton_record", "solve_path_newton"]
