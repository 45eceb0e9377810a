"""The primal problem of FETI as algebra: block-diagonal K, load f, constraint rows B u (=, <=) c.

    min ½ uᵀ K u − fᵀ u   s.t.   B_E u = c_E,  B_I u <= c_I,   K = diag(K_s),

with a basis R_s of ker K_s per block (empty for a nonsingular block). Nothing here knows about
meshes or DOLFINx: :meth:`BlockSystem.from_rows` takes the arrays the FEM side hands over
(:class:`~dolfinx_feti.fem.assembly.SubdomainData`) and the constraint rows, and the transforms
of :mod:`.transforms` and :mod:`.corners` produce new systems from it.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..constraints.rows import Kind, Rows
from ..errors import collective
from .kplus import FixingNodesInverse, LocalInverse

#: Singular values of R_s restricted to its held dofs at or below this (R_s has orthonormal
#: columns, so they are at most 1) count as zero: that rigid motion is not held there.
KERNEL_TOL = 1e-10

#: Row types of a system: a plain equality, an inequality (λ >= 0), a bounded multiplier
#: (friction: a box or a disc on λ, the row itself an equality in the primal).
EQUALITY, INEQUALITY, BOUNDED = 0, 1, 2


def petsc_aij(csr: sp.csr_matrix, rows: tuple[int, int], cols: tuple[int, int],
              comm: MPI.Comm) -> PETSc.Mat:
    """An MPIAIJ matrix from the local rows (global column indices) as a SciPy CSR matrix."""
    csr = sp.csr_matrix(csr)
    csr.sort_indices()
    M = PETSc.Mat().createAIJ(size=(rows, cols), csr=(csr.indptr.astype(PETSc.IntType),
                                                      csr.indices.astype(PETSc.IntType),
                                                      csr.data), comm=comm)
    M.assemble()
    return M


def local_csr(M: PETSc.Mat) -> sp.csr_matrix:
    """The local rows of an MPIAIJ matrix as SciPy CSR with global column indices."""
    indptr, indices, data = M.getValuesCSR()
    return sp.csr_matrix((data, indices, indptr), shape=(M.getLocalSize()[0], M.getSize()[1]))


def row_types(rows: Rows) -> np.ndarray:
    """EQUALITY, INEQUALITY or BOUNDED for each row."""
    t = np.full(rows.size, EQUALITY, dtype=np.int8)
    t[rows.inequality] = INEQUALITY
    t[rows.kind == Kind.TANGENT] = BOUNDED
    return t


def row_blocks(rows: Rows) -> np.ndarray:
    """A label per row: its node and kind class (gluing, Dirichlet, other).

    Rows with one label couple in B diag(K)⁻¹ Bᵀ (the k − 1 gluing rows of one node component
    set, the rows of one contact node); the stiffness scaling inverts these blocks.
    """
    cls = np.select([rows.kind == Kind.GLUE, rows.kind == Kind.DIRICHLET], [0, 1], 2)
    return rows.node.astype(np.int64) * 3 + cls


def same_matrix(a: sp.csr_matrix, b: sp.csr_matrix) -> bool:
    """Whether two CSR matrices are equal: the same arrays (shared memory), or equal ones."""
    if a is b:
        return True
    if a.shape != b.shape or a.nnz != b.nnz:
        return False

    def same(x: np.ndarray, y: np.ndarray) -> bool:
        shared = x.dtype == y.dtype and x.shape == y.shape and x.strides == y.strides and \
            x.__array_interface__["data"][0] == y.__array_interface__["data"][0]
        return shared or np.array_equal(x, y)

    return same(a.indptr, b.indptr) and same(a.indices, b.indices) and same(a.data, b.data)


class PreconditionerOperands(NamedTuple):
    """What the lumped and Dirichlet preconditioners act with (:mod:`.precond`).

    Attributes:
        K: The rank's block-diagonal matrix (CSR, local numbering).
        B: The rows of the dual (MPIAIJ, columns in the layout of ``K``).
        left_out: Local mask of dofs held in the Dirichlet preconditioner (FETI-DP's corners),
            or None.
        row_blocks: Per local row of ``B``, a label of its block of B diag(K)⁻¹ Bᵀ (see
            :func:`row_blocks`), or None (then no stiffness scaling).
        offsets: Local offsets of the blocks (subdomains) of ``K``, or None (then no
            explicit local blocks, :mod:`.precond_explicit`).
    """

    K: sp.csr_matrix
    B: PETSc.Mat
    left_out: np.ndarray | None = None
    row_blocks: np.ndarray | None = None
    offsets: np.ndarray | None = None


def nullspace_columns(M: np.ndarray, tol: float = KERNEL_TOL) -> np.ndarray:
    """An orthonormal basis (columns) of the null space of a small dense matrix."""
    if M.shape[0] == 0:
        return np.eye(M.shape[1])
    _, sv, Vt = np.linalg.svd(M, full_matrices=True)
    sv = np.r_[sv, np.zeros(M.shape[1] - sv.size)]
    return Vt[sv <= tol * max(sv.max(initial=0.0), 1.0)].T


class RowOperands:
    """The row and column layout of a primal system with constraint matrix B."""

    def _set_rows(self, B: PETSc.Mat, c: np.ndarray, types: np.ndarray) -> None:
        self.B = B
        self.types = np.asarray(types, dtype=np.int8)
        self.c = B.createVecLeft()
        self.c.array[:] = c
        lo, hi = B.getOwnershipRange()
        self.rows_local = slice(lo, hi)
        self.dual_size = B.getLocalSize()[0], B.getSize()[0]
        self.primal_size = B.getLocalSize()[1], B.getSize()[1]
        self.primal_start = B.getOwnershipRangeColumn()[0]

    def with_rhs(self, f: np.ndarray, c: np.ndarray):
        """The same problem with the load ``f`` and right-hand sides ``c`` (local arrays).

        The copy shares every operator (K, its factor, B, the kernels): a new load case costs
        two vectors. It frees only those two vectors (:meth:`destroy`); the operators stay
        with the system they came from.
        """
        new = copy.copy(self)
        new.c, new.f = self.B.createVecLeft(), self.B.createVecRight()
        new.c.array[:] = c
        new.f.array[:] = f
        new._shares_operators = True
        return new

    def destroy_rows(self) -> None:
        """Free f and c, and B unless shared with the system this one was copied from."""
        self._destroy_rows()

    def _destroy_rows(self) -> bool:
        """Free f and c, and B unless shared; whether the operators are this system's own."""
        own = not getattr(self, "_shares_operators", False)
        for obj in (self.B, self.c, self.f) if own else (self.c, self.f):
            obj.destroy()
        return own


class BlockSystem(RowOperands):
    """A FETI primal problem with block-diagonal K, distributed by blocks over the ranks.

    Args:
        comm: The communicator.
        K: Block-diagonal matrix of this rank's blocks (CSR, local numbering).
        f: Local load.
        B: Constraint matrix (dual rows × primal), MPIAIJ with the primal layout of ``K``.
        c: Local right-hand sides of the owned rows of ``B``.
        types: Local row types (``EQUALITY``, ``INEQUALITY``, ``BOUNDED``).
        offsets: Local offsets of the blocks (length ``number of blocks + 1``).
        kernels: Per block, a basis of ker K_s (n_s × k_s; k_s may be 0).
        labels: Per block, a name for messages.
        bodies: Per block, the name of what it belongs to (e.g. its body), for messages about
            rigid motions; ``labels`` if not given.
        blocks: Per local row, its label for the stiffness scaling (:func:`row_blocks`), or
            None.
    """

    def __init__(self, comm: MPI.Comm, K: sp.csr_matrix, f: np.ndarray, B: PETSc.Mat,
                 c: np.ndarray, types: np.ndarray, offsets: np.ndarray,
                 kernels: Sequence[np.ndarray], labels: Sequence[str],
                 bodies: Sequence[str] | None = None, blocks: np.ndarray | None = None
                 ) -> None:
        self.comm, self.K = comm, sp.csr_matrix(K)
        self.blocks = blocks
        self.offsets = np.asarray(offsets, dtype=np.int64)
        self.kernels, self.labels = list(kernels), list(labels)
        self.bodies = list(labels if bodies is None else bodies)
        self._set_rows(B, c, types)
        self.f = B.createVecRight()
        self.f.array[:] = f
        self.Kplus: FixingNodesInverse | None = None

    @classmethod
    def from_rows(cls, data, rows) -> BlockSystem:
        """The Total FETI system: every subdomain a block with its rigid modes, all rows in B.

        Args:
            data: The :class:`~dolfinx_feti.fem.assembly.SubdomainData` of this rank.
            rows: This rank's rows (:class:`~dolfinx_feti.setup.share.RankRows`: gluing,
                Dirichlet, contact, friction) with the global primal column of each entry.
        """
        own = rows.own
        Bloc = sp.csr_matrix((own.e_coef, (own.e_row, rows.cols)),
                             shape=(own.size, data.primal_size[1]))
        B = petsc_aij(Bloc, (own.size, rows.size), data.primal_size, data.comm)
        return cls(data.comm, data.K, data.f, B, own.rhs, row_types(own), data.offsets,
                   data.kernels, data.labels, data.bodies, row_blocks(own))

    # --- the generalized inverse -----------------------------------------------------------
    def factorize(self, factor: str | None = None, site: str = "") -> None:
        """Factor K once (K⁺ by fixing nodes on the singular blocks; collective).

        ``site`` names the phase for :func:`~dolfinx_feti.errors.collective` (one guard, not
        nested in another: a rank failing in an outer guard would meet the others' inner one).
        """
        with collective(self.comm, site):
            self.Kplus = FixingNodesInverse(self.K, self.kernels, factor, self.labels)

    @property
    def factored(self) -> bool:
        """Whether K⁺ is there (:meth:`factorize` done, or a factor adopted)."""
        return self.Kplus is not None

    def adopt_factors(self, other: BlockSystem) -> None:
        """Take the factor of ``other``, a system of the same K (other rows)."""
        self.Kplus = other.Kplus

    def apply_kplus(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = K⁺ x (the local solves)."""
        self.Kplus.solve(x.array_r, y.array)

    def local_inverse(self) -> LocalInverse:
        """K⁺ = diag(K_s⁺) on this rank, by blocks (for :mod:`.explicit`; after factorize)."""
        return LocalInverse(self.Kplus, self.offsets)

    def kernel_matrix(self) -> tuple[sp.csr_matrix, list[str]]:
        """R as local rows with global columns (k_s columns per block, in block order).

        Returns:
            The local rows of R (n_local × m) and, on every rank, the body (see ``bodies``) of
            each column of R.
        """
        k = np.array([R.shape[1] for R in self.kernels], dtype=np.int64)
        counts = self.comm.allgather(int(k.sum()))
        first = int(sum(counts[:self.comm.rank]))
        m = int(sum(counts))
        blocks = [sp.csr_matrix(R) for R in self.kernels]
        R = sp.block_diag(blocks, format="csr") if blocks else sp.csr_matrix((0, 0))
        R = sp.csr_matrix((R.data, R.indices + first, R.indptr), shape=(self.K.shape[0], m))
        labels = sum(self.comm.allgather([lab for lab, kk in zip(self.bodies, k, strict=True)
                                          for _ in range(kk)]), [])
        return R, labels

    def held(self, mask: np.ndarray) -> tuple[sp.csr_matrix, list[np.ndarray]]:
        """K with the dofs in ``mask`` held, and the blocks' kernels left.

        Held dofs get identity rows and columns (the layout does not change); a block's kernel
        becomes the rigid motions that vanish there, R_s null(R_s[mask]).
        """
        keep = (~mask).astype(float)
        K = (sp.diags(keep) @ self.K @ sp.diags(keep) + sp.diags(1.0 - keep)).tocsr()
        K.eliminate_zeros()
        kernels = []
        for i, seg in self.segments():
            R = self.kernels[i]
            m = mask[seg]
            if R.shape[1] and m.any():
                R = R @ nullspace_columns(R[m])
                R[m] = 0.0
            kernels.append(R)
        return K, kernels

    def segments(self):
        """(block index, local slice) of every local block."""
        for i in range(len(self.kernels)):
            yield i, slice(int(self.offsets[i]), int(self.offsets[i + 1]))

    # --- checks on a primal solution -------------------------------------------------------
    def residuals(self, u: PETSc.Vec, lam: PETSc.Vec) -> dict[str, float]:
        """Equilibrium residual ||K u − f + Bᵀλ|| / max(||f||, ||Bᵀλ||, κ ||u||).

        κ = max_i ||K_i||_∞ keeps the measure meaningful when no load acts (a problem driven
        by prescribed displacements only, where f and Bᵀλ may both vanish).
        """
        w = self.B.createVecRight()
        self.B.multTranspose(lam, w)
        ua, wa, fa = u.array_r, w.array_r, self.f.array_r
        r2 = float(np.sum((self.K @ ua - fa + wa) ** 2))
        kappa = float(abs(self.K).sum(axis=1).max()) if self.K.shape[0] else 0.0
        r2 = self.comm.allreduce(r2, op=MPI.SUM)
        kappa = self.comm.allreduce(kappa, op=MPI.MAX)
        ref = max(self.f.norm(), w.norm(), kappa * u.norm(), 1e-300)
        w.destroy()
        return {"equilibrium": float(np.sqrt(r2) / ref)}

    def energy(self, u: PETSc.Vec) -> float:
        """½ uᵀ K u − fᵀ u summed over the blocks."""
        ua, fa = u.array_r, self.f.array_r
        e = 0.5 * float(ua @ (self.K @ ua)) - float(fa @ ua)
        return self.comm.allreduce(e, op=MPI.SUM)

    def preconditioner_operands(self) -> PreconditionerOperands:
        """K, B and the row blocks: what the lumped and Dirichlet preconditioners act with."""
        return PreconditionerOperands(self.K, self.B, None, self.blocks, self.offsets)

    def destroy_factors(self) -> None:
        """Free K⁺ (shared with every :meth:`with_rhs` copy and adopter of it)."""
        if self.Kplus is not None:
            self.Kplus.destroy()
            self.Kplus = None

    def destroy(self) -> None:
        """Free the PETSc objects (of a :meth:`with_rhs` copy: its vectors only)."""
        if self._destroy_rows():
            self.destroy_factors()
