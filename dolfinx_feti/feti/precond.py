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
from petsc4py import PETSc

from ..errors import SolveError
from .kplus import SparseCholesky


class LumpedPreconditioner:
    """M⁻¹ = B K Bᵀ: one sparse matrix-vector product with the rank's block-diagonal K (cheap)."""

    name = "lumped"

    def __init__(self, feti) -> None:
        """Use the subdomain matrices of a :class:`~dolfinx_feti.feti.TotalFETI`."""
        self.feti = feti
        self.count = 0
        self._w = feti.B.createVecRight()
        self._v = feti.B.createVecRight()

    def _local(self, w: np.ndarray) -> np.ndarray:
        return self.feti.K_local @ w

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = B K Bᵀ x (or B S Bᵀ x for the Dirichlet preconditioner)."""
        self.count += 1
        self.feti.B.multTranspose(x, self._w)
        self._v.array[:] = self._local(self._w.array_r)
        self.feti.B.mult(self._v, y)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        self._w.destroy()
        self._v.destroy()


class DirichletPreconditioner(LumpedPreconditioner):
    """M⁻¹ = B S Bᵀ with S_i = K_bb − K_bi K_ii⁻¹ K_ib on the dofs b that B touches.

    The interior blocks of all local subdomains are factored together (block diagonal).
    """

    name = "dirichlet"

    def __init__(self, feti, factor: str = "cholmod") -> None:
        """Factor the interior blocks of the local subdomains."""
        super().__init__(feti)
        rows, dec, bs = feti.rows, feti.dec, feti.bs
        mine = np.isin(rows.e_sub, np.fromiter(feti.R, dtype=np.int64))
        start = np.zeros(dec.num_subdomains, dtype=np.int64)  # local offset of each subdomain
        for s, seg in feti._segments():
            start[s] = seg.start
        sub = rows.e_sub[mine]
        local = start[sub] + bs * (dec.pair_index(sub, rows.e_node[mine]) - dec.sub_ptr[sub]) \
            + rows.e_comp[mine]
        n = feti.K_local.shape[0]
        self._b = np.unique(local)
        interior = np.setdiff1d(np.arange(n), self._b)
        K = feti.K_local
        self._Kbb = K[self._b][:, self._b].tocsr()
        self._Kib = K[interior][:, self._b].tocsr()
        try:
            self._chol = SparseCholesky(K[interior][:, interior], factor) if interior.size \
                else None
        except PETSc.Error as e:
            raise SolveError("Dirichlet preconditioner: an interior block is singular (the "
                             "constrained dofs of a subdomain do not fix it)") from e

    def _local(self, w: np.ndarray) -> np.ndarray:
        out = np.zeros_like(w)
        wb = w[self._b]
        sb = self._Kbb @ wb
        if self._chol is not None:
            sb -= self._Kib.T @ self._chol.solve(self._Kib @ wb)
        out[self._b] = sb
        return out

    def destroy(self) -> None:
        """Free the factorization."""
        super().destroy()
        if self._chol is not None:
            self._chol.destroy()


def make_preconditioner(kind: str, feti, factor: str = "cholmod"):
    """``"none"`` → None, ``"lumped"``, ``"dirichlet"``."""
    if kind == "none":
        return None
    if kind == "lumped":
        return LumpedPreconditioner(feti)
    if kind == "dirichlet":
        return DirichletPreconditioner(feti, factor)
    raise ValueError(f"unknown preconditioner {kind!r}: use 'none', 'lumped' or 'dirichlet'")
