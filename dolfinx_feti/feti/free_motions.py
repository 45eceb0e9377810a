"""The representative of a solution that a rigid motion no condition fixes leaves undetermined.

A body that nothing holds in some direction (sliding on a frictionless surface, floating
unloaded) has solutions u + z for every such motion z: B R n = 0 (no row sees it) and the load
has no component along it. Total FETI's recovery u = K⁺(f − Bᵀλ) + Rα picks one of them
through the generalized inverse and the coarse amplitudes, which depend on the decomposition.
:func:`remove_free_motions` returns instead the one orthogonal to every free motion in the
nodal ℓ² inner product (each mesh node counted once): the displacement has zero mean along
each free motion, whatever the decomposition and the number of ranks.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc


def remove_free_motions(feti, null_space: np.ndarray, u: PETSc.Vec) -> None:
    """Make ``u`` orthogonal to the free rigid motions (in place; collective).

    Args:
        feti: The :class:`~dolfinx_feti.feti.tfeti.TotalFETI` operators (kernels, layout).
        null_space: Orthonormal coarse vectors n_k with Gᵀ n_k = B R n_k = 0 (columns).
        u: The primal solution, subdomain copies of each node included.
    """
    K = null_space.shape[1]
    if K == 0:
        return
    dec, k, bs = feti.dec, feti.k, feti.bs
    count = np.diff(dec.node_subdomains()[0])  # subdomains holding each node
    n_loc = u.getLocalSize()
    Z = np.zeros((n_loc, K))
    w = np.zeros(n_loc)
    for s, seg in feti._segments():
        Z[seg] = feti.R[s] @ null_space[k * s:k * (s + 1)]
        w[seg] = np.repeat(1.0 / count[dec.nodes(s)], bs)
    ua = u.array
    gram = feti.comm.allreduce(Z.T @ (w[:, None] * Z), op=MPI.SUM)
    coef = feti.comm.allreduce(Z.T @ (w * ua), op=MPI.SUM)
    ua -= Z @ np.linalg.solve(gram, coef)


__all__ = ["remove_free_motions"]
