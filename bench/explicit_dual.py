"""Explicit local dual operators against the implicit F: time per F x, set-up, break-even.

For each problem and decomposition (Total FETI unless named), on the ranks it is run on:

- ``implicit``: one y = F x as Bᵀ, the block-diagonal sparse Cholesky solve, B;
- ``explicit``: one y = F x by the dense blocks F_s = B_s K_s⁺ B_sᵀ (gather, one GEMV per
  subdomain, scatter-add);
- ``set-up``: forming the blocks (the batched solves and products), once;
- ``break-even``: set-up / (implicit − explicit), the F-multiplications after which the explicit
  operator has paid (∞ when it is not faster);
- ``Dirichlet``: one application of the Dirichlet preconditioner (stiffness scaling) implicit
  and by its explicit blocks (:mod:`dolfinx_feti.feti.precond_explicit`), and the extra set-up
  of the blocks (explicit build − implicit build);
- ``solve``: with ``--solve``, the wall time of ``df.solve(rtol=1e-6)`` with each operator
  (its F-multiplications in parentheses);
- the cost model of ``dual_operator="auto"`` (:mod:`dolfinx_feti.feti.explicit`): its predicted
  explicit time and set-up, and its choice at N = ``EXPECTED_MULTS``.

Every time is the median over ``--repeat`` runs of the slowest rank's time (the set-up: the
median of three builds).

    python bench/explicit_dual.py --solve                   # 1 rank
    mpirun -n 2 python bench/explicit_dual.py --solve       # 2 ranks
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fmult_split import timed  # noqa: E402  (median over repeats of the slowest rank's time)

import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402
from dolfinx_feti.feti import explicit  # noqa: E402
from dolfinx_feti.feti.dualize import ImplicitDual  # noqa: E402
from dolfinx_feti.feti.preconditioner import make_preconditioner  # noqa: E402
from dolfinx_feti.io import meshes_occ  # noqa: E402

COMM = MPI.COMM_WORLD


@functools.cache
def demo_mesh() -> df.MeshData:
    """The mesh of demos/demo_hertz2d.py at its default h = 0.05."""
    return df.build_mesh(meshes_occ.disk_on_block, h_contact_disk=0.05, h_contact_block=0.05,
                         R=8.0, comm=COMM)


def demo_hertz2d(parts: int) -> df.ContactProblem:
    """The problem of demos/demo_hertz2d.py (mortar contact), ``Parts(parts)``."""
    mesh = demo_mesh()
    return df.ContactProblem(
        mesh, df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -10.0 / 2 / 8.0)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar(slave="disk_contact", master="block_contact")],
        decomposition=df.Parts(parts))


def solve_time(build, method: str, operator: str) -> str:
    """Wall time of a whole solve and its F-multiplications."""
    problem = build()
    COMM.Barrier()
    t0 = time.perf_counter()
    s = df.solve(problem, comm=COMM, rtol=1e-6, method=method, dual_operator=operator)
    t = COMM.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    return f"{t:.2f} ({s.report.hessian_mults_total})"


def measure(name: str, build, method: str, repeat: int, solve: bool) -> list:
    qp = df.dual_qp(build(), COMM, method=method)
    primal = qp.feti.primal
    imp = ImplicitDual(primal)
    x = qp.feti.d.duplicate()
    x.array[:] = np.random.default_rng(COMM.rank).standard_normal(x.getLocalSize())
    y = x.duplicate()
    t_imp = timed(lambda: imp.mult(x, y), repeat)
    builds = []
    for _ in range(3):
        COMM.Barrier()
        t0 = time.perf_counter()
        exp = explicit.ExplicitDual(primal)
        builds.append(COMM.allreduce(time.perf_counter() - t0, op=MPI.MAX))
        if len(builds) < 3:
            exp.destroy()
    setup = float(np.median(builds))
    t_exp = timed(lambda: exp.mult(x, y), repeat)
    model = explicit.measured_costs(primal, imp)
    pattern = exp.pattern
    m_max = COMM.allreduce(pattern.m_max, op=MPI.MAX)
    entries = COMM.allreduce(pattern.entries, op=MPI.MAX)
    saving = t_imp - t_exp
    even = f"{setup / saving:.0f}" if saving > 0 else "∞"
    subs = COMM.allreduce(int(pattern.sizes.size))
    exp.destroy()
    pre, build_t = {}, {}
    for e in (False, True):
        COMM.Barrier()
        t0 = time.perf_counter()
        pre[e] = make_preconditioner("dirichlet", qp.primal, scaling="stiffness", explicit=e)
        build_t[e] = COMM.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    t_pre = {e: timed(lambda e=e: pre[e].mult(x, y), repeat) for e in pre}
    for p in pre.values():
        p.destroy()
    solves = [solve_time(build, method, op) if solve else "–" for op in ("implicit", "explicit")]
    return [name, method, COMM.size, qp.system.primal_size[1], subs, m_max,
            f"{8e-6 * entries:.1f}", f"{1e3 * t_imp:.3f}", f"{1e3 * t_exp:.3f}",
            f"{1e3 * setup:.1f}", even, f"{1e3 * model['t_explicit']:.3f}",
            f"{1e3 * model['setup']:.1f}", "explicit" if model["explicit"] else "implicit",
            f"{1e3 * t_pre[False]:.3f}", f"{1e3 * t_pre[True]:.3f}",
            f"{1e3 * (build_t[True] - build_t[False]):.1f}", *solves]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--solve", action="store_true", help="also time whole solves")
    args = ap.parse_args()
    cases = [("demo Hertz 2D (mortar), Parts(2)", lambda: demo_hertz2d(2), "tfeti"),
             ("demo Hertz 2D (mortar), Parts(8)", lambda: demo_hertz2d(8), "tfeti"),
             ("demo Hertz 2D (mortar), Parts(32)", lambda: demo_hertz2d(32), "tfeti"),
             ("demo Hertz 2D (mortar), Parts(32)", lambda: demo_hertz2d(32), "fetidp"),
             ("3D blocks n=16, Parts(2)", lambda: P.blocks3d(16, 2), "tfeti"),
             ("3D blocks n=16, Parts(8)", lambda: P.blocks3d(16, 8), "tfeti"),
             ("3D blocks n=16, Parts(32)", lambda: P.blocks3d(16, 32), "tfeti"),
             ("3D blocks n=16, Parts(32)", lambda: P.blocks3d(16, 32), "fetidp"),
             ("3D blocks n=24, Parts(8)", lambda: P.blocks3d(24, 8), "tfeti"),
             ("3D blocks n=24, Parts(32)", lambda: P.blocks3d(24, 32), "tfeti"),
             ("3D blocks n=24, Parts(32)", lambda: P.blocks3d(24, 32), "fetidp")]
    header = ["problem", "method", "ranks", "primal dofs", "subdomains", "max m_s",
              "blocks [MB/rank]", "implicit F [ms]", "explicit F [ms]", "set-up [ms]",
              "break-even [F-mults]", "model: explicit F [ms]", "model: set-up [ms]",
              f"auto (N = {explicit.EXPECTED_MULTS})", "Dirichlet implicit [ms]",
              "Dirichlet explicit [ms]", "Dirichlet blocks set-up [ms]", "solve implicit [s]",
              "solve explicit [s]"]
    rows = []
    for name, build, method in cases:
        rows.append(measure(name, build, method, args.repeat, args.solve))
        if P.is_root():
            print(" | ".join(map(str, rows[-1])), flush=True)
    if P.is_root():
        print(f"\n{COMM.size} rank(s); {P.machine()}; code {P.git_state()}\n")
        print(P.md_table(header, rows))


if __name__ == "__main__":
    main()
