"""A mesh spread over the ranks in blocks of cells: what each rank holds after the input.

:func:`~dolfinx_feti.read_gmsh` with ``distribute=True`` reads the model on rank 0 (gmsh holds
the whole model there anyway), checks it, and hands every rank a block of the cells — with the
vertices those cells use, numbered locally in the order of their global numbers, and the
facets of the boundary groups that bound those cells — then drops the whole arrays. From then
on no rank holds an array of the size of the whole mesh.

The blocks are spatially compact: equal numbers of consecutive cells along a Morton
(Z-order) curve through the cells' midpoints, each block in the order of the global cell
numbers. Blocks of the file's order can be anything: for the structured triangle meshes of
the benchmarks, on 4 ranks no two cells of a block shared a facet, and every step that joins
cells across ranks (the connected pieces of the decomposition) then exchanged every facet.
The numbers of cells and vertices stay the file's, so nothing computed from them depends on
the blocks.

The checks that compare a facet or a node with the whole mesh (is a boundary group on the
boundary, is the mesh conforming) need the whole mesh, so rank 0 runs them while it has it and
keeps their verdicts, which are small (:class:`Verdicts`); the problem looks them up later,
when it knows which groups it uses as what.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from mpi4py import MPI

from ..errors import InputError, collective
from ..parallel.exchange import hand_out
from .checks import (
    boundary_group_verdicts,
    check_conforming,
    check_contact_surface,
    nonconforming_nodes,
    unfit_groups,
)
from .data import MeshData
from .decompose import midpoints_of
from .topology import locate_facets


@dataclass
class Verdicts:
    """Rank 0's checks of the whole mesh that depend on how the problem uses its groups.

    Attributes:
        boundary: Group → why it cannot carry a boundary integral (``{what}`` stands for the
            use), for the groups that cannot.
        contact: Group → why it cannot be a contact surface, for the groups that cannot.
        conformity: None for a conforming mesh; else a small mesh of the nonconforming nodes
            and the facets they lie on (with the boundary groups restricted to those nodes),
            and the (node, facet) pairs in its numbering, for
            :func:`~.checks.check_conforming` once the contact groups are known.
        orphans: Group → why it cannot be used at all (facets of no cell).
    """

    boundary: dict[str, str]
    contact: dict[str, str]
    conformity: tuple[MeshData, np.ndarray, np.ndarray] | None
    orphans: dict[str, str] = field(default_factory=dict)

    def check_group(self, name: str, what: str | None = None) -> None:
        """Refuse a group the whole mesh's checks found unfit for its use.

        Args:
            name: The group.
            what: Its use as the surface of a boundary integral, named for the message; None
                for a contact surface; "" for a use that only needs facets of cells (a
                Dirichlet condition).
        """
        if name in self.orphans:
            raise InputError(self.orphans[name])
        if what == "":
            return
        table = self.contact if what is None else self.boundary
        if name in table:
            raise InputError(table[name].replace("{what}", what or ""))

    def check_conforming(self, exempt_groups) -> None:
        """Refuse the mesh if nodes outside the exempt (contact) groups are nonconforming."""
        if self.conformity is not None:
            tiny, node, facet = self.conformity
            check_conforming(tiny, exempt_groups, found=(node, facet))


@dataclass
class MeshPart:
    """What one rank holds of a distributed mesh (``MeshData.part``).

    The rank's :class:`MeshData` holds its cells, their vertices (numbered locally, in the
    order of ``vertex_ids``) and the facets of its cells in the boundary groups.

    Attributes:
        comm: The ranks the mesh is spread over.
        vertex_ids: Global number of each local vertex (ascending).
        cell_ids: Global number of each local cell (ascending).
        group_sizes: Number of facets of every boundary group in the whole mesh.
        verdicts: Rank 0's checks of the whole mesh (:class:`Verdicts`).
        facet_index: Group → the position of each local facet in the whole group (the
            file's order, which the contact rows follow).
        whole_cells: The whole mesh's cells, when this rank holds the whole mesh (a mesh read
            whole, :func:`block_of`): the facet index the mesh checks cached for them serves
            the block (:func:`.connected_parts.rank_facets`). None for a distributed read.
    """

    comm: MPI.Comm
    vertex_ids: np.ndarray
    cell_ids: np.ndarray
    group_sizes: dict[str, int]
    verdicts: Verdicts
    facet_index: dict[str, np.ndarray]
    whole_cells: np.ndarray | None = None


def verdicts(mesh: MeshData) -> Verdicts:
    """The group and conformity checks of the whole ``mesh`` (on the rank that holds it)."""
    boundary = boundary_group_verdicts(mesh)
    contact = unfit_groups(mesh, check_contact_surface)
    node, facet = nonconforming_nodes(mesh)
    if node.size == 0:
        return Verdicts(boundary, contact, None)
    used = np.unique(np.r_[node, facet.ravel()])
    new = np.full(mesh.num_nodes, -1, dtype=np.int64)
    new[used] = np.arange(used.size)
    # one cell of each nonconforming node, for the body the message names
    ci, cj = np.nonzero(np.isin(mesh.cells, node))
    _, first = np.unique(mesh.cells[ci, cj], return_index=True)
    cells = mesh.cells[ci[first]]
    # the groups as the lists of their nodes among those kept (all the exemption reads)
    groups = {n: (lambda v: v[v >= 0].reshape(-1, 1))(new[np.unique(f)])
              for n, f in mesh.facet_groups.items()}
    tiny = replace(mesh.names_only(), x=mesh.x[used], cells=new[cells],
                   cell_body=mesh.cell_body[ci[first]], node_tags=mesh.node_tags[used],
                   facet_groups=groups, counts={})
    return Verdicts(boundary, contact, (tiny, new[node], new[facet]))


def compact_blocks(points: np.ndarray, size: int) -> np.ndarray:
    """The rank of each point: ``size`` nearly equal runs of the points along a Morton curve.

    The coordinates are scaled to 21-bit integers in the bounding box and their bits
    interleaved (a loop over the bits, not the points); ties keep the points' order, so the
    blocks depend on the points alone.
    """
    points = np.asarray(points, dtype=np.float64)
    n, dim = points.shape
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    lo, hi = points.min(axis=0), points.max(axis=0)
    bits = 21
    scale = np.where(hi > lo, (2**bits - 1) / np.where(hi > lo, hi - lo, 1.0), 0.0)
    q = ((points - lo) * scale).astype(np.uint64)
    code = np.zeros(n, dtype=np.uint64)
    for d in range(dim):
        code |= _spread(q[:, d], dim) << np.uint64(d)
    rank = np.empty(n, dtype=np.int64)
    rank[np.argsort(code, kind="stable")] = np.arange(n, dtype=np.int64) * size // n
    return rank


#: The bits of a 21-bit number spread to every 2nd / 3rd bit: (shift, mask) steps.
_SPREAD = {2: ((16, 0x0000FFFF0000FFFF), (8, 0x00FF00FF00FF00FF), (4, 0x0F0F0F0F0F0F0F0F),
               (2, 0x3333333333333333), (1, 0x5555555555555555)),
           3: ((32, 0x001F00000000FFFF), (16, 0x001F0000FF0000FF), (8, 0x100F00F00F00F00F),
               (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249))}


def _rows(a: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    """``a[rows]``; ``a`` itself for all its rows (None)."""
    return a if rows is None else a[rows]


def _spread(q: np.ndarray, dim: int) -> np.ndarray:
    """Bit b of each 21-bit ``q`` moved to bit b · dim (a few shifts and masks per array)."""
    if dim not in _SPREAD:
        out = np.zeros_like(q)
        for b in range(21):
            out |= ((q >> np.uint64(b)) & np.uint64(1)) << np.uint64(b * dim)
        return out
    q = q.copy()
    for shift, mask in _SPREAD[dim]:
        q = (q | (q << np.uint64(shift))) & np.uint64(mask)
    return q


def scatter_mesh(mesh: MeshData | None, comm: MPI.Comm) -> MeshData:
    """Hand every rank a block of the cells of rank 0's ``mesh`` (:func:`compact_blocks`).

    Args:
        mesh: The whole mesh, checked (rank 0; None elsewhere).
        comm: The ranks.

    Returns:
        This rank's part: a :class:`MeshData` of its cells, with ``part`` set.
    """
    return _blocks(mesh, comm, verdicts, replicated=False)[0]


def block_of(mesh: MeshData, comm: MPI.Comm, cell_arrays: dict | None = None,
             midpoints: np.ndarray | None = None) -> tuple[MeshData, dict]:
    """This rank's block of a whole mesh a problem was checked on (collective).

    The input of the one set-up pipeline (:mod:`.setup.share_distributed`) for a mesh every
    rank holds (each cuts its own block: no communication) or rank 0 alone holds
    (``root_only``: rank 0 hands the blocks out). The problem's checks have seen the whole
    mesh, so the verdicts keep only what the shares carry (the boundary groups' fitness for
    boundary integrals).

    Args:
        mesh: The whole mesh (on a root-only mesh, its arrays on rank 0 only).
        comm: The ranks.
        cell_arrays: Name → an array with one row per cell of the whole mesh (rank 0's), of
            which each rank gets its block's rows.
        midpoints: The cells' midpoints, if the caller has them (where the whole mesh is).

    Returns:
        This rank's part (``part`` set) and its rows of ``cell_arrays``.
    """
    def found(whole):
        return Verdicts(boundary_group_verdicts(whole), {}, None)

    return _blocks(mesh if mesh.holds_arrays else None, comm, found,
                   replicated=mesh.root_only is None, cell_arrays=cell_arrays,
                   midpoints=midpoints, keep_whole=True)


def _blocks(mesh: MeshData | None, comm: MPI.Comm, checks, replicated: bool,
            cell_arrays: dict | None = None, midpoints: np.ndarray | None = None,
            keep_whole: bool = False) -> tuple[MeshData, dict]:
    """The blocks of :func:`scatter_mesh` and :func:`block_of`.

    Planned on rank 0 (on every rank if ``replicated``), cut locally (``replicated``) or
    handed out; ``checks(mesh)`` gives rank 0's verdicts. ``keep_whole``: the ranks holding
    the whole mesh keep a reference to its cells (``MeshPart.whole_cells``).
    """
    common = make = None
    cell_arrays = cell_arrays or {}
    with collective(comm, "mesh"):
        if comm.rank == 0 or replicated:
            owner = np.zeros(mesh.num_cells, dtype=np.int64) if comm.size == 1 else \
                compact_blocks(midpoints_of(mesh.x, mesh.cells) if midpoints is None
                               else midpoints, comm.size)
            order = np.argsort(owner, kind="stable")  # by rank, then by cell number
            start = np.searchsorted(owner[order], np.arange(comm.size + 1))
            facet_rank, orphans = {}, {}
            for name, f in mesh.facet_groups.items():
                cell, _ = locate_facets(mesh.cells, f, mesh.cell_type)
                facet_rank[name] = np.where(cell >= 0, owner[np.maximum(cell, 0)], -1)
                if np.any(cell < 0):
                    orphans[name] = (f"boundary group {name!r} has facets that are no facet "
                                     "of any cell of the mesh")
            index = np.empty(mesh.num_nodes, dtype=np.int64)
            used = np.zeros(mesh.num_nodes, dtype=bool)

            def make(r):
                cells = order[start[r]:start[r + 1]]
                used[:] = False
                used[mesh.cells[cells]] = True
                ids = np.flatnonzero(used)
                index[ids] = np.arange(ids.size)
                if cells.size == mesh.num_cells and ids.size == mesh.num_nodes and \
                        mesh.cells.dtype == index.dtype:
                    cells = ids = None  # the whole mesh, numbered as it is: no copies
                return {"x": _rows(mesh.x, ids),
                        "cells": mesh.cells if cells is None else index[mesh.cells[cells]],
                        "cell_body": _rows(mesh.cell_body, cells),
                        "node_tags": _rows(mesh.node_tags, ids),
                        "facets": {n: index[f[facet_rank[n] == r]]
                                   for n, f in mesh.facet_groups.items()},
                        "vertex_ids": np.arange(mesh.num_nodes) if ids is None else ids,
                        "cell_ids": np.arange(mesh.num_cells) if cells is None else cells,
                        "facet_index": {n: np.flatnonzero(facet_rank[n] == r)
                                        for n in mesh.facet_groups},
                        "arrays": {k: _rows(a, cells) for k, a in cell_arrays.items()}}

        if comm.rank == 0:
            found = checks(mesh)
            found.orphans = orphans
            common = {"names": mesh.names_only(), "verdicts": found,
                      "sizes": {n: int(f.shape[0]) for n, f in mesh.facet_groups.items()}}
    common = comm.bcast(common, root=0)
    p = make(comm.rank) if replicated else hand_out(comm, make, "handing out the mesh")
    names = common["names"]
    part = MeshPart(comm=comm, vertex_ids=p["vertex_ids"], cell_ids=p["cell_ids"],
                    group_sizes=common["sizes"], verdicts=common["verdicts"],
                    facet_index=p["facet_index"],
                    whole_cells=mesh.cells if keep_whole and mesh is not None else None)
    return replace(names, x=p["x"], cells=p["cells"], cell_body=p["cell_body"],
                   node_tags=p["node_tags"], facet_groups=p["facets"], part=part,
                   counts=dict(names.counts)), p["arrays"]


__all__ = ["MeshPart", "Verdicts", "block_of", "compact_blocks", "scatter_mesh", "verdicts"]
