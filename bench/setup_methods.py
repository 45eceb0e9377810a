"""The set-up of each method on the same decomposition: FETI-DP's against TFETI's.

``FetiSolver(problem, method=...)`` alone (decomposition, rows, assembly, factorizations, the
dual operators, coarse problem and preconditioner; no iterations) on the graded rigid sphere
S2, the graded 2D Hertz H2 and the user's graded DOLFINx box (``bench/graded_box.py``), each
``Parts(n, balance="volume")``. CPU seconds of the process (the machine is shared: wall time
is not comparable), the least of ``--repeat`` runs, and the report's phases of that run.

Run: ``python bench/setup_methods.py`` (~3 min); ``--cases S2 --parts 8``.
Writes ``output/bench/setup_methods.md`` and ``.json``. ``--profile DIR``: also one more
set-up per case and method under cProfile with the process's CPU time as its clock (the
machine is shared), written to ``DIR/<case>_<method>.prof`` and its largest internal times
printed (read with ``pstats``).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

from mpi4py import MPI

import dolfinx_feti as df

sys.path.insert(0, str(Path(__file__).resolve().parent))
import auto_decomposition as A  # noqa: E402

import problems as P  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cases", default="S2,H2,box20")
    parser.add_argument("--parts", type=int, default=8)
    parser.add_argument("--methods", default="tfeti,feti1,fetidp")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/setup_methods.md")
    parser.add_argument("--profile", type=Path, default=None)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    for case in args.cases.split(","):
        problem = A.build(case, df.Parts(args.parts, balance="volume"))
        row = {"case": case, "parts": args.parts}
        for method in args.methods.split(","):
            best = float("inf")
            for _ in range(args.repeat):
                c0 = time.process_time()
                solver = df.FetiSolver(problem, comm=comm, method=method)
                best = min(best, comm.allreduce(time.process_time() - c0, op=MPI.MAX))
                del solver
            row[method] = round(best, 2)
            if args.profile is not None:
                _profile(problem, comm, method, args.profile / f"{case}_{method}.prof")
        rows.append(row)
        if comm.rank == 0:
            print(row, flush=True)
    if comm.rank != 0:
        return
    methods = args.methods.split(",")
    lines = [f"Set-up CPU [s] (FetiSolver alone), Parts({args.parts}, balance='volume'), "
             f"{comm.size} rank(s), least of {args.repeat}", "",
             "| case | " + " | ".join(methods) + " | FETI-DP / TFETI |",
             "|---|" + "---|" * (len(methods) + 1)]
    lines += [f"| {r['case']} | " + " | ".join(str(r[m]) for m in methods)
              + f" | {r['fetidp'] / r['tfeti']:.2f} |" for r in rows]
    P.write_outputs(args.out, lines, rows)


def _profile(problem, comm, method: str, path: Path) -> None:
    """One more set-up under cProfile (CPU clock), its stats to ``path``, the top printed."""
    path.parent.mkdir(parents=True, exist_ok=True)
    prof = cProfile.Profile(time.process_time)
    prof.enable()
    solver = df.FetiSolver(problem, comm=comm, method=method)
    prof.disable()
    del solver
    if comm.rank == 0:
        prof.dump_stats(str(path))
        print(f"--- {path.stem}: CPU {pstats.Stats(prof).total_tt:.2f} s", flush=True)
        pstats.Stats(prof).sort_stats("tottime").print_stats(8)


if __name__ == "__main__":
    main()
