"""The Dirichlet preconditioner by explicit local blocks: B_s S_s B_sᵀ dense per subdomain.

As the dual operator (:mod:`.explicit`), the Dirichlet preconditioner B S Bᵀ (scaled:
Z B Δ S Δ Bᵀ Z) is a sum of local terms B_s S_s B_sᵀ over the subdomains, S_s the Schur
complement of K_s on the dofs B touches. :class:`DirichletPreconditioner` applies it with one
sparse solve of the interior blocks per application; here the dense blocks B_s (Δ) S_s (Δ) B_sᵀ
are formed once (max_s m_s batched interior solves, :class:`.explicit.LocalBlocks`), and an
application is a gather, one GEMV per subdomain and a scatter-add. The set-up and the saving
per application are those of the explicit dual operator (the same blocks' sizes, an interior
solve against a K⁺ solve), so it is used when F is explicit (``dual_operator``).
"""

from __future__ import annotations

from petsc4py import PETSc

from ..errors import SolveError
from .explicit import LocalBlocks
from .precond import DirichletPreconditioner


class ExplicitDirichletPreconditioner(DirichletPreconditioner):
    """M⁻¹ = B S Bᵀ (or Z B Δ S Δ Bᵀ Z) by dense local blocks formed once (collective)."""

    def __init__(self, operands, factor: str | None = None, scaling: str = "multiplicity") -> None:
        """Factor the interior blocks, then form B_s (Δ) S_s (Δ) B_sᵀ per subdomain."""
        super().__init__(operands, factor, scaling)
        if self.offsets is None:
            raise SolveError("the explicit Dirichlet preconditioner needs the offsets of the "
                             "subdomain blocks (PreconditionerOperands.offsets)")
        delta = None if self._scale is None else self._scale.delta
        self._blocks = LocalBlocks(self.B, self.offsets, self._local, delta)
        self._u = self.B.createVecLeft()

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = B S Bᵀ x (scaled if asked) by the local blocks."""
        self.count += 1
        z = self._scale
        if z is None:
            self._blocks.mult(x, y)
            return
        z.apply(x, self._t)
        self._blocks.mult(self._t, self._u)
        z.apply(self._u, y)

    def destroy(self) -> None:
        """Free the blocks and the factorization."""
        super().destroy()
        self._blocks.destroy()
        self._u.destroy()
