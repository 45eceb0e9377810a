"""The mesh as global NumPy arrays (:class:`MeshData`), whatever it was read from.

Every rank holds the whole mesh as plain arrays (or rank 0 alone, or each rank a block of its
cells: ``root_only``, ``part``); the readers (:mod:`.gmsh_input`, :mod:`.dolfinx_input`) fill
it, and the topology, checks, dof points and decomposition read it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from ..errors import InputError

#: Topological dimension of each cell type.
TDIM = {"triangle": 2, "quadrilateral": 2, "tetrahedron": 3, "hexahedron": 3}


@dataclass
class MeshData:
    """A mesh with its named physical groups, as global arrays (identical on every rank).

    Attributes:
        x: Node coordinates, shape (N, gdim).
        cells: Cell-to-vertex connectivity, shape (C, vertices per cell), node indices into
            ``x``, in DOLFINx's vertex order (tensor-product order for quadrilaterals and
            hexahedra).
        cell_type: ``"triangle"``, ``"tetrahedron"``, ``"quadrilateral"`` or ``"hexahedron"``
            (first-order cells: the nodes are the vertices).
        cell_body: For each cell, the index of its body in ``body_names``.
        body_names: The physical volume (surface in 2D) groups, in tag order.
        facet_groups: Boundary physical groups: name → facets as (F, vertices per facet)
            node indices (vertex facets, whatever the degree of the space).
        node_tags: The gmsh tag of each node (for messages).
        group_tags: name → gmsh physical tag, for every group (bodies and facet groups).
        source: The DOLFINx mesh this data was made from by :func:`~dolfinx_feti.from_dolfinx`
            (the solution is returned on it), else None.
        high_order: For a second-order (curved) mesh, the positions of its geometry nodes
            besides the vertices: entity dimension → (the entities' vertices (n, vertices per
            entity), the node's coordinates (n, gdim)), one node per edge, and per
            quadrilateral face and cell interior of quadrilaterals and hexahedra; None for a
            first-order mesh.
        root_only: For a mesh whose arrays only rank 0 of this communicator holds (the
            other ranks hold empty arrays with the same names: :meth:`names_only`), the
            communicator; None when every rank holds them.
        counts: On a rank without the arrays, the sizes of the whole mesh: ``"nodes"``,
            ``"cells"`` and ``"points<degree>"`` (dof points of a space of that degree, once
            a problem has needed them).
        part: For a mesh spread over the ranks in blocks of cells (:func:`read_gmsh` with
            ``distribute=True``), what this rank holds besides its arrays
            (:class:`~.distributed.MeshPart`); None otherwise.
    """

    x: np.ndarray
    cells: np.ndarray
    cell_type: str
    cell_body: np.ndarray
    body_names: tuple[str, ...]
    facet_groups: dict[str, np.ndarray]
    node_tags: np.ndarray
    group_tags: dict[str, int] = field(default_factory=dict)
    source: object = field(default=None, repr=False, compare=False)
    high_order: dict | None = field(default=None, repr=False, compare=False)
    root_only: MPI.Comm | None = field(default=None, repr=False, compare=False)
    counts: dict[str, int] = field(default_factory=dict, repr=False, compare=False)
    part: object = field(default=None, repr=False, compare=False)

    @property
    def holds_arrays(self) -> bool:
        """Whether this rank holds the whole arrays.

        Every rank does, except the ranks other than 0 of a root-only mesh, and every rank of
        a distributed mesh (each holds its block).
        """
        return self.part is None and (self.root_only is None or self.root_only.rank == 0)

    def names_only(self) -> MeshData:
        """The same mesh without its arrays: names, types and sizes of the arrays' rows.

        What the ranks other than 0 hold of a root-only mesh (:func:`read_gmsh` with
        ``replicate=False``).
        """
        def empty(a):
            return np.zeros((0,) + a.shape[1:], dtype=a.dtype)
        return MeshData(x=empty(self.x), cells=empty(self.cells), cell_type=self.cell_type,
                        cell_body=empty(self.cell_body), body_names=self.body_names,
                        facet_groups={n: empty(f) for n, f in self.facet_groups.items()},
                        node_tags=empty(self.node_tags), group_tags=dict(self.group_tags),
                        high_order=None if self.high_order is None else {},
                        counts={"nodes": self.num_nodes, "cells": self.num_cells})

    @property
    def geometry_degree(self) -> int:
        """1 for straight-sided cells, 2 for a second-order (curved) mesh."""
        return 1 if self.high_order is None else 2

    @property
    def gdim(self) -> int:
        """Geometric dimension."""
        return self.x.shape[1]

    @property
    def tdim(self) -> int:
        """Topological dimension of the cells."""
        return TDIM[self.cell_type]

    @property
    def num_nodes(self) -> int:
        """Number of nodes (of the whole mesh, also on a rank without the arrays)."""
        return self.counts.get("nodes", self.x.shape[0])

    @property
    def num_cells(self) -> int:
        """Number of cells (of the whole mesh, also on a rank without the arrays)."""
        return self.counts.get("cells", self.cells.shape[0])

    def body_index(self, name: str) -> int:
        """The index of a body by name, with an error that lists the known bodies."""
        try:
            return self.body_names.index(name)
        except ValueError:
            raise InputError(f"unknown body {name!r}: the mesh's bodies (physical groups of "
                             f"dimension {self.tdim}) are {list(self.body_names)}") from None

    def check_group_name(self, name: str) -> None:
        """Refuse the name of a boundary group the mesh does not have, listing those it has."""
        if name not in self.facet_groups:
            raise InputError(f"unknown boundary group {name!r}: the mesh's boundary physical "
                             f"groups (dimension {self.tdim - 1}) are {sorted(self.facet_groups)}")

    def facets(self, name: str) -> np.ndarray:
        """The facets of a boundary group, with an error that lists the known groups.

        On a rank without the arrays (a root-only mesh) only the name is checked; on a
        distributed mesh, the rank's facets of the group.
        """
        self.check_group_name(name)
        f = self.facet_groups[name]
        empty = self.part.group_sizes[name] == 0 if self.part is not None else \
            f.shape[0] == 0 and self.holds_arrays
        if empty:
            raise InputError(f"boundary group {name!r} is empty: it holds no mesh facet")
        return f


def answered_by_root(comm: MPI.Comm, query: np.ndarray, answer) -> np.ndarray:
    """``answer(query)`` of every rank's query, computed on rank 0 (collective).

    For lookups in tables of a root-only mesh, which only rank 0 holds.
    """
    asked = comm.gather(query, root=0)
    return comm.scatter([answer(q) for q in asked] if comm.rank == 0 else None, root=0)


__all__ = ["MeshData", "answered_by_root"]
