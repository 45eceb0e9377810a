"""A rank's own rows from distributed data vs the serial build_rows, on ~10^6 dof points.

The unit square as an n × n grid of squares split into triangles (n = 1000: 1 002 001 points),
elasticity (2 components), Parts(64) (coordinate bisection), Dirichlet on x = 0 (both
components) and on y = 0 (a function, one component), no contact. Each rank builds the global
problem (not timed), cuts its inputs from the serial decomposition (as the distributed set-up
will hand them over; not timed) and times:

- serial: ``build_rows(problem, dec)`` (Dirichlet mask, gluing, Dirichlet rows, sort), on
  every rank, as rank 0 runs it today, and its part after the mask (gluing and Dirichlet rows,
  sort);
- distributed: ``dirichlet_mask_distributed`` then ``own_rows`` (the largest time over the
  ranks), and checks the rows equal the serial ones the rank owns.

Best of ``--repeat`` runs. The commands:

    python bench/distributed_rows.py
    mpirun -n 2 python bench/distributed_rows.py
    mpirun -n 2 python bench/distributed_rows.py --all-points   # every point asks the directory
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import fields
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.constraints import Rows
from dolfinx_feti.constraints.dirichlet import dirichlet_mask, dirichlet_rows
from dolfinx_feti.constraints.distributed_rows import (
    dirichlet_mask_distributed,
    own_rows,
    shared_points,
)
from dolfinx_feti.constraints.gluing import gluing_rows
from dolfinx_feti.mesh.decompose import decompose
from dolfinx_feti.setup.share import row_slice

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "support"))
from distributed_inputs import RankInputs  # noqa: E402
from serial_setup import build_rows, row_ranges  # noqa: E402

COMM = MPI.COMM_WORLD


def square(n: int) -> df.MeshData:
    """The unit square, n × n squares each split along its diagonal; groups "left", "bottom"."""
    t = np.linspace(0.0, 1.0, n + 1)
    x = np.stack(np.meshgrid(t, t, indexing="xy"), axis=-1).reshape(-1, 2)
    v = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()  # lower-left corners
    cells = np.concatenate([np.c_[v, v + 1, v + n + 2], np.c_[v, v + n + 2, v + n + 1]])
    side = np.arange(n)
    left = np.c_[side * (n + 1), (side + 1) * (n + 1)]
    bottom = np.c_[side, side + 1]
    return df.MeshData(x=x, cells=cells, cell_type="triangle",
                       cell_body=np.zeros(cells.shape[0], dtype=np.int32), body_names=("square",),
                       facet_groups={"left": left, "bottom": bottom},
                       node_tags=np.arange(1, x.shape[0] + 1))


def best(fn, repeat: int) -> tuple[float, object]:
    """The least time of ``repeat`` calls (collective: the largest over the ranks), the result."""
    times = []
    for _ in range(repeat):
        COMM.Barrier()
        t = time.perf_counter()
        out = fn()
        times.append(COMM.allreduce(time.perf_counter() - t, op=MPI.MAX))
    return min(times), out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000, help="squares per side")
    parser.add_argument("--parts", type=int, default=64)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--all-points", action="store_true",
                        help="settle every point in the directory (shared=None), not only the "
                             "points other ranks hold too")
    args = parser.parse_args()
    problem = df.ContactProblem(
        square(args.n), df.Elasticity(1.0, 0.3),
        dirichlet=[df.Dirichlet("left"), df.Dirichlet("bottom", lambda x: 0.1 * x[:, 0],
                                                      components=(1,))],
        decomposition=df.Parts(args.parts))
    mesh, bs, N = problem.mesh, problem.value_size, problem.dof_points.num_points
    dec = decompose(mesh, problem.decomposition, COMM.size, problem.dof_points)
    inputs = RankInputs(problem, dec, dec.sub_rank, COMM.rank)
    shared = shared_points(inputs.ptr, inputs.subs, dec.sub_rank, COMM.rank)
    mask_shared = None if args.all_points else shared

    t_serial, serial = best(lambda: build_rows(problem, dec), args.repeat)
    node_ptr, node_subs = dec.node_subdomains()
    fixed_all, values_all = dirichlet_mask(problem, mesh)

    def serial_rows() -> Rows:  # build_rows after the mask, without contact
        rows = Rows.concatenate([
            gluing_rows(node_ptr, node_subs, fixed_all, bs, mesh.gdim, problem.gluing),
            dirichlet_rows(node_ptr, node_subs, fixed_all, values_all, bs, mesh.gdim)])
        assert np.all(np.isfinite(rows.rhs)) and np.all(np.isfinite(rows.e_coef))
        return rows.permuted(np.argsort(rows.min_subdomain(), kind="stable"))

    t_glue, _ = best(serial_rows, args.repeat)
    t_mask, (fixed, values) = best(lambda: dirichlet_mask_distributed(
        inputs.points, inputs.conditions, bs, N, COMM, mask_shared), args.repeat)
    t_rows, (rows, start, size) = best(lambda: own_rows(
        inputs.points, inputs.ptr, inputs.subs, fixed, values, bs, mesh.gdim, problem.gluing,
        dec.sub_rank, COMM), args.repeat)

    lo, hi = row_ranges(serial, dec, COMM.size)[COMM.rank:COMM.rank + 2]
    theirs = row_slice(serial, lo, hi)
    same = start == lo and size == serial.size and all(
        np.array_equal(getattr(rows, f.name), getattr(theirs, f.name)) for f in fields(Rows))
    same = COMM.allreduce(same, op=MPI.LAND)
    points = COMM.allreduce(inputs.points.size, op=MPI.MAX)
    shared_max = COMM.allreduce(int(shared.sum()), op=MPI.MAX)
    if COMM.rank == 0:
        print(f"{COMM.size} rank(s): {N} dof points, {dec.num_subdomains} subdomains, "
              f"{serial.size} rows; per rank at most {points} points ({shared_max} shared)")
        print(f"  serial build_rows (every row)        {t_serial:8.3f} s")
        print(f"    of which gluing + Dirichlet rows   {t_glue:8.3f} s")
        print(f"  dirichlet_mask_distributed           {t_mask:8.3f} s")
        print(f"  own_rows                             {t_rows:8.3f} s")
        print(f"  distributed total                    {t_mask + t_rows:8.3f} s")
        print(f"  equal to the serial rows: {same}")


if __name__ == "__main__":
    main()
