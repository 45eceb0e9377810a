"""Output on the whole (undecomposed) mesh: merged Functions and XDMF files."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from mpi4py import MPI

from . import compat
from .errors import collective
from .mesh.gmsh_input import MeshData

_PARENT_CACHE: dict[tuple[int, int], object] = {}


def parent_mesh(mesh: MeshData, comm: MPI.Comm):
    """The whole mesh as a DOLFINx mesh distributed over ``comm`` (built once per MeshData)."""
    key = (id(mesh), comm.py2f())
    if key not in _PARENT_CACHE:
        if comm.rank == 0:
            cells, x = mesh.cells, mesh.x
        else:
            cells = np.empty((0, mesh.cells.shape[1]), dtype=np.int64)
            x = np.empty((0, mesh.gdim))
        _PARENT_CACHE.clear()  # keep at most one parent mesh alive
        _PARENT_CACHE[key] = compat.create_mesh(comm, cells, x, mesh.cell_type)
    return _PARENT_CACHE[key]


def parent_function(mesh: MeshData, nodal: np.ndarray, comm: MPI.Comm, name: str, msh=None):
    """A P1 Function on the parent mesh with the given values at the global nodes."""
    msh = msh if msh is not None else parent_mesh(mesh, comm)
    bs = nodal.shape[1]
    V = compat.function_space(msh, bs)
    u = compat.function(V, name)
    node = compat.node_input_indices(msh)[compat.vertex_dof_nodes(V)]
    u.x.array[:] = nodal[node].ravel()
    return u


def cell_function(mesh: MeshData, values: np.ndarray, name: str, msh):
    """A DG0 (cell-wise constant) Function on the parent mesh ``msh``, one value per input cell."""
    V = compat.dg0_space(msh)
    f = compat.function(V, name)
    dofs = compat.cell_dofs(V).ravel()  # one dof per local cell, in cell order
    cells = compat.cell_input_indices(msh)
    n = min(dofs.size, cells.size)
    f.x.array[dofs[:n]] = np.asarray(values, dtype=float)[cells[:n]]
    compat.scatter_forward(f)
    return f


def write_xdmf(path: str | os.PathLike, u, functions) -> None:
    """Write Functions on one mesh to XDMF; the files appear under their names only when done.

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
