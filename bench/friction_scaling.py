"""Iterations with Tresca friction against frictionless contact as the subdomains multiply (B4).

The seed reports for its FETI-DP 2D contact benchmark 50 → 107 iterations frictionless and
63 → 187 with Tresca friction for 16 → 900 subdomains. Here: Total FETI + SMALBE-M + MPRGP
(box bounds on the tangential multipliers) on benchmark B4 (``demos/demo_tresca2d.py``: a
block [1,3]×[0,1] pressed on a foundation [0,4]×[−1,0] and sheared, E = 21.19, ν = 0.277, top
displaced by (0.02, −0.02), Tresca g = 0.1), both bodies cut into a regular grid of H×H
squares with H/h fixed, for several H. Each row: subdomains, primal and dual sizes, and for
the frictionless and the Tresca solve the SMALBE outer iterations, the F-multiplications and
the solve time; plus the share of slipping contact nodes.

Run: ``python bench/friction_scaling.py`` (``--help``; under ``mpirun -n N`` for speed, the
counts do not depend on N). Writes ``output/bench/friction_scaling.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

ROOT = Path(__file__).resolve().parent.parent
E, NU, SHIFT = 21.19, 0.277, (0.02, -0.02)


def grid(H: float) -> df.ByFunction:
    """Regular H×H squares (on cell midpoints); block and foundation never share a label."""
    def label(m):
        i = np.floor(m[:, 0] / H + 1e-9).astype(np.int64)
        j = np.floor((m[:, 1] + 1.0) / H + 1e-9).astype(np.int64)
        return i + 100000 * j
    return df.ByFunction(label)


def run(H: Fraction, hh: int, g: float, rtol: float, comm, method: str = "tfeti",
        preconditioner: str | None = None, expansion: str | None = None) -> dict:
    n = int(hh / H)  # elements per unit length
    mesh = df.build_mesh(meshes.tresca2d, n=n, comm=comm)
    row = {"H": str(H), "H/h": hh, "n": n, "method": method,
           "preconditioner": preconditioner or "default", "expansion": expansion or "default"}
    for name, friction in (("frictionless", None), ("tresca", df.Tresca(g))):
        problem = df.ContactProblem(
            mesh, df.Elasticity(E, NU),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=SHIFT)],
            contact=[df.NodeToNode("block_bottom", "foundation_top", friction=friction)],
            decomposition=grid(float(H)))
        t0 = time.perf_counter()
        sol = df.solve(problem, comm=comm, rtol=rtol, max_it=20000, max_outer=1000,
                       method=method, preconditioner=preconditioner,
                       mprgp_expansion=expansion)
        t = time.perf_counter() - t0
        r = sol.report
        row.update({"subdomains": r.sizes["subdomains"], "primal": r.sizes["primal"],
                    "dual": r.sizes.get("dual_method", r.sizes["dual"]),
                    "contact_nodes": r.sizes["inequality"],
                    "corners": r.sizes.get("corner_nodes", "")})
        row[name] = {"converged": r.converged, "outer": r.outer_iterations,
                     "iterations": r.iterations, "hessian_mults": r.hessian_mults,
                     "time": round(t, 3)}
        if friction is not None:
            st = sol.contact.state
            row[name]["slip_share"] = float(np.mean(st == df.ContactData.SLIP))
    return row


def main() -> None:
    """Sweep H and write the table."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--hh", type=int, default=8, help="H/h, elements per subdomain side")
    parser.add_argument("--H", type=str, default="1/2,1/4,1/6,1/8,1/10",
                        help="subdomain sizes (comma-separated fractions)")
    parser.add_argument("--g", type=float, default=0.1, help="Tresca slip bound")
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--methods", type=str, default="tfeti",
                        help="FETI methods, comma-separated (tfeti, feti1, fetidp)")
    parser.add_argument("--preconditioners", type=str, default="default",
                        help="preconditioners, comma-separated ('default': the library's)")
    parser.add_argument("--expansion", type=str, default=None,
                        help="MPRGP's expansion step (fixed, optimal, projcg; default: the "
                             "library's)")
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/friction_scaling.md")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    for method in args.methods.split(","):
        for pre in args.preconditioners.split(","):
            for H in (Fraction(s) for s in args.H.split(",")):
                rows.append(run(H, args.hh, args.g, args.rtol, comm, method,
                                None if pre == "default" else pre, args.expansion))
                if comm.rank == 0:
                    print(json.dumps(rows[-1]), flush=True)
    lines = [
        f"B4, H/h = {args.hh}, Tresca g = {args.g}, rtol = {args.rtol:g}, {comm.size} rank(s), "
        f"MPRGP expansion {args.expansion or 'default'}",
        "",
        "| method | preconditioner | H | subdomains | primal dofs | dual dofs | corners | "
        "contact nodes | frictionless: outer / F-mults / s | Tresca: outer / F-mults / s | "
        "slipping |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        f, t = r["frictionless"], r["tresca"]
        lines.append(
            f"| {r['method']} | {r['preconditioner']} | {r['H']} | {r['subdomains']} | "
            f"{r['primal']} | {r['dual']} | {r['corners']} | "
            f"{r['contact_nodes']} | {f['outer']} / {f['hessian_mults']} / {f['time']:.2f} | "
            f"{t['outer']} / {t['hessian_mults']} / {t['time']:.2f} | "
            f"{100 * t['slip_share']:.0f} % |"
            + ("" if f["converged"] and t["converged"] else " (not converged)"))
    if comm.rank == 0:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("\n".join(lines) + "\n")
        args.out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
        print("\n".join(lines))


if __name__ == "__main__":
    main()
