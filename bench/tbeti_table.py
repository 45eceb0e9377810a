"""The seed's table "BETI for 2nd kind variational inequality", and TBETI against TFETI.

Table "seed": the unit square on a regular grid of H×H subdomains, H/h boundary elements along
each subdomain side, H ∈ {1/2, 1/4, 1/6, 1/8} and H/h ∈ {4, 8, 16, 24} as in the seed, solved
by Total BETI (``method="tbeti"``): the primal dimension (boundary unknowns: 4 H/h per
subdomain, exactly the seed's), the dual dimension, the solve time and the iterations (inner
MPRGP iterations; F-multiplications), beside the seed's ``primal/dual/time iterations``.

The problem. The seed's "2nd kind variational inequality" is a scalar problem with a
friction-type term, which the library does not take (friction needs a vector problem). We solve
its 1st-kind twin on the same square and the same subdomains: the square as two bodies,
(0,½)×(0,1) held at x = 0 and (½,1)×(0,1) floating, in scalar contact on x = ½
(u_left − u_right ≤ 0), loaded by fluxes only (boundary elements have no volume terms):
−1 on the right body's top and ¾ − y on its end x = 1 (net −¼), so the contact is active on
part of the interface. Total BETI: the Dirichlet conditions are rows of B, every subdomain floats.

Table "compare": the same problems by TBETI and by TFETI (P1 finite elements on the same
mesh, every subdomain's interior included): unknowns, dual dimension, F-multiplications, the
time of one F-multiplication (median of 20 on a random vector), set-up time (everything before
the iterations), solve time, and the relative difference of the two solutions (max norm of
the nodal values: the discretization error between the two methods).

Table "hertz": the 2D Hertz half model (B2, ``problems.hertz2d``: disk R = 8 on a block,
E = 200, ν = 0.3, line load P = 10; graded mesh, h = 0.05 at the contact) by both methods with
``Parts(k)``: the same columns, and the peak contact pressure against Hertz's
p₀ = (P E* / (π R))^½ = 6.612.

Run: ``python bench/tbeti_table.py`` (``--help``; ~2 min serial). Writes
``output/bench/tbeti_table.md`` and ``.json``. The counts do not depend on the number of ranks.
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
from dolfinx_feti.bem.models import split_square
from problems import hertz2d

#: Hertz's peak pressure of the 2D model of ``problems.hertz2d``.
P0_HERTZ = float(np.sqrt(10.0 * 200.0 / (2 * (1 - 0.3 ** 2)) / (np.pi * 8.0)))

ROOT = Path(__file__).resolve().parent.parent

#: The seed's table, (H/h, H) → (primal, dual, time [s], iterations).
SEED = {(24, "1/2"): (384, 100, 0.04, 14), (24, "1/4"): (1536, 592, 0.86, 21),
        (24, "1/6"): (3456, 1476, 9.40, 25), (24, "1/8"): (6144, 2752, 25.40, 25),
        (16, "1/2"): (256, 68, 0.02, 10), (16, "1/4"): (1024, 400, 0.36, 14),
        (16, "1/6"): (2304, 996, 2.54, 20), (16, "1/8"): (4096, 1856, 6.50, 17),
        (8, "1/2"): (128, 36, 0.02, 8), (8, "1/4"): (512, 208, 0.12, 11),
        (8, "1/6"): (1152, 516, 0.59, 15), (8, "1/8"): (2048, 960, 1.52, 12),
        (4, "1/2"): (64, 20, 0.04, 7), (4, "1/4"): (256, 112, 0.06, 9),
        (4, "1/6"): (576, 276, 0.17, 10), (4, "1/8"): (1024, 512, 0.39, 10)}


def grid(H: Fraction) -> df.ByFunction:
    """Subdomains: the H×H squares of the unit square."""
    k = int(1 / H)
    h = float(H)
    return df.ByFunction(
        lambda m: (np.floor(m[:, 0] / h) + k * np.floor(m[:, 1] / h)).astype(np.int64))


def end_flux(x):
    """The flux on x = 1: 3/4 − y (UFL or NumPy coordinates)."""
    return 0.75 - 1.0 * x[1]


def problem(mesh, H: Fraction) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.Poisson(0.0, flux={"top_right": -1.0, "end": end_flux}),
        dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=grid(H))


def time_F(make, method: str, comm, repeat: int = 20) -> float:
    """Median time of one F-multiplication (seconds)."""
    qp = df.dual_qp(make(), comm, method=method)
    F = qp.feti.F
    x = F.createVecRight()
    x.setRandom()
    y = F.createVecLeft()
    times = []
    for _ in range(repeat):
        comm.Barrier()
        t0 = time.perf_counter()
        F.mult(x, y)
        times.append(comm.allreduce(time.perf_counter() - t0, op=MPI.MAX))
    return float(np.median(times))


def run(make, method: str, rtol: float, comm) -> dict:
    t0 = time.perf_counter()
    sol = df.solve(make(), comm=comm, rtol=rtol, method=method, max_it=20000)
    total = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    r = sol.report
    it = r.timings.get("iterations", 0.0)
    return {"method": method, "unknowns": r.sizes.get("boundary_dofs", r.sizes["primal"]),
            "dual": r.sizes["dual"], "iterations": r.iterations, "outer": r.outer_iterations,
            "F_mults": r.hessian_mults, "solve": round(it, 3),
            "setup": round(total - it, 3), "total": round(total, 3),
            "converged": r.converged, "active": int((sol.contact.force > 0).sum()),
            "p_max": float(sol.contact.pressure.max()), "u": sol.nodal_values()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--ratios", type=str, default="24,16,8,4", help="H/h")
    parser.add_argument("--H", type=str, default="1/2,1/4,1/6,1/8")
    parser.add_argument("--parts", type=str, default="2,4,8,16", help="Hertz: Parts(k)")
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/tbeti_table.md")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    Hs = [Fraction(s) for s in args.H.split(",")]
    rows = []
    for hh in (int(s) for s in args.ratios.split(",")):
        for H in Hs:
            cells = int(hh / H)
            mesh = df.build_mesh(split_square, cells, comm=comm)

            def make(mesh=mesh, H=H):
                return problem(mesh, H)

            res = {m: run(make, m, args.rtol, comm) for m in ("tbeti", "tfeti")}
            rows.append({"ratio": hh, "H": str(H), "seed": SEED.get((hh, str(H))),
                         **compare(make, res, comm)})
            if comm.rank == 0:
                t, f = res["tbeti"], res["tfeti"]
                print(f"H/h={hh} H={H}: TBETI {t['unknowns']}/{t['dual']} "
                      f"{t['iterations']} it {t['F_mults']} F {t['total']} s; TFETI "
                      f"{f['unknowns']}/{f['dual']} {f['F_mults']} F {f['total']} s; "
                      f"diff {rows[-1]['diff']:.1e}", flush=True)
    hertz = []
    for k in (int(s) for s in args.parts.split(",") if s):
        def make(k=k):
            return hertz2d(k)

        make()  # the mesh, built once and cached: not in the timings

        res = {m: run(make, m, args.rtol, comm) for m in ("tbeti", "tfeti")}
        hertz.append({"parts": k, **compare(make, res, comm)})
        if comm.rank == 0:
            t, f = res["tbeti"], res["tfeti"]
            print(f"Hertz Parts({k}): TBETI {t['F_mults']} F p_max {t['p_max']:.4f}; TFETI "
                  f"{f['F_mults']} F p_max {f['p_max']:.4f}", flush=True)
    if comm.rank == 0:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.with_suffix(".json").write_text(json.dumps(
            {"rtol": args.rtol, "ranks": comm.size, "rows": rows, "hertz": hertz}, indent=1))
        args.out.write_text(markdown(rows, Hs, args) + hertz_markdown(hertz))


def compare(make, res: dict, comm) -> dict:
    """The difference of the two solutions and the time of one F-multiplication of each."""
    a, b = res["tfeti"].pop("u"), res["tbeti"].pop("u")
    diff = float(np.abs(a - b).max() / np.abs(a).max())
    for m in res:
        res[m]["time_F"] = time_F(make, m, comm)
    return {"diff": diff, **res}


def method_cells(t: dict) -> str:
    """Unknowns, dual, F-mults, time per F [ms], set-up and solve [s] of one run."""
    return (f"{t['unknowns']} | {t['dual']} | {t['F_mults']} | {1e3 * t['time_F']:.3f} | "
            f"{t['setup']} | {t['solve']}")


def hertz_markdown(hertz: list[dict]) -> str:
    lines = ["", "## 2D Hertz (B2) by TBETI and TFETI", "",
             "| Parts | method | unknowns | dual | F-mults | time/F [ms] | set-up [s] | "
             f"solve [s] | p_max (Hertz {P0_HERTZ:.3f}) | diff |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in hertz:
        lines += [f"| {r['parts']} | {m} | {method_cells(r[m])} | {r[m]['p_max']:.4f} | "
                  f"{r['diff']:.1e} |" for m in ("tbeti", "tfeti")]
    return "\n".join(lines) + "\n"


def markdown(rows: list[dict], Hs: list[Fraction], args) -> str:
    by = {(r["ratio"], r["H"]): r for r in rows}
    ratios = sorted({r["ratio"] for r in rows}, reverse=True)
    head = "| H/h \\ H | " + " | ".join(f"{H} ours | {H} seed" for H in Hs) + " |\n|---|" + \
        "---|" * (2 * len(Hs))
    lines = ["## TBETI: primal/dual/time [s] inner iterations (ours: and F-mults)", "", head]
    for hh in ratios:
        cells = []
        for H in Hs:
            r = by.get((hh, str(H)))
            if r is None:
                cells += ["", ""]
                continue
            t, s = r["tbeti"], r["seed"]
            seed = f"{s[0]}/{s[1]}/{s[2]} {s[3]}" if s else "–"
            cells += [f"{t['unknowns']}/{t['dual']}/{t['total']} {t['iterations']}, "
                      f"{t['F_mults']} F", seed]
        lines.append(f"| {hh} | " + " | ".join(cells) + " |")
    lines += ["", "## TBETI against TFETI", "",
              "| H/h | H | method | unknowns | dual | F-mults | time/F [ms] | set-up [s] | "
              "solve [s] | active | diff |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines += [f"| {r['ratio']} | {r['H']} | {m} | {method_cells(r[m])} | {r[m]['active']} | "
                  f"{r['diff']:.1e} |" for m in ("tbeti", "tfeti")]
    lines += ["", f"rtol {args.rtol}; `python bench/tbeti_table.py`"]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
