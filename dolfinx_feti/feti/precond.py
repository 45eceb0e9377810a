"""FETI preconditioners of the dual operator F = B K⁺ Bᵀ: lumped (B K Bᵀ) and Dirichlet (B S Bᵀ).

The rows of B are orthonormal on the gluing (k − 1 Helmert rows at a node of k subdomains),
which is the multiplicity scaling for these rows: with equal subdomains, B S Bᵀ inverts F on an
interface exactly. S_i is the Schur complement of K_i on the dofs that B touches (the
interface, Dirichlet and contact dofs of the subdomain), applied with a sparse Cholesky
factorization of the interior block.

Both are applied as ``mult(x, y)`` objects on dual vectors; the QP solvers project and mask
them as the constraints require.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from ..errors import SolveError


class _Cholesky:
    """A sparse Cholesky solver of an SPD SciPy matrix through PETSc (COMM_SELF)."""

    def __init__(self, A: sp.csr_matrix, factor: str) -> None:
        A = A.tocsr()
        A.sort_indices()
        self._A = PETSc.Mat().createAIJ(size=A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                                         A.indices.astype(PETSc.IntType), A.data),
                                        comm=PETSc.COMM_SELF)
        self._A.setOption(PETSc.Mat.Option.SPD, True)
        self._ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        self._ksp.setOperators(self._A)
        self._ksp.setType("preonly")
        self._ksp.getPC().setType("cholesky")
        self._ksp.getPC().setFactorSolverType(factor)
        self._ksp.setUp()
        self._b, self._x = self._A.createVecs()

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        self._b.array[:] = rhs
        self._ksp.solve(self._b, self._x)
        return self._x.array_r.copy()

    def destroy(self) -> None:
        for obj in (self._ksp, self._A, self._b, self._x):
            obj.destroy()


class LumpedPreconditioner:
    """M⁻¹ = B K Bᵀ: one sparse matrix-vector product per subdomain (cheap)."""

    name = "lumped"

    def __init__(self, feti) -> None:
        """Use the subdomain matrices of a :class:`~dolfinx_feti.feti.TotalFETI`."""
        self.feti = feti
        self.count = 0
        self._w = feti.B.createVecRight()
        self._v = feti.B.createVecRight()

    def _local(self, s: int, w: np.ndarray) -> np.ndarray:
        return self.feti.K[s] @ w

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = B K Bᵀ x (or B S Bᵀ x for the Dirichlet preconditioner)."""
        self.count += 1
        self.feti.B.multTranspose(x, self._w)
        wa, va = self._w.array_r, self._v.array
        for s, seg in self.feti._segments():
            va[seg] = self._local(s, wa[seg])
        self.feti.B.mult(self._v, y)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        self._w.destroy()
        self._v.destroy()


class DirichletPreconditioner(LumpedPreconditioner):
    """M⁻¹ = B S Bᵀ with S_i = K_bb − K_bi K_ii⁻¹ K_ib on the dofs b that B touches."""

    name = "dirichlet"

    def __init__(self, feti, factor: str = "cholmod") -> None:
        """Factor the interior blocks of the local subdomains."""
        super().__init__(feti)
        self._parts = {}
        rows, dec, bs = feti.rows, feti.dec, feti.bs
        for s, seg in feti._segments():
            mine = rows.e_sub == s
            local = bs * (dec.pair_index(rows.e_sub[mine], rows.e_node[mine])
                          - dec.sub_ptr[s]) + rows.e_comp[mine]
            n = seg.stop - seg.start
            b = np.unique(local)
            interior = np.setdiff1d(np.arange(n), b)
            K = feti.K[s]
            if interior.size == 0:
                self._parts[s] = (b, K[b][:, b].tocsr(), None, None)
                continue
            Kib = K[interior][:, b].tocsr()
            try:
                solver = _Cholesky(K[interior][:, interior], factor)
            except PETSc.Error as e:
                raise SolveError(f"Dirichlet preconditioner: the interior block of subdomain "
                                 f"{s} is singular (its constrained dofs do not fix it)") from e
            self._parts[s] = (b, K[b][:, b].tocsr(), Kib, solver)

    def _local(self, s: int, w: np.ndarray) -> np.ndarray:
        b, Kbb, Kib, solver = self._parts[s]
        out = np.zeros_like(w)
        wb = w[b]
        sb = Kbb @ wb
        if solver is not None:
            sb -= Kib.T @ solver.solve(Kib @ wb)
        out[b] = sb
        return out

    def destroy(self) -> None:
        """Free the factorizations."""
        super().destroy()
        for _, _, _, solver in self._parts.values():
            if solver is not None:
                solver.destroy()


def make_preconditioner(kind: str, feti, factor: str = "cholmod"):
    """``"none"`` → None, ``"lumped"``, ``"dirichlet"``."""
    if kind == "none":
        return None
    if kind == "lumped":
        return LumpedPreconditioner(feti)
    if kind == "dirichlet":
        return DirichletPreconditioner(feti, factor)
    raise ValueError(f"unknown preconditioner {kind!r}: use 'none', 'lumped' or 'dirichlet'")
