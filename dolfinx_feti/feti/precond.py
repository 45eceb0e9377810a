"""FETI preconditioners of the dual operator F = B K⁺ Bᵀ: lumped (B K Bᵀ) and Dirichlet (B S Bᵀ).

The rows of B are orthonormal on the gluing (k − 1 Helmert rows at a node of k subdomains),
which is the multiplicity scaling for these rows: with equal subdomains, B S Bᵀ inverts F on an
interface exactly. S_i is the Schur complement of K_i on the dofs that B touches (the
interface, Dirichlet and contact dofs of the subdomain), applied with a sparse Cholesky
factorization of the interior block.

Stiffness scaling (``scaling="stiffness"``, Rixen & Farhat, IJNME 44 (1999) 489–516): with
Δ = diag(K)⁻¹ (each dof weighted by the inverse of its own stiffness) the preconditioner is
Z B Δ K Bᵀ Δ Z (lumped) or Z B Δ S Δ Bᵀ Z (Dirichlet), Z = (B Δ Bᵀ)⁻¹. Across a coefficient
jump the stiff side then carries the interface, which multiplicity scaling cannot see. Z is
applied with a sparse Cholesky factorization of the dual matrix B Δ Bᵀ (the ``factor``
package, redundantly on every rank when there are several): two extra sparse solves of dual
size per application.

Both are applied as ``mult(x, y)`` objects on dual vectors; the QP solvers project and mask
them as the constraints require. They are built from the operands a primal system gives
(``preconditioner_operands()``): its block-diagonal K, the rows B of the dual, and the dofs to
leave out (FETI-DP's corners, which are primal unknowns: the Dirichlet preconditioner then
takes the Schur complement with them held, B_r S_rr B_rᵀ).
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..errors import SolveError
from ..factor import default_factor
from .kplus import SparseCholesky

SCALINGS = ("multiplicity", "stiffness")


class _DualScaling:
    """Z = (B Δ Bᵀ)⁻¹ with Δ = diag(K)⁻¹: the stiffness scaling of the dual space."""

    def __init__(self, K, B, factor: str | None = None) -> None:
        diag = K.diagonal()
        if diag.size and not np.all(diag > 0):
            raise SolveError("stiffness scaling: a subdomain matrix has a non-positive "
                             "diagonal entry")
        self.delta = 1.0 / diag
        Bd = B.duplicate(copy=True)
        dvec = B.createVecRight()
        dvec.array[:] = self.delta
        Bd.diagonalScale(R=dvec)  # B Δ
        self._C = Bd.matTransposeMult(B)  # B Δ Bᵀ
        Bd.destroy()
        dvec.destroy()
        # B Δ Bᵀ is tiny and very sparse (rows couple only through shared dofs): factor it with
        # the sequential package (CHOLMOD, else PETSc's own by default; MUMPS took 4 s and 45 ms
        # per solve where CHOLMOD took 3 ms and 0.2 ms, 32 256 rows); on several ranks
        # redundantly on each (PCREDUNDANT), which needs no parallel factorization.
        factor = factor or default_factor()
        comm = B.getComm()
        self._ksp = PETSc.KSP().create(comm)
        self._ksp.setOperators(self._C)
        self._ksp.setType("preonly")
        pc = self._ksp.getPC()
        opts, prefix = PETSc.Options(), f"feti_dualscale_{id(self)}_"
        if comm.getSize() == 1:
            pc.setType("cholesky")
            pc.setFactorSolverType(factor)
        else:
            self._ksp.setOptionsPrefix(prefix)
            pc.setType("redundant")
            opts[f"{prefix}redundant_pc_type"] = "cholesky"
            opts[f"{prefix}redundant_pc_factor_mat_solver_type"] = factor
            self._ksp.setFromOptions()
        try:
            self._ksp.setUp()
            singular = not self._solves_accurately()
        except PETSc.Error:
            singular = True
        finally:
            for key in ("redundant_pc_type", "redundant_pc_factor_mat_solver_type"):
                opts.delValue(f"{prefix}{key}")
        if singular:
            raise SolveError("stiffness scaling: B diag(K)⁻¹ Bᵀ cannot be factored (are the "
                             "rows of B redundant? use gluing='orthonormal')")

    def _solves_accurately(self) -> bool:
        """A trial solve with a random right-hand side (collective).

        CHOLMOD refuses a singular B Δ Bᵀ while factoring it; PETSc's own Cholesky only flags a
        zero pivot in the solve's converged reason, and round-off pivots pass unflagged, so
        the residual decides: a regular matrix is solved to round-off, a singular one leaves the
        part of a random vector outside its range (of order 1/sqrt(rows)).
        """
        b, y = self._C.createVecs()
        r = b.duplicate()
        b.array[:] = np.random.default_rng(b.getOwnershipRange()[0]).standard_normal(
            b.getLocalSize())
        self._ksp.solve(b, y)
        self._C.mult(y, r)
        r.axpy(-1.0, b)
        ok = self._ksp.getConvergedReason() >= 0 and r.norm() <= 1e-6 * b.norm()
        for v in (b, y, r):
            v.destroy()
        return bool(ok)

    def apply(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = Z x."""
        self._ksp.solve(x, y)
        if self._ksp.getConvergedReason() < 0:
            raise SolveError("stiffness scaling: the solve with B diag(K)⁻¹ Bᵀ failed")

    def destroy(self) -> None:
        self._ksp.destroy()
        self._C.destroy()


