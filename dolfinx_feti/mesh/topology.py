"""Vectorized mesh topology and geometry on global arrays: facets, neighbours, normals, areas.

Cells are first-order triangles, tetrahedra, quadrilaterals or hexahedra with their vertices in
DOLFINx's (basix's) reference order: counter-clockwise for simplices as given, tensor-product
order for quadrilaterals ``(0,0), (1,0), (0,1), (1,1)`` and hexahedra (x fastest). The
functions take the cell type; without it a cell of 3 vertices is a triangle and one of 4 a
tetrahedron (the simplex meshes of older callers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ReferenceCell:
    """The local entities of a reference cell, as lists of its local vertices (basix order)."""

    tdim: int
    num_vertices: int
    edges: tuple[tuple[int, ...], ...]
    facets: tuple[tuple[int, ...], ...]

    @property
    def simplex(self) -> bool:
        """Whether the cell is a simplex."""
        return self.num_vertices == self.tdim + 1


#: The reference cells (checked against ``basix.topology`` in the tests).
REFERENCE = {
    "triangle": ReferenceCell(2, 3, ((1, 2), (0, 2), (0, 1)), ((1, 2), (0, 2), (0, 1))),
    "quadrilateral": ReferenceCell(2, 4, ((0, 1), (0, 2), (1, 3), (2, 3)),
                                   ((0, 1), (0, 2), (1, 3), (2, 3))),
    "tetrahedron": ReferenceCell(3, 4, ((2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1)),
                                 ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))),
    "hexahedron": ReferenceCell(
        3, 8, ((0, 1), (0, 2), (0, 4), (1, 3), (1, 5), (2, 3), (2, 6), (3, 7), (4, 5), (4, 6),
               (5, 7), (6, 7)),
        ((0, 1, 2, 3), (0, 1, 4, 5), (0, 2, 4, 6), (1, 3, 5, 7), (2, 3, 6, 7), (4, 5, 6, 7))),
}

#: The facets' own reference cell: a facet with these vertices is a line, triangle or quad.
FACET_TYPE = {"triangle": "interval", "quadrilateral": "interval", "tetrahedron": "triangle",
              "hexahedron": "quadrilateral"}


def reference(cells: np.ndarray, cell_type: str | None = None) -> ReferenceCell:
    """The reference cell of ``cells`` (simplices when ``cell_type`` is None)."""
    if cell_type is None:
        cell_type = {3: "triangle", 4: "tetrahedron"}[cells.shape[1]]
    ref = REFERENCE[cell_type]
    if cells.ndim != 2 or cells.shape[1] != ref.num_vertices:
        raise ValueError(f"{cell_type} cells need {ref.num_vertices} vertices, got an array of "
                         f"shape {cells.shape}")
    return ref


def row_keys(a: np.ndarray, bound: int | None = None) -> np.ndarray:
    """One sortable scalar per row of a non-negative integer array, the same for permuted rows.

    With ``bound`` (all entries < bound) and bound**width < 2**63 the key is an int64 (fast to
    sort); otherwise the row's bytes. Either way the keys sort as the sorted rows do
    lexicographically, so a monotone renumbering of the entries keeps their order (a rank's
    local entities are numbered in the global order: :func:`~dolfinx_feti.setup.share.share_out`).
    """
    a = np.ascontiguousarray(np.sort(a, axis=1), dtype=np.int64)
    width = a.shape[1]
    if bound is not None and width * np.log2(max(bound, 2)) < 62:
        key = np.zeros(a.shape[0], dtype=np.int64)
        for j in range(width):  # over the 2 to 8 vertices of an entity
            key = key * bound + a[:, j]
        return key
    # big-endian: byte order (memcmp, how NumPy sorts void) is then numeric order
    a = np.ascontiguousarray(a, dtype=">i8")
    return a.view(np.dtype((np.void, a.dtype.itemsize * width))).ravel()


# (cells, sorted keys, order, bound), the latest used first: the facet indices of the last two
# cells arrays, kept for reuse (two: a mesh's index outlives the small meshes checked beside it,
# such as the contact surface the set-up builds)
_FACET_INDEX: list = []
_FACET_INDEX_KEPT = 2


def facet_index(cells: np.ndarray, cell_type: str | None = None, cache: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, int]:
    """Sorted keys of all cell facets and their positions (cached for the last cells array).

    Position p is facet ``p % nf`` of cell ``p // nf`` (nf facets per cell). ``cache=False``
    for a passing array (a few cells), whose index would evict a mesh's.
    """
    for i, entry in enumerate(_FACET_INDEX):
        if entry[0] is cells:
            _FACET_INDEX.insert(0, _FACET_INDEX.pop(i))
            return entry[1:]
    f = cell_facets(cells, cell_type)
    bound = int(cells.max()) + 1 if cells.size else 1
    keys = row_keys(f.reshape(-1, f.shape[2]), bound)
    order = np.argsort(keys, kind="stable")
    if cache:
        _FACET_INDEX[:] = [(cells, keys[order], order, bound), *_FACET_INDEX][:_FACET_INDEX_KEPT]
    return keys[order], order, bound


def cell_facets(cells: np.ndarray, cell_type: str | None = None) -> np.ndarray:
    """All facets of all cells, shape (C, nf, nvf), in the reference order.

    For simplices facet j is the one opposite vertex j.
    """
    return cells[:, np.array(reference(cells, cell_type).facets)]


def facets_per_cell(cells: np.ndarray, cell_type: str | None = None) -> int:
    """Number of facets of each cell."""
    return len(reference(cells, cell_type).facets)


def facet_neighbours(cells: np.ndarray, cell_type: str | None = None) -> np.ndarray:
    """Pairs of cells that share a facet, shape (P, 2)."""
    nf = facets_per_cell(cells, cell_type)
    sorted_keys, order, _ = facet_index(cells, cell_type)
    same = sorted_keys[1:] == sorted_keys[:-1]
    owner = order // nf
    return np.stack([owner[:-1][same], owner[1:][same]], axis=1)


def locate_few_facets(cells: np.ndarray, facets: np.ndarray, cell_type: str | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`locate_facets` for facets that are few against the cells, without their index.

    Only a cell with a whole facet on the facets' vertices can hold one: the facets are
    located among those cells (the same cell as :func:`locate_facets` finds: the first),
    without the sort of all the cells' facets.
    """
    facets = np.asarray(facets)
    nvf = len(reference(cells, cell_type).facets[0])
    on = np.zeros(int(max(cells.max(initial=-1), facets.max(initial=-1))) + 1, dtype=bool)
    on[facets] = True
    near = np.flatnonzero(np.count_nonzero(on[cells], axis=1) >= nvf)
    cell, local = locate_facets(cells[near], facets, cell_type, cache=False)
    return np.where(cell >= 0, near[np.maximum(cell, 0)] if near.size else -1, -1), local


