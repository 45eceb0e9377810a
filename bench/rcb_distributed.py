"""Distributed recursive coordinate bisection (``rcb_distributed``) against the serial ``rcb``.

Each rank holds a contiguous block of the points (by id), as after the scatter of the cells;
the distributed bisection must give exactly the serial labels (checked here on every run).
Two point sets of about 10^6 points: random points in [0, 2] × [0, 1] × [0, 1], and the
integer grid 100 × 100 × 100 (whole planes of equal coordinates: the ties are broken by the
levels above). Printed per case: the wall time of the serial ``rcb`` on the whole set (rank 0
alone), the wall time of ``rcb_distributed`` (the slowest rank) and its number of collective
calls (every rank makes the same ones)::

    mpirun -n 1 .venv/bin/python bench/rcb_distributed.py
    mpirun -n 2 --oversubscribe .venv/bin/python bench/rcb_distributed.py
    mpirun -n 2 --oversubscribe .venv/bin/python bench/rcb_distributed.py --points 200000 \
        --parts 4 64
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from mpi4py import MPI

from dolfinx_feti.mesh.decompose import rcb
from dolfinx_feti.mesh.distributed_decompose import rcb_distributed
from dolfinx_feti.parallel.exchange import Blocks


class Counting:
    """A communicator that counts the collective calls made through it."""

    def __init__(self, comm: MPI.Comm):
        self.comm, self.calls = comm, 0

    def __getattr__(self, name: str):
        attr = getattr(self.comm, name)
        if name[0].isupper() or name in ("allgather", "gather", "exscan"):
            self.calls += 1
        return attr


def point_sets(m: int) -> dict[str, np.ndarray]:
    side = round(m ** (1 / 3))
    k = np.arange(side, dtype=np.float64)
    grid = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)[:, ::-1]
    return {"random": np.random.default_rng(0).random((m, 3)) * [2.0, 1.0, 1.0],
            "grid": np.ascontiguousarray(grid)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=10**6)
    parser.add_argument("--parts", type=int, nargs="+", default=[16, 256])
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        print(f"{comm.size} rank(s); serial = rcb on rank 0, distributed = the slowest rank")
        print(f"{'points':>8} {'set':>7} {'parts':>5} {'weights':>7} {'serial s':>9} "
              f"{'distr. s':>9} {'collectives':>11}")
    for name, pts in point_sets(args.points).items():
        m = pts.shape[0]
        ids = np.arange(*Blocks(m, comm.size).local(comm.rank).indices(m))
        w = np.random.default_rng(1).random(m) + 0.5
        for n in args.parts:
            for weights in (None, w):
                serial, ref = float("nan"), None
                if comm.rank == 0:
                    t = time.perf_counter()
                    ref = rcb(pts, n, weights)
                    serial = time.perf_counter() - t
                counting = Counting(comm)
                comm.Barrier()
                t = time.perf_counter()
                got = rcb_distributed(pts[ids], ids, n, counting,
                                      None if weights is None else weights[ids])
                wall = comm.allreduce(time.perf_counter() - t, op=MPI.MAX)
                parts = comm.gather(got, root=0)
                if comm.rank == 0:
                    assert np.array_equal(np.concatenate(parts), ref), "not the serial labels"
                    print(f"{m:>8} {name:>7} {n:>5} {'volume' if weights is not None else '-':>7} "
                          f"{serial:>9.2f} {wall:>9.2f} {counting.calls:>11}")


if __name__ == "__main__":
    main()
