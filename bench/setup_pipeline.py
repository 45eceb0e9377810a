"""The set-up's sharing stage: the one pipeline against the replicated set-up it replaced.

B1 (Dostál's two membranes, Poisson, node-to-node contact) on 2 × n² squares, H×H subdomains
(``ByFunction``), the mesh read whole (every rank; ``--root-only``: rank 0). In one process,
alternating ``--repeat`` times: ``setup.stages.share_problem`` (decomposition, dof points,
cells to their owners, rows, the shares: the library's one pipeline) and the replicated
set-up (rank 0 decomposes, builds every row and hands out the shares: the tests' oracle,
``tests/support/serial_setup.py``). Wall times (collective, between barriers); medians and
minima. Alternating in one process keeps the two under the same load on a shared machine.

    python bench/setup_pipeline.py                       # n = 512, H = 1/8
    mpirun -n 2 python bench/setup_pipeline.py --root-only
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

ROOT = Path(__file__).resolve().parent
sys.path[:0] = [str(ROOT.parent), str(ROOT), str(ROOT.parent / "tests" / "support")]
import serial_setup  # noqa: E402

import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402
from dolfinx_feti.io import meshes  # noqa: E402
from dolfinx_feti.setup.stages import share_problem  # noqa: E402
from dolfinx_feti.timing import Timer  # noqa: E402

COMM = MPI.COMM_WORLD


def main() -> None:
    import gmsh

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=512, help="squares per membrane side")
    ap.add_argument("--H", type=float, default=1 / 8, help="subdomain size")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--root-only", action="store_true")
    args = ap.parse_args()
    if COMM.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        meshes.membranes(args.n)
    mesh = df.read_gmsh(None, COMM, replicate=not args.root_only)
    if COMM.rank == 0:
        gmsh.finalize()
    problem = df.ContactProblem(
        mesh, df.Poisson(source=P.b1_source), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=P.grid(args.H))

    def timed(f) -> float:
        COMM.Barrier()
        t0 = time.perf_counter()
        f()
        COMM.Barrier()
        return time.perf_counter() - t0

    spent: dict[str, list[float]] = {"replicated (oracle)": [], "one pipeline": []}
    for _ in range(args.repeat):
        spent["replicated (oracle)"].append(
            timed(lambda: serial_setup.serial_share_problem(problem, COMM, "tfeti")))
        spent["one pipeline"].append(timed(lambda: share_problem(problem, COMM, "tfeti",
                                                                 Timer())))
    if COMM.rank == 0:
        print(f"{COMM.size} rank(s), {P.machine()}\ncode: {P.git_state()}\n"
              f"B1 n={args.n}, H={args.H:g}, {mesh.num_cells} cells, "
              f"{'root-only' if args.root_only else 'replicated'} mesh")
        for name, t in spent.items():
            print(f"  {name:22s} median {np.median(t):.3f} s, min {min(t):.3f} s")


if __name__ == "__main__":
    main()
