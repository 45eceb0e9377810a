"""The primal step of Total BETI: from the subdomains' nodes to their boundary nodes.

The parent is the system in the layout of every (subdomain, node) pair, as FEM has it (its K
holds S_s on the boundary dofs and nothing inside: what the solution is checked against); the
child keeps the boundary dofs only (K = diag(S_s), B without the interior columns, which are
zero: every row lives on boundary nodes). Back in the parent's layout the interior values come
from the representation formula (one sparse matrix of dense subdomain blocks), so the output
has the whole field.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from ..errors import InputError
from ..feti.system import BlockSystem, local_csr, petsc_aij


class BoundaryReduction:
    """Keep the boundary dofs of a block system; interior values by a given linear map.

    Args:
        parent: The system in the layout of all pairs.
        bdofs: Local parent dofs of the boundary, ascending (the child's dofs, in order).
        idofs: Local parent dofs inside, ascending.
        K: The child's block-diagonal matrix (diag(S_s), CSR).
        offsets: The child's local block offsets.
        kernels: The child's kernel per block.
        interior: CSR map (len(idofs) × len(bdofs)) from boundary to interior values.

    Attributes:
        child: The boundary system.
        kept: Local mask of the parent's rows the child keeps (all).
    """

    def __init__(self, parent: BlockSystem, bdofs: np.ndarray, idofs: np.ndarray,
                 K: sp.csr_matrix, offsets: np.ndarray, kernels: list[np.ndarray],
                 interior: sp.csr_matrix) -> None:
        self.parent, self.bdofs, self.idofs, self.interior = parent, bdofs, idofs, interior
        comm = parent.comm
        inside = np.zeros(parent.K.shape[0], dtype=bool)
        inside[idofs] = True
        Bl = local_csr(parent.B)
        cols = Bl.indices - parent.primal_start
        mine = (cols >= 0) & (cols < inside.size)
        on_inside = np.any(inside[cols[mine]]) if Bl.nnz else False
        if comm.allreduce(bool(on_inside)):
            raise InputError("TBETI: a constraint row has an entry on a node inside a "
                             "subdomain (a boundary group inside a body?); the boundary "
                             "element subdomains have unknowns on their boundaries only")
        nb = bdofs.size
        first = comm.exscan(nb) or 0
        total = comm.allreduce(nb)
        P = sp.csr_matrix((np.ones(nb), (bdofs, first + np.arange(nb))),
                          shape=(parent.K.shape[0], total))
        Pmat = petsc_aij(P, parent.primal_size, (nb, total), comm)
        B = parent.B.matMult(Pmat)
        Pmat.destroy()
        self.kept = np.ones(parent.dual_size[0], dtype=bool)
        self.child = BlockSystem(comm, K, parent.f.array_r[bdofs], B, parent.c.array_r,
                                 parent.types, offsets, kernels, parent.labels, parent.bodies,
                                 parent.blocks)

    def map_primal(self, Z: np.ndarray) -> np.ndarray:
        """Homogeneous primal vectors (columns, local rows) of the child → of the parent."""
        out = np.zeros((self.parent.K.shape[0], Z.shape[1]))
        out[self.bdofs] = Z
        out[self.idofs] = self.interior @ Z
        return out

    def map_back(self, u: PETSc.Vec, lam: PETSc.Vec) -> tuple[PETSc.Vec, PETSc.Vec]:
        """(u, λ) of the child → of the parent: the interior values by the representation."""
        up = self.parent.B.createVecRight()
        ub = u.array_r
        up.array[self.bdofs] = ub
        up.array[self.idofs] = self.interior @ ub
        return up, lam.copy()


__all__ = ["BoundaryReduction"]
