"""Gluing rows: continuity of the displacement at nodes shared by several subdomains.

Subdomains are glued through the global node numbers they share (exact, no coordinate
tolerance).
"""

from __future__ import annotations

import numpy as np

from .rows import Kind, Rows


def _helmert(k: int) -> np.ndarray:
    """k − 1 orthonormal rows spanning {v in R^k : sum(v) = 0} (the differences e_a − e_b)."""
    H = np.zeros((k - 1, k))
    for j in range(1, k):
        H[j - 1, :j] = 1.0
        H[j - 1, j] = -j
        H[j - 1] /= np.sqrt(j * (j + 1))
    return H


def _pairs(k: int, scheme: str) -> np.ndarray:
    if scheme == "orthonormal":
        return _helmert(k)
    idx = [(a, b) for a in range(k) for b in range(a + 1, k)] if scheme == "redundant" else \
        [(a, a + 1) for a in range(k - 1)]
    M = np.zeros((len(idx), k))
    for r, (a, b) in enumerate(idx):
        M[r, a], M[r, b] = 1.0 / np.sqrt(2.0), -1.0 / np.sqrt(2.0)
    return M


def gluing_rows(node_ptr: np.ndarray, node_subs: np.ndarray, fixed: np.ndarray, bs: int,
                gdim: int, scheme: str) -> Rows:
    """Rows u_a = u_b for every component of every node in k >= 2 subdomains.

    Components with a Dirichlet condition are skipped: their Dirichlet rows on every copy of
    the node already make the copies equal.

    Args:
        node_ptr: Node → subdomains containing it (CSR pointer) ...
        node_subs: ... and the subdomains, sorted per node.
        fixed: (N, bs) mask of Dirichlet-constrained components.
        bs: Components per node.
        gdim: Geometric dimension (shape of the normal field).
        scheme: "orthonormal", "redundant" or "nonredundant".
    """
    mult = np.diff(node_ptr)
    blocks = []
    for k in np.unique(mult[mult >= 2]):
        coef = _pairs(int(k), scheme)  # (r, k)
        r = coef.shape[0]
        for c in range(bs):
            nodes = np.flatnonzero((mult == k) & ~fixed[:, c])
            if nodes.size == 0:
                continue
            subs = node_subs[node_ptr[nodes][:, None] + np.arange(k)]  # (n, k)
            n = nodes.size
            nz = coef != 0.0
            row_local, col_local = np.nonzero(nz)
            e_row = (np.arange(n)[:, None] * r + row_local[None, :]).ravel()
            e_sub = subs[:, col_local].ravel()
            e_node = np.repeat(nodes, row_local.size)
            e_coef = np.tile(coef[nz], n)
            nrows = n * r
            blocks.append(Rows(
                e_row=e_row, e_sub=e_sub.astype(np.int32), e_node=e_node,
                e_comp=np.full(e_row.size, c, dtype=np.int8), e_coef=e_coef,
                rhs=np.zeros(nrows), kind=np.full(nrows, Kind.GLUE, dtype=np.int8),
                scale=np.ones(nrows), node=np.repeat(nodes, r), partner=np.full(nrows, -1),
                normal=np.zeros((nrows, gdim)), spec=np.full(nrows, -1, dtype=np.int32)))
    if not blocks:
        return Rows.empty(gdim)
    # Node-major order (then component) for a deterministic, readable layout.
    rows = Rows.concatenate(blocks)
    comp = np.zeros(rows.size, dtype=np.int64)
    comp[rows.e_row] = rows.e_comp
    return rows.permuted(np.lexsort((comp, rows.node)))
