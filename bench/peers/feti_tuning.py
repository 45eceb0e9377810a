"""FETI options on the peers' 3D rigid sphere (or 2D Hertz): F-multiplications, time, error.

A factorial sweep of ``preconditioner`` × ``preconditioner_scaling`` × ``mprgp_expansion`` ×
``smalbe_rho`` × ``Parts(k)``
(``expansion`` ``bb`` = ``mprgp_expansion='fixed', mprgp_alpha='bb'``) on one mesh level of
``bench/peers/common.py`` at one rtol. The F-multiplication counts are deterministic; times
are the minimum of ``--repeat`` solves on a shared machine (the load average is in the
header). Error = max(‖u − u*‖∞/‖u*‖∞, ‖λ − λ*‖∞/‖λ*‖∞) against the reference of ``run.py``
(sphere: SNES-VI at rtol 1e-14; Hertz: the PDAS solve of tests/support/reference.py; computed and
cached in output/peers/raw the first time).

    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/feti_tuning.py --level S1
    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/feti_tuning.py --level S2 --parts 8
    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/feti_tuning.py --level S3 --expansion fixed \
        --rho 1.1 --scaling multiplicity stiffness --tag scaling
    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/feti_tuning.py --level H1 ...   # 2D Hertz

Writes output/bench/feti_tuning_<level>.md and .json (one file per command; ``--tag`` names
it). ``--products`` only times one F and one PFP product per ``--parts`` value
(output/bench/feti_products_<level>.md).
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as C  # noqa: E402
import methods as M  # noqa: E402
import run as R  # noqa: E402

import dolfinx_feti as df  # noqa: E402

OUT = C.ROOT / "output" / "bench"


def feti_options(precond: str, expansion: str, rho: float,
                 scaling: str = "multiplicity") -> dict:
    opts = {"preconditioner": precond, "smalbe_rho": rho}
    if precond != "none":
        opts["preconditioner_scaling"] = scaling
    if expansion == "bb":
        opts.update(mprgp_expansion="fixed", mprgp_alpha="bb")
    else:
        opts["mprgp_expansion"] = expansion
    return opts


def make_problem(level: str, parts: int):
    """The sphere (S*) or 2D Hertz (H*) problem of the peers suite with ``Parts(parts)``."""
    return (C.hertz_problem if level.startswith("H") else C.sphere_problem)(level, parts)


def solve_one(level: str, parts: int, rtol: float, options: dict, mono, ref: dict,
              repeat: int) -> dict:
    best = None
    for _ in range(max(1, repeat)):
        prob = make_problem(level, parts)
        t = C.Clock()
        sol = df.solve(prob, rtol=rtol, **options)
        elapsed = t()
        if best is None:
            r = sol.report
            u = sol.nodal_values().ravel()
            lam = np.zeros(mono.nodes.size)
            pos = {int(n): i for i, n in enumerate(mono.nodes)}
            for n, f in zip(sol.contact.node, sol.contact.force, strict=True):
                lam[pos[int(n)]] = f
            best = {"t": elapsed, "t_iter": r.timings.get("iterations", 0.0),
                    "t_prec": r.timings.get("preconditioner", 0.0),
                    "mults": r.hessian_mults, "its": r.iterations,
                    "outer": r.outer_iterations, "converged": bool(r.converged),
                    "reason": r.reason, "dual": r.sizes["dual"],
                    **R.metrics("hertz" if level.startswith("H") else "sphere", mono,
                                ref, u, lam)}
        else:
            best["t"] = min(best["t"], elapsed)
            best["t_iter"] = min(best["t_iter"], sol.report.timings.get("iterations", 0.0))
        del sol
    return best


def time_products(level: str, parts_list, repeat: int = 20) -> list[str]:
    """Wall time of one F and one P F P product (mean of ``repeat``) per number of parts."""
    from mpi4py import MPI

    lines = ["| parts | dual size | F (ms) | P F P (ms) |", "|---|---|---|---|"]
    for parts in parts_list:
        qp = df.dual_qp(make_problem(level, parts), MPI.COMM_SELF)
        x, y = qp.b.copy(), qp.b.duplicate()
        x.setRandom()
        cells = []
        for A in (qp.feti.F, qp.A):
            A.mult(x, y)
            t = C.Clock()
            for _ in range(repeat):
                A.mult(x, y)
            cells.append(f"{1000 * t() / repeat:.1f}")
        lines.append(f"| {parts} | {qp.b.getSize()} | {cells[0]} | {cells[1]} |")
        print(lines[-1], flush=True)
        del qp
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--level", default="S1", choices=[*C.SPHERE_LEVELS, *C.HERTZ_LEVELS],
                        help="S1-S3: the 3D rigid sphere; H1-H3: 2D Hertz (two bodies)")
    parser.add_argument("--rtol", type=float, default=1e-8)
    parser.add_argument("--precond", nargs="*", default=["none", "lumped", "dirichlet"])
    parser.add_argument("--expansion", nargs="*", default=["fixed", "optimal", "projcg", "bb"])
    parser.add_argument("--rho", nargs="*", type=float, default=[1.1, 10.0, 100.0],
                        help="smalbe_rho (relative to ||PFP||)")
    parser.add_argument("--scaling", nargs="*", default=["multiplicity"],
                        help="preconditioner_scaling (multiplicity, stiffness); "
                             "ignored without a preconditioner")
    parser.add_argument("--parts", nargs="*", type=int, default=[4, 8, 16])
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--tag", default="")
    parser.add_argument("--products", action="store_true",
                        help="only time one F and one PFP product per number of parts")
    args = parser.parse_args()
    t0 = time.perf_counter()
    if args.products:
        lines = time_products(args.level, args.parts)
        md = [f"# One product on the rigid sphere {args.level}", "",
              f"Machine: {C.P.machine()}. Code: {C.code_state()}.",
              f"Command: `OMP_NUM_THREADS=1 python {' '.join(sys.argv)}`", "", *lines]
        OUT.mkdir(parents=True, exist_ok=True)
        (OUT / f"feti_products_{args.level}.md").write_text("\n".join(md) + "\n")
        return
    if args.level.startswith("H"):
        mono = C.hertz_monolithic(args.level)
        ref = R.reference("hertz", args.level, mono)
    else:
        mono = C.sphere_monolithic(args.level)
        ref = R.reference("sphere", args.level, mono, M.Rotated(mono))
    rows = []
    load0 = C.P.machine()
    for parts, precond, scaling, expansion, rho in itertools.product(
            args.parts, args.precond, args.scaling, args.expansion, args.rho):
        if precond == "none" and scaling != args.scaling[0]:
            continue  # the scaling only acts on a preconditioner
        opts = feti_options(precond, expansion, rho, scaling)
        r = solve_one(args.level, parts, args.rtol, opts, mono, ref, args.repeat)
        scaling = scaling if precond != "none" else "-"
        row = {"level": args.level, "ndofs": mono.ndofs, "parts": parts, "precond": precond,
               "scaling": scaling, "expansion": expansion, "smalbe_rho": rho,
               "rtol": args.rtol, **r}
        rows.append(row)
        print(f"{args.level} parts {parts:3d} {precond:9s} {scaling:12s} {expansion:8s} "
              f"rho {rho:6g}: "
              f"{r['mults']:5d} F-mults ({r['outer']} outer), {r['t']:6.2f} s "
              f"(iterations {r['t_iter']:.2f} s), err {r['err']:.1e}, "
              f"{'ok' if r['converged'] else 'NOT converged ' + r['reason']}", flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    name = f"feti_tuning_{args.level}{'_' + args.tag if args.tag else ''}"
    header = ["parts", "preconditioner", "scaling", "expansion", "smalbe_rho", "F-mults",
              "outer", "time (s)", "iterations (s)", "preconditioner (s)", "error (u, λ)",
              "converged"]
    table = [[r["parts"], r["precond"], r["scaling"], r["expansion"], f"{r['smalbe_rho']:g}",
              r["mults"], r["outer"], f"{r['t']:.2f}", f"{r['t_iter']:.2f}",
              f"{r['t_prec']:.2f}", f"{r['err']:.1e}",
              "yes" if r["converged"] else r["reason"]] for r in rows]
    what = "2D Hertz" if args.level.startswith("H") else "the rigid sphere"
    md = [f"# FETI options on {what} {args.level} ({mono.ndofs} free dofs), "
          f"rtol {args.rtol:g}", "",
          f"Machine at the start: {load0}; at the end: {C.P.machine()}. "
          f"Code: {C.code_state()}. "
          f"Run time {(time.perf_counter() - t0) / 60:.1f} min.",
          f"Command: `OMP_NUM_THREADS=1 python {' '.join(sys.argv)}`", "",
          C.P.md_table(header, table)]
    (OUT / f"{name}.md").write_text("\n".join(md) + "\n")
    (OUT / f"{name}.json").write_text(json.dumps(rows, indent=1, default=float))
    print("\n".join(md))


if __name__ == "__main__":
    main()
