"""What rtol buys: the error against the exact discrete solution, per method, problem and rtol.

For B1 (two membranes, node-to-node contact), 2D Hertz (mortar, ``meshes/disk_on_block.msh``)
and the 3D rigid sphere of docs/peers.md (level S1, node-to-obstacle), each method (tfeti,
feti1, fetidp) is solved at each rtol with the stopping test ``stop_test="dual"`` (before:
‖gᴾ‖ ≤ rtol‖b‖) and ``"kkt"`` (after: the KKT residuals in physical units ≤ rtol). The error
is measured against a tight solve (TFETI, ``stop_test="dual"``, rtol 1e-12; the spread of the
three methods' tight solves is printed as the reference's own uncertainty): ``u`` the largest
nodal displacement error relative to max|u|, ``λ`` the largest nodal contact force error
relative to the largest force. Also: F-multiplications (those of the stopping test's checks
included), the exact checks, the largest KKT residual, and the solve time (set-up excluded).

Run: ``python bench/rtol_accuracy.py`` (~3 minutes); ``--problems b1 --rtols 1e-6`` for less;
``mpirun -n 2 python bench/rtol_accuracy.py`` for 2 ranks. ``--sphere S2`` for the finer
sphere, ``--b1 32`` for a finer B1 (n×n squares per membrane, 4×4 subdomains each); solver
options pass through (``-feti_mprgp_expansion projcg``, the tight references too).
"""

from __future__ import annotations

import argparse
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
METHODS = ("tfeti", "feti1", "fetidp")
SOLVE_PHASES = ("iterations", "recovery", "stopping test")


def b1(n: int) -> df.ContactProblem:
    return df.ContactProblem(
        P.membranes_mesh(n), df.Poisson(source=P.b1_source),
        dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=P.grid(0.25))


def hertz(parts: int) -> df.ContactProblem:
    mesh = df.read_gmsh(ROOT / "meshes/disk_on_block.msh")
    return df.ContactProblem(
        mesh, df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -10.0 / 2 / 8.0)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar(slave="disk_contact", master="block_contact")],
        decomposition=df.Parts(parts))


def sphere(level: str, parts: int) -> df.ContactProblem:
    return C.sphere_problem(level, parts)


def fields(sol: df.Solution) -> tuple[np.ndarray, np.ndarray]:
    """Nodal values and the nodal contact forces (global row order: rank-independent)."""
    return sol.nodal_values(), sol.contact.force


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300)) if b.size else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", default="b1,hertz,sphere")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--rtols", default="1e-4,1e-6,1e-8")
    ap.add_argument("--tests", default="dual,kkt")
    ap.add_argument("--b1", type=int, default=16, help="B1: squares per membrane side")
    ap.add_argument("--sphere", default="S1", help="sphere level of docs/peers.md")
    ap.add_argument("--parts", type=int, default=4, help="Hertz and sphere: Parts(n)")
    args, feti = P.parse_with_feti_options(ap)  # e.g. -feti_mprgp_expansion projcg
    comm = MPI.COMM_WORLD
    make = {"b1": lambda: b1(args.b1), "hertz": lambda: hertz(args.parts),
            "sphere": lambda: sphere(args.sphere, args.parts)}
    rtols = [float(r) for r in args.rtols.split(",")]
    methods = args.methods.split(",")
    rows = []
    for name in args.problems.split(","):
        problem = make[name]()
        tight = {m: fields(df.solve(problem, comm=comm, method=m, rtol=1e-12, stop_test="dual",
                                      options=feti))
                 for m in METHODS}
        u_ref, f_ref = tight["tfeti"]
        spread = max(max(rel(u, u_ref), rel(f, f_ref)) for u, f in tight.values())
        if comm.rank == 0:
            print(f"{name}: {u_ref.size} nodal values, {f_ref.size} contact rows, reference "
                  f"spread of the methods at 1e-12: {spread:.1e}", flush=True)
        for method in methods:
            for rtol in rtols:
                for test in args.tests.split(","):
                    t0 = time.perf_counter()
                    sol = df.solve(problem, comm=comm, method=method, rtol=rtol, stop_test=test,
                                   options=feti)
                    wall = time.perf_counter() - t0
                    rep = sol.report
                    u, f = fields(sol)
                    solve_t = sum(rep.timings.get(k, 0.0) for k in SOLVE_PHASES)
                    row = (name, method, rtol, test, rel(u, u_ref), rel(f, f_ref),
                           rep.hessian_mults, rep.stopping.get("checks", 0),
                           max(rep.kkt.values()), solve_t, wall, rep.converged)
                    rows.append(row)
                    if comm.rank == 0:
                        print(f"  {method:6s} rtol {rtol:.0e} {test:4s}: u {row[4]:.1e}  "
                              f"lambda {row[5]:.1e}  F {row[6]:4d}  checks {row[7]}  KKT "
                              f"{row[8]:.1e}  solve {solve_t:6.2f} s  (wall {wall:.1f} s)"
                              f"{'' if rep.converged else '  NOT CONVERGED'}", flush=True)
    if comm.rank == 0:
        print(f"\n{comm.size} rank(s)\n" + table(rows))


def table(rows: list[tuple]) -> str:
    """Markdown: per problem, method and rtol, the dual test (before) beside the KKT test."""
    by = {(r[0], r[1], r[2], r[3]): r for r in rows}
    out = ["| problem | method | rtol | before: error u / λ | F | after: error u / λ | F | "
           "checks | max KKT | solve [s] before / after |", "|---|---|---|---|---|---|---|---|"
           "---|---|"]
    for (name, method, rtol, test), r in by.items():
        if test != "kkt" or (name, method, rtol, "dual") not in by:
            continue
        d = by[(name, method, rtol, "dual")]
        out.append(f"| {name} | {method} | {rtol:.0e} | {d[4]:.1e} / {d[5]:.1e} | {d[6]} | "
                   f"{r[4]:.1e} / {r[5]:.1e} | {r[6]} | {r[7]} | {r[8]:.1e} | {d[9]:.2f} / "
                   f"{r[9]:.2f} |")
    return "\n".join(out)

if __name__ == "__main__":
    main()
