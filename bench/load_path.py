"""Load paths on one set-up: what each step costs against the first, warm against cold.

A path of load steps of 10 % each (load_k = 1.1^k, k = 0 … ``--steps``) solved with
``df.solve_path``'s loop (one ``FetiSolver``: ``update`` + a warm ``solve`` per step; with
friction the step acts on the slip increment). Each step is solved again from the cold start on
a second set-up of the same path (``solve(x0="cold")``; with Coulomb friction also from g = ∞),
the slip history being the warm path's. Reported per step: the set-up seconds (every phase but
the iterations, the KKT checks and the recovery: for k = 0 the whole set-up, later the update)
and their ratio to the first step's, the F-multiplications warm and cold and their ratio. The
issue's targets: set-up ≤ 5 % of the first's, warm ≤ 30 % of cold.

Cases: ``hertz2d`` (disk on block, mortar contact, the load rising: meshes/disk_on_block.msh),
``coulomb2d`` (the Hertz disk on block, node-to-node, Coulomb 𝓕 = 0.4: P fixed, the tangential
load Q rising by 10 % per step from 0.3 𝓕P), ``sphere3d`` (a rigid sphere pressed into a quarter
block, docs/peers.md level S3: the indentation depth rising; the sphere's normals move with it,
so every step is a row update), ``pushed3d`` (the same indentation with the sphere held and the
block's bottom pushed up: B stays).

Run (one process): ``python bench/load_path.py --case hertz2d`` (seconds), ``--case coulomb2d``
(seconds), ``--case sphere3d --steps 4`` or ``pushed3d`` (minutes). Writes
``output/bench/load_path_<case>.json``; prints a Markdown table.
``--reuse k`` keeps k CG directions (Krylov recycling, the default 80; ``--reuse 0``: the
counts without it; ``--no-deflate``: its Galerkin steps only; ``--no-project``: no projected
Galerkin expansion; ``--no-carry``: a row update clears the directions),
``--expansion``/``--alpha`` MPRGP's expansion step, in the warm and the cold solves alike.
The JSON holds each step's step counts (CG, expansion, proportioning, Galerkin steps and
projected Galerkin expansions) and KKT checks, warm and cold.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import ufl
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "peers"))
import common as C  # noqa: E402  (bench/peers/common.py)
from reuse import (  # noqa: E402  (bench/reuse.py's cases and options)
    SOLVE_PHASES,
    add_recycle_arguments,
    hertz2d,
    recycle_options,
    setup_time,
    sphere3d,
)


def solve_time(report) -> float:
    """The seconds of the solve: the iterations, the KKT checks and the recovery."""
    return float(sum(v for k, v in report.timings.items() if k in SOLVE_PHASES and k != "total"))

ROOT = HERE.parent
R, P, F = 8.0, 10.0, 0.4


def coulomb2d(mesh, s: float) -> df.ContactProblem:
    q = 0.3 * s * F * P
    m = 3.0 * q / (2.0 * R**2)  # no moment of q about the contact point

    def traction(x):
        return ufl.as_vector((q / (2 * R), -P / (2 * R) + m * x[0]))

    return df.ContactProblem(
        mesh, df.Elasticity(200.0, 0.3, tractions={"load": traction}),
        dirichlet=[df.Dirichlet("bottom")],
        contact=[df.NodeToNode("disk_contact", "block_contact", friction=df.Coulomb(F))],
        decomposition=df.Parts(2))


def pushed3d(mesh, s: float, parts: int) -> df.ContactProblem:
    """sphere3d with the sphere held and the block's bottom pushed up by the depth.

    The same indentation, but the rows stay (B does not change).
    """
    sphere = df.Sphere(center=(0.0, 0.0, C.SPHERE_R), radius=C.SPHERE_R)
    return df.ContactProblem(
        mesh, df.Elasticity(C.SPHERE_E, C.SPHERE_NU),
        dirichlet=[df.Dirichlet("bottom", value=(0.0, 0.0, s * C.SPHERE_D)),
                   df.Dirichlet("symmetry_x", components=[0]),
                   df.Dirichlet("symmetry_y", components=[1])],
        contact=[df.RigidObstacle("top", sphere)], decomposition=df.Parts(parts))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("hertz2d", "coulomb2d", "sphere3d", "pushed3d"),
                    default="hertz2d")
    ap.add_argument("--steps", type=int, default=8, help="load steps after the first")
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--method", default="tfeti")
    ap.add_argument("--level", default="S3", help="sphere3d: mesh level of docs/peers.md")
    ap.add_argument("--parts", type=int, default=8, help="sphere3d: subdomains")
    add_recycle_arguments(ap)
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    if args.case == "hertz2d":
        mesh = df.read_gmsh(ROOT / "meshes/disk_on_block.msh")

        def make(s):
            return hertz2d(mesh, s)
    elif args.case == "coulomb2d":
        mesh = df.build_mesh(meshes.hertz2d_full, h_contact=0.1)

        def make(s):
            return coulomb2d(mesh, s)
    else:
        mesh = C.sphere_mesh(args.level)
        case = sphere3d if args.case == "sphere3d" else pushed3d

        def make(s):
            return case(mesh, s, args.parts)
    loads = 1.1 ** np.arange(args.steps + 1)
    opts = {"rtol": args.rtol, "method": args.method, **recycle_options(args)}
    solver = df.FetiSolver(make(loads[0]), comm=comm, **opts)
    # the cold solves on a set-up of their own, so that the warm chain is the one a load path
    # runs (a cold solve in between would hand the next warm start its state; x0="cold" also
    # forgets the recycled directions)
    reference = df.FetiSolver(make(loads[0]), comm=comm, **opts)
    rows, prev = [], None
    for k, s in enumerate(loads):
        if k:
            solver.update(make(float(s)), slip_from=prev)
            reference.update(make(float(s)), slip_from=prev)
        warm = solver.solve()
        cold = reference.solve(x0="cold")  # the same step from the default start
        row = {"step": k, "load": float(s), "setup": setup_time(warm.report),
               "setup_phases": {p: t for p, t in warm.report.timings.items()
                                if p not in SOLVE_PHASES},
               "mults_warm": warm.report.hessian_mults, "mults_cold": cold.report.hessian_mults,
               "solve_warm": solve_time(warm.report), "solve_cold": solve_time(cold.report),
               # where they went: CG / expansion / proportioning / Galerkin steps ('recycle'),
               # projected Galerkin expansions ('galerkin'), KKT checks and their F-mults
               "counts_warm": warm.report.counts, "counts_cold": cold.report.counts,
               "checks_warm": {k: v for k, v in warm.report.stopping.items() if k != "history"},
               "checks_cold": {k: v for k, v in cold.report.stopping.items() if k != "history"},
               "converged": bool(warm.report.converged and cold.report.converged)}
        fr = warm.report.extra.get("friction")
        if fr and "fixed_point_steps" in fr:
            row["coulomb_warm"] = fr["fixed_point_steps"]
            row["coulomb_cold"] = cold.report.extra["friction"]["fixed_point_steps"]
        rows.append(row)
        prev = warm
    first = rows[0]["setup"]
    for r in rows:
        r["setup_ratio"] = r["setup"] / first
        r["mults_ratio"] = r["mults_warm"] / r["mults_cold"]
    later = rows[1:]
    summary = {"case": args.case, "ranks": comm.size, "method": prev.report.method,
               "primal": prev.report.sizes["primal"], "rtol": args.rtol,
               "setup_first": first,
               "setup_ratio_max": max(r["setup_ratio"] for r in later),
               "setup_ratio_median": float(np.median([r["setup_ratio"] for r in later])),
               "mults_ratio_median": float(np.median([r["mults_ratio"] for r in later])),
               "mults_ratio_max": max(r["mults_ratio"] for r in later),
               "converged": all(r["converged"] for r in rows), "steps": rows}
    solver.destroy()
    reference.destroy()
    if comm.rank == 0:
        out = ROOT / "output/bench"
        out.mkdir(parents=True, exist_ok=True)
        (out / f"load_path_{args.case}.json").write_text(json.dumps(summary, indent=1))
        print(f"{args.case}: {summary['primal']} primal dofs, {comm.size} rank(s), "
              f"{summary['method']}, rtol {args.rtol:g}")
        print("| step | load | set-up s | / first | F-mults warm | cold | warm/cold |"
              + (" Coulomb steps warm/cold |" if "coulomb_warm" in rows[0] else ""))
        print("|---|---|---|---|---|---|---|" + ("---|" if "coulomb_warm" in rows[0] else ""))
        for r in rows:
            print(f"| {r['step']} | {r['load']:.3f} | {r['setup']:.3f} | "
                  f"{100 * r['setup_ratio']:.1f} % | {r['mults_warm']} | {r['mults_cold']} | "
                  f"{100 * r['mults_ratio']:.0f} % |"
                  + (f" {r['coulomb_warm']} / {r['coulomb_cold']} |" if "coulomb_warm" in r
                     else ""))
        print(f"set-up after the first: max {100 * summary['setup_ratio_max']:.1f} %, median "
              f"{100 * summary['setup_ratio_median']:.1f} % of the first (target <= 5 %); "
              f"F-mults warm/cold: median {100 * summary['mults_ratio_median']:.0f} %, max "
              f"{100 * summary['mults_ratio_max']:.0f} % (target <= 30 %)")


if __name__ == "__main__":
    main()
