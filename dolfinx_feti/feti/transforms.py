"""Transforms of the FETI primal problem: each builds the next problem and maps a solution back.

As PERMON's QPT does, every step of the chain

    [eliminate Dirichlet conditions] → [eliminate corners] → dualize → homogenize → project

is an object that holds the problem it produced (``child``) and turns a solution of that problem
into one of its parent (``map_back``). The primal steps live here and in :mod:`.corners`; the
dualization in :mod:`.dualize`; homogenization and projection are the QP transforms of
:mod:`dolfinx_feti.qp.equality`. A row that a step removes (a Dirichlet row whose dof is
eliminated, a gluing row between corner copies that became one dof) gets its multiplier back in
``map_back`` from the equilibrium of its parent, so every method returns the multipliers of
all rows, the same as Total FETI's.
"""

from __future__ import annotations

import copy

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError, SolveError
from .system import EQUALITY, BlockSystem, local_csr, petsc_aij, same_matrix


def select_rows(B: PETSc.Mat, keep: np.ndarray, drop_below: float = 0.0) -> PETSc.Mat:
    """The local rows ``keep`` (a local mask) of B as a new MPIAIJ matrix.

    Entries with ``|b| <= drop_below · max|row|`` are left out.
    """
    Bl = local_csr(B)
    if drop_below > 0:
        Bl = drop_small(Bl, drop_below)
    Bl = Bl[np.flatnonzero(keep)]
    n = int(keep.sum())
    return petsc_aij(Bl, (n, B.getComm().tompi4py().allreduce(n)), B.getSizes()[1],
                     B.getComm().tompi4py())


def row_max(A: sp.csr_matrix) -> np.ndarray:
    """The largest |entry| of every row (0 for an empty row)."""
    out = np.zeros(A.shape[0])
    nz = np.diff(A.indptr) > 0
    if A.nnz:
        out[nz] = np.maximum.reduceat(np.abs(A.data), A.indptr[:-1][nz])
    return out


def drop_small(A: sp.csr_matrix, rtol: float, scale: np.ndarray | None = None
                ) -> sp.csr_matrix:
    """A without the entries below rtol times ``scale`` of their row (default: the row's max).

    Used for cancellations: pass the row sizes of the matrix before the cancelling product.
    """
    A = sp.csr_matrix(A, copy=True)
    scale = row_max(A) if scale is None else scale
    A.data[np.abs(A.data) <= rtol * np.repeat(scale, np.diff(A.indptr))] = 0.0
    A.eliminate_zeros()
    return A


def recover_multipliers(parent, u: PETSc.Vec, lam: PETSc.Vec, dropped: np.ndarray) -> None:
    """Fill the multipliers of the dropped rows of ``parent`` from its equilibrium (collective).

    With ``lam`` holding the kept rows' multipliers (zero on the dropped ones), the residual
    r = f − K u − Bᵀλ must be B_Dᵀ λ_D; λ_D is its least-squares solution
    (B_D B_Dᵀ) λ_D = B_D r, by CG (B_D B_Dᵀ is diagonal for Dirichlet rows and the identity for
    orthonormal gluing rows).
    """
    comm = parent.comm
    if comm.allreduce(int(dropped.sum())) == 0:
        return
    r = parent.B.createVecRight()
    parent.B.multTranspose(lam, r)
    r.array[:] = parent.f.array_r - parent.K @ u.array_r - r.array_r
    BD = select_rows(parent.B, dropped)
    y = BD.createVecLeft()
    BD.mult(r, y)
    C = BD.matTransposeMult(BD)
    ksp = PETSc.KSP().create(BD.getComm())
    ksp.setOperators(C)
    ksp.setType("cg")
    ksp.getPC().setType("jacobi")
    ksp.setTolerances(rtol=1e-14, atol=0.0, max_it=1000)
    lamD = y.duplicate()
    ksp.solve(y, lamD)
    lam.array[dropped] = lamD.array_r
    for obj in (ksp, C, BD, y, lamD, r):
        obj.destroy()


