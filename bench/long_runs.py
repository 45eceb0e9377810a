"""Long runs on one solver object: memory over many solves (issue 26, "Long runs").

``--solves N`` load cases on one ``FetiSolver`` (``update`` to a new load, ``solve``), each
Solution dropped after use; the resident memory (the process's maxrss and current RSS) and the
time per solve are printed every ``--every`` solves. Flat memory means the solver releases the
PETSc objects of each solve and update (vectors of the load case, the QP solver's work
vectors, the Solution's).

``--path N`` runs a load path of N steps instead (``df.solve_path``, a press then a shear
with Coulomb friction carried from step to step), keeping every step's Solution as the
driver returns them, and prints the memory after it.

Run: ``python bench/long_runs.py --solves 1000`` (2D Hertz on the demo mesh, about a minute),
``python bench/long_runs.py --path 200``, ``mpirun -n 2 python bench/long_runs.py --solves 200``.
"""

from __future__ import annotations

import argparse
import gc
import resource
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df

ROOT = Path(__file__).resolve().parent.parent


def rss_mib() -> float:
    """Current resident set size of this process (MiB)."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * resource.getpagesize() / 2**20


def problem(mesh, load: float) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -10.0 / 2 / 8.0)},
                            load_factor=load),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar(slave="disk_contact", master="block_contact")],
        decomposition=df.Parts(2))


def path(mesh, steps: int, rtol: float, comm: MPI.Comm) -> None:
    """A press-then-shear path with Coulomb friction; memory before and after it."""
    def problem_at(t: float) -> df.ContactProblem:
        p = min(t, 1.0)
        q = 0.3 * max(t - 1.0, 0.0) * np.sin(4 * np.pi * t)  # back and forth under Coulomb
        return df.ContactProblem(
            mesh, df.Elasticity(200.0, 0.3, tractions={"load": (q, -10.0 / 2 / 8.0 * p)}),
            dirichlet=[df.Dirichlet("bottom")],
            contact=[df.Mortar(slave="disk_contact", master="block_contact",
                               friction=df.Coulomb(0.5))],
            decomposition=df.Parts(2))

    times = np.linspace(0.2, 2.0, steps)
    # the same path by hand, keeping only the last step (what a long path needs): flat?
    solver = df.FetiSolver(problem_at(times[0]), comm=comm, rtol=rtol)
    last = solver.solve()
    marks = []
    for k, t in enumerate(times[1:], start=1):
        solver.update(problem_at(float(t)), slip_from=last)
        last = solver.solve()
        if k in (steps // 4, steps - 1):
            gc.collect()
            marks.append(comm.allreduce(rss_mib(), op=MPI.MAX))
    solver.destroy()
    if comm.rank == 0:
        print(f"{steps} steps by hand, the last Solution kept: RSS after {steps // 4} steps "
              f"{marks[0]:.1f} MiB, after {steps - 1} {marks[1]:.1f} MiB "
              f"({1024 * (marks[1] - marks[0]) / max(steps - 1 - steps // 4, 1):+.1f} KiB "
              "per step)")
    del last
    gc.collect()
    r0 = comm.allreduce(rss_mib(), op=MPI.MAX)
    t0 = time.perf_counter()
    sols = df.solve_path(problem_at, times[: steps // 2], comm=comm, rtol=rtol,
                         progress=False)
    gc.collect()
    r1 = comm.allreduce(rss_mib(), op=MPI.MAX)
    sols += df.solve_path(problem_at, times[steps // 2:], comm=comm, rtol=rtol,
                          progress=False)
    gc.collect()
    r2 = comm.allreduce(rss_mib(), op=MPI.MAX)
    dt = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    if comm.rank == 0:
        print(f"{steps} steps in {dt:.1f} s; RSS before {r0:.1f} MiB, after {steps // 2} "
              f"{r1:.1f} MiB, after {steps} {r2:.1f} MiB (every Solution kept: "
              f"{1024 * (r2 - r1) / max(steps - steps // 2, 1):.1f} KiB per step)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solves", type=int, default=1000)
    ap.add_argument("--every", type=int, default=100)
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--path", type=int, default=0, help="a load path of this many steps")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    mesh = df.read_gmsh(ROOT / "meshes/disk_on_block.msh")
    if args.path:
        return path(mesh, args.path, args.rtol, comm)
    solver = df.FetiSolver(problem(mesh, 1.0), comm=comm, rtol=args.rtol)
    solver.solve()
    rng = np.random.default_rng(0)
    rows = []
    t0 = time.perf_counter()
    for k in range(1, args.solves + 1):
        solver.update(problem(mesh, float(rng.uniform(0.5, 1.5))))
        sol = solver.solve()
        assert sol.report.converged
        del sol
        if k % args.every == 0:
            gc.collect()
            rss = comm.allreduce(rss_mib(), op=MPI.MAX)
            dt = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX) / args.every
            rows.append((k, rss, dt))
            if comm.rank == 0:
                print(f"{k:6d} solves  RSS {rss:8.1f} MiB  {1e3 * dt:7.1f} ms per solve",
                      flush=True)
            t0 = time.perf_counter()
    if comm.rank == 0 and len(rows) > 1:
        first, last = rows[0][1], rows[-1][1]
        print(f"RSS after {rows[0][0]} solves {first:.1f} MiB, after {rows[-1][0]} "
              f"{last:.1f} MiB: {last - first:+.1f} MiB "
              f"({1024 * (last - first) / max(rows[-1][0] - rows[0][0], 1):+.1f} KiB per solve)")


if __name__ == "__main__":
    main()