class LumpedPreconditioner:
    """M⁻¹ = B K Bᵀ: one sparse matrix-vector product with the rank's block-diagonal K (cheap).

    With ``scaling="stiffness"``: M⁻¹ = Z B Δ K Δ Bᵀ Z (see the module docstring).
    """

    name = "lumped"

    def __init__(self, operands, scaling: str = "multiplicity", factor: str | None = None) -> None:
        """Use ``operands = (K, B, left_out)`` of a primal system (see the module docstring)."""
        if scaling not in SCALINGS:
            raise ValueError(f"preconditioner scaling must be one of {SCALINGS}, got "
                             f"{scaling!r}")
        self.K, self.B, self.left_out = operands
        self.count = 0
        self._w = self.B.createVecRight()
        self._v = self.B.createVecRight()
        #: Notes for the report (a scaling that could not be applied).
        self.notes: list[str] = []
        self._scale = self._t = None
        if scaling == "stiffness":
            try:
                self._scale = _DualScaling(self.K, self.B, factor)
                self._t = self.B.createVecLeft()  # a dual work vector for Z
            except SolveError as e:
                # Redundant rows of B (gluing="redundant", two obstacles on one surface) make
                # B Δ Bᵀ singular: keep the preconditioner, unscaled, and say so.
                scaling = "multiplicity"
                self.notes.append(f"{e}; the {self.name} preconditioner uses multiplicity "
                                  "scaling instead")
        self.scaling = scaling

    def _local(self, w: np.ndarray) -> np.ndarray:
        return self.K @ w

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = B K Bᵀ x (or B S Bᵀ x for the Dirichlet preconditioner), scaled if asked."""
        self.count += 1
        z = self._scale
        if z is None:
            self.B.multTranspose(x, self._w)
            self._v.array[:] = self._local(self._w.array_r)
            self.B.mult(self._v, y)
            return
        z.apply(x, self._t)
        self.B.multTranspose(self._t, self._w)
        self._v.array[:] = z.delta * self._local(z.delta * self._w.array_r)
        self.B.mult(self._v, self._t)
        z.apply(self._t, y)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        self._w.destroy()
        self._v.destroy()
        if self._scale is not None:
            self._scale.destroy()
            self._t.destroy()


class DirichletPreconditioner(LumpedPreconditioner):
    """M⁻¹ = B S Bᵀ with S_i = K_bb − K_bi K_ii⁻¹ K_ib on the dofs b that B touches.

    The interior blocks of all local subdomains are factored together (block diagonal). Dofs
    left out (``operands[2]``) that B does not touch are held: neither b nor interior.
    """

    name = "dirichlet"

    def __init__(self, operands, factor: str | None = None, scaling: str = "multiplicity") -> None:
        """Factor the interior blocks of the local subdomains."""
        super().__init__(operands, scaling, factor)
        K, B = self.K, self.B
        n = K.shape[0]
        # the dofs touched by some row (on any rank): Bᵀ w ≠ 0 for positive random weights w
        w = B.createVecLeft()
        w.array[:] = 1.0 + np.random.default_rng(B.getComm().getRank()).random(w.getLocalSize())
        t = B.createVecRight()
        B.multTranspose(w, t)
        self._b = np.flatnonzero(t.array_r != 0.0)
        w.destroy()
        t.destroy()
        inner = np.ones(n, dtype=bool)
        inner[self._b] = False
        if self.left_out is not None:
            inner &= ~self.left_out
        interior = np.flatnonzero(inner)
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


def make_preconditioner(kind: str, primal, factor: str | None = None,
                        scaling: str = "multiplicity"):
    """``"none"`` → None, ``"lumped"``, ``"dirichlet"`` (``scaling``: see the module).

    ``primal`` is a primal system (its ``preconditioner_operands()``) or the operands.
    """
    if kind == "none":
        return None
    operands = primal.preconditioner_operands() if hasattr(primal, "preconditioner_operands") \
        else primal
    if kind == "lumped":
        return LumpedPreconditioner(operands, scaling, factor)
    if kind == "dirichlet":
        return DirichletPreconditioner(operands, factor, scaling)
    raise ValueError(f"unknown preconditioner {kind!r}: use 'none', 'lumped' or 'dirichlet'")
