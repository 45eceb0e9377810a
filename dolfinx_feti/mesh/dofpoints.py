"""Where the dofs of a continuous Lagrange space sit: global dof points of degree 1 and 2.

Topology and decomposition work on cells and vertices (:mod:`.topology`, :mod:`.decompose`);
the primal dof order and the rows of B (gluing, Dirichlet, contact) are addressed by
(subdomain, dof point, component). For degree 1 the dof points are the vertices. For degree 2
they are the vertices (numbered as in the mesh), then one point per edge, per quadrilateral face
of a hexahedron and per quadrilateral or hexahedral cell (the interior dof): the entities that
carry one dof of basix's Lagrange element of degree 2. An entity is known by the sorted global
numbers of its vertices; the points of one dimension are numbered in the order of those keys, so
the numbering is the same on every rank and for every number of ranks, and each rank could
compute the numbers of its own entities from distributed data. The coordinates are the entity
midpoints on first-order cells (straight edges, bilinear faces: the image of the reference dof
point), and the mesh's own geometry nodes on a second-order (curved) mesh, where the degree-2
space is isoparametric.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .data import MeshData, answered_by_root
from .topology import FACET_TYPE, REFERENCE, locate_facets, row_keys


def degree2_entities(cell_type: str) -> tuple[tuple[int, tuple[tuple[int, ...], ...]], ...]:
    """The entities with a dof of degree 2 besides the vertices: ((dim, local vertex lists),)."""
    return _DEGREE2_ENTITIES[cell_type]


#: Entities with a dof of degree 2 besides the vertices: cell type → (dim, local vertex lists).
_DEGREE2_ENTITIES = {
    "triangle": ((1, REFERENCE["triangle"].edges),),
    "tetrahedron": ((1, REFERENCE["tetrahedron"].edges),),
    "quadrilateral": ((1, REFERENCE["quadrilateral"].edges), (2, ((0, 1, 2, 3),))),
    "hexahedron": ((1, REFERENCE["hexahedron"].edges), (2, REFERENCE["hexahedron"].facets),
                   (3, (tuple(range(8)),))),
}

#: facet type → degree → (entities on the facet beyond its vertices, as (dim, local vertex
#: lists); the integral of each point's basis function over the facet / the facet's measure).
_FACET_LAYOUT = {
    "interval": {1: ((), [1 / 2, 1 / 2]),
                 2: (((1, ((0, 1),)),), [1 / 6, 1 / 6, 2 / 3])},
    # degree 2: the integrals of the transformed basis of the contact rows (the plain vertex
    # functions integrate to zero; constraints/quadratic_triangles.py)
    "triangle": {1: ((), [1 / 3] * 3),
                 2: (((1, REFERENCE["triangle"].edges),), [2 / 15] * 3 + [1 / 5] * 3)},
    "quadrilateral": {1: ((), [1 / 4] * 4),
                      2: (((1, REFERENCE["quadrilateral"].edges), (2, ((0, 1, 2, 3),))),
                          [1 / 36] * 4 + [1 / 9] * 4 + [4 / 9])},
}


def facet_weights(cell_type: str, degree: int) -> np.ndarray:
    """For each dof point of a facet of ``cell_type`` cells, ∫ φ / |facet| (degree 1 or 2)."""
    return np.array(_FACET_LAYOUT[FACET_TYPE[cell_type]][degree][1])


@dataclass
class DofPoints:
    """The global dof points of a Lagrange space of degree 1 or 2 on a first-order mesh.

    Attributes:
        degree: The polynomial degree.
        cell_type: The cells' type.
        x: Coordinates of the points, shape (M, gdim); the first ``num_vertices`` are the
            mesh's vertices in its order.
        cell_points: The points of each cell, (C, k): its vertices, then its edges, faces and
            interior in the reference order.
        num_vertices: Number of vertices of the mesh.
        entities: dim → (sorted keys of the entities of that dimension with a point, the index
            of the first such point).
    """

    degree: int
    cell_type: str
    x: np.ndarray
    cell_points: np.ndarray
    num_vertices: int
    entities: dict[int, tuple[np.ndarray, int]]

    @property
    def num_points(self) -> int:
        """Number of dof points."""
        return self.x.shape[0]

    @property
    def facet_weights(self) -> np.ndarray:
        """For each point of a facet (see :meth:`facet_points`), ∫ φ / |facet|."""
        return facet_weights(self.cell_type, self.degree)

    def lookup(self, dim: int, vertices: np.ndarray) -> np.ndarray:
        """The point of each entity of dimension ``dim`` given by its global vertices (rows).

        Vertices (dim 0) are their own points; -1 for an entity that has no point (no such
        entity in the mesh).
        """
        vertices = np.asarray(vertices, dtype=np.int64)
        if dim == 0:
            return vertices.reshape(-1)
        if dim not in self.entities or vertices.shape[0] == 0:
            return np.full(vertices.shape[0], -1, dtype=np.int64)
        keys, first = self.entities[dim]
        k = row_keys(vertices, self.num_vertices)
        pos = np.minimum(np.searchsorted(keys, k), keys.size - 1)
        return np.where(keys[pos] == k, first + pos, -1)

    def facet_points(self, mesh: MeshData, facets: np.ndarray) -> np.ndarray:
        """The points on each facet, (F, kf): its vertices, then its edges and face interior.

        The facets are given by their vertices in any order; the points follow the order of
        :attr:`facet_weights`.

        Raises:
            ValueError: If a facet is no facet of a cell.
        """
        facets = np.asarray(facets, dtype=np.int64)
        if self.degree == 1:
            return facets
        cell, local = locate_facets(mesh.cells, facets, mesh.cell_type)
        if np.any(cell < 0):
            raise ValueError("facets that belong to no cell")
        ref = np.array(REFERENCE[mesh.cell_type].facets)
        facets = mesh.cells[cell[:, None], ref[local]]  # in the cell's (reference) facet order
        parts = [facets]
        for dim, local_entities in _FACET_LAYOUT[FACET_TYPE[mesh.cell_type]][2][0]:
            v = facets[:, np.array(local_entities)]  # (F, ne, nve)
            parts.append(self.lookup(dim, v.reshape(-1, v.shape[2])).reshape(v.shape[:2]))
        out = np.concatenate(parts, axis=1)
        if np.any(out < 0):
            raise ValueError("facets that belong to no cell")
        return out

    def group_points(self, mesh: MeshData, group: str) -> np.ndarray:
        """The sorted points on the facets of a boundary group (vertices, edges, faces)."""
        try:
            return np.unique(self.facet_points(mesh, mesh.facets(group)))
        except ValueError:
            raise InputError(f"boundary group {group!r} has facets that are no facet of any "
                             "cell of the mesh") from None


@dataclass
class RootPoints(DofPoints):
    """The dof points of a root-only mesh on a rank without its arrays.

    It knows the sizes of the whole mesh's points; :func:`root_lookup` answers its lookups
    through rank 0.
    """

    total: int = 0

    @property
    def num_points(self) -> int:
        """Number of dof points of the whole mesh."""
        return self.total


class RootLookup:
    """Dof points of a root-only mesh whose lookups rank 0 answers (collective calls).

    Every rank of the mesh's communicator wraps its points (rank 0 its global ones) and calls
    :meth:`lookup` the same number of times with the same dimensions.
    """

    def __init__(self, points: DofPoints, comm) -> None:
        self.points, self.comm = points, comm

    def __getattr__(self, name):
        return getattr(self.points, name)

    def lookup(self, dim: int, vertices: np.ndarray) -> np.ndarray:
        """:meth:`DofPoints.lookup`, answered by rank 0 (collective)."""
        if dim == 0:
            return np.asarray(vertices, dtype=np.int64).reshape(-1)
        return answered_by_root(self.comm, np.asarray(vertices, dtype=np.int64),
                                lambda v: self.points.lookup(dim, v))


_CACHE: list = []  # (x, cells, degree, DofPoints) of the last meshes, by identity


def dof_points(mesh: MeshData, degree: int = 1) -> DofPoints:
    """The dof points of the Lagrange space of ``degree`` (1 or 2) on ``mesh`` (cached)."""
    for x, cells, d, pts in _CACHE:
        if x is mesh.x and cells is mesh.cells and d == degree:
            return pts
    pts = _build(mesh, degree)
    _CACHE.insert(0, (mesh.x, mesh.cells, degree, pts))
    del _CACHE[4:]
    return pts


def _build(mesh: MeshData, degree: int) -> DofPoints:
    if degree not in (1, 2):
        raise ValueError(f"Lagrange degree {degree}: only 1 and 2 are supported")
    cells, N = mesh.cells, mesh.num_nodes
    if not mesh.holds_arrays:
        total = N if degree == 1 else mesh.counts.get(f"points{degree}", -1)
        k = cells.shape[1] + (0 if degree == 1 else sum(
            len(local) for _, local in _DEGREE2_ENTITIES[mesh.cell_type]))
        return RootPoints(degree, mesh.cell_type, mesh.x, np.zeros((0, k), dtype=np.int64), N,
                          {}, total=total)
    if degree == 1:
        return DofPoints(1, mesh.cell_type, mesh.x, cells, N, {})
    C = cells.shape[0]
    parts, xs, entities, offset = [cells], [mesh.x], {}, N
    for dim, local in _DEGREE2_ENTITIES[mesh.cell_type]:
        v = cells[:, np.array(local)]  # (C, ne, nve)
        flat = v.reshape(-1, v.shape[2])
        keys, first, inv = np.unique(row_keys(flat, N), return_index=True, return_inverse=True)
        parts.append(offset + inv.reshape(C, v.shape[1]))
        xs.append(_positions(mesh, dim, flat[first], keys))
        entities[dim] = (keys, offset)
        offset += keys.size
    return DofPoints(2, mesh.cell_type, np.concatenate(xs), np.concatenate(parts, axis=1), N,
                     entities)


def _positions(mesh: MeshData, dim: int, vertices: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """The dof points of entities (sorted by ``keys``): their curved-geometry node, or midpoint.

    A midpoint sums the vertices in the order of their global numbers, so that it does not
    depend on which cell supplies the entity (bit for bit: the distributed set-up computes it
    from any cell that holds the entity, :mod:`.distributed_points`).
    """
    if mesh.high_order is None:
        return mesh.x[np.sort(vertices, axis=1)].mean(axis=1)
    ent, pos = mesh.high_order.get(dim, (np.zeros((0, vertices.shape[1]), dtype=np.int64),
                                         np.zeros((0, mesh.gdim))))
    k = row_keys(ent, mesh.num_nodes)
    order = np.argsort(k)
    at = np.searchsorted(k[order], keys)
    at = np.minimum(at, max(k.size - 1, 0))
    if k.size == 0 or np.any(k[order][at] != keys):
        raise InputError("the second-order mesh lacks the geometry node of some edge or face")
    return pos[order][at]


__all__ = ["DofPoints", "RootLookup", "RootPoints", "dof_points"]
