"""Dof points of degree 2 and the point → subdomain directory: distributed against serial.

A structured mesh of about 10⁶ cells (Kuhn tetrahedra of an n³ grid, 6n³ cells, or n³
hexahedra, whose face and interior keys are byte strings), split in contiguous cell blocks as
the scatter of the distributed set-up gives them, and subdomains by recursive coordinate
bisection (``--parts``). Timed, wall and CPU time (the CPU time is the steadier figure on a
busy machine), each the maximum over the ranks (median of ``--repeat``):

- ``number_points``: :func:`dolfinx_feti.mesh.distributed_points.number_points` (degree 2);
- ``point_coordinates``: the coordinates of the local points;
- ``point_subdomains``: the directory and the subdomain sizes;
- on one rank also the serial code on the whole mesh: ``dofpoints._build(mesh, 2)`` (numbers
  and coordinates) and ``decompose._build`` + ``node_subdomains()`` (the pairs and the
  directory), the steps the distributed functions replace.

    python bench/distributed_points.py --cell hexahedron --n 100        # serial and 1 rank
    mpirun -n 2 python bench/distributed_points.py --cell hexahedron --n 100
    python bench/distributed_points.py --cell tetrahedron --n 55
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes import _kuhn_simplices
from dolfinx_feti.mesh import distributed_points as dp
from dolfinx_feti.mesh import dofpoints
from dolfinx_feti.mesh.decompose import _build as decomposition
from dolfinx_feti.mesh.decompose import rcb

COMM = MPI.COMM_WORLD


def structured(cell: str, n: int) -> df.MeshData:
    """The unit cube in n³ hexahedra or 6n³ Kuhn tetrahedra (vertices x fastest)."""
    k = np.arange(n + 1)
    x = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)[:, ::-1] / n
    if cell == "tetrahedron":
        cells = _kuhn_simplices((n, n, n))
    else:
        c = np.stack(np.meshgrid(k[:-1], k[:-1], k[:-1], indexing="ij"), axis=-1).reshape(-1, 3)
        cells = np.stack([(c[:, 2] + a) + (n + 1) * ((c[:, 1] + b) + (n + 1) * (c[:, 0] + d))
                          for d in (0, 1) for b in (0, 1) for a in (0, 1)], axis=1)
    return df.MeshData(x=x, cells=cells.astype(np.int64), cell_type=cell,
                       cell_body=np.zeros(cells.shape[0], dtype=np.int32), body_names=("body",),
                       facet_groups={}, node_tags=np.arange(x.shape[0]))


def timed(fn, repeat: int, comm: MPI.Comm):
    """fn()'s result and the medians over repeats of its wall and CPU times (max over ranks)."""
    times = []
    for _ in range(repeat):
        comm.Barrier()
        wall, cpu = time.perf_counter(), time.process_time()
        out = fn()
        spent = (time.perf_counter() - wall, time.process_time() - cpu)
        times.append(comm.allreduce(spent, op=MPI.MAX))
    return out, tuple(np.median(np.array(times), axis=0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cell", choices=["tetrahedron", "hexahedron"], default="hexahedron")
    parser.add_argument("--n", type=int, default=100, help="cells per side of the cube")
    parser.add_argument("--parts", type=int, default=64, help="subdomains")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    mesh = structured(args.cell, args.n)
    C, N = mesh.num_cells, mesh.num_nodes
    cell_sub_all = rcb(mesh.x[mesh.cells].mean(axis=1), args.parts).astype(np.int32)
    lo = np.arange(COMM.size + 1) * C // COMM.size
    ids = np.arange(lo[COMM.rank], lo[COMM.rank + 1])
    cells, cell_sub = mesh.cells[ids], cell_sub_all[ids]
    cell_x = mesh.x[cells]
    rows = {}

    (cell_points, num_points, _), rows["number_points"] = timed(
        lambda: dp.number_points(cells, args.cell, 2, N, COMM), args.repeat, COMM)
    _, rows["point_coordinates"] = timed(
        lambda: dp.point_coordinates(cell_points, cells, cell_x, args.cell, 2), args.repeat, COMM)
    _, rows["point_subdomains"] = timed(
        lambda: dp.point_subdomains(cell_points, cell_sub, num_points, args.parts, COMM),
        args.repeat, COMM)
    if COMM.size == 1:
        points, rows["serial dof points (_build)"] = timed(
            lambda: dofpoints._build(mesh, 2), args.repeat, COMM)
        assert np.array_equal(points.cell_points, cell_points)

        def pairs():
            d = decomposition(mesh, cell_sub_all, 1, points.cell_points, points.num_points)
            return d, d.node_subdomains()

        _, rows["serial pairs + node_subdomains"] = timed(pairs, args.repeat, COMM)
    if COMM.rank == 0:
        print(f"{args.cell}: {C} cells, {N} vertices, {num_points} P2 points, {args.parts} "
              f"subdomains, {COMM.size} rank(s), median of {args.repeat}")
        print(f"  {'':32s} {'wall':>8s} {'CPU':>8s}")
        for name, (wall, cpu) in rows.items():
            print(f"  {name:32s} {wall:8.2f} {cpu:8.2f} s")


if __name__ == "__main__":
    main()
