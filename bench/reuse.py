"""Set up once, solve many: what a second solve on one ``FetiSolver`` costs.

For each case: set up and solve the problem at load 1; ``update`` to load ``--scale`` and solve
again (warm-started from the first multipliers); then a cold ``df.solve`` of the same new
problem. Reported, in one run: the first solve's set-up time (every phase but the iterations,
the KKT checks and the recovery), the update's (the phases before the second solve's
iterations) and their ratio; the F-multiplications of the warm and of the cold solve and their
ratio; the largest difference of u and of the nodal contact forces between warm and cold,
relative to their maxima. Then ``--cases`` load cases (loads spread over [0.5, 1.5]) on one
set-up against as many separate ``df.solve`` calls: the wall time per case both ways.

Cases: ``hertz2d`` (the main demo's problem: disk on block, mortar contact, the load),
``sphere3d`` (a rigid sphere pressed into a quarter block, docs/peers.md level S3: the load is
the indentation depth; the sphere's normals move with it, so B changes and the update is a
row update), ``b1`` (two membranes, node-to-node, the source term; H/h = 128 and H = 1/8 give
the 2.13 M-dof run).

Run (one process): ``python bench/reuse.py --case hertz2d`` (seconds), ``--case sphere3d``
(about a minute); on 2 ranks: ``mpirun -n 2 python bench/reuse.py --case b1 --n 1024 --H 0.125
--cases 0`` (several minutes). Writes ``output/bench/reuse_<case>.json``; prints a Markdown row.
``--reuse k`` keeps k CG directions (Krylov recycling, the default 80; ``--reuse 0``: the
counts without it; ``--no-deflate``: its Galerkin steps only), in the warm and the cold
solves alike.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "peers"))
import common as C  # noqa: E402  (bench/peers/common.py)

import problems as P  # noqa: E402

ROOT = HERE.parent
#: Phases of a solve that are not set-up: what the QP solver, the way back and the KKT test's
#: checks cost.
SOLVE_PHASES = ("iterations", "recovery", "stopping test", "total")


def hertz2d(mesh, scale: float) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -10.0 / 2 / 8.0)},
                            load_factor=scale),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar(slave="disk_contact", master="block_contact")],
        decomposition=df.Parts(2))


def sphere3d(mesh, scale: float, parts: int) -> df.ContactProblem:
    sphere = df.Sphere(center=(0.0, 0.0, C.SPHERE_R - scale * C.SPHERE_D), radius=C.SPHERE_R)
    return df.ContactProblem(
        mesh, df.Elasticity(C.SPHERE_E, C.SPHERE_NU),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry_x", components=[0]),
                   df.Dirichlet("symmetry_y", components=[1])],
        contact=[df.RigidObstacle("top", sphere)], decomposition=df.Parts(parts))


def b1(mesh, scale: float, H: float) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.Poisson(source=P.b1_source, load_factor=scale),
        dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=P.grid(H))


def add_recycle_arguments(ap: argparse.ArgumentParser) -> None:
    """The Krylov recycling's and MPRGP's expansion arguments, for warm and cold solves alike.

    ``--reuse k``, ``--no-deflate``, ``--no-project``, ``--no-carry``, ``--expansion``,
    ``--alpha``.
    """
    defaults = df.SolverOptions()
    ap.add_argument("--reuse", type=int, default=defaults.mprgp_reuse,
                    help="Krylov recycling: CG directions kept (0: off, as before recycling)")
    ap.add_argument("--no-deflate", dest="deflate", action="store_false",
                    help="with --reuse: the Galerkin steps only, no deflated CG")
    ap.add_argument("--no-project", dest="project", action="store_false",
                    help="with --reuse: expansions in recycled faces by MPRGP's own step only "
                         "(no projected Galerkin step)")
    ap.add_argument("--no-carry", dest="carry", action="store_false",
                    help="with --reuse: a row update (a moved curved obstacle) clears the "
                         "recycled directions (no stale carry)")
    ap.add_argument("--expansion", default=defaults.mprgp_expansion,
                    help="MPRGP's expansion step: fixed, optimal or projcg")
    ap.add_argument("--alpha", default=defaults.mprgp_alpha,
                    help="MPRGP's expansion length: fixed or bb")


def recycle_options(args: argparse.Namespace) -> dict:
    """The solver options of :func:`add_recycle_arguments`' arguments."""
    return {"mprgp_reuse": args.reuse, "mprgp_deflate": args.deflate,
            "mprgp_project": args.project, "mprgp_carry": args.carry,
            "mprgp_expansion": args.expansion,
            "mprgp_alpha": args.alpha}


