"""P2 against P1 on the 2D Hertz problem with mortar contact (independent meshes).

The half model of :func:`dolfinx_feti.io.meshes_occ.disk_on_block` (a quarter disk on a block,
each body meshed on its own: the contact surfaces do not match). P1 on the mesh of size h at
the contact (1.7 h on the block) against P2 on the mesh of size 2h, which has about as many
dofs; P2 on the straight-sided mesh (edge points on the chords of the disk, inside the circle
by the sagitta) and on the second-order mesh of the same model (``setOrder(2)``: edge nodes
on the circle, the mortar integrals along the curved segments: ``constraints/mortar_p2_curved``).

For each run the pressure at the slave (disk) dof points (nodal force / ∫ N_j) is compared with
Hertz's p(x) = p0 sqrt(1 − x²/a²): the peak error, the half-width of the computed contact zone,
the RMS and maximum of p_h − p over the dof points with x < 0.9 a, relative to p0.

Run: ``python bench/hertz_mortar_degree.py [--h 0.2 0.1 0.05] [--p1-h 0.075 0.04]`` (serially
or under mpirun); ``--normals flatter`` for the rows along the block's normal.
"""

from __future__ import annotations

import argparse

import gmsh
from hertz_degree import NU, P0, A, E, P, R, hertz_errors, print_row, save_rows
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes_occ import disk_on_block


def curved_disk_on_block(*args, **kwargs):
    """The model with second-order cells (edge nodes on the circle)."""
    groups = disk_on_block(*args, **kwargs)
    gmsh.model.mesh.setOrder(2)
    return groups


def run(h: float, degree: int, curved: bool, comm: MPI.Comm, normals: str = "slave") -> dict:
    model = curved_disk_on_block if curved else disk_on_block
    mesh = df.build_mesh(model, h, 1.7 * h, comm=comm)
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"load": (0.0, -P / 2 / R)}, degree=degree),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar("disk_contact", "block_contact", normals=normals)],
        decomposition=df.Parts(4))
    sol = df.solve(problem, comm=comm, rtol=1e-10)
    return hertz_errors(sol, degree=degree, curved=curved, h=h)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--h", type=float, nargs="*", default=[0.2, 0.1, 0.05])
    parser.add_argument("--p1-h", type=float, nargs="*", default=[],
                        help="extra P1 runs at these sizes (to match P2's dofs)")
    parser.add_argument("--normals", default="slave", choices=("slave", "flatter"),
                        help="the rows' normals (df.Mortar's option)")
    parser.add_argument("--json", default=None, help="write the rows here")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    runs = [(d, hd, cv) for h in args.h
            for d, hd, cv in ((1, h, False), (2, 2 * h, False), (2, 2 * h, True))]
    for degree, hd, curved in runs + [(1, h, False) for h in args.p1_h]:
        rows.append(run(hd, degree, curved, comm, args.normals))
        if comm.rank == 0:
            print_row(rows[-1])
    save_rows(comm, args.json, {"a": A, "p0": P0}, rows)


if __name__ == "__main__":
    main()