def locate_facets(cells: np.ndarray, facets: np.ndarray, cell_type: str | None = None,
                  cache: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """For each given facet, one cell containing it and the local index of the facet in that cell.

    Returns ``(cell, local)``; both are -1 for a facet that is no facet of any cell.
    ``cache``: as :func:`facet_index`.
    """
    nf = facets_per_cell(cells, cell_type)
    sorted_keys, order, bound = facet_index(cells, cell_type, cache)
    facets = np.asarray(facets)
    if facets.size and facets.max() >= bound:
        return np.full(facets.shape[0], -1), np.full(facets.shape[0], -1)
    keys = row_keys(facets, bound)
    pos = np.searchsorted(sorted_keys, keys)
    pos = np.minimum(pos, order.size - 1)
    hit = sorted_keys[pos] == keys if order.size else np.zeros(keys.size, dtype=bool)
    flat = np.where(hit, order[pos], -1) if order.size else np.full(keys.size, -1)
    return np.where(hit, flat // nf, -1), np.where(hit, flat % nf, -1)


def facets_in_cell_order(cells: np.ndarray, facets: np.ndarray, cell_type: str | None = None
                         ) -> np.ndarray:
    """The facets' vertices in the order of the reference facet of a cell that holds them.

    For quadrilateral facets (of hexahedra) that is the tensor order ``(0, 0), (1, 0),
    (0, 1), (1, 1)`` of their bilinear map; segments and triangles are returned as given.

    Raises:
        ValueError: If a facet belongs to no cell.
    """
    if facets.shape[1] != 4:
        return facets
    cell, local = locate_facets(cells, facets, cell_type)
    if np.any(cell < 0):
        raise ValueError("facets that belong to no cell")
    return cells[cell[:, None], np.array(reference(cells, cell_type).facets)[local]]


def facet_normals(x: np.ndarray, cells: np.ndarray, facets: np.ndarray,
                  cell_type: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals and measures (length/area) of boundary facets.

    The normal of a quadrilateral facet (of a hexahedron) is that of its diagonals' plane and
    its area half their cross product (exact for a planar quadrilateral). The outward side is
    the side away from the centroid of the cell that holds the facet; with a facet of two
    cells (an interior facet) the first one found is used.
    """
    cell, local = locate_facets(cells, facets, cell_type)
    if np.any(cell < 0):
        raise ValueError("facets that belong to no cell")
    if facets.shape[1] == 4:  # put the quadrilateral's vertices in the cell's (tensor) order
        facets = cells[cell[:, None], np.array(reference(cells, cell_type).facets)[local]]
    p = x[facets]
    if x.shape[1] == 2:
        t = p[:, 1] - p[:, 0]
        n = np.stack([t[:, 1], -t[:, 0]], axis=1)
    elif facets.shape[1] == 4:  # tensor order: the diagonals are 0-3 and 1-2
        n = np.cross(p[:, 3] - p[:, 0], p[:, 2] - p[:, 1])
    else:
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    size = np.linalg.norm(n, axis=1)
    if x.shape[1] == 3:
        size = size / 2.0
    inside = x[cells[cell]].mean(axis=1)
    sign = np.sign(np.einsum("ij,ij->i", n, p.mean(axis=1) - inside))
    n = n * (sign / np.linalg.norm(n, axis=1))[:, None]
    return n, size


def nodal_normals_and_areas(x: np.ndarray, cells: np.ndarray, facets: np.ndarray,
                            cell_type: str | None = None
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node-wise outward normals and lumped areas of a boundary surface (vertices of P1/Q1).

    Returns ``(nodes, normals, areas)``: the surface's nodes (sorted), the unit normal at each
    (the area-weighted mean of its facets' normals) and its lumped area (the integral of its
    hat function over the surface, exact on parallelograms).

    Raises:
        ValueError: If the facet normals cancel at a node (a surface folded onto itself).
    """
    nv = facets.shape[1]
    return surface_points(x, cells, facets, facets, np.full(nv, 1.0 / nv), cell_type)


def surface_points(x: np.ndarray, cells: np.ndarray, facets: np.ndarray,
                   facet_points: np.ndarray, weights: np.ndarray, cell_type: str | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Normals and lumped areas at the points of a surface that carry dofs.

    Args:
        x: Vertex coordinates.
        cells: Cells (vertices).
        facets: The surface's facets (vertices), (F, nvf).
        facet_points: The points on each facet (dof points), (F, k).
        weights: The integral of each point's basis function over a facet divided by the
            facet's measure, (k,).
        cell_type: The cells' type.

    Returns:
        ``(points, normals, areas)``: the sorted points, the area-weighted mean of the normals
        of the facets around each, and the lumped areas Σ weight × facet measure.

    Raises:
        ValueError: If the facet normals cancel at a point (a surface folded onto itself).
    """
    n, size = facet_normals(x, cells, facets, cell_type)
    points, inv = np.unique(facet_points, return_inverse=True)
    inv = inv.reshape(facet_points.shape)
    acc = np.zeros((points.size, x.shape[1]))
    area = np.zeros(points.size)
    for j in range(facet_points.shape[1]):  # over the 2 to 9 points of a facet, not over nodes
        np.add.at(acc, inv[:, j], n * size[:, None])
        np.add.at(area, inv[:, j], size * weights[j])
    norm = np.linalg.norm(acc, axis=1)
    scale = np.zeros(points.size)
    np.add.at(scale, inv.ravel(), np.repeat(size, facet_points.shape[1]))
    if np.any(norm <= 1e-8 * scale):
        raise ValueError("facet normals cancel at some nodes")
    return points, acc / norm[:, None], area


def corner_jacobians(x: np.ndarray, cells: np.ndarray, cell_type: str) -> np.ndarray:
    """The Jacobian determinant of a quadrilateral/hexahedron at each corner, shape (C, nv).

    At corner i (tensor bits a, b[, c]) it is the determinant of the edges to the corner's
    neighbours along each axis, signed so that all corners of a valid cell have the sign of
    its orientation; a corner of the other sign (or zero) means a folded (or flat) cell.
    """
    ref = REFERENCE[cell_type]
    d = ref.tdim
    out = np.empty((cells.shape[0], ref.num_vertices))
    for i in range(ref.num_vertices):  # 4 or 8 corners
        e = np.stack([x[cells[:, i ^ (1 << k)]] - x[cells[:, i]] for k in range(d)], axis=1)
        sign = (-1.0) ** bin(i).count("1")
        out[:, i] = sign * np.linalg.det(e[:, :, :d]) if x.shape[1] == d else \
            sign * np.linalg.norm(np.cross(e[:, 0], e[:, 1]), axis=1)
    return out


def cell_volumes(x: np.ndarray, cells: np.ndarray, cell_type: str | None = None) -> np.ndarray:
    """Signed cell volumes (areas in 2D).

    For quadrilaterals and hexahedra the mean corner Jacobian (exact for parallelograms and
    parallelepipeds).
    """
    ref = reference(cells, cell_type)
    if not ref.simplex:
        return corner_jacobians(x, cells, cell_type).mean(axis=1)
    tdim = ref.tdim
    e = x[cells[:, 1:]] - x[cells[:, :1]]
    if tdim == 2 and x.shape[1] == 2:
        return 0.5 * (e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    if tdim == 3:  # the triple product: np.linalg.det calls LAPACK once per cell
        return np.einsum("ij,ij->i", np.cross(e[:, 0], e[:, 1]), e[:, 2]) / 6.0
    return 0.5 * np.linalg.norm(np.cross(e[:, 0], e[:, 1]), axis=1)
