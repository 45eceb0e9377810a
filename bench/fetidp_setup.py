"""FETI-DP's corners and floating motions: rank 0 on the whole mesh vs a distributed mesh.

B1 (Dostál's two membranes, Poisson, node-to-node contact) on 2 × n² squares, H×H subdomains.
In one process, back to back, ``--repeat`` times each: the set-up of ``dual_qp(...,
method="fetidp")`` on the mesh read whole (``replicate=True``) and read with
``distribute=True``; timed are only the calls that make FETI-DP's data — the replicated
set-up's ``fetidp_parts`` (rank 0, the global arrays; what the other ranks waited for; the
library no longer runs it: it is the tests' oracle, ``tests/support/serial_setup.py``) and
the library's ``fem.distributed_corners.fetidp_share`` (the largest time over the ranks). Both
give the same corners (the script checks the counts). The medians are printed.

    mpirun -n 2 python bench/fetidp_setup.py                  # n = 512, H = 1/8
    mpirun -n 2 python bench/fetidp_setup.py --n 1024 --H 0.0625
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT.parent / "tests" / "support"))
import serial_setup  # noqa: E402

import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402
from dolfinx_feti.fem import distributed_corners  # noqa: E402
from dolfinx_feti.io import meshes  # noqa: E402

COMM = MPI.COMM_WORLD


def timed(module, name: str, spent: list) -> None:
    """Wrap ``module.name`` to append its wall time to ``spent``."""
    inner = getattr(module, name)

    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        out = inner(*args, **kwargs)
        spent.append(time.perf_counter() - t0)
        return out

    setattr(module, name, wrapper)


def problem(n: int, H: float, distribute: bool) -> df.ContactProblem:
    import gmsh

    if COMM.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        meshes.membranes(n)
    mesh = df.read_gmsh(None, COMM, distribute=distribute)
    if COMM.rank == 0:
        gmsh.finalize()
    return df.ContactProblem(
        mesh, df.Poisson(source=P.b1_source), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=P.grid(H))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=512, help="squares per membrane side")
    ap.add_argument("--H", type=float, default=1 / 8, help="subdomain size")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    spent: dict[str, list] = {"replicated": [], "distributed": []}
    timed(serial_setup, "fetidp_parts", spent["replicated"])
    timed(distributed_corners, "fetidp_share", spent["distributed"])
    whole, spread = problem(args.n, args.H, False), problem(args.n, args.H, True)
    infos = []
    for _ in range(args.repeat):
        for p, dual_qp in ((whole, serial_setup.serial_dual_qp), (spread, df.dual_qp)):
            COMM.Barrier()
            qp = dual_qp(p, method="fetidp")
            infos.append(qp.info)
            del qp
    if any(i != infos[0] for i in infos):
        raise AssertionError(f"the two set-ups chose other corners: {infos}")
    rep = float(np.median(COMM.bcast(spent["replicated"], root=0)))
    dist = float(np.median([COMM.allreduce(t, op=MPI.MAX) for t in spent["distributed"]]))
    if COMM.rank == 0:
        print(f"{COMM.size} rank(s), {P.machine()}\ncode: {P.git_state()}\n"
              f"B1 n={args.n}, H={args.H:g}, {whole.mesh.num_cells} cells: {infos[0]}\n"
              f"FETI-DP data, median of {args.repeat}: replicated (rank 0) {rep:.3f} s, "
              f"distributed (max over ranks) {dist:.3f} s")


if __name__ == "__main__":
    main()
