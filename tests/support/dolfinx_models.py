"""One gmsh model read both ways: by df.read_gmsh and by DOLFINx's gmshio (a distributed mesh)."""

from __future__ import annotations

import gmsh
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti import compat


def gmsh_both(generator, *args, gdim: int, comm: MPI.Comm = MPI.COMM_WORLD, **kwargs):
    """Run ``generator`` on rank 0 and read its model both ways.

    Returns:
        ``(mesh_data, (msh, cell_tags, facet_tags, names))``: the MeshData of read_gmsh, and
        the DOLFINx mesh distributed over ``comm`` with its tags and the physical names.
    """
    names = None
    if comm.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        names = generator(*args, **kwargs)
    try:
        names = comm.bcast(names, root=0)
        data = df.read_gmsh(None, comm, gdim)
        msh, ct, ft = compat.gmsh_model_to_mesh(gmsh.model, comm, 0, gdim)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    return data, (msh, ct, ft, names)
