"""Output on the whole (undecomposed) mesh: Functions and XDMF files.

The output mesh is the user's own DOLFINx mesh when the problem came from
:func:`~dolfinx_feti.from_dolfinx`, else a mesh built once from the :class:`MeshData` and
distributed over the communicator. Values at the global dof points (:mod:`.mesh.dofpoints`)
become Lagrange Functions of the problem's degree on it; values per cell become DG0 Functions.

The Lagrange Functions are filled from the distributed solution: each rank gives its own
(dof point, value) pairs, and asks for the values at the dof points of its own dofs of the
output space through a directory (rank r keeps the points r·M // size to (r + 1)·M // size − 1),
so no rank holds an array of the whole mesh's values. (The parent mesh itself is still built
from the global mesh arrays on rank 0, as long as the input is global.)
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .. import compat
from ..errors import collective
from ..fem.dofmap import dof_points_of_space
from ..mesh.data import MeshData
from ..mesh.dofpoints import DofPoints, RootLookup, dof_points
from ..parallel.exchange import Blocks, RankNumbering, answer, exchange

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
        if mesh.part is not None:
            cells, x = _part_input(mesh, comm)
        else:
            points = dof_points(mesh, degree)  # rank 0 holds the arrays (the others: sizes)
            cells, x = points.cell_points, points.x
            if comm.rank != 0:
                cells, x = cells[:0], x[:0]
        _PARENT = None  # keep at most one parent mesh alive
        _PARENT = (mesh, comm.py2f(), compat.create_mesh(comm, cells, x, mesh.cell_type, degree))
    return _PARENT[2]


def output_mesh(mesh: MeshData, comm: MPI.Comm, msh=None) -> tuple[object, np.ndarray, np.ndarray]:
    """The mesh to put results on, and the global vertex and cell of its local ones.

    Args:
        mesh: The mesh data.
        comm: The communicator of the parent mesh (unused with a user's mesh).
        msh: The parent mesh, if already made (e.g. that of ``solution.u``: the cache keeps
            only the last parent mesh, and Functions combined in UFL or in one file must live
            on one mesh object).

    Returns:
        ``(msh, vertex, cell)``: the user's mesh (input from DOLFINx) or the parent mesh; the
        global vertex of each local geometry node; the global cell of each local cell.
    """
    if mesh.source is not None:
        return mesh.source.mesh, mesh.source.vertex_ids(), mesh.source.cell_ids()
    msh = parent_mesh(mesh, comm) if msh is None else msh
    cells = compat.cell_input_indices(msh)
    if mesh.part is not None:  # DOLFINx numbered the ranks' blocks one after the other
        cells = _block_cells(mesh.part, cells, comm)
    return msh, compat.node_input_indices(msh), cells


def _block_cells(part, positions: np.ndarray, comm: MPI.Comm) -> np.ndarray:
    """The global cell of each position in the ranks' blocks of cells, end to end."""
    blocks = RankNumbering(comm, part.cell_ids.size)
    return blocks.read(part.cell_ids, *blocks.route(positions))


def _part_input(mesh: MeshData, comm: MPI.Comm) -> tuple[np.ndarray, np.ndarray]:
    """A distributed mesh's input to DOLFINx: each rank's cells, and its block of the nodes.

    DOLFINx numbers the input nodes by rank (rank r gives the nodes after those of the ranks
    before it), so rank r gives the coordinates of the vertices ``Blocks(N).local(r)``.
    """
    part = mesh.part
    blocks = Blocks(mesh.num_nodes, comm.size)
    (ids, x), *_ = exchange(comm, blocks.home(part.vertex_ids), part.vertex_ids, mesh.x)
    mine = blocks.local(comm.rank)
    out = np.zeros((mine.stop - mine.start, mesh.gdim))
    out[ids - mine.start] = x
    return part.vertex_ids[mesh.cells], out


def distributed_function(mesh: MeshData, nodes: np.ndarray, values: np.ndarray,
                         comm: MPI.Comm, name: str, points: DofPoints | None = None,
                         degree: int | None = None, local: bool = False, msh=None):
    """A Lagrange Function on the output mesh from (global dof point, value) pairs.

    Args:
        mesh: The mesh data.
        nodes: Global dof point of each pair.
        values: The pairs' values, shape (pairs, value size).
        comm: The ranks that hold the pairs (those of the output mesh).
        name: The Function's name.
        points: The dof points of the pairs (default: the vertices).
        degree: The Lagrange degree of the Function (default: that of ``points``); a degree-1
            Function of degree-2 values takes their values at the vertices.
        local: The pairs are the same on every rank (e.g. gathered contact data): values of
            repeated points are summed, no communication. Otherwise each rank gives its own
            pairs and the value at a point is the mean over all ranks' pairs there.
        msh: The parent mesh, if already made (see :func:`output_mesh`).
    """
    points = dof_points(mesh, 1) if points is None else points
    degree = points.degree if degree is None else degree
    nodes = np.asarray(nodes, dtype=np.int64)
    values = np.asarray(values, dtype=np.float64)
    if degree != points.degree:  # the vertices are the first dof points of every degree
        keep = nodes < mesh.num_nodes
        points = points.with_degree(degree) if mesh.part is not None else \
            dof_points(mesh, degree)
        nodes, values = nodes[keep], values[keep]
    if mesh.root_only is not None:  # only rank 0 knows the points of edges and faces
        points = RootLookup(points, mesh.root_only)
    msh, vertex, _ = output_mesh(mesh, comm, msh)
    bs = values.shape[1]
    V = compat.function_space(msh, bs, degree)
    u = compat.function(V, name)
    wanted = dof_points_of_space(V, vertex, points)
    if local:
        keys, inv = np.unique(nodes, return_inverse=True)
        summed = np.zeros((keys.size, bs))
        np.add.at(summed, inv, values)
        pos = np.minimum(np.searchsorted(keys, wanted), max(keys.size - 1, 0))
        hit = keys[pos] == wanted if keys.size else np.zeros(wanted.size, dtype=bool)
        out = np.where(hit[:, None], summed[pos] if keys.size else 0.0, 0.0)
    else:
        out = node_values(nodes, values, wanted, points.num_points, comm)
    u.x.array[:] = out.ravel()
    return u


def node_values(nodes: np.ndarray, values: np.ndarray, wanted: np.ndarray, num_nodes: int,
                comm: MPI.Comm) -> np.ndarray:
    """The mean of the given (point, value) pairs of all ranks at the ``wanted`` points.

    Args:
        nodes: Global (dof) point of each local pair (a point may repeat: subdomain copies).
        values: The pairs' values, shape (pairs, bs).
        wanted: Global points whose values this rank needs.
        num_nodes: Number of (dof) points of the whole mesh.
        comm: The ranks.

    Returns:
        Shape (wanted, bs); zero at a point no rank gave.
    """
    blocks = Blocks(num_nodes, comm.size)
    (rn, rv), *_ = exchange(comm, blocks.home(nodes), np.asarray(nodes, dtype=np.int64),
                            np.asarray(values, dtype=np.float64))
    bs = values.shape[1]
    mine = blocks.local(comm.rank)
    acc = np.zeros((mine.stop - mine.start, bs))
    cnt = np.zeros(mine.stop - mine.start)
    np.add.at(acc, rn - mine.start, rv)
    np.add.at(cnt, rn - mine.start, 1.0)
    mean = acc / np.maximum(cnt, 1.0)[:, None]
    (asked,), order, counts, rcounts = exchange(comm, blocks.home(wanted),
                                                np.asarray(wanted, dtype=np.int64))
    return answer(comm, mean[asked - mine.start], order, counts, rcounts)


def cell_function(mesh: MeshData, values: np.ndarray, name: str, comm: MPI.Comm, msh=None,
                  cells: np.ndarray | None = None, num_cells: int | None = None):
    """A DG0 (cell-wise constant) Function on the output mesh.

    ``values`` holds one value per global cell, or, with ``cells`` (this rank's global cells,
    e.g. those of its subdomains) and ``num_cells`` (of the whole mesh), one value per given
    cell: the values then go to the ranks that hold those cells of the output mesh.
    ``msh``: the parent mesh, if already made (see :func:`output_mesh`).
    """
    msh, _, cell = output_mesh(mesh, comm, msh)
    V = compat.dg0_space(msh)
    f = compat.function(V, name)
    dofs = compat.cell_dofs(V).ravel()  # one dof per local cell, in cell order
    n = min(dofs.size, cell.size)
    if cells is None:
        f.x.array[dofs[:n]] = np.asarray(values, dtype=float)[cell[:n]]
    else:
        f.x.array[dofs[:n]] = node_values(cells, np.asarray(values, dtype=float)[:, None],
                                          cell[:n], num_cells, comm)[:, 0]
    compat.scatter_forward(f)
    return f


def write_xdmf(path: str | os.PathLike, u, functions) -> None:
    """Write Functions on one mesh to XDMF; the files appear under their names only when done.

    XDMF holds Lagrange Functions of the mesh's own geometry degree: on a straight-sided mesh
    pass degree-2 fields as their vertex values (:func:`distributed_function` with ``degree=1``).

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
    publish_xdmf(tmp, path, comm)


def publish_xdmf(tmp: Path, path: Path, comm: MPI.Comm) -> None:
    """Rename a finished XDMF file ``tmp`` (and its HDF5 file) to ``path`` (collective)."""
    with collective(comm, "outputs"):
        if comm.rank == 0:
            h5_tmp, h5 = tmp.with_suffix(".h5"), path.with_suffix(".h5")
            text = tmp.read_text().replace(h5_tmp.name, h5.name)
            os.replace(h5_tmp, h5)
            tmp.write_text(text)
            os.replace(tmp, path)
