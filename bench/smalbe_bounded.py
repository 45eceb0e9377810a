"""Bounded counts on B1: SMALBE's outer iterations and F-multiplications per halving of H.

B1 (Dostál's two membranes, ``problems.b1``) at fixed H/h, H = 1/4, 1/8, 1/16, solved under the
dual stopping test at rtol 1e-6 (the seed's test) with SMALBE's defaults (ρ = 1.1, M = 1
relative to ‖PFP‖, η = 0.1‖b‖: the parameters are already scaled by ‖PFP‖ and ‖b‖, as the
seed scales b by 1/‖PFP‖) and variants: a larger ρ, a smaller M, a larger η, no Anderson
acceleration, the Dirichlet preconditioner. Each cell: outer·F-mults; the last column the
growth of the default's F-mults per halving of H.

Run: ``python bench/smalbe_bounded.py --ratio 8`` (~1 min); ``--ratio 16`` (~5 min);
``--variants rho`` for ρ of order 10–1000 with M, η and the Dirichlet preconditioner;
``--stop-test kkt`` for the library's default stopping test; ``--method`` (default tfeti,
passed explicitly: the library's default method may change).
Writes ``output/bench/smalbe_bounded_<ratio>.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mpi4py import MPI

import dolfinx_feti as df

sys.path.insert(0, str(Path(__file__).resolve().parent))
import problems as P  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
VARIANTS = {"default": {}, "ρ = 10": {"smalbe_rho": 10.0}, "M = 0.1": {"smalbe_M": 0.1},
            "η = ‖b‖": {"smalbe_eta": 1.0}, "no Anderson": {"smalbe_acceleration": "none"},
            "Dirichlet": {"preconditioner": "dirichlet"}}
#: More scalings of SMALBE (``--variants rho``): ρ of order 10–1000 ‖PFP‖, with M and η.
RHO_VARIANTS = {"default": {}, "ρ = 10": {"smalbe_rho": 10.0},
                "ρ = 100": {"smalbe_rho": 100.0}, "ρ = 1000": {"smalbe_rho": 1000.0},
                "ρ = 100, M = 10": {"smalbe_rho": 100.0, "smalbe_M": 10.0},
                "ρ = 10, η = 0.01": {"smalbe_rho": 10.0, "smalbe_eta": 0.01},
                "ρ = 10, Dirichlet": {"smalbe_rho": 10.0, "preconditioner": "dirichlet"}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ratio", type=int, default=8, help="H/h")
    parser.add_argument("--levels", default="4,8,16", help="1/H of each level")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--method", default="tfeti", help="FETI method (passed explicitly)")
    parser.add_argument("--stop-test", default="dual", help="'dual' (the seed's) or 'kkt'")
    parser.add_argument("--variants", default="issue", help="'issue' or 'rho' (RHO_VARIANTS)")
    args = parser.parse_args()
    variants = RHO_VARIANTS if args.variants == "rho" else VARIANTS
    out = args.out or ROOT / f"output/bench/smalbe_bounded_{args.ratio}.md"
    comm = MPI.COMM_WORLD
    rows, last = [], None
    for inv_H in (int(v) for v in args.levels.split(",")):
        problem = P.b1(args.ratio * inv_H, 1.0 / inv_H)
        row = {"H": f"1/{inv_H}", "dofs": None}
        for name, kw in variants.items():
            r = df.solve(problem, comm=comm, rtol=1e-6, stop_test=args.stop_test,
                         method=args.method, **kw).report
            row["dofs"] = r.sizes["primal"]
            row[name] = (r.outer_iterations, r.hessian_mults)
        mults = row["default"][1]
        row["growth"] = None if last is None else round(mults / last, 2)
        last = mults
        rows.append(row)
        if comm.rank == 0:
            print(row, flush=True)
    if comm.rank != 0:
        return
    lines = [f"B1, H/h = {args.ratio}, rtol 1e-6 ({args.stop_test} test), {args.method}, "
             f"{comm.size} rank(s): outer·F-mults",
             "", "| H | primal dofs | " + " | ".join(variants) + " | default's growth |",
             "|---|---|" + "---|" * (len(variants) + 1)]
    lines += [f"| {r['H']} | {r['dofs']} | "
              + " | ".join(f"{r[v][0]}·{r[v][1]}" for v in variants)
              + f" | {r['growth'] or '–'} |" for r in rows]
    P.write_outputs(out, lines, rows)


if __name__ == "__main__":
    main()