def setup_time(report) -> float:
    return float(sum(v for k, v in report.timings.items() if k not in SOLVE_PHASES))


def rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300)) if b.size else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("hertz2d", "sphere3d", "b1"), default="hertz2d")
    ap.add_argument("--scale", type=float, default=1.1, help="the second load over the first")
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--method", default="tfeti")
    ap.add_argument("--level", default="S3", help="sphere3d: mesh level of docs/peers.md")
    ap.add_argument("--parts", type=int, default=8, help="sphere3d: subdomains")
    ap.add_argument("--n", type=int, default=128, help="b1: squares per membrane side")
    ap.add_argument("--H", type=float, default=1 / 8, help="b1: subdomain size")
    ap.add_argument("--cases", type=int, default=5, help="load cases for the amortized cost")
    add_recycle_arguments(ap)
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    if args.case == "hertz2d":
        mesh = df.read_gmsh(ROOT / "meshes/disk_on_block.msh")

        def make(s):
            return hertz2d(mesh, s)
    elif args.case == "sphere3d":
        mesh = C.sphere_mesh(args.level)

        def make(s):
            return sphere3d(mesh, s, args.parts)
    else:
        mesh = P.membranes_mesh(args.n)

        def make(s):
            return b1(mesh, s, args.H)
    opts = {"rtol": args.rtol, "method": args.method, "comm": comm, **recycle_options(args)}

    t0 = time.perf_counter()
    solver = df.FetiSolver(make(1.0), **opts)
    first = solver.solve()
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    solver.update(make(args.scale))
    warm = solver.solve()
    t_second = time.perf_counter() - t0
    cold = df.solve(make(args.scale), **opts)
    u_w, u_c = warm.nodal_values(), cold.nodal_values()
    row = {
        "case": args.case, "ranks": comm.size, "method": first.report.method,
        "primal": first.report.sizes["primal"], "dual": first.report.sizes["dual"],
        "setup_first": setup_time(first.report), "setup_update": setup_time(warm.report),
        "update_phases": {k: v for k, v in warm.report.timings.items()
                          if k not in SOLVE_PHASES},
        "mults_first": first.report.hessian_mults, "mults_warm": warm.report.hessian_mults,
        "mults_cold": cold.report.hessian_mults,
        "u_diff": rel_diff(u_w, u_c) if comm.rank == 0 else 0.0,
        "force_diff": rel_diff(warm.contact.force, cold.contact.force),
        "wall_first": t_first, "wall_second": t_second,
        "converged": bool(first.report.converged and warm.report.converged
                          and cold.report.converged),
    }
    row["u_diff"] = comm.bcast(row["u_diff"], root=0)
    row["setup_ratio"] = row["setup_update"] / row["setup_first"]
    row["mults_ratio"] = row["mults_warm"] / row["mults_cold"]
    if args.cases:
        loads = np.linspace(0.5, 1.5, args.cases)
        t0 = time.perf_counter()
        for s in loads:
            solver.update(make(float(s)))
            solver.solve()
        per_case_solver = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX) / args.cases
        t0 = time.perf_counter()
        for s in loads:
            df.solve(make(float(s)), **opts)
        per_case_solve = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX) / args.cases
        row.update(cases=args.cases, per_case_solver=per_case_solver,
                   per_case_solve=per_case_solve, amortized_ratio=per_case_solver / per_case_solve)
    if comm.rank == 0:
        out = ROOT / "output/bench"
        out.mkdir(parents=True, exist_ok=True)
        (out / f"reuse_{args.case}.json").write_text(json.dumps(row, indent=1))
        print(json.dumps(row, indent=1))
        print(f"| {args.case} | {comm.size} | {row['method']} | {row['primal']} | "
              f"{row['setup_first']:.2f} | {row['setup_update']:.3f} | "
              f"{100 * row['setup_ratio']:.1f} % | {row['mults_cold']} | {row['mults_warm']} | "
              f"{100 * row['mults_ratio']:.0f} % | {row['u_diff']:.1e} | "
              f"{row['force_diff']:.1e} | "
              + (f"{row['per_case_solver']:.2f} / {row['per_case_solve']:.2f} |"
                 if args.cases else "– |"))


if __name__ == "__main__":
    main()


