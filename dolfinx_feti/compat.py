"""Every call that depends on the DOLFINx version lives here: 0.5.2 (Debian 12) and 0.11.

Nothing else in the package, its tests, demos or benchmarks calls version-specific DOLFINx API;
they call the functions below. The module is organized by topic (imports and versions, meshes,
tags, spaces and Functions, forms and assembly, linear solves, files); each branch names the
version that changed the call. Between 0.5 and 0.11 DOLFINx renamed the function space
constructors (``FunctionSpace``/``VectorFunctionSpace`` → ``functionspace``), the coordinate
elements (``ufl.VectorElement`` → ``basix.ufl.element``), the argument order of
``mesh.create_mesh``, the dofmap layouts (AdjacencyList → 2D array), the gmsh module
(``io.gmshio`` → ``io.gmsh``, returning a ``MeshData``) and a few keyword names.
"""

from __future__ import annotations

# DOLFINx 0.11's PyPI wheel finds its MPI library only once mpi4py.MPI has loaded it: import it
# before dolfinx and petsc4py. (Harmless on 0.5.2.)
from mpi4py import MPI  # isort: skip

import inspect
import re
import sys
from pathlib import Path

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.io
import dolfinx.mesh
import numpy as np
import ufl
from petsc4py import PETSc

# ---------------------------------------------------------------------------------------------
# Versions
# ---------------------------------------------------------------------------------------------

DOLFINX_VERSION = dolfinx.__version__
#: (major, minor) of DOLFINx, e.g. (0, 5) or (0, 11).
VERSION = tuple(int(p) for p in re.match(r"(\d+)\.(\d+)", DOLFINX_VERSION).groups())

if VERSION >= (0, 9):
    import basix.ufl
    import dolfinx.graph


def version_label() -> str:
    """'DOLFINx 0.11.0 (PETSc 3.25.5)': for messages that depend on the installed stack."""
    petsc = ".".join(str(v) for v in PETSc.Sys.getVersion())
    return f"DOLFINx {DOLFINX_VERSION} (PETSc {petsc})"


# ---------------------------------------------------------------------------------------------
# Meshes: creation and numbering
# ---------------------------------------------------------------------------------------------

def ufl_domain(cell_type: str, gdim: int, degree: int = 1) -> ufl.Mesh:
    """The UFL domain of a Lagrange geometry (also for UFL expressions without a mesh)."""
    if VERSION >= (0, 9):
        return ufl.Mesh(basix.ufl.element("Lagrange", cell_type, degree, shape=(gdim,)))
    return ufl.Mesh(ufl.VectorElement("Lagrange", getattr(ufl, cell_type), degree, dim=gdim))


def create_mesh(comm: MPI.Comm, cells: np.ndarray, x: np.ndarray, cell_type: str,
                degree: int = 1) -> dolfinx.mesh.Mesh:
    """A mesh of Lagrange geometry of ``degree`` from a cell-to-node array and coordinates.

    ``cells`` in DOLFINx's node order: the vertices (tensor-product order for quadrilaterals
    and hexahedra), then for ``degree`` 2 the edge, face and interior nodes in basix's order.
    On a communicator with several ranks, pass all data on rank 0 and empty arrays elsewhere;
    DOLFINx distributes it. On one rank under DOLFINx 0.5 the partitioner is skipped (every cell
    stays here): the default one builds the dual graph first, a third of the mesh creation;
    and no ghost layer is asked for (on one rank there is none to build).
    """
    cells = np.ascontiguousarray(cells, dtype=np.int64)
    x = np.ascontiguousarray(x, dtype=np.float64)
    domain = ufl_domain(cell_type, x.shape[1], degree)
    if VERSION >= (0, 10):  # the element moved before the coordinates
        return dolfinx.mesh.create_mesh(comm, cells, domain, x)
    if VERSION < (0, 6) and comm.size == 1:  # 0.5's partitioner signature
        return dolfinx.mesh.create_mesh(comm, dolfinx.cpp.graph.AdjacencyList_int64(cells), x,
                                        domain, ghost_mode=dolfinx.mesh.GhostMode.none,
                                        partitioner=_all_here)
    return dolfinx.mesh.create_mesh(comm, cells, x, domain)


