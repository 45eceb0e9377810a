"""The connected-pieces step of the distributed decomposition: memory per rank and time.

B1 (two membranes, ``meshes.membranes(n)``) read with ``read_gmsh(..., distribute=True)``:
every rank holds a contiguous block of the gmsh file's cells, not spatially compact (on 3
ranks at n = 362 the pieces of a rank have one or two cells, nearly all touching other ranks'
cells); or (``--deal round-robin``) cell i on rank i mod ranks, which makes every cell a piece
on any number of ranks. Labels as ``Parts(parts)`` per membrane (coordinate bisection), then
the connected pieces of equal label (``distributed_decompose._split``). Or (``--strip N``) a
strip of N squares dealt round-robin with randomly numbered vertices, one label (``ByTags``):
its pieces form one chain across the ranks, the slowest case of the search across ranks.
Printed per rank: its cells, the peak of the memory the pieces step allocates (tracemalloc,
started just before the step and stopped after it: the arrays of the step alone, not those
the rank held before), and, once for all ranks, the wall time of ``decompose_distributed``
and of the pieces step inside it (the slowest rank, the best of ``--repeat`` runs without
tracemalloc), the rounds of the distributed connected-components search (when the code
records them) and the collective calls of the pieces step (every rank makes the same)::

    mpirun -n 2 --allow-run-as-root --oversubscribe .venv/bin/python bench/split_components.py
    mpirun -n 3 --allow-run-as-root --oversubscribe .venv/bin/python bench/split_components.py \
        --n 362 --parts 32 --repeat 3
    mpirun -n 2 --allow-run-as-root --oversubscribe .venv/bin/python bench/split_components.py \
        --n 256 --deal round-robin
    mpirun -n 2 --allow-run-as-root --oversubscribe .venv/bin/python bench/split_components.py \
        --strip 200000
"""

from __future__ import annotations

import argparse
import inspect
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes
from dolfinx_feti.mesh import distributed_decompose as dd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rcb_distributed import Counting  # noqa: E402


def strip(n: int, comm: MPI.Comm):
    """This rank's squares of a 1 × n strip (square i on rank i mod ranks): (cells, ids, x).

    The vertices are numbered at random, so that the facet directory's ranks see scattered
    links of the chain of pieces, not runs of it.
    """
    number = np.random.default_rng(0).permutation(2 * (n + 1))  # vertex (i, j) is 2 i + j
    ids = np.arange(comm.rank, n, comm.size)
    corners = 2 * ids[:, None] + np.array([0, 2, 1, 3])  # DOLFINx's quadrilateral order
    x = np.column_stack([corners // 2, corners % 2]).reshape(-1, 4, 2).astype(np.float64)
    return number[corners], ids, x.reshape(ids.size, 4, 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=256, help="squares per membrane side")
    ap.add_argument("--parts", type=int, default=32, help="Parts(parts) per membrane")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs (the best is printed)")
    ap.add_argument("--deal", choices=["blocks", "round-robin"], default="blocks",
                    help="blocks: read_gmsh(..., distribute=True); round-robin: cell i on rank "
                         "i mod ranks (no two neighbours on one rank: every cell a piece)")
    ap.add_argument("--strip", type=int, default=0, metavar="N",
                    help="instead of B1: a strip of N squares, square i on rank i mod ranks, "
                         "its vertices numbered at random (the pieces a chain across ranks)")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    how = df.Parts(args.parts)
    if args.strip:
        cells, ids, cell_x = strip(args.strip, comm)
        body, cell_type, names, num = np.zeros(ids.size, np.int32), "quadrilateral", ("s",), \
            args.strip
        how, title = df.ByTags(), f"a strip of {args.strip} quadrilaterals dealt round-robin"
    else:
        if args.deal == "blocks":
            mesh = df.build_mesh(meshes.membranes, args.n, distribute=True)
            cells, ids = mesh.part.vertex_ids[mesh.cells], mesh.part.cell_ids
            cell_x, body = mesh.x[mesh.cells], mesh.cell_body
        else:  # the whole mesh read on every rank, then every size-th cell kept
            mesh = df.build_mesh(meshes.membranes, args.n)
            ids = np.arange(comm.rank, mesh.num_cells, comm.size)
            cells = mesh.cells[ids]
            cell_x, body = mesh.x[cells], mesh.cell_body[ids]
        cell_type, names, num = mesh.cell_type, mesh.body_names, mesh.num_cells
        title = (f"B1 n={args.n}, Parts({args.parts}) per membrane, {num} cells dealt as "
                 f"{args.deal}")

    def run():
        return dd.decompose_distributed(cells, cell_x, ids, body, cell_type, names, num, how,
                                        comm)

    split = dd._split
    record = {"seconds": 0.0, "peak": 0.0}
    stats: dict = {}
    counts = "stats" in inspect.signature(split).parameters  # the code records its rounds

    def measured(*a, **k):
        t = time.perf_counter()
        if record.get("trace"):
            tracemalloc.start()
        counting = Counting(a[4])  # (cells, ids, label, cell_type, comm, ...)
        try:
            return split(*a[:4], counting, *a[5:], **k, **({"stats": stats} if counts else {}))
        finally:
            if record.get("trace"):
                record["peak"] = tracemalloc.get_traced_memory()[1] / 2**20
                tracemalloc.stop()
            record["seconds"] = time.perf_counter() - t
            record["calls"] = counting.calls

    dd._split = measured
    try:
        record["trace"] = True
        cell_sub, _ = run()
        record["trace"] = False
        best = best_split = np.inf
        for _ in range(args.repeat):
            comm.Barrier()
            t = time.perf_counter()
            run()
            best = min(best, comm.allreduce(time.perf_counter() - t, op=MPI.MAX))
            best_split = min(best_split, comm.allreduce(record["seconds"], op=MPI.MAX))
    finally:
        dd._split = split
    nsub = comm.allreduce(int(cell_sub.max()) + 1 if cell_sub.size else 0, op=MPI.MAX)
    rounds = stats.get("rounds", "not recorded")
    rows = comm.gather((comm.rank, cells.shape[0], record["peak"]), root=0)
    if comm.rank == 0:
        print(f"{title}, {nsub} subdomains, {comm.size} rank(s)")
        for rank, nc, peak in rows:
            print(f"rank {rank}: {nc} cells, pieces step peak {peak:.1f} MiB (tracemalloc)")
        print(f"decompose_distributed {best:.3f} s, pieces step {best_split:.3f} s "
              f"(slowest rank, best of {args.repeat}); rounds {rounds}, collective calls "
              f"{record['calls']}")


if __name__ == "__main__":
    main()
