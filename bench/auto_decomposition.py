"""What ``Auto()`` (the default decomposition) and ``method="auto"`` are derived from.

Every method (TFETI, FETI-1, FETI-DP; default options, ``rtol`` 1e-6 on the KKT test) on
``Parts(n)`` with n per body chosen for a number of cells per subdomain (so H/h varies), on
the graded 2D Hertz mesh H2, the graded 3D rigid sphere S2 (docs/peers.md) and a user's
graded DOLFINx box (``bench/graded_box.py``, ``create_box`` + ``from_dolfinx``). Each row:
the case, the cells per subdomain aimed at, the subdomains, and per method the
F-multiplications, the set-up (wall, the report's phases) and the total CPU time of
``df.solve`` (the largest over the ranks; each rank one thread: on an idle machine its wall
time — on a shared machine the CPU time is what a comparison can trust; ``wall`` in the JSON).
The fewest seconds of a case show where the cost is lowest: the rule of
:mod:`dolfinx_feti.mesh.auto_parts` and :func:`dolfinx_feti.setup.stages.choose_method`.

Run: ``python bench/auto_decomposition.py`` (serial, ~15 min on an idle machine);
``mpirun -n 2 python bench/auto_decomposition.py --out output/bench/auto_decomposition_np2.md``
for 2 ranks; ``--cases H2 --cells 1000,4000`` for a part. Writes
``output/bench/auto_decomposition.md`` and ``.json``.
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

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
import common as C  # noqa: E402  (bench/peers/common.py)
import graded_box as G  # noqa: E402

import problems as P  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
METHODS = ("tfeti", "feti1", "fetidp")
#: The phases of the report's timings that are not the set-up.
SOLVE_PHASES = ("iterations", "recovery", "stopping test", "total")


def build(case: str, dec) -> df.ContactProblem:
    """The case's problem with decomposition ``dec``."""
    if case.startswith("H"):
        h, h_far = C.HERTZ_LEVELS[case]
        return P.hertz2d(h_contact=h, h_far=h_far, decomposition=dec)
    if case.startswith("S"):
        p = C.sphere_problem(case, 1)
        return df.ContactProblem(p.mesh, p.forms, dirichlet=p.dirichlet, contact=p.contact,
                                 decomposition=dec)
    return G.box_problem(int(case[3:]), dec)


def parts_for(mesh: df.MeshData, cells: int, balance: str) -> df.Parts:
    """Parts(n, balance) with n per body the body's cells over ``cells`` (at least 1)."""
    count = np.bincount(mesh.cell_body, minlength=len(mesh.body_names))
    return df.Parts({name: max(1, round(int(c) / cells))
                     for name, c in zip(mesh.body_names, count, strict=True)}, balance=balance)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cases", default="H2,S2,box24")
    parser.add_argument("--cells", default="1000,2500,5000,10000,20000")
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--balance", default="volume", choices=("cells", "volume"))
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/auto_decomposition.md")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    for case in args.cases.split(","):
        mesh = build(case, df.ByTags()).mesh
        for cells in (int(c) for c in args.cells.split(",")):
            dec = parts_for(mesh, cells, args.balance)
            row = {"case": case, "cells": int(mesh.cells.shape[0]), "per_sub": cells}
            for method in args.methods.split(","):
                problem = build(case, dec)
                t0, c0 = time.perf_counter(), time.process_time()
                sol = df.solve(problem, comm=comm, rtol=args.rtol, method=method, max_it=20000)
                t = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
                cpu = comm.allreduce(time.process_time() - c0, op=MPI.MAX)
                r = sol.report
                row["subdomains"] = r.sizes["subdomains"]
                row["dofs"] = r.sizes["primal"]
                setup = sum(v for k, v in r.timings.items() if k not in SOLVE_PHASES)
                row[method] = {"F_mults": r.hessian_mults, "time": round(cpu, 2),
                               "wall": round(t, 2),
                               "setup": None if setup is None else round(setup, 2),
                               "converged": r.converged}
            rows.append(row)
            if comm.rank == 0:
                print(json.dumps(row), flush=True)
    if comm.rank != 0:
        return
    methods = args.methods.split(",")
    lines = [f"Cells per subdomain against time, Parts(n, balance={args.balance!r}), "
             f"rtol {args.rtol:g}, {comm.size} rank(s): "
             "F-mults / set-up [s] / total CPU [s]; the least total of a case in bold", "",
             "| case | cells | primal dofs | cells per subdomain | subdomains | "
             + " | ".join(methods) + " |", "|---" * (5 + len(methods)) + "|"]
    best = {c: min(r[m]["time"] for r in rows if r["case"] == c for m in methods)
            for c in {r["case"] for r in rows}}

    def cell(r, m):
        t = r[m]["time"]
        return f"{r[m]['F_mults']} / {r[m]['setup']} / " + \
            (f"**{t}**" if t == best[r["case"]] else f"{t}") + \
            ("" if r[m]["converged"] else " (not converged)")

    lines += [f"| {r['case']} | {r['cells']} | {r['dofs']} | {r['per_sub']} | {r['subdomains']} | "
              + " | ".join(cell(r, m) for m in methods) + " |" for r in rows]
    P.write_outputs(args.out, lines, rows)


if __name__ == "__main__":
    main()
