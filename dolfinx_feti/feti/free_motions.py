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


def remove_free_motions(Z: np.ndarray, weight: np.ndarray | None, u: PETSc.Vec,
                        comm: MPI.Comm) -> None:
    """Make ``u`` orthogonal to the free rigid motions (in place; collective).

    Args:
        Z: The free motions at the local entries of ``u`` (columns; Z = R n_k mapped back to
            the layout of ``u``, n_k with Gᵀ n_k = B R n_k = 0).
        weight: Per local entry, 1 / the number of subdomain copies of its node (each mesh
            node counted once); None for all ones.
        u: The primal solution, subdomain copies of each node included.
        comm: The communicator of ``u``.
    """
    if Z.shape[1] == 0:
        return
    w = np.ones(Z.shape[0]) if weight is None else weight
    ua = u.array
    gram = comm.allreduce(Z.T @ (w[:, None] * Z), op=MPI.SUM)
    coef = comm.allreduce(Z.T @ (w * ua), op=MPI.SUM)
    ua -= Z @ np.linalg.solve(gram, coef)


__all__ = ["remove_free_motions"]
