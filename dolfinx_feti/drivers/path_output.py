"""Output of a load path over time: one XDMF file with a time per step, a JSON history.

The XDMF file holds the mesh once and, per step, the displacement, the contact pressure and
with friction the tangential traction and the stick/slip state at the step's time (ParaView's
time slider); it is written under a temporary name and appears
under its own when the path is done. The JSON history is rewritten after every step (a path
that stops early leaves the steps done).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .. import compat
from ..constraints.friction import SLIP, STICK
from ..errors import InputError, collective
from ..problem.contact_problem import ContactProblem
from ..results.output import publish_xdmf
from ..results.solution import Solution

#: Phases of a report's timings that are the solve itself (the KKT test's checks too); the rest
#: is set-up or update.
SOLVE_PHASES = ("iterations", "recovery", "stopping test")


def setup_seconds(sol: Solution) -> float:
    """Seconds of a solve's set-up or update (its report's timings less the QP solve)."""
    t = sol.report.timings
    return float(t.get("total", 0.0) - sum(t.get(p, 0.0) for p in SOLVE_PHASES))


class TimeSeries:
    """The displacement and contact pressure of every step in one XDMF file (collective).

    Args:
        path: The XDMF file (its HDF5 file beside it).
        comm: The ranks of the solve.
    """

    def __init__(self, path: str | Path, comm: MPI.Comm) -> None:
        self.path, self.comm = Path(path), comm
        self.tmp = self.path.with_name(f".tmp-{self.path.name}")
        self._file = None
        self._done = False
        with collective(comm, "outputs"):
            if comm.rank == 0:
                self.path.parent.mkdir(parents=True, exist_ok=True)

    @staticmethod
    def check(problem: ContactProblem) -> None:
        """Refuse a problem whose displacement XDMF cannot hold (before any solve)."""
        degree = problem.mesh.geometry_degree
        if problem.degree != degree:
            raise InputError(f"solve_path: xdmf output holds fields of the mesh's geometry "
                             f"degree ({degree}), the problem has degree {problem.degree}; "
                             "write each step's solution.write_xdmf instead")

    def write(self, sol: Solution, t: float) -> None:
        """Add a step at time ``t``."""
        u = sol.u
        with collective(self.comm, "outputs"):
            if self._file is None:
                self._file = compat.open_xdmf_series(self.tmp, u.function_space.mesh)
            self._file.write_function(u, t)
            for f in self.fields(sol):
                self._file.write_function(f, t)

    @staticmethod
    def fields(sol: Solution) -> list:
        """The contact fields of a step.

        The pressure; with friction the tangential traction and the state (0 off contact or
        frictionless, 1 stick, 2 slip).
        """
        degree, c = sol.problem.degree, sol.contact
        out = [sol.pressure_function(degree=degree)]
        if c.tangential_traction is not None:
            out.append(sol.contact_function(c.tangential_traction, "tangential_traction",
                                            degree))
            out.append(sol.contact_function(c.state, "stick_slip", degree))
        return out

    def close(self) -> None:
        """Finish the file and give it its name."""
        if self._file is None:
            return
        self._file.close()
        self._file = None
        publish_xdmf(self.tmp, self.path, self.comm)
        self._done = True

    def abort(self) -> None:
        """After a failure: close and remove the temporary files (no-op once closed)."""
        if self._file is not None:
            self._file.close()
            self._file = None
        if not self._done and self.comm.rank == 0:
            for p in (self.tmp, self.tmp.with_suffix(".h5")):
                p.unlink(missing_ok=True)


class History:
    """The per-step records of a load path, as JSON on rank 0.

    Args:
        path: The JSON file.
        comm: The ranks of the solve.
    """

    def __init__(self, path: str | Path, comm: MPI.Comm) -> None:
        self.path, self.comm = Path(path), comm
        self.records: list[dict] = []

    @staticmethod
    def record(sol: Solution) -> dict:
        """What the history keeps of a step (the same on every rank)."""
        rep, c = sol.report, sol.contact
        pressed = (c.force > 0) & (c.pressure > 0)  # a pressed node's lumped area: force/pressure
        rec = {"step": rep.extra.get("step"), "time": rep.extra.get("time"),
               "converged": bool(rep.converged), "reason": rep.reason,
               "iterations": int(rep.iterations), "outer_iterations": int(rep.outer_iterations),
               "hessian_mults": int(rep.hessian_mults),
               "setup_time": setup_seconds(sol),
               "solve_time": float(sum(rep.timings.get(p, 0.0) for p in SOLVE_PHASES)),
               "contact_force": [float(v) for v in sol.total_contact_force],
               "contact_nodes": int(np.count_nonzero(pressed)),
               "contact_area": float(np.sum(c.force[pressed] / c.pressure[pressed]))}
        if sol.problem.value_size > 1:
            per = {}
            for i in np.unique(c.spec):
                m = c.spec == i
                f = (c.force[m, None] * c.normal[m]).sum(axis=0)
                if c.tangential_force is not None:
                    f = f + c.tangential_force[m].sum(axis=0)
                per[str(int(i))] = [float(v) for v in f]
            rec["contact_force_per_condition"] = per
        if c.state is not None:
            rec["stick_nodes"] = int(np.count_nonzero(c.state == STICK))
            rec["slip_nodes"] = int(np.count_nonzero(c.state == SLIP))
            fr = rep.extra.get("friction", {})
            if "fixed_point_steps" in fr:
                rec["coulomb_steps"] = int(fr["fixed_point_steps"])
        return rec

    def append(self, record: dict) -> None:
        """Add a step and rewrite the file."""
        self.records.append(record)
        with collective(self.comm, "outputs"):
            if self.comm.rank == 0:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                tmp = self.path.with_name(f".tmp-{self.path.name}")
                tmp.write_text(json.dumps({"steps": self.records}, indent=1))
                os.replace(tmp, self.path)

    def close(self) -> None:
        """Nothing left to write (each step rewrote the file)."""


class PathOutput:
    """The outputs of a load path: the XDMF time series and the JSON history (either optional).

    Args:
        xdmf: The XDMF file, or None.
        history: The JSON file, or None.
        comm: The ranks of the solve.
    """

    def __init__(self, xdmf: str | Path | None, history: str | Path | None,
                 comm: MPI.Comm) -> None:
        self.series = TimeSeries(xdmf, comm) if xdmf is not None else None
        self.log = History(history, comm) if history is not None else None

    def check(self, problem: ContactProblem) -> None:
        """Refuse, before any solve, a problem the XDMF file cannot hold."""
        if self.series is not None:
            self.series.check(problem)

    def write(self, sol: Solution, t: float, record: dict) -> None:
        """Add a step: its fields at time ``t`` and its history ``record``."""
        if self.series is not None:
            self.series.write(sol, t)
        if self.log is not None:
            self.log.append(record)

    def close(self) -> None:
        """Finish both files (after the last step)."""
        if self.series is not None:
            self.series.close()
        if self.log is not None:
            self.log.close()

    def abort(self) -> None:
        """After a failure: remove the unfinished XDMF file (no-op once closed)."""
        if self.series is not None:
            self.series.abort()


__all__ = ["SOLVE_PHASES", "History", "PathOutput", "TimeSeries", "setup_seconds"]