class EliminateDirichlet:
    """FETI-1's primal step: Dirichlet rows u_j = c/b leave B, their dofs leave the unknowns.

    The eliminated dof keeps its place, with an identity row and column in K and zero load, so
    the layout of the primal vector does not change; its column leaves every row of B and its
    known value moves to the right-hand sides, c ← c − B_D u_D. Rows left without entries
    (the Dirichlet rows themselves) are removed. A block's kernel becomes the rigid motions that
    vanish on its fixed dofs, R_s ← R_s null(R_s[D]): empty for a held block, so only floating
    blocks keep one (FETI-1).

    Args:
        parent: The system with Dirichlet rows (Total FETI).
        eliminate: Local mask of the rows to eliminate: equality rows with one entry each, on
            a dof of this rank.
        like: This step of a system with the same K and other rows (a row update): where it
            fixed the same dofs, its held K and kernels are taken instead of built again.

    Attributes:
        child: The system without them.
        kept: Local mask of the parent's rows that the child keeps.
    """

    def __init__(self, parent: BlockSystem, eliminate: np.ndarray, *,
                 like: EliminateDirichlet | None = None) -> None:
        self.parent = parent
        comm = parent.comm
        Bl = local_csr(parent.B)
        start = parent.primal_start
        rows = np.flatnonzero(eliminate)
        nnz = np.diff(Bl.indptr)[rows]
        bad = np.any(nnz != 1) or np.any(parent.types[rows] != EQUALITY)
        if not bad and rows.size:
            col = Bl.indices[Bl.indptr[rows]] - start
            bad = bool(np.any((col < 0) | (col >= parent.K.shape[0])))
        if comm.allreduce(bool(bad), op=MPI.LOR):
            raise SolveError("EliminateDirichlet: a row to eliminate is not an equality with a "
                             "single entry on a dof of its own rank")
        col = Bl.indices[Bl.indptr[rows]] - start if rows.size else np.zeros(0, np.int64)
        if np.unique(col).size != col.size:
            raise InputError("EliminateDirichlet: a dof has two Dirichlet rows")
        self._rows, self._col, self._diag = rows, col, Bl.data[Bl.indptr[rows]]
        n = parent.K.shape[0]
        self.fixed = np.zeros(n, dtype=bool)
        self.fixed[col] = True

        # B without the fixed columns (its other rows may be on other ranks)
        keep_col = parent.B.createVecRight()
        keep_col.array[:] = (~self.fixed).astype(float)
        Bk = parent.B.duplicate(copy=True)
        Bk.diagonalScale(R=keep_col)
        Bl = local_csr(Bk)
        Bl.eliminate_zeros()
        Bk.destroy()
        keep_col.destroy()
        empty = np.diff(Bl.indptr) == 0
        self.kept = ~(empty & (parent.types == EQUALITY))
        self._gone = ~self.kept & ~eliminate
        self.values, f, c = self._lift(parent)
        nk = int(self.kept.sum())
        B = petsc_aij(Bl[np.flatnonzero(self.kept)], (nk, comm.allreduce(nk)),
                      parent.B.getSizes()[1], comm)
        if like is not None and np.array_equal(like.fixed, self.fixed) and \
                same_matrix(parent.K, like.parent.K):  # K held alike: a rank-local choice
            Kc, kernels = like.child.K, like.child.kernels
        else:
            Kc, kernels = parent.held(self.fixed)
        self.child = BlockSystem(comm, Kc, f, B, c, parent.types[self.kept], parent.offsets,
                                 kernels, parent.labels, parent.bodies,
                                 None if parent.blocks is None else parent.blocks[self.kept])

    def _lift(self, parent: BlockSystem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """u_D from the parent's Dirichlet rows, and the child's f and c (local arrays).

        c ← c − B u_D; the load of a free dof loses K u_D, a fixed dof's is zero.
        """
        comm = parent.comm
        values = np.zeros(parent.K.shape[0])
        values[self._col] = parent.c.array_r[self._rows] / self._diag
        uD = parent.B.createVecRight()
        uD.array[:] = values
        BuD = parent.B.createVecLeft()
        parent.B.mult(uD, BuD)
        c = parent.c.array_r - BuD.array_r
        uD.destroy()
        BuD.destroy()
        inconsistent = np.abs(c[self._gone]) > 1e-12 * max(
            np.abs(parent.c.array_r).max(initial=0.0), 1e-300)
        if comm.allreduce(bool(np.any(inconsistent)), op=MPI.LOR):
            raise InputError("an equality row (gluing) involves only dofs with Dirichlet "
                             "conditions whose prescribed values it does not satisfy")
        f = parent.f.array_r - parent.K @ values
        f[self.fixed] = 0.0
        return values, f, c[self.kept]

    def adopt_factors(self, other: EliminateDirichlet) -> None:
        """Take the factor of ``other``'s child: the same K held on the same dofs (collective).

        Raises:
            SolveError: When ``other`` eliminated other dofs (its factor is of another K).
        """
        same = np.array_equal(self.fixed, other.fixed)
        if not self.parent.comm.allreduce(bool(same), op=MPI.LAND):
            raise SolveError("the new rows eliminate other Dirichlet dofs than the set-up's: "
                             "create a new FetiSolver")
        self.child.Kplus = other.child.Kplus

    def for_load(self, parent: BlockSystem) -> EliminateDirichlet:
        """This step applied to ``parent``, a new load case of its parent (same K and B).

        Only u_D and the child's right-hand sides are recomputed; the child shares K, its
        factor and B with this step's child (:meth:`BlockSystem.with_rhs`).
        """
        new = copy.copy(self)
        new.parent = parent
        new.values, f, c = self._lift(parent)
        new.child = self.child.with_rhs(f, c)
        return new

    def map_primal(self, Z: np.ndarray) -> np.ndarray:
        """Homogeneous primal vectors (columns, local rows) of the child → of the parent."""
        return Z

    def map_back(self, u: PETSc.Vec, lam: PETSc.Vec) -> tuple[PETSc.Vec, PETSc.Vec]:
        """(u, λ) of the child → of the parent: u_D put back, the Dirichlet reactions recovered."""
        up = u.copy()
        up.array[self.fixed] = self.values[self.fixed]
        lp = self.parent.B.createVecLeft()
        lp.set(0.0)
        lp.array[self.kept] = lam.array_r
        recover_multipliers(self.parent, up, lp, ~self.kept)
        return up, lp
