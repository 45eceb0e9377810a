"""The parent mesh that results are written on belongs to the problem's own mesh data."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.results.output import parent_mesh

MESHES = Path(__file__).resolve().parents[2] / "meshes"


def _check(msh, mesh: df.MeshData) -> None:
    cell_type, gdim, _ = compat.describe_mesh(msh)
    assert (cell_type, gdim) == (mesh.cell_type, mesh.gdim)
    assert MPI.COMM_WORLD.allreduce(compat.cell_counts(msh)[0], op=MPI.SUM) \
        == mesh.cells.shape[0]


def test_parent_mesh_follows_its_mesh_data():
    """A freed MeshData's address is reused by the next one: its parent mesh must not be.

    The cache was keyed by ``id(mesh)``: a 3D problem made right after a 2D one had been freed
    got the 2D parent mesh (found under DOLFINx 0.11 by the command's 3D problem file). CPython
    gives a new object of the same type the address just freed, as this test sees.
    """
    comm = MPI.COMM_WORLD
    flat = df.read_gmsh(MESHES / "membranes_8.msh", comm=comm)
    solid = df.read_gmsh(MESHES / "blocks3d.msh", comm=comm)
    for first, second in [(flat, solid), (solid, flat)]:
        mesh = dataclasses.replace(first)
        _check(parent_mesh(mesh, comm), mesh)
        del mesh
        mesh = dataclasses.replace(second)  # most likely at the address just freed
        _check(parent_mesh(mesh, comm), mesh)
