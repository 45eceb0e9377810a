"""FETI coarse matrices Gᵀ = B R of a Cartesian lattice of subdomains, without a mesh.

``ns^dim`` box subdomains of ``q^dim`` cells each share their interface nodes; the gluing and
Dirichlet rows are the library's own (``constraints.gluing``, ``constraints.dirichlet``) and
R is the library's rigid-mode basis, so ``G Gᵀ`` has the pattern and scaling of a real Total
FETI coarse problem (one face clamped) at any number of subdomains. Used by the coarse-problem
tests and by ``bench/coarse_problem.py``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from dolfinx_feti.constraints.dirichlet import dirichlet_rows
from dolfinx_feti.constraints.gluing import gluing_rows
from dolfinx_feti.constraints.rows import Rows
from dolfinx_feti.fem.rigid import rigid_modes


def _grid(n: int, dim: int) -> np.ndarray:
    return np.stack(np.meshgrid(*[np.arange(n)] * dim, indexing="ij"), -1).reshape(-1, dim)


def lattice_gt(ns: int, dim: int, value_size: int | None = None, q: int = 2,
               clamped: bool = True, gluing: str = "orthonormal") -> sp.csr_matrix:
    """Gᵀ (dual rows × k·ns^dim) of the lattice, k rigid modes per subdomain.

    Args:
        ns: Subdomains per direction.
        dim: 2 or 3.
        value_size: 1 (scalar, k = 1) or ``dim`` (elasticity, k = 3 or 6); default ``dim``.
        q: Cells per subdomain and direction.
        clamped: Dirichlet rows on the face x = 0; without them ``G Gᵀ`` is singular (the
            rigid motions of the whole lattice).
        gluing: Gluing scheme (see ``ContactProblem.gluing``).
    """
    bs = dim if value_size is None else value_size
    n1 = ns * q + 1
    grid = _grid(n1, dim)
    x = grid / (n1 - 1)
    num_nodes = grid.shape[0]
    ijk = _grid(ns, dim)[:, None, :] * q + _grid(q + 1, dim)[None]
    node = np.ravel_multi_index(tuple(np.moveaxis(ijk, -1, 0)), (n1,) * dim)  # sorted per sub
    nsub, per_sub = node.shape
    pair_sub = np.repeat(np.arange(nsub), per_sub)
    order = np.argsort(node.ravel(), kind="stable")
    node_ptr = np.concatenate([[0], np.cumsum(np.bincount(node.ravel(), minlength=num_nodes))])
    node_subs = pair_sub[order]
    fixed = np.zeros((num_nodes, bs), dtype=bool)
    if clamped:
        fixed[grid[:, 0] == 0] = True
    rows = Rows.concatenate([gluing_rows(node_ptr, node_subs, fixed, bs, dim, gluing),
                             dirichlet_rows(node_ptr, node_subs, fixed,
                                            np.zeros((num_nodes, bs)), bs, dim)])
    keys = (pair_sub * num_nodes + node.ravel()).astype(np.int64)  # sorted
    pair = np.searchsorted(keys, rows.e_sub.astype(np.int64) * num_nodes + rows.e_node)
    B = sp.csr_matrix((rows.e_coef, (rows.e_row, bs * pair + rows.e_comp)),
                      shape=(rows.size, bs * keys.size))
    R = sp.block_diag([sp.csr_matrix(rigid_modes(x[node[s]], bs)) for s in range(nsub)],
                     format="csr")
    Gt = (B @ R).tocsr()
    Gt.eliminate_zeros()
    return Gt
