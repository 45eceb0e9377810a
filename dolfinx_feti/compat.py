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

_UFL_CELL = {"triangle": ufl.triangle, "tetrahedron": ufl.tetrahedron,
             "quadrilateral": ufl.quadrilateral, "hexahedron": ufl.hexahedron}


# ------------------------------------------------------------------------------------------
# Meshes: creation and description
# ------------------------------------------------------------------------------------------


def create_mesh(comm: MPI.Comm, cells: np.ndarray, x: np.ndarray, cell_type: str,
                degree: int = 1) -> dolfinx.mesh.Mesh:
    """A mesh from a cell-to-node array (DOLFINx node order) and node coordinates.

    ``degree`` is that of the geometry: 1 (straight-sided cells, the nodes are the vertices)
    or 2 (curved cells: vertices, then edge, face and interior nodes in basix's order). On a
    communicator with several ranks, pass all data on rank 0 and empty arrays elsewhere;
    DOLFINx distributes it.
    """
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", _UFL_CELL[cell_type], degree,
                                        dim=x.shape[1]))
    return dolfinx.mesh.create_mesh(comm, np.ascontiguousarray(cells, dtype=np.int64),
                                    np.ascontiguousarray(x, dtype=np.float64), domain)


def is_mesh(obj) -> bool:
    """Whether ``obj`` is a DOLFINx mesh."""
    return isinstance(obj, dolfinx.mesh.Mesh)


def describe_mesh(msh: dolfinx.mesh.Mesh) -> tuple[str, int, int]:
    """``(cell type name, geometric dimension, degree of the coordinate element)``."""
    return (msh.topology.cell_type.name, int(msh.geometry.dim),
            int(msh.ufl_domain().ufl_coordinate_element().degree()))


def cell_counts(msh: dolfinx.mesh.Mesh) -> tuple[int, int]:
    """``(owned cells, owned + ghost cells)`` of this rank."""
    im = msh.topology.index_map(msh.topology.dim)
    return im.size_local, im.size_local + im.num_ghosts


def cell_geometry_nodes(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """The geometry nodes of each local cell (owned and ghost), (C, nodes per cell).

    In basix's order: the vertices first (in the reference order), then for a second-order
    mesh the nodes on edges, faces and the interior.
    """
    return msh.geometry.dofmap.array.reshape(cell_counts(msh)[1], -1)


def geometry_x(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """Coordinates of the local geometry nodes, (nodes, gdim)."""
    return msh.geometry.x[:, :msh.geometry.dim]


def entity_geometry_nodes(msh: dolfinx.mesh.Mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """The geometry nodes of local entities (e.g. facets), (n, nodes per entity).

    The vertices come first, those of a quadrilateral facet in the reference (tensor) order.
    """
    msh.topology.create_connectivity(dim, msh.topology.dim)
    ents = np.ascontiguousarray(entities, dtype=np.int32)
    return np.asarray(dolfinx.cpp.mesh.entities_to_geometry(msh._mesh, dim, ents, False),
                      dtype=np.int64).reshape(ents.size, -1)


def tags_data(tags) -> tuple[int, np.ndarray, np.ndarray]:
    """``(dimension, local entity indices, values)`` of MeshTags."""
    return int(tags.dim), np.asarray(tags.indices, dtype=np.int64), \
        np.asarray(tags.values, dtype=np.int64)


def node_input_indices(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """For each geometry node of ``msh`` (local numbering), its index in the input array ``x``."""
    return np.asarray(msh.geometry.input_global_indices, dtype=np.int64)


def cell_input_indices(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """For each local cell of ``msh``, its index in the input cell array."""
    return np.asarray(msh.topology.original_cell_index, dtype=np.int64)


# ------------------------------------------------------------------------------------------
# Function spaces and their dof layout
# ------------------------------------------------------------------------------------------


def function_space(msh: dolfinx.mesh.Mesh, value_size: int,
                   degree: int = 1) -> dolfinx.fem.FunctionSpace:
    """The continuous Lagrange space of ``degree``, scalar (``value_size == 1``) or vector."""
    if value_size == 1:
        return dolfinx.fem.FunctionSpace(msh, ("Lagrange", degree))
    return dolfinx.fem.VectorFunctionSpace(msh, ("Lagrange", degree), dim=value_size)


def space_mesh(V) -> dolfinx.mesh.Mesh:
    """The mesh of a function space."""
    return V.mesh


def same_space(W, V) -> bool:
    """Whether the UFL function space ``W`` is ``V`` (the same element on the same mesh)."""
    return W is V or (W.ufl_element() == V.ufl_element()
                      and getattr(W, "mesh", None) is V.mesh)


def describe_space(W) -> str:
    """A short description of a UFL function space, for messages."""
    e = W.ufl_element()
    mesh = getattr(W, "mesh", None)
    return f"{e.family()} of degree {e.degree()} with {e.value_size()} component(s)" + (
        "" if mesh is None else f" on a mesh of {cell_counts(mesh)[0]} local cells")


def cell_dofs(V) -> np.ndarray:
    """The (blocked) dofs of each local cell, (C, dofs per cell), in the reference order."""
    return V.dofmap.list.array.reshape(cell_counts(V.mesh)[1], -1)


def dof_entities(V) -> list[tuple[int, int]]:
    """For each local dof of a cell, the reference entity (dim, local index) it sits on."""
    layout = V.dofmap.dof_layout
    tdim = V.mesh.topology.dim
    out: dict[int, tuple[int, int]] = {}
    for dim in range(tdim + 1):
        n = dolfinx.cpp.mesh.cell_num_entities(V.mesh.topology.cell_type, dim)
        for i in range(n):
            for j in layout.entity_dofs(dim, i):
                out[int(j)] = (dim, i)
    return [out[j] for j in range(len(out))]


def dof_count(V) -> int:
    """Number of (blocked) dofs of this rank, owned and ghost."""
    return V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts


def dg0_space(msh: dolfinx.mesh.Mesh) -> dolfinx.fem.FunctionSpace:
    """The piecewise constant scalar space (for cell-wise material data)."""
    return dolfinx.fem.FunctionSpace(msh, ("DG", 0))


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
    """The topological vertex of each geometry node (-1 for edge, face and interior nodes)."""
    tdim = msh.topology.dim
    c_to_v = msh.topology.connectivity(tdim, 0).array
    nv = c_to_v.size // cell_counts(msh)[1]
    geom = cell_geometry_nodes(msh)[:, :nv]
    out = np.full(msh.geometry.x.shape[0], -1, dtype=np.int64)
    out[geom.ravel()] = c_to_v
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


def interpolate_expression(f: dolfinx.fem.Function, expr) -> None:
    """Interpolate a UFL expression into ``f`` (at its element's interpolation points)."""
    f.interpolate(dolfinx.fem.Expression(expr, f.function_space.element.interpolation_points()))


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
