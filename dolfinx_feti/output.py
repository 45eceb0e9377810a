"""Output on the whole (undecomposed) mesh: merged Functions and XDMF files.

The Functions are filled from the distributed solution: each rank of the parent mesh asks for
the values at its own nodes through a directory (rank r keeps the nodes r·N // size to
(r + 1)·N // size − 1), so no rank holds an array of the whole mesh's values. (The parent mesh
itself is still built from the global mesh arrays on rank 0, as long as the input is global.)
"""

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


def distributed_function(mesh: MeshData, nodes: np.ndarray, values: np.ndarray,
                         comm: MPI.Comm, name: str, msh=None, local: bool = False):
    """A P1 Function on the parent mesh from (global node, value) pairs.

    Args:
        mesh: The global mesh (for the parent mesh).
        nodes: Global node of each pair.
        values: The pairs' values, shape (pairs, bs).
        comm: The ranks.
        name: The Function's name.
        msh: The parent mesh, if already made.
        local: The pairs are the same on every rank (e.g. gathered contact data): values of
            repeated nodes are summed, no communication. Otherwise each rank gives its own
            pairs and the value at a node is the mean over all ranks' pairs there.
    """
    msh = msh if msh is not None else parent_mesh(mesh, comm)
    bs = values.shape[1]
    V = compat.function_space(msh, bs)
    u = compat.function(V, name)
    wanted = compat.node_input_indices(msh)[compat.vertex_dof_nodes(V)]
    if local:
        keys, inv = np.unique(np.asarray(nodes, dtype=np.int64), return_inverse=True)
        summed = np.zeros((keys.size, bs))
        np.add.at(summed, inv, values)
        pos = np.minimum(np.searchsorted(keys, wanted), max(keys.size - 1, 0))
        hit = keys[pos] == wanted if keys.size else np.zeros(wanted.size, dtype=bool)
        out = np.where(hit[:, None], summed[pos] if keys.size else 0.0, 0.0)
    else:
        out = node_values(nodes, values, wanted, mesh.num_nodes, comm)
    u.x.array[:] = out.ravel()
    return u


def _exchange(comm: MPI.Comm, dest: np.ndarray, *arrays: np.ndarray):
    """Send row i of each array to rank ``dest[i]``.

    Returns the received arrays, and the send order and counts (to answer in that layout).
    """
    order = np.argsort(dest, kind="stable")
    counts = np.bincount(dest, minlength=comm.size).astype(np.int64)
    rcounts = np.empty_like(counts)
    comm.Alltoall(counts, rcounts)
    out = []
    for a in arrays:
        a = np.ascontiguousarray(a[order])
        width = int(np.prod(a.shape[1:], dtype=np.int64))
        recv = np.empty((int(rcounts.sum()),) + a.shape[1:], dtype=a.dtype)
        comm.Alltoallv([a, counts * width], [recv, rcounts * width])
        out.append(recv)
    return out, order, counts, rcounts


def _answer(comm: MPI.Comm, values: np.ndarray, order: np.ndarray, counts: np.ndarray,
            rcounts: np.ndarray) -> np.ndarray:
    """Return to each sender of :func:`_exchange` the rows ``values`` answering its rows."""
    width = int(np.prod(values.shape[1:], dtype=np.int64))
    back = np.empty((int(counts.sum()),) + values.shape[1:], dtype=values.dtype)
    comm.Alltoallv([np.ascontiguousarray(values), rcounts * width], [back, counts * width])
    out = np.empty_like(back)
    out[order] = back
    return out


def node_values(nodes: np.ndarray, values: np.ndarray, wanted: np.ndarray, num_nodes: int,
                comm: MPI.Comm) -> np.ndarray:
    """The mean of the given (node, value) pairs of all ranks at the ``wanted`` nodes.

    Args:
        nodes: Global node of each local pair (a node may repeat: subdomain copies).
        values: The pairs' values, shape (pairs, bs).
        wanted: Global nodes whose values this rank needs.
        num_nodes: Number of nodes of the whole mesh.
        comm: The ranks.

    Returns:
        Shape (wanted, bs); zero at a node no rank gave.
    """
    size = comm.size
    lo = np.arange(size + 1, dtype=np.int64) * num_nodes // size  # directory blocks

    def home(p):  # the rank whose block [lo[r], lo[r + 1]) holds node p
        return np.searchsorted(lo, np.asarray(p, dtype=np.int64), side="right") - 1

    (rn, rv), *_ = _exchange(comm, home(nodes), np.asarray(nodes, dtype=np.int64),
                             np.asarray(values, dtype=np.float64))
    bs = values.shape[1]
    n_home = int(lo[comm.rank + 1] - lo[comm.rank])
    acc = np.zeros((n_home, bs))
    cnt = np.zeros(n_home)
    np.add.at(acc, rn - lo[comm.rank], rv)
    np.add.at(cnt, rn - lo[comm.rank], 1.0)
    mean = acc / np.maximum(cnt, 1.0)[:, None]
    (asked,), order, counts, rcounts = _exchange(comm, home(wanted),
                                                 np.asarray(wanted, dtype=np.int64))
    return _answer(comm, mean[asked - lo[comm.rank]], order, counts, rcounts)


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