def _all_here(comm, nparts, tdim, cells, ghost_mode):
    """A cell partitioner (DOLFINx 0.5) that keeps every cell on rank 0 (a mesh on one rank)."""
    return dolfinx.cpp.graph.AdjacencyList_int32(np.zeros(cells.num_nodes, dtype=np.int32))


def is_mesh(obj) -> bool:
    """Whether ``obj`` is a DOLFINx mesh."""
    return isinstance(obj, dolfinx.mesh.Mesh)


def describe_mesh(msh: dolfinx.mesh.Mesh) -> tuple[str, int, int]:
    """``(cell type name, geometric dimension, degree of the coordinate element)``."""
    cmaps = getattr(msh.geometry, "cmaps", None)  # 0.10 and later; `cmap` is deprecated there
    cmap = cmaps[0] if cmaps else msh.geometry.cmap
    return msh.topology.cell_type.name, int(msh.geometry.dim), int(cmap.degree)


def cell_counts(msh: dolfinx.mesh.Mesh) -> tuple[int, int]:
    """``(owned cells, owned + ghost cells)`` of this rank."""
    im = msh.topology.index_map(msh.topology.dim)
    return im.size_local, im.size_local + im.num_ghosts


def geometry_x(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """Coordinates of the local geometry nodes, (nodes, gdim)."""
    return msh.geometry.x[:, :msh.geometry.dim]


def entity_geometry_nodes(msh: dolfinx.mesh.Mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """The geometry nodes of local entities (e.g. facets), (n, nodes per entity).

    The vertices come first, those of a quadrilateral facet in the reference (tensor) order.
    """
    msh.topology.create_connectivity(dim, msh.topology.dim)
    ents = np.ascontiguousarray(entities, dtype=np.int32)
    if hasattr(dolfinx.mesh, "entities_to_geometry"):  # a Python wrapper in newer DOLFINx
        nodes = dolfinx.mesh.entities_to_geometry(msh, dim, ents, False)
    else:
        nodes = dolfinx.cpp.mesh.entities_to_geometry(msh._mesh, dim, ents, False)
    return np.asarray(nodes, dtype=np.int64).reshape(ents.size, -1)


def cell_geometry_nodes(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """The geometry nodes of each local cell (ghosts included): a (cells × nodes) array.

    In basix's order: the vertices first (in the reference order), then for a second-order
    mesh the nodes on edges, faces and the interior.
    """
    if VERSION >= (0, 10):  # one dofmap per coordinate element (mixed-topology meshes)
        return msh.geometry.dofmaps[0]
    if VERSION >= (0, 9):
        return msh.geometry.dofmap
    ncells = cell_counts(msh)[1]
    return msh.geometry.dofmap.array.reshape(ncells, -1)


def node_input_indices(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """For each geometry node of ``msh`` (local numbering), its index in the input array ``x``."""
    return np.asarray(msh.geometry.input_global_indices, dtype=np.int64)


def cell_input_indices(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """For each local cell of ``msh``, its index in the input cell array."""
    return np.asarray(msh.topology.original_cell_index, dtype=np.int64)


def _geometry_node_to_vertex(msh: dolfinx.mesh.Mesh) -> np.ndarray:
    """The topological vertex of each geometry node (-1 for edge, face and interior nodes)."""
    tdim = msh.topology.dim
    c_to_v = msh.topology.connectivity(tdim, 0).array
    nv = c_to_v.size // cell_counts(msh)[1]
    out = np.full(msh.geometry.x.shape[0], -1, dtype=np.int64)
    out[cell_geometry_nodes(msh)[:, :nv].ravel()] = c_to_v
    return out


# ---------------------------------------------------------------------------------------------
# Mesh tags
# ---------------------------------------------------------------------------------------------


def facet_tags(msh: dolfinx.mesh.Mesh, facets: np.ndarray, values: np.ndarray):
    """Facet MeshTags from facets given by their (local, geometry = vertex for P1) nodes."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    # For P1 meshes geometry nodes and vertices coincide but are numbered separately.
    vertex_of_node = _geometry_node_to_vertex(msh)
    ents = np.ascontiguousarray(vertex_of_node[np.asarray(facets, dtype=np.int64)],
                                dtype=np.int32)
    if VERSION >= (0, 9):
        adj = dolfinx.graph.adjacencylist(ents)
    else:
        adj = dolfinx.cpp.graph.AdjacencyList_int32(ents)
    return dolfinx.mesh.meshtags_from_entities(msh, tdim - 1, adj,
                                               np.ascontiguousarray(values, dtype=np.int32))


def tags_data(tags) -> tuple[int, np.ndarray, np.ndarray]:
    """``(dimension, local entity indices, values)`` of MeshTags."""
    return int(tags.dim), np.asarray(tags.indices, dtype=np.int64), \
        np.asarray(tags.values, dtype=np.int64)


def tags_topology(tags):
    """The (C++) topology the MeshTags were made on; None if this DOLFINx does not tell.

    0.5.2's MeshTags keep their mesh (``tags.mesh``), 0.11's their topology.
    """
    top = getattr(tags, "topology", None)
    if top is None:
        top = getattr(getattr(tags, "mesh", None), "topology", None)
    return getattr(top, "_cpp_object", top)


def mesh_topology(msh: dolfinx.mesh.Mesh):
    """The (C++) topology of a mesh, comparable with :func:`tags_topology` by ``==``."""
    return getattr(msh.topology, "_cpp_object", msh.topology)


def entity_vertices(topology, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """``(offsets, vertices)`` of the local entities of ``dim`` (owned and ghost; collective).

    The number of local entities is ``offsets.size - 1``.
    """
    topology.create_connectivity(dim, 0)
    c = topology.connectivity(dim, 0)
    return np.asarray(c.offsets, dtype=np.int64), np.asarray(c.array, dtype=np.int64)


def cell_tags(msh: dolfinx.mesh.Mesh, cells: np.ndarray, values: np.ndarray):
    """Cell MeshTags from local cell indices."""
    order = np.argsort(cells)
    return dolfinx.mesh.meshtags(msh, msh.topology.dim,
                                 np.ascontiguousarray(cells[order], dtype=np.int32),
                                 np.ascontiguousarray(values[order], dtype=np.int32))


# ---------------------------------------------------------------------------------------------
# Function spaces and Functions
# ---------------------------------------------------------------------------------------------


def function_space(msh: dolfinx.mesh.Mesh, value_size: int,
                   degree: int = 1) -> dolfinx.fem.FunctionSpace:
    """The continuous Lagrange space of ``degree``, scalar (``value_size == 1``) or vector."""
    if VERSION >= (0, 9):
        shape = () if value_size == 1 else (value_size,)
        return dolfinx.fem.functionspace(msh, ("Lagrange", degree, shape))
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
    mesh = getattr(W, "mesh", None)
    return f"{W.ufl_element()}" + ("" if mesh is None else
                                   f" on a mesh of {cell_counts(mesh)[0]} local cells")


def dg0_space(msh: dolfinx.mesh.Mesh) -> dolfinx.fem.FunctionSpace:
    """The piecewise constant scalar space (for cell-wise material data)."""
    if VERSION >= (0, 9):
        return dolfinx.fem.functionspace(msh, ("DG", 0))
    return dolfinx.fem.FunctionSpace(msh, ("DG", 0))


def cell_dofs(V: dolfinx.fem.FunctionSpace) -> np.ndarray:
    """The (unblocked) dofs of each local cell: a (cells × dofs per cell) array."""
    dofs = V.dofmap.list
    if VERSION >= (0, 9):  # a 2D array already
        return dofs
    return dofs.array.reshape(cell_counts(V.mesh)[1], -1)


def dof_entities(V: dolfinx.fem.FunctionSpace, entities: dict[int, int]
                 ) -> list[tuple[int, int]]:
    """For each dof of a cell (reference order), the entity (dim, local index) it sits on.

    ``entities``: the number of entities of each dimension of the cell.
    """
    layout = V.dofmap.dof_layout
    out: dict[int, tuple[int, int]] = {}
    for dim, n in entities.items():
        for i in range(n):
            for j in layout.entity_dofs(dim, i):
                out[int(j)] = (dim, i)
    return [out[j] for j in range(len(out))]


def space_degree(V) -> int:
    """The polynomial degree of a function space's element."""
    degree = V.ufl_element().degree
    return int(degree() if callable(degree) else degree)  # a property of basix.ufl elements


def dof_count(V: dolfinx.fem.FunctionSpace) -> int:
    """Number of (blocked) dofs of this rank, owned and ghost."""
    return V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts


def owned_dof_count(V: dolfinx.fem.FunctionSpace) -> int:
    """Number of (unblocked) dofs owned by this rank."""
    return V.dofmap.index_map.size_local


def function(V: dolfinx.fem.FunctionSpace, name: str) -> dolfinx.fem.Function:
    """A zero Function with a name (the name is what ParaView shows)."""
    u = dolfinx.fem.Function(V)
    u.name = name
    return u


def interpolate_expression(f: dolfinx.fem.Function, expr) -> None:
    """Interpolate a UFL expression into ``f`` (at its element's interpolation points)."""
    points = f.function_space.element.interpolation_points
    points = points() if callable(points) else points  # a property since DOLFINx 0.8
    f.interpolate(dolfinx.fem.Expression(expr, points))


def scatter_forward(u: dolfinx.fem.Function) -> None:
    """Update ghost values of a Function from their owners."""
    u.x.scatter_forward()


# ---------------------------------------------------------------------------------------------
# Forms and assembly
# ---------------------------------------------------------------------------------------------


def garbage_cleanup(comm: MPI.Comm) -> None:
    """Destroy the PETSc objects Python has collected (collective on ``comm``).

    Since petsc4py 3.18 a parallel PETSc object whose Python wrapper is collected is only
    queued for destruction (destroying it there could deadlock: not every rank collects at
    the same moment); the queue is emptied here, at a point every rank reaches together.
    Without it, every solve's vectors and matrices stay allocated.

    Skipped on the way out of a Ctrl-C (a KeyboardInterrupt propagating through the ``finally``
    that calls this): the ranks stop at their own moments, and a rank still blocked in another
    collective call would never meet this one (the job would hang instead of ending).
    """
    if isinstance(sys.exc_info()[1], KeyboardInterrupt):
        return
    cleanup = getattr(PETSc, "garbage_cleanup", None)
    if cleanup is not None:
        cleanup(comm)


def constant(msh: dolfinx.mesh.Mesh, value) -> dolfinx.fem.Constant:
    """A constant (scalar or vector) on ``msh``: a runtime value, not a literal of the form.

    The compiled form then does not depend on the value, so a new load of the same kind
    reuses it instead of compiling again.
    """
    return dolfinx.fem.Constant(msh, np.asarray(value, dtype=PETSc.ScalarType))


def measure(kind: str, msh: dolfinx.mesh.Mesh, tags=None) -> ufl.Measure:
    """A UFL integration measure (``"dx"`` or ``"ds"``) on ``msh`` with optional MeshTags."""
    return ufl.Measure(kind, domain=msh, subdomain_data=tags)


def assemble_matrix(a: ufl.Form) -> PETSc.Mat:
    """Assemble a bilinear form (no boundary conditions) into a PETSc matrix."""
    A = dolfinx.fem.petsc.assemble_matrix(dolfinx.fem.form(a))
    A.assemble()
    return A


def compile_form(form: ufl.Form):
    """The DOLFINx form of a UFL form (compiled, or taken from the JIT cache)."""
    return dolfinx.fem.form(form)


def assemble_vector(L) -> PETSc.Vec:
    """Assemble a linear form (UFL, or from :func:`compile_form`); ghosts summed."""
    b = dolfinx.fem.petsc.assemble_vector(L if not isinstance(L, ufl.Form) else
                                          dolfinx.fem.form(L))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return b


def assemble_scalar(M: ufl.Form, comm: MPI.Comm) -> float:
    """Assemble a functional and sum it over ``comm``."""
    return comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(M)), op=MPI.SUM)


# ---------------------------------------------------------------------------------------------
# Linear solves (monolithic references in tests and benchmarks)
# ---------------------------------------------------------------------------------------------


def solve_linear(a: ufl.Form, L: ufl.Form, bcs, petsc_options: dict,
                 prefix: str = "dolfinx_feti_linear_") -> dolfinx.fem.Function:
    """Solve a(u, v) = L(v) with Dirichlet conditions by ``fem.petsc.LinearProblem``."""
    if VERSION >= (0, 10):  # the options prefix became a required argument
        problem = dolfinx.fem.petsc.LinearProblem(a, L, bcs=bcs, petsc_options=petsc_options,
                                                  petsc_options_prefix=prefix)
        out = problem.solve()
        return out[0] if isinstance(out, tuple) else out
    problem = dolfinx.fem.petsc.LinearProblem(a, L, bcs=bcs, petsc_options=petsc_options)
    return problem.solve()


# ---------------------------------------------------------------------------------------------
# Files: XDMF and gmsh
# ---------------------------------------------------------------------------------------------


def write_xdmf(path: str | Path, msh: dolfinx.mesh.Mesh, functions) -> None:
    """Write a mesh and Functions of its geometry degree (or DG0) to XDMF."""
    with dolfinx.io.XDMFFile(msh.comm, str(path), "w") as f:
        f.write_mesh(msh)
        for u in functions:
            f.write_function(u)


def open_xdmf_series(path: str | Path, msh: dolfinx.mesh.Mesh):
    """An XDMF file with ``msh`` written, for Functions at several times.

    ``write_function(u, t)`` and ``close()`` are the same calls in every supported version.
    """
    f = dolfinx.io.XDMFFile(msh.comm, str(path), "w")
    f.write_mesh(msh)
    return f


def read_xdmf_mesh(comm: MPI.Comm, path: str | Path, name: str = "mesh") -> dolfinx.mesh.Mesh:
    """Read back a mesh written by :func:`write_xdmf`."""
    with dolfinx.io.XDMFFile(comm, str(path), "r") as f:
        return f.read_mesh(name=name)


def gmsh_initialize(gmsh) -> None:
    """``gmsh.initialize()``, keeping Python's Ctrl-C (a KeyboardInterrupt).

    gmsh ≥ 4.9 sets SIGINT to its default action while it is initialized
    (``interruptible=True``, restored only by ``finalize``): a Ctrl-C would then kill the
    process without a word, and the command could not end with its one line.
    """
    if "interruptible" in inspect.signature(gmsh.initialize).parameters:
        gmsh.initialize(interruptible=False)
    else:
        gmsh.initialize()


def gmsh_model_to_mesh(model, comm: MPI.Comm, rank: int, gdim: int):
    """DOLFINx's conversion of a gmsh model held on ``rank``: (mesh, cell tags, facet tags)."""
    if VERSION >= (0, 10):  # io.gmshio became io.gmsh and returns a MeshData
        from dolfinx.io import gmsh as gmshio

        data = gmshio.model_to_mesh(model, comm, rank, gdim=gdim)
        return data.mesh, data.cell_tags, data.facet_tags
    from dolfinx.io import gmshio

    out = gmshio.model_to_mesh(model, comm, rank, gdim=gdim)
    return out[0], out[1], out[2]
