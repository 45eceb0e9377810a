"""Output on the whole (undecomposed) mesh: Functions and XDMF files.

The output mesh is the user's own DOLFINx mesh when the problem came from
:func:`~dolfinx_feti.from_dolfinx`, else a mesh built once from the :class:`MeshData` and
distributed over the communicator. Values at the global dof points (:mod:`.mesh.dofpoints`)
become Lagrange Functions of the problem's degree on it; values per cell become DG0 Functions.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from mpi4py import MPI

from . import compat
from .errors import collective
from .fem.dofmap import dof_points_of_space
from .mesh.dofpoints import DofPoints, dof_points
from .mesh.gmsh_input import MeshData

#: The last parent mesh built: (the MeshData it was built from, communicator handle, mesh). The
#: MeshData itself is held (not its id): an id is reused once an object is freed, and a later
#: problem's data at the same address must not get another mesh's parent.
_PARENT: tuple[MeshData, int, object] | None = None


def parent_mesh(mesh: MeshData, comm: MPI.Comm):
    """The whole mesh as a DOLFINx mesh distributed over ``comm`` (built once per MeshData).

    Its input nodes are the global vertices, or for a curved mesh the global dof points of
    degree 2 (its geometry nodes).
    """
    global _PARENT
    if _PARENT is None or _PARENT[0] is not mesh or _PARENT[1] != comm.py2f():
        degree = mesh.geometry_degree
        points = dof_points(mesh, degree)
        cells, x = points.cell_points, points.x
        if comm.rank != 0:
            cells, x = cells[:0], x[:0]
        _PARENT = None  # keep at most one parent mesh alive
        _PARENT = (mesh, comm.py2f(), compat.create_mesh(comm, cells, x, mesh.cell_type, degree))
    return _PARENT[2]


def output_mesh(mesh: MeshData, comm: MPI.Comm) -> tuple[object, np.ndarray, np.ndarray]:
    """The mesh to put results on, and the global vertex and cell of its local ones.

    Returns:
        ``(msh, vertex, cell)``: the user's mesh (input from DOLFINx) or the parent mesh; the
        global vertex of each local geometry node; the global cell of each local cell.
    """
    if mesh.source is not None:
        return mesh.source.mesh, mesh.source.vertex_ids(), mesh.source.cell_ids()
    msh = parent_mesh(mesh, comm)
    return msh, compat.node_input_indices(msh), compat.cell_input_indices(msh)


def point_function(mesh: MeshData, values: np.ndarray, comm: MPI.Comm, name: str,
                   points: DofPoints | None = None, degree: int | None = None):
    """A Lagrange Function on the output mesh with the given values at the global dof points.

    Args:
        mesh: The mesh data.
        values: (M, value size) values at the dof points of ``points``.
        comm: The communicator of the parent mesh (unused with a user's mesh).
        name: The Function's name.
        points: The dof points of the values (default: the vertices).
        degree: The Lagrange degree of the Function (default: that of ``points``); a degree-1
            Function of degree-2 values takes their values at the vertices.
    """
    points = dof_points(mesh, 1) if points is None else points
    degree = points.degree if degree is None else degree
    if degree != points.degree:
        points, values = dof_points(mesh, degree), values[:mesh.num_nodes]
    msh, vertex, _ = output_mesh(mesh, comm)
    V = compat.function_space(msh, values.shape[1], degree)
    u = compat.function(V, name)
    u.x.array[:] = values[dof_points_of_space(V, vertex, points)].ravel()
    return u


def cell_function(mesh: MeshData, values: np.ndarray, name: str, comm: MPI.Comm):
    """A DG0 (cell-wise constant) Function on the output mesh, one value per global cell."""
    msh, _, cell = output_mesh(mesh, comm)
    V = compat.dg0_space(msh)
    f = compat.function(V, name)
    dofs = compat.cell_dofs(V).ravel()  # one dof per local cell, in cell order
    n = min(dofs.size, cell.size)
    f.x.array[dofs[:n]] = np.asarray(values, dtype=float)[cell[:n]]
    compat.scatter_forward(f)
    return f


def write_xdmf(path: str | os.PathLike, u, functions) -> None:
    """Write Functions on one mesh to XDMF; the files appear under their names only when done.

    XDMF holds Lagrange Functions of the mesh's own geometry degree: on a straight-sided mesh
    pass degree-2 fields as their vertex values (:func:`point_function` with ``degree=1``).

    Collective; a failure on any rank (the folder cannot be made, the disk is full) raises on
    every rank and leaves no file behind.
    """
    path = Path(path)
    comm = u.function_space.mesh.comm
    tmp = path.with_name(f".tmp-{path.name}")
    with collective(comm, "outputs"):
        if comm.rank == 0:
            path.parent.mkdir(parents=True, exist_ok=True)
    try:
        with collective(comm, "outputs"):
            compat.write_xdmf(tmp, u.function_space.mesh, functions)
    except BaseException:
        if comm.rank == 0:  # leave no partial temporary files behind either
            for p in (tmp, tmp.with_suffix(".h5")):
                p.unlink(missing_ok=True)
        raise
    with collective(comm, "outputs"):
        if comm.rank == 0:
            h5_tmp, h5 = tmp.with_suffix(".h5"), path.with_suffix(".h5")
            text = tmp.read_text().replace(h5_tmp.name, h5.name)
            os.replace(h5_tmp, h5)
            tmp.write_text(text)
            os.replace(tmp, path)
