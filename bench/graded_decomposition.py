"""Decompositions of meshes graded toward the contact: Parts balancing cells or volume.

``Parts(n)`` cuts each body by recursive coordinate bisection into parts of equal cell count.
On a mesh graded toward the contact (the 2D Hertz meshes H1–H3 and the rigid sphere S1–S4 of
docs/peers.md) that puts many small subdomains where the contact is, and RCB pieces that fall
apart there (each piece a subdomain). ``Parts(n, balance="volume")`` makes the parts' volumes
equal instead. Each row: the mesh, n, the balance, the subdomains that result, and per method
the dual size, the F-multiplications and the total time.

Run: ``python bench/graded_decomposition.py`` (~10 min; ``--cases H1,S1`` for a shorter run).
Writes ``output/bench/graded_decomposition.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from mpi4py import MPI

import dolfinx_feti as df

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
import common as C  # noqa: E402  (bench/peers/common.py)

import problems as P  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def problem(case: str, parts: int, balance: str) -> df.ContactProblem:
    dec = df.Parts(parts, balance=balance)
    if case.startswith("H"):
        h, h_far = C.HERTZ_LEVELS[case]
        return P.hertz2d(decomposition=dec, h_contact=h, h_far=h_far)
    prob = C.sphere_problem(case, parts)
    return df.ContactProblem(prob.mesh, prob.forms, dirichlet=prob.dirichlet,
                             contact=prob.contact, decomposition=dec)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cases", default="H1,H2,S2")
    parser.add_argument("--parts", default="4,16")
    parser.add_argument("--methods", default="tfeti,fetidp")
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/graded_decomposition.md")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    for case in args.cases.split(","):
        for parts in (int(p) for p in args.parts.split(",")):
            for balance in ("cells", "volume"):
                row = {"case": case, "parts": parts, "balance": balance}
                for method in args.methods.split(","):
                    t0 = time.perf_counter()
                    prob = problem(case, parts, balance)
                    sol = df.solve(prob, comm=comm, rtol=args.rtol, method=method, max_it=20000)
                    t = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
                    r = sol.report
                    row["dofs"] = prob.value_size * prob.dof_points.num_points
                    row["subdomains"] = r.sizes["subdomains"]
                    row[method] = {"dual": r.sizes.get("dual_method", r.sizes["dual"]),
                                   "F_mults": r.hessian_mults, "time": round(t, 2),
                                   "converged": r.converged}
                rows.append(row)
                if comm.rank == 0:
                    print(json.dumps(row), flush=True)
    if comm.rank != 0:
        return
    methods = args.methods.split(",")
    lines = [f"Graded meshes, Parts(n, balance), rtol {args.rtol:g}, default options, "
             f"{comm.size} rank(s): dual / F-mults / total [s] per method", "",
             "| mesh | dofs | n per body | balance | subdomains | " + " | ".join(methods) + " |",
             "|---|---|---|---|---|" + "---|" * len(methods)]
    for r in rows:
        cells = [f"{r[m]['dual']} / {r[m]['F_mults']} / {r[m]['time']}"
                 + ("" if r[m]["converged"] else " (not converged)") for m in methods]
        lines.append(f"| {r['case']} | {r['dofs']} | {r['parts']} | {r['balance']} | "
                     f"{r['subdomains']} | " + " | ".join(cells) + " |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    args.out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
