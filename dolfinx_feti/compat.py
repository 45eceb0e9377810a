"""Every call that depends on the DOLFINx version lives here (Debian bookworm: DOLFINx 0.5.2).

A port to a newer DOLFINx (0.9/0.10 renamed ``VectorFunctionSpace``, ``Mesh._mesh``, the
``dolfinx.fem.petsc`` helpers and the mesh constructors) should only touch this module.
"""

from __future__ import annotations

from pathlib import Path

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.io
import dolfinx.mesh
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

DOLFINX_VERSION = dolfinx.__version__

_UFL_CELL = {"triangle": ufl.triangle, "tetrahedron": ufl.tetrahedron}


def create_mesh(comm: MPI.Comm, cells: np.ndarray, x: np.ndarray,
                cell_type: str) -> dolfinx.mesh.Mesh:
    """A first-order simplex mesh from a cell-to-node array and node coordinates.

    On a communicator with several ranks, pass all data on rank 0 and empty arrays elsewhere;
    DOLFINx distributes it. On one rank the partitioner is skipped (every cell stays here): the
    default one builds the dual graph first, a third of the time of creating the mesh.
    """
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", _UFL_CELL[cell_type], 1, dim=x.shape[1]))
    extra = {"partitioner": _all_here} if comm.size == 1 else {}
    return dolfinx.mesh.create_mesh(comm, np.ascontiguousarray(cells, dtype=np.int64),
                                    np.ascontiguousarray(x, dtype=np.float64), domain, **extra)


def _all_here(comm, nparts, tdim, cells, ghost_mode):
    """A cell partitioner that sends every cell to rank 0 (for a mesh on one rank)."""
    return dolfinx.cpp.graph.AdjacencyList_int32(np.zeros(cells.num_nodes, dtype=np.int32))


def node_input_indices(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """For each geometry node of ``msh`` (local numbering), its index in the input array ``x``."""
    return np.asarray(msh.geometry.input_global_indices, dtype=np.int64)


def cell_input_indices(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """For each local cell of ``msh``, its index in the input cell array."""
    return np.asarray(msh.topology.original_cell_index, dtype=np.int64)


def function_space(msh: dolfinx.mesh.Mesh, value_size: int) -> dolfinx.fem.FunctionSpace:
    """The continuous P1 space, scalar (``value_size == 1``) or vector valued."""
    if value_size == 1:
        return dolfinx.fem.FunctionSpace(msh, ("Lagrange", 1))
    return dolfinx.fem.VectorFunctionSpace(msh, ("Lagrange", 1), dim=value_size)


def dg0_space(msh: dolfinx.mesh.Mesh) -> dolfinx.fem.FunctionSpace:
    """The piecewise constant scalar space (for cell-wise material data)."""
    return dolfinx.fem.FunctionSpace(msh, ("DG", 0))


def vertex_dof_nodes(V: dolfinx.fem.FunctionSpace) -> np.ndarray:
    """For each (unblocked) dof of a P1 space, the geometry node it sits on.

    P1 dofs and first-order geometry nodes are listed in the same order within each cell, so
    the two cell-wise maps, read side by side, pair them.
    """
    msh = V.mesh
    ncells = msh.topology.index_map(msh.topology.dim).size_local + \
        msh.topology.index_map(msh.topology.dim).num_ghosts
    nv = msh.geometry.dofmap.array.size // ncells
    dofs = V.dofmap.list.array.reshape(-1, nv)
    geom = msh.geometry.dofmap.array.reshape(-1, nv)
    n_dofs = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
    out = np.empty(n_dofs, dtype=np.int64)
    out[dofs.ravel()] = geom.ravel()
    return out


def owned_dof_count(V: dolfinx.fem.FunctionSpace) -> int:
    """Number of (unblocked) dofs owned by this rank."""
    return V.dofmap.index_map.size_local


def facet_tags(msh: dolfinx.mesh.Mesh, facets: np.ndarray, values: np.ndarray):
    """Facet MeshTags from facets given by their (local, geometry = vertex for P1) nodes."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    # For P1 meshes geometry nodes and vertices coincide but are numbered separately.
    vertex_of_node = _geometry_node_to_vertex(msh)
    ents = vertex_of_node[np.asarray(facets, dtype=np.int64)]
    adj = dolfinx.cpp.graph.AdjacencyList_int32(np.ascontiguousarray(ents, dtype=np.int32))
    return dolfinx.mesh.meshtags_from_entities(msh, tdim - 1, adj,
                                               np.ascontiguousarray(values, dtype=np.int32))


def cell_tags(msh: dolfinx.mesh.Mesh, cells: np.ndarray, values: np.ndarray):
    """Cell MeshTags from local cell indices."""
    order = np.argsort(cells)
    return dolfinx.mesh.meshtags(msh, msh.topology.dim,
                                 np.ascontiguousarray(cells[order], dtype=np.int32),
                                 np.ascontiguousarray(values[order], dtype=np.int32))


def _geometry_node_to_vertex(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    tdim = msh.topology.dim
    c_to_v = msh.topology.connectivity(tdim, 0).array
    geom = msh.geometry.dofmap.array
    out = np.empty(msh.geometry.x.shape[0], dtype=np.int64)
    out[geom] = c_to_v
    return out


def measure(kind: str, msh: dolfinx.mesh.Mesh, tags=None) -> ufl.Measure:
    """A UFL integration measure (``"dx"`` or ``"ds"``) on ``msh`` with optional MeshTags."""
    return ufl.Measure(kind, domain=msh, subdomain_data=tags)


def assemble_matrix(a: ufl.Form) -> PETSc.Mat:
    """Assemble a bilinear form (no boundary conditions) into a PETSc matrix."""
    A = dolfinx.fem.petsc.assemble_matrix(dolfinx.fem.form(a))
    A.assemble()
    return A


def assemble_vector(L: ufl.Form) -> PETSc.Vec:
    """Assemble a linear form into a PETSc vector (ghosts summed)."""
    b = dolfinx.fem.petsc.assemble_vector(dolfinx.fem.form(L))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return b


def assemble_scalar(M: ufl.Form, comm: MPI.Comm) -> float:
    """Assemble a functional and sum it over ``comm``."""
    return comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(M)), op=MPI.SUM)


def function(V: dolfinx.fem.FunctionSpace, name: str) -> dolfinx.fem.Function:
    """A zero Function with a name (the name is what ParaView shows)."""
    u = dolfinx.fem.Function(V)
    u.name = name
    return u


def scatter_forward(u: dolfinx.fem.Function) -> None:
    """Update ghost values of a Function from their owners."""
    u.x.scatter_forward()


def write_xdmf(path: str | Path, msh: dolfinx.mesh.Mesh, functions) -> None:
    """Write a mesh and P1 Functions to XDMF (readable by ParaView and DOLFINx)."""
    with dolfinx.io.XDMFFile(msh.comm, str(path), "w") as f:
        f.write_mesh(msh)
        for u in functions:
            f.write_function(u)


def read_xdmf_mesh(comm: MPI.Comm, path: str | Path, name: str = "mesh") -> dolfinx.mesh.Mesh:
    """Read back a mesh written by :func:`write_xdmf`."""
    with dolfinx.io.XDMFFile(comm, str(path), "r") as f:
        return f.read_mesh(name=name)
