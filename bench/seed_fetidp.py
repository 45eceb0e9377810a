"""The seed's FETI-DP table with nodal multipliers (Dostál et al.), and B1 by each method.

Table "fetidp": B1 (two membranes) on a regular H×H grid of subdomains, FETI-DP with nodal
multipliers, H/h × H as in the seed: primal dimension (all subdomain copies), dual dimension
(FETI-DP: gluing and contact rows, Dirichlet eliminated, corner gluing gone), corner nodes and
the F-multiplications, beside the seed's figures (``primal/dual/corners iterations``). The talk
gives two tables of that layout without saying what differs; both are shown. Ours: B1 as
specified (the left membrane floats: semicoercive FETI-DP, SMALBE on the natural coarse space)
and its coercive variant (``b1_held``: the right membrane also held, no coarse space, MPRGP
alone).

Table "methods": B1 with each method (TFETI, FETI-1, FETI-DP), the sizes of the seed's TFETI
table (docs/benchmarks.md § 1) that finish in minutes here: primal and dual dimensions, outer
iterations, F-multiplications, solve time.

Run: ``python bench/seed_fetidp.py`` (``--help``; ~3 min). Writes
``output/bench/seed_fetidp.md`` and ``.json``. The counts do not depend on the number of ranks.
"""

from __future__ import annotations

import argparse
import json
import time
from fractions import Fraction
from pathlib import Path

from mpi4py import MPI

import dolfinx_feti as df
from problems import b1, b1_held, elements_per_unit

ROOT = Path(__file__).resolve().parent.parent

#: The seed's two FETI-DP tables, (H/h, H) → (primal, dual, corners, iterations).
SEED = [{(4, "1/2"): (200, 33, 10, 17), (4, "1/4"): (800, 161, 42, 21),
         (4, "1/8"): (3200, 705, 154, 27), (8, "1/2"): (648, 73, 10, 22),
         (8, "1/4"): (2592, 369, 42, 36), (8, "1/8"): (10365, 1633, 154, 38),
         (16, "1/2"): (2312, 153, 10, 27), (16, "1/4"): (9248, 785, 42, 48),
         (16, "1/8"): (36992, 3489, 154, 51)},
        {(4, "1/2"): (200, 33, 10, 24), (4, "1/4"): (800, 161, 42, 24),
         (4, "1/8"): (3200, 705, 154, 31), (8, "1/2"): (648, 73, 10, 27),
         (8, "1/4"): (2592, 369, 42, 39), (8, "1/8"): (10365, 1633, 154, 46),
         (16, "1/2"): (2312, 153, 10, 41), (16, "1/4"): (9248, 785, 42, 57),
         (16, "1/8"): (36992, 3489, 154, 63)}]


def solve(problem, method: str, rtol: float, comm) -> dict:
    t0 = time.perf_counter()
    sol = df.solve(problem, comm=comm, rtol=rtol, method=method, max_it=20000, max_outer=1000)
    t = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    r = sol.report
    return {"method": method, "primal": r.sizes["primal"],
            "dual": r.sizes.get("dual_method", r.sizes["dual"]),
            "corners": r.sizes.get("corner_nodes", ""), "solver": r.solver,
            "outer": r.outer_iterations, "F_mults": r.hessian_mults, "time": round(t, 2),
            "converged": r.converged}


def cell(r: dict) -> str:
    s = f"{r['primal']}/{r['dual']}/{r['corners']} **{r['F_mults']}**"
    return s + ("" if r["converged"] else " (not converged)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--ratios", type=str, default="4,8,16", help="H/h of the FETI-DP table")
    parser.add_argument("--H", type=str, default="1/2,1/4,1/8")
    parser.add_argument("--method-ratios", type=str, default="8,32",
                        help="H/h of the table by method")
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/seed_fetidp.md")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    Hs = [Fraction(s) for s in args.H.split(",")]
    out: dict = {"rtol": args.rtol, "ranks": comm.size, "fetidp": [], "methods": []}
    for hh in (int(s) for s in args.ratios.split(",")):
        for H in Hs:
            n = elements_per_unit(float(H), hh)
            for variant, build in (("b1", b1), ("b1_held", b1_held)):
                row = {"H/h": hh, "H": str(H), "variant": variant,
                       **solve(build(n, float(H)), "fetidp", args.rtol, comm)}
                out["fetidp"].append(row)
                if comm.rank == 0:
                    print(json.dumps(row), flush=True)
    for hh in (int(s) for s in args.method_ratios.split(",")):
        for H in Hs:
            n = elements_per_unit(float(H), hh)
            for method in ("tfeti", "feti1", "fetidp"):
                row = {"H/h": hh, "H": str(H), **solve(b1(n, float(H)), method, args.rtol, comm)}
                out["methods"].append(row)
                if comm.rank == 0:
                    print(json.dumps(row), flush=True)
    if comm.rank != 0:
        return
    lines = [f"FETI-DP, B1 with nodal multipliers, rtol {args.rtol:g} (default options), "
             f"{comm.size} rank(s): primal/dual/corner nodes **F-mults**; the seed's "
             "primal/dual/corners iterations", "",
             "| H/h | H | B1 (semicoercive) | B1 held (coercive) | seed, 1st table | "
             "seed, 2nd table |", "|---|---|---|---|---|---|"]
    rows = {(r["H/h"], r["H"], r["variant"]): r for r in out["fetidp"]}
    for hh in (int(s) for s in args.ratios.split(",")):
        for H in Hs:
            seed = ["{}/{}/{} **{}**".format(*t[(hh, str(H))]) if (hh, str(H)) in t else ""
                    for t in SEED]
            lines.append(f"| {hh} | {H} | {cell(rows[hh, str(H), 'b1'])} | "
                         f"{cell(rows[hh, str(H), 'b1_held'])} | {seed[0]} | {seed[1]} |")
    lines += ["", f"B1 by method, rtol {args.rtol:g}: primal / dual, outer · F-mults, "
              "solve time [s]", "", "| H/h | H | method | primal | dual | solver | outer | "
              "F-mults | time |", "|---|---|---|---|---|---|---|---|---|"]
    for r in out["methods"]:
        lines.append(f"| {r['H/h']} | {r['H']} | {r['method']} | {r['primal']} | {r['dual']} | "
                     f"{r['solver']} | {r['outer']} | {r['F_mults']} | {r['time']} |"
                     + ("" if r["converged"] else " (not converged)"))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    args.out.with_suffix(".json").write_text(json.dumps(out, indent=1))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
