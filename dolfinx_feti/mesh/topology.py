"""Vectorized mesh topology and geometry on global arrays: facets, neighbours, normals, areas."""

from __future__ import annotations

import numpy as np

# Local facets of a simplex: facet j is the one opposite vertex j.
_LOCAL_FACETS = {
    2: np.array([[1, 2], [0, 2], [0, 1]]),
    3: np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]),
}


def _row_keys(a: np.ndarray, bound: int | None = None) -> np.ndarray:
    """One sortable scalar per row of a non-negative integer array, the same for permuted rows.

    With ``bound`` (all entries < bound) and bound**width < 2**63 the key is an int64 (fast to
    sort); otherwise the row's bytes.
    """
    a = np.ascontiguousarray(np.sort(a, axis=1), dtype=np.int64)
    width = a.shape[1]
    if bound is not None and width * np.log2(max(bound, 2)) < 62:
        key = np.zeros(a.shape[0], dtype=np.int64)
        for j in range(width):  # over the 2 or 3 vertices of a facet
            key = key * bound + a[:, j]
        return key
    return a.view(np.dtype((np.void, a.dtype.itemsize * width))).ravel()


_FACET_INDEX: list = []  # (cells, sorted keys, order): one mesh's facet index, kept for reuse


def _facet_index(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Sorted keys of all cell facets and their positions (cached for the last cells array)."""
    if _FACET_INDEX and _FACET_INDEX[0][0] is cells:
        return _FACET_INDEX[0][1:]
    tdim = cells.shape[1] - 1
    bound = int(cells.max()) + 1 if cells.size else 1
    keys = _row_keys(cell_facets(cells).reshape(-1, tdim), bound)
    order = np.argsort(keys, kind="stable")
    _FACET_INDEX[:] = [(cells, keys[order], order, bound)]
    return keys[order], order, bound


def cell_facets(cells: np.ndarray) -> np.ndarray:
    """All facets of all cells, shape (C, tdim + 1, tdim); facet j is opposite vertex j."""
    tdim = cells.shape[1] - 1
    return cells[:, _LOCAL_FACETS[tdim]]


def facet_neighbours(cells: np.ndarray) -> np.ndarray:
    """Pairs of cells that share a facet, shape (P, 2)."""
    tdim = cells.shape[1] - 1
    sorted_keys, order, _ = _facet_index(cells)
    same = sorted_keys[1:] == sorted_keys[:-1]
    owner = order // (tdim + 1)
    return np.stack([owner[:-1][same], owner[1:][same]], axis=1)


def locate_facets(cells: np.ndarray, facets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each given facet, one cell containing it and the local index of the facet in that cell.

    Returns ``(cell, local)``; both are -1 for a facet that is no facet of any cell.
    """
    tdim = cells.shape[1] - 1
    sorted_keys, order, bound = _facet_index(cells)
    facets = np.asarray(facets)
    if facets.size and facets.max() >= bound:
        return np.full(facets.shape[0], -1), np.full(facets.shape[0], -1)
    keys = _row_keys(facets, bound)
    pos = np.searchsorted(sorted_keys, keys)
    pos = np.minimum(pos, order.size - 1)
    hit = sorted_keys[pos] == keys
    flat = np.where(hit, order[pos], -1)
    return np.where(hit, flat // (tdim + 1), -1), np.where(hit, flat % (tdim + 1), -1)


def facet_normals(x: np.ndarray, cells: np.ndarray,
                  facets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals and measures (length/area) of boundary facets.

    The outward side is the side away from the cell that holds the facet; with a facet of two
    cells (an interior facet) the first one found is used.
    """
    cell, local = locate_facets(cells, facets)
    if np.any(cell < 0):
        raise ValueError("facets that belong to no cell")
    p = x[facets]
    if x.shape[1] == 2:
        t = p[:, 1] - p[:, 0]
        n = np.stack([t[:, 1], -t[:, 0]], axis=1)
    else:
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    size = np.linalg.norm(n, axis=1)
    if x.shape[1] == 3:
        size = size / 2.0
    opposite = x[cells[cell, local]]
    sign = np.sign(np.einsum("ij,ij->i", n, p[:, 0] - opposite))
    n = n * (sign / np.linalg.norm(n, axis=1))[:, None]
    return n, size


def nodal_normals_and_areas(x: np.ndarray, cells: np.ndarray, facets: np.ndarray
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node-wise outward normals and lumped areas of a boundary surface.

    Returns ``(nodes, normals, areas)``: the surface's nodes (sorted), the unit normal at each
    (the area-weighted mean of its facets' normals) and its lumped area (the integral of its
    hat function over the surface).

    Raises:
        ValueError: If the facet normals cancel at a node (a surface folded onto itself).
    """
    n, size = facet_normals(x, cells, facets)
    nodes, inv = np.unique(facets, return_inverse=True)
    inv = inv.reshape(facets.shape)
    nv = facets.shape[1]
    acc = np.zeros((nodes.size, x.shape[1]))
    area = np.zeros(nodes.size)
    for j in range(nv):  # loop over the 2 or 3 vertices of a facet, not over nodes
        np.add.at(acc, inv[:, j], n * size[:, None])
        np.add.at(area, inv[:, j], size / nv)
    norm = np.linalg.norm(acc, axis=1)
    if np.any(norm <= 1e-8 * area):
        raise ValueError("facet normals cancel at some nodes")
    return nodes, acc / norm[:, None], area


def cell_volumes(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Signed cell volumes (areas in 2D)."""
    tdim = cells.shape[1] - 1
    e = x[cells[:, 1:]] - x[cells[:, :1]]
    if tdim == 2 and x.shape[1] == 2:
        return 0.5 * (e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    if tdim == 3:  # the triple product: np.linalg.det calls LAPACK once per cell
        return np.einsum("ij,ij->i", np.cross(e[:, 0], e[:, 1]), e[:, 2]) / 6.0
    return 0.5 * np.linalg.norm(np.cross(e[:, 0], e[:, 1]), axis=1)
