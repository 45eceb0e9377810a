"""A generalized inverse K⁺ of a singular subdomain matrix by fixing nodes (sparse Cholesky)."""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from petsc4py import PETSc

from ..errors import SolveError


def choose_fixing_dofs(R: np.ndarray) -> np.ndarray:
    """k dofs whose rows of the kernel basis R (n × k) form a well-conditioned k × k block.

    Column-pivoted QR of Rᵀ picks, greedily, the dof whose kernel row is largest after removing
    the directions already taken: for rigid modes that is nodes far apart, as the theory of the
    fixing-nodes inverse asks.
    """
    _, _, piv = scipy.linalg.qr(R.T, pivoting=True, mode="economic")
    return np.sort(piv[: R.shape[1]])


class FixingNodesInverse:
    """K⁺ = [[A⁻¹, 0], [0, 0]] with A = K without the fixed dofs (exactly dim ker K of them).

    Then K K⁺ K = K holds exactly when ker K is spanned by R and R restricted to the fixed dofs
    is regular; this is checked once on a random vector of Im K.

    Args:
        K: The subdomain stiffness matrix (symmetric positive semidefinite).
        R: Basis of ker K (n × k).
        factor: PETSc Cholesky package: "cholmod", "mumps" or "petsc".
        label: Names the subdomain in error messages.
    """

    def __init__(self, K: sp.csr_matrix, R: np.ndarray, factor: str = "cholmod",
                 label: str = "") -> None:
        n = K.shape[0]
        self.fixed = choose_fixing_dofs(R)
        free = np.ones(n, dtype=bool)
        free[self.fixed] = False
        self.free = np.flatnonzero(free)
        A = K[self.free][:, self.free].tocsr()
        A.sort_indices()
        self._A = PETSc.Mat().createAIJ(size=A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                                         A.indices.astype(PETSc.IntType), A.data),
                                        comm=PETSc.COMM_SELF)
        self._A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        self._A.setOption(PETSc.Mat.Option.SPD, True)
        self._ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        self._ksp.setOperators(self._A)
        self._ksp.setType("preonly")
        pc = self._ksp.getPC()
        pc.setType("cholesky")
        pc.setFactorSolverType(factor)
        try:
            self._ksp.setUp()
        except PETSc.Error as e:
            raise SolveError(f"{label}: the Cholesky factorization ({factor}) of the stiffness "
                             "matrix without its fixing dofs failed; the matrix is not positive "
                             "definite there (a mechanism beyond the rigid-body modes, or a "
                             "non-positive material constant)") from e
        self._b, self._x = self._A.createVecs()
        self._check(K, label)

    def _check(self, K: sp.csr_matrix, label: str) -> None:
        v = np.random.default_rng(0).standard_normal(K.shape[0])
        b = K @ v
        y = np.empty_like(b)
        self.solve(b, y)
        err = np.linalg.norm(K @ y - b) / max(np.linalg.norm(b), 1e-300)
        if not err < 1e-6:
            raise SolveError(f"{label}: K K⁺ K = K fails (relative error {err:.2e}); the "
                             "stiffness matrix has a larger null space than the rigid-body "
                             "modes (a part attached by a single node, or a zero material "
                             "constant)")

    def solve(self, rhs: np.ndarray, out: np.ndarray) -> None:
        """out = K⁺ rhs (``out`` may be a view into a larger array)."""
        self._b.array[:] = rhs[self.free]
        self._ksp.solve(self._b, self._x)
        out[self.fixed] = 0.0
        out[self.free] = self._x.array_r

    def destroy(self) -> None:
        """Free the PETSc objects."""
        for obj in (self._ksp, self._A, self._b, self._x):
            obj.destroy()
