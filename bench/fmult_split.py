"""Time of one multiplication by P F P split into local solves, communication and projection.

Run on 1 and 2 ranks (``mpirun -n 2 python bench/fmult_split.py``). One application of the
projected dual operator P F P (what every iteration pays) is split into:

- ``solves``: the subdomain forward/backward solves (one block-diagonal CHOLMOD factor per rank);
- ``B, Bᵀ local``: the two products with B without their communication;
- ``B, Bᵀ comm``: their communication, measured as two scatters of the ghost entries B's local
  rows need (what MPIAIJ's product sends and receives);
- ``proj. local``: the local sparse products with G (4 per P F P: G x and Gᵀ y twice);
- ``proj. Allreduce``: the two reductions of the m-vector G x;
- ``coarse solves``: the two applications of T and Tᵀ (T Tᵀ = (G Gᵀ)⁻¹);
- ``rest``: P F P minus the parts (Python dispatch, vector copies).

Each part is the median over ``--repeat`` runs of its maximum over the ranks.

    python bench/fmult_split.py                    # 1 rank
    mpirun -n 2 python bench/fmult_split.py        # 2 ranks
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

sys.path.insert(0, str(Path(__file__).resolve().parent))
import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402

COMM = MPI.COMM_WORLD


def timed(fn, repeat: int) -> float:
    """Median over repeats of the slowest rank's time of ``fn()``."""
    times = []
    for _ in range(repeat):
        COMM.Barrier()
        t0 = time.perf_counter()
        fn()
        times.append(COMM.allreduce(time.perf_counter() - t0, op=MPI.MAX))
    return float(np.median(times))


def ghost_scatter(feti) -> tuple[PETSc.Scatter, PETSc.Vec, PETSc.Vec]:
    """A scatter of the primal entries that this rank's rows of B need from other ranks."""
    _, cols, _ = feti.B.getValuesCSR()
    lo, hi = feti.B.getOwnershipRangeColumn()
    ghosts = np.unique(cols[(cols < lo) | (cols >= hi)]).astype(PETSc.IntType)
    src = feti.B.createVecRight()
    dst = PETSc.Vec().createSeq(ghosts.size, comm=PETSc.COMM_SELF)
    iset = PETSc.IS().createGeneral(ghosts, comm=PETSc.COMM_SELF)
    return PETSc.Scatter().create(src, iset, dst, None), src, dst


def split(name: str, problem: df.ContactProblem, repeat: int) -> str:
    qp = df.dual_qp(problem, COMM)
    feti, ocon = qp.feti, qp.constraint
    x = feti.d.duplicate()
    x.setRandom()
    y, w, v = x.duplicate(), feti.B.createVecRight(), feti.B.createVecRight()
    w.setRandom()
    sc, src, dst = ghost_scatter(feti)
    base = ocon.base
    z = base.mult(x)
    zl = np.ascontiguousarray(base._D_local @ x.array_r)
    zr = np.empty_like(zl)

    t_pfp = timed(lambda: qp.A.mult(x, y), repeat)
    t_solve = timed(feti.primal.Kplus._chol.solve_in_place, repeat)
    t_b = timed(lambda: (feti.B.multTranspose(x, w), feti.B.mult(v, y)), repeat)
    t_comm = timed(lambda: (sc.scatter(src, dst), sc.scatter(src, dst)), repeat)
    t_local = timed(lambda: (base._D_local @ x.array_r, base.Dt_local @ z), repeat)
    t_allred = timed(lambda: COMM.Allreduce(zl, zr, op=MPI.SUM), repeat)
    t_coarse = timed(lambda: ocon.transform_transpose(ocon.transform(z)), repeat)
    parts = {"solves": t_solve, "B, Bᵀ local": t_b - t_comm, "B, Bᵀ comm": t_comm,
             "proj. local": 2 * t_local, "proj. Allreduce": 2 * t_allred,
             "coarse solves": 2 * t_coarse}
    parts["rest"] = t_pfp - sum(parts.values())
    sizes = (f"{feti.primal_size[1]} / {feti.dual_size[1]} / {feti.coarse_size} "
             f"({ocon.method})")
    cells = " | ".join(f"{1e3 * t:.2f}" for t in parts.values())
    return f"| {name} | {COMM.size} | {sizes} | {1e3 * t_pfp:.2f} | {cells} |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    rows = [("B1 n=512, H=1/8 (128 subd.)", P.b1(512, 1 / 8)),
            ("B1 n=256, H=1/16 (512 subd.)", P.b1(256, 1 / 16)),
            ("3D blocks n=16, Parts(8)", P.blocks3d(16, 8))]
    out = [f"{COMM.size} rank(s); {P.machine()}; code {P.git_state()}", "",
           "| problem | ranks | primal / dual / coarse | P F P [ms] | solves | B, Bᵀ local | "
           "B, Bᵀ comm | proj. local | proj. Allreduce | coarse solves | rest |",
           "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, problem in rows:
        out.append(split(name, problem, args.repeat))
        if COMM.rank == 0:
            print(out[-1], flush=True)
    if COMM.rank == 0:
        print("\n".join(out))


if __name__ == "__main__":
    main()
