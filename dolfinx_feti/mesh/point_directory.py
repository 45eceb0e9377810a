"""The global dof points of a distributed mesh, looked up through a directory of entities.

On a mesh read with ``distribute=True`` no rank holds the table of all edges and faces that
:meth:`~.dofpoints.DofPoints.lookup` searches. Each rank knows the global point of every entity
of its own cells (its share); it registers them with a home rank chosen from the entity's
vertices, and a lookup asks the home of each entity.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from ..parallel.exchange import answer, exchange
from .dofpoints import degree2_entities
from .topology import row_keys


def _home(vertices: np.ndarray, size: int) -> np.ndarray:
    """The rank that keeps an entity: from the sum of its (global) vertices."""
    return (vertices.sum(axis=1) % size).astype(np.int64)


class PointDirectory:
    """Lookups of global dof points by entity vertices on a distributed mesh (collective).

    It stands in for :class:`~.dofpoints.DofPoints` where the output maps the dofs of a
    DOLFINx space to global points: ``degree``, ``cell_type``, ``num_points`` and
    :meth:`lookup`, which every rank calls the same number of times with the same dimensions.

    Args:
        cell_type: The cells' type.
        degree: 1 (the vertices) or the share's degree.
        num_vertices: Number of vertices of the whole mesh.
        comm: The ranks.
        share: This rank's share (:class:`~dolfinx_feti.setup.share.RankShare`), whose entities
            are registered (needed for degree 2).
    """

    def __init__(self, cell_type: str, degree: int, num_vertices: int, comm: MPI.Comm,
                 share=None) -> None:
        self.degree, self.cell_type, self.comm = degree, cell_type, comm
        self.num_points = num_vertices if degree == 1 else share.num_points
        self.num_vertices = num_vertices
        self._tables: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        if degree == 1:
            return
        vertex_ids = share.point_ids[:share.mesh.x.shape[0]]  # the vertices come first
        cells = share.mesh.cells
        column = cells.shape[1]
        for dim, local in degree2_entities(self.cell_type):
            v = np.sort(vertex_ids[cells[:, np.array(local)]], axis=2)  # (C, ne, nve)
            pts = share.point_ids[share.points.cell_points[:, column:column + len(local)]]
            column += len(local)
            flat = v.reshape(-1, v.shape[2])
            (rv, rp), *_ = exchange(comm, _home(flat, comm.size), flat, pts.ravel())
            keys = row_keys(rv, num_vertices)
            keys, first = np.unique(keys, return_index=True)
            self._tables[dim] = (keys, rp[first])

    def with_degree(self, degree: int) -> PointDirectory:
        """The directory of another degree: only degree 1 (the vertices) is made from this."""
        if degree == self.degree:
            return self
        if degree != 1:
            raise ValueError(f"a directory of degree {degree} needs the share")
        return PointDirectory(self.cell_type, 1, self.num_vertices, self.comm)

    def lookup(self, dim: int, vertices: np.ndarray) -> np.ndarray:
        """The global point of each entity given by its global vertices (-1: no such entity)."""
        vertices = np.asarray(vertices, dtype=np.int64)
        if dim == 0:
            return vertices.reshape(-1)
        flat = np.sort(vertices, axis=1)
        (asked,), order, counts, rcounts = exchange(self.comm, _home(flat, self.comm.size), flat)
        keys, pts = self._tables.get(dim, (np.zeros(0, dtype=np.int64), np.zeros(0, np.int64)))
        k = row_keys(asked, self.num_vertices)
        if keys.size:
            pos = np.minimum(np.searchsorted(keys, k), keys.size - 1)
            found = np.where(keys[pos] == k, pts[pos], -1)
        else:
            found = np.full(asked.shape[0], -1, dtype=np.int64)
        return answer(self.comm, found.astype(np.int64), order, counts, rcounts)


__all__ = ["PointDirectory"]
