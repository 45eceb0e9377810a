"""Peak memory per rank on 1, 2, 4, 8 ranks: fixed problem and fixed work per rank.

B1 (two membranes), ``Parts`` decomposition (coordinate bisection) per membrane:

- fixed problem (``--fixed n parts``, default 512 64): n squares per membrane side,
  Parts(parts) per membrane (532 512 primal dofs, 128 subdomains) on every number of ranks;
- fixed work per rank (``--weak n0 parts0``, default 181 8): n ≈ n0·√ranks,
  Parts(parts0·ranks) per membrane (≈ 66 000 dofs and 16 subdomains per rank, H/h ≈ 64).

Per rank: the peak resident set size (VmHWM) after the mesh is built (gmsh on rank 0, the
arrays broadcast, or with ``--root-only`` kept on rank 0: ``replicate=False``) and after the
solve (``df.solve``, rtol 1e-6), and the growth in between (what the FETI data add); "ranks
> 0" is the largest peak of the ranks that did not read the mesh. Beyond 2 ranks the 2 cores
are oversubscribed: memory, not time, is the figure. The driver starts one ``mpirun`` per
case:

    python bench/memory_scaling.py                 # both tables, ~10 min
    python bench/memory_scaling.py --ranks 1 2     # fewer cases
    python bench/memory_scaling.py --fixed 362 32 --weak 128 8   # smaller (docs/benchmarks.md)
    python bench/memory_scaling.py --root-only     # the mesh on rank 0 only
    python bench/memory_scaling.py --distribute    # no rank holds the whole mesh
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def vm_hwm_mib() -> float:
    """Peak resident set size of this process so far (MiB)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return math.nan


def worker(n: int, parts: int, layout: int) -> None:
    from mpi4py import MPI

    sys.path.insert(0, str(ROOT / "bench"))
    import dolfinx_feti as df
    import problems as P
    from dolfinx_feti.io import meshes

    comm = MPI.COMM_WORLD
    base = vm_hwm_mib()
    # layout 0: replicated, 1: rank 0 only (replicate=False), 2: distribute=True
    mesh = df.build_mesh(meshes.membranes, n, replicate=layout == 0, distribute=layout == 2)
    after_mesh = vm_hwm_mib()
    sol = df.solve(df.ContactProblem(
        mesh, df.Poisson(source=P.b1_source), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=df.Parts(parts)),
        rtol=1e-6)
    after_solve = vm_hwm_mib()
    rec = {"rank": comm.rank, "start": base, "mesh": after_mesh, "solve": after_solve,
           "primal": sol.report.sizes["primal"], "subdomains": sol.report.sizes["subdomains"],
           "converged": sol.report.converged, "mults": sol.report.hessian_mults}
    recs = comm.gather(rec, root=0)
    if comm.rank == 0:
        print("RESULT " + json.dumps(recs), flush=True)


def run_case(ranks: int, n: int, parts: int, layout: int) -> list[dict]:
    cmd = ["mpirun", "-n", str(ranks), "--allow-run-as-root", "--oversubscribe",
           sys.executable, __file__, "--worker", str(n), str(parts), str(layout)]
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True).stdout
    line = next(ln for ln in out.splitlines() if ln.startswith("RESULT "))
    return json.loads(line[len("RESULT "):])


def table(title: str, cases: list[tuple[int, int, int, list[dict]]]) -> str:
    lines = [f"**{title}**", "",
             "| ranks | n | subdomains | primal dofs | dofs / rank | F-mults | peak after mesh "
             "[MiB] (max / mean) | peak after solve [MiB] (max / mean / ranks > 0) | solve − "
             "mesh [MiB] (max / mean) |", "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for ranks, n, _, recs in cases:
        m = np.array([r["mesh"] for r in recs])
        s = np.array([r["solve"] for r in recs])
        d = s - m
        r0 = recs[0]
        lines.append(f"| {ranks} | {n} | {r0['subdomains']} | {r0['primal']} | "
                     f"{r0['primal'] // ranks} | {r0['mults']} | {m.max():.0f} / {m.mean():.0f} | "
                     f"{s.max():.0f} / {s.mean():.0f} / "
                     f"{s[1:].max() if s.size > 1 else float('nan'):.0f} | "
                     f"{d.max():.0f} / {d.mean():.0f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worker", nargs=3, type=int, help=argparse.SUPPRESS)
    ap.add_argument("--root-only", action="store_true",
                    help="read the mesh with replicate=False (the arrays on rank 0 only)")
    ap.add_argument("--distribute", action="store_true",
                    help="read the mesh with distribute=True (every rank a block of cells)")
    ap.add_argument("--ranks", nargs="*", type=int, default=[1, 2, 4, 8])
    ap.add_argument("--fixed", nargs=2, type=int, default=[512, 64], metavar=("N", "PARTS"))
    ap.add_argument("--weak", nargs=2, type=int, default=[181, 8], metavar=("N0", "PARTS0"))
    ap.add_argument("--json", type=Path, default=ROOT / "output/bench/memory_scaling.json")
    args = ap.parse_args()
    if args.worker:
        worker(*args.worker)
        return
    layout = 2 if args.distribute else 1 if args.root_only else 0
    fixed, weak = [], []
    for r in args.ranks:
        fn, fp = args.fixed
        fixed.append((r, fn, fp, run_case(r, fn, fp, layout)))
        print(table("fixed", fixed[-1:]).splitlines()[-1], flush=True)
        n0, p0 = args.weak
        n = int(round(n0 * math.sqrt(r)))
        weak.append((r, n, p0 * r, run_case(r, n, p0 * r, layout)))
        print(table("weak", weak[-1:]).splitlines()[-1], flush=True)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"fixed": fixed, "weak": weak}, indent=1))
    print(table(f"Fixed problem: B1 n = {args.fixed[0]}, Parts({args.fixed[1]}) per membrane",
                fixed))
    print()
    print(table(f"Fixed work per rank: n ≈ {args.weak[0]}·√ranks, Parts({args.weak[1]}·ranks) "
                "per membrane", weak))


if __name__ == "__main__":
    main()
