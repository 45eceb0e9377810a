"""Vectorized mesh topology and geometry on global arrays: facets, neighbours, normals, areas."""

from __future__ import annotations

import numpy as np

# Local facets of a simplex: facet j is the one opposite vertex j.
_LOCAL_FACETS = {
    2: np.array([[1, 2], [0, 2], [0, 1]]),
    3: np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]),
}


def _row_keys(a: np.ndarray) -> np.ndarray:
    """One hashable scalar per row of an integer array with sorted rows (for set operations)."""
    a = np.ascontiguousarray(np.sort(a, axis=1), dtype=np.int64)
    return a.view(np.dtype((np.void, a.dtype.itemsize * a.shape[1]))).ravel()


def cell_facets(cells: np.ndarray) -> np.ndarray:
    """All facets of all cells, shape (C, tdim + 1, tdim); facet j is opposite vertex j."""
    tdim = cells.shape[1] - 1
    return cells[:, _LOCAL_FACETS[tdim]]


def facet_neighbours(cells: np.ndarray) -> np.ndarray:
    """Pairs of cells that share a facet, shape (P, 2)."""
    tdim = cells.shape[1] - 1
    f = cell_facets(cells).reshape(-1, tdim)
    keys = _row_keys(f)
    order = np.argsort(keys, kind="stable")
    same = keys[order[1:]] == keys[order[:-1]]
    owner = order // (tdim + 1)
    return np.stack([owner[:-1][same], owner[1:][same]], axis=1)


def locate_facets(cells: np.ndarray, facets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each given facet, one cell containing it and the local index of the facet in that cell.

    Returns ``(cell, local)``; both are -1 for a facet that is no facet of any cell.
    """
    tdim = cells.shape[1] - 1
    all_keys = _row_keys(cell_facets(cells).reshape(-1, tdim))
    order = np.argsort(all_keys, kind="stable")
    keys = _row_keys(facets)
    pos = np.searchsorted(all_keys[order], keys)
    pos = np.minimum(pos, order.size - 1)
    hit = all_keys[order][pos] == keys
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
    if tdim == 3:
        return np.linalg.det(e) / 6.0
    return 0.5 * np.linalg.norm(np.cross(e[:, 0], e[:, 1]), axis=1)
