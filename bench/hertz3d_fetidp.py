"""The seed's FETI-DP 3D Hertz case on our 3D Hertz problem, every method side by side.

The seed (Dostál et al.): 55 666 dofs, 47 iterations, 61 matrix-vector products. Ours: the
rigid sphere pressed into an elastic quarter block of docs/peers.md (levels S1–S4; S3 ≈ 50k
dofs).

The block is held at its bottom and on its symmetry planes, so FETI-DP's K̃ is definite and
the contact problem is a bound-constrained QP for MPRGP alone. Counts: F-multiplications
(the matrix-vector products with the dual operator) and the solve time, at the given rtol
(the stopping test ||g^P|| <= rtol ||b||), and the largest difference of u to the TFETI
solution relative to max |u|.

Run: ``python bench/hertz3d_fetidp.py --level S3 --parts 4,8,16`` (~5 min). Writes
``output/bench/hertz3d_fetidp.md`` and ``.json``.
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

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--level", default="S3", choices=sorted(C.SPHERE_LEVELS))
    parser.add_argument("--parts", default="4,8,16")
    parser.add_argument("--methods", default="fetidp,feti1,tfeti")
    parser.add_argument("--rtol", type=float, default=1e-5)
    parser.add_argument("--variants", default="default",
                        help="option sets, comma-separated: 'default' or "
                             "'<preconditioner>+<mprgp expansion>', e.g. 'dirichlet+projcg'")
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/hertz3d_fetidp.md")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows, base = [], {}
    for parts in (int(p) for p in args.parts.split(",")):
        for method, variant in ((m, v) for m in args.methods.split(",")
                                for v in args.variants.split(",")):
            kw = {} if variant == "default" else dict(zip(
                ("preconditioner", "mprgp_expansion"), variant.split("+"), strict=True))
            t0 = time.perf_counter()
            problem = C.sphere_problem(args.level, parts)
            sol = df.solve(problem, comm=comm, rtol=args.rtol, method=method, max_it=20000,
                           **kw)
            t = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
            r = sol.report
            u = sol.nodal_values()
            base.setdefault(parts, u)
            row = {"level": args.level, "parts": parts, "method": method, "variant": variant,
                   "dofs": 3 * problem.mesh.num_nodes,
                   "primal": r.sizes["primal"], "dual": r.sizes.get("dual_method",
                                                                    r.sizes["dual"]),
                   "corners": r.sizes.get("corner_nodes", ""), "solver": r.solver,
                   "iterations": r.iterations, "F_mults": r.hessian_mults,
                   "total": round(t, 2), "converged": r.converged,
                   "diff_to_first": float(np.abs(u - base[parts]).max() / np.abs(u).max())}
            rows.append(row)
            if comm.rank == 0:
                print(json.dumps(row), flush=True)
    if comm.rank != 0:
        return
    lines = [f"3D Hertz (rigid sphere, level {args.level}, {rows[0]['dofs']} dofs), rtol "
             f"{args.rtol:g}, {comm.size} rank(s); seed (FETI-DP): 55 666 dofs, 47 iterations, "
             "61 matrix-vector products", "",
             "| Parts | method | options | primal | dual | corners | solver | iterations | "
             "F-mults | total [s] | u vs first |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['parts']} | {r['method']} | {r['variant']} | {r['primal']} | "
                     f"{r['dual']} | {r['corners']} | {r['solver']} | {r['iterations']} | "
                     f"{r['F_mults']} | {r['total']} | {r['diff_to_first']:.1e} |"
                     + ("" if r["converged"] else " (not converged)"))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    args.out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
