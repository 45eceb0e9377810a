"""A mesh spread over the ranks in blocks of cells: what each rank holds after the input.

:func:`~dolfinx_feti.read_gmsh` with ``distribute=True`` reads the model on rank 0 (gmsh holds
the whole model there anyway), checks it, and hands every rank a contiguous block of the cells
in the file's order — with the vertices those cells use, numbered locally in the order of their
global numbers, and the facets of the boundary groups that bound those cells — then drops the
whole arrays. From then on no rank holds an array of the size of the whole mesh.

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
from ..exchange import Blocks, hand_out
from .checks import (
    boundary_group_verdicts,
    check_conforming,
    check_contact_surface,
    nonconforming_nodes,
    unfit_groups,
)
from .gmsh_input import MeshData
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
    """

    comm: MPI.Comm
    vertex_ids: np.ndarray
    cell_ids: np.ndarray
    group_sizes: dict[str, int]
    verdicts: Verdicts
    facet_index: dict[str, np.ndarray]


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


def scatter_mesh(mesh: MeshData | None, comm: MPI.Comm) -> MeshData:
    """Hand every rank a contiguous block of the cells of rank 0's ``mesh`` (collective).

    Args:
        mesh: The whole mesh, checked (rank 0; None elsewhere).
        comm: The ranks.

    Returns:
        This rank's part: a :class:`MeshData` of its cells, with ``part`` set.
    """
    common = make = None
    with collective(comm, "mesh"):
        if comm.rank == 0:
            blocks = Blocks(mesh.num_cells, comm.size)
            facet_rank, orphans = {}, {}
            for name, f in mesh.facet_groups.items():
                cell, _ = locate_facets(mesh.cells, f, mesh.cell_type)
                facet_rank[name] = np.where(cell >= 0, blocks.home(np.maximum(cell, 0)), -1)
                if np.any(cell < 0):
                    orphans[name] = (f"boundary group {name!r} has facets that are no facet "
                                     "of any cell of the mesh")
            found = verdicts(mesh)
            found.orphans = orphans
            common = {"names": mesh.names_only(), "verdicts": found,
                      "sizes": {n: int(f.shape[0]) for n, f in mesh.facet_groups.items()}}
            index = np.empty(mesh.num_nodes, dtype=np.int64)
    common = comm.bcast(common, root=0)
    if comm.rank == 0:

        def make(r):
            cells = np.arange(blocks.lo[r], blocks.lo[r + 1])
            ids = np.unique(mesh.cells[cells])
            index[ids] = np.arange(ids.size)
            return {"x": mesh.x[ids], "cells": index[mesh.cells[cells]],
                    "cell_body": mesh.cell_body[cells], "node_tags": mesh.node_tags[ids],
                    "facets": {n: index[f[facet_rank[n] == r]]
                               for n, f in mesh.facet_groups.items()},
                    "vertex_ids": ids, "cell_ids": cells,
                    "facet_index": {n: np.flatnonzero(facet_rank[n] == r)
                                    for n in mesh.facet_groups}}

    p = hand_out(comm, make, "handing out the mesh")
    names = common["names"]
    part = MeshPart(comm=comm, vertex_ids=p["vertex_ids"], cell_ids=p["cell_ids"],
                    group_sizes=common["sizes"], verdicts=common["verdicts"],
                    facet_index=p["facet_index"])
    return replace(names, x=p["x"], cells=p["cells"], cell_body=p["cell_body"],
                   node_tags=p["node_tags"], facet_groups=p["facets"], part=part,
                   counts=dict(names.counts))


__all__ = ["MeshPart", "Verdicts", "scatter_mesh", "verdicts"]
