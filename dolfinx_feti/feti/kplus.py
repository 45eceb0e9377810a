"""A generalized inverse K⁺ of the block-diagonal K = diag(K_i) by fixing nodes.

All subdomains of a rank are factored together as one block-diagonal matrix, so applying K⁺
costs one gather, one sparse Cholesky solve and one scatter per rank, whatever the number of
subdomains: no Python work per subdomain on the hot path.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from petsc4py import PETSc

from ..errors import SolveError
from ..factor import default_factor, set_cholesky


class CornerCoarse(NamedTuple):
    """FETI-DP's coarse correction of K̃⁺ (see :mod:`.corners`): K̃⁺ = K_rr⁺ + its rank-nc part.

    Attributes:
        Psi: Ψ = K_rr⁺ K_rc, local rows × corner unknowns (SciPy CSR).
        S_plus: The generalized inverse of the corner Schur complement S_cc (replicated).
        n_coarse: Number of corner unknowns (rank 0 holds them after its local entries).
    """

    Psi: sp.csr_matrix
    S_plus: FixingNodesInverse
    n_coarse: int


class LocalInverse(NamedTuple):
    """The block-diagonal part of a primal system's K⁺ on this rank (the explicit dual's input).

    Attributes:
        kplus: The factored blocks, on the first ``offsets[-1]`` local primal entries.
        offsets: Local offsets of the blocks (subdomains).
        coarse: FETI-DP's corner correction, or None (Total FETI, FETI-1).
    """

    kplus: FixingNodesInverse
    offsets: np.ndarray
    coarse: CornerCoarse | None = None


def choose_fixing_dofs(R: np.ndarray) -> np.ndarray:
    """k dofs whose rows of the kernel basis R (n × k) form a well-conditioned k × k block.

    Column-pivoted QR of Rᵀ picks, greedily, the dof whose kernel row is largest after removing
    the directions already taken: for rigid modes that is nodes far apart, as the theory of the
    fixing-nodes inverse asks.
    """
    if R.shape[1] == 0:  # a nonsingular block (held by Dirichlet conditions or corners)
        return np.zeros(0, dtype=np.int64)
    _, _, piv = scipy.linalg.qr(R.T, pivoting=True, mode="economic")
    return np.sort(piv[: R.shape[1]])


class SparseCholesky:
    """Sparse Cholesky factorization of an SPD SciPy matrix through PETSc (COMM_SELF).

    ``factor`` names the package (see :mod:`dolfinx_feti.factor`; None: the default).
    """

    def __init__(self, A: sp.csr_matrix, factor: str | None = None) -> None:
        """Factor ``A`` (raises PETSc.Error if it is not positive definite)."""
        factor = factor or default_factor()
        A = A.tocsr()
        A.sort_indices()
        self._A = PETSc.Mat().createAIJ(size=A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                                         A.indices.astype(PETSc.IntType), A.data),
                                        comm=PETSc.COMM_SELF)
        if factor != "petsc":
            # PETSc 3.25's own Cholesky (nested-dissection ordering) mis-solves a matrix marked
            # symmetric that has decoupled identity rows (a FETI-1 subdomain with its Dirichlet
            # dofs eliminated: error O(1) or inf), and solves it to round-off unmarked.
            self._A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
            self._A.setOption(PETSc.Mat.Option.SPD, True)
        self.b, self.x = self._A.createVecs()
        self._ksp = None
        if A.shape[0] == 0:  # a rank without subdomains: CHOLMOD refuses an empty matrix
            return
        self._ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        self._ksp.setOperators(self._A)
        self._ksp.setType("preonly")
        set_cholesky(self._ksp.getPC(), factor)
        self._ksp.setUp()

    def solve_in_place(self) -> None:
        """x = A⁻¹ b on the held vectors ``b`` and ``x`` (no copies)."""
        if self._ksp is not None:
            self._ksp.solve(self.b, self.x)

    def solve_matrix(self, rhs: np.ndarray) -> np.ndarray:
        """A⁻¹ rhs for the columns of a dense (n × k) array: one batched solve (MatMatSolve).

        The result is column-major (PETSc's dense layout, written in place); a column-major
        float64 ``rhs`` is used without a copy.
        """
        n, k = rhs.shape
        out = np.zeros((n, k), order="F")
        if self._ksp is None or k == 0:
            return out
        B = PETSc.Mat().createDense((n, k), array=np.asfortranarray(rhs, dtype=float),
                                    comm=PETSc.COMM_SELF)
        X = PETSc.Mat().createDense((n, k), array=out, comm=PETSc.COMM_SELF)
        X.assemble()
        self._ksp.getPC().getFactorMatrix().matSolve(B, X)
        B.destroy()
        X.destroy()
        return out

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """A⁻¹ rhs as a new array."""
        self.b.array[:] = rhs
        self.solve_in_place()
        return self.x.array_r.copy()

    def destroy(self) -> None:
        """Free the PETSc objects."""
        for obj in (self._ksp, self._A, self.b, self.x):
            if obj is not None:
                obj.destroy()


class FixingNodesInverse:
    """K⁺ = [[A⁻¹, 0], [0, 0]] for each block: A = K_i without as many dofs as it has rigid modes.

    K_i K_i⁺ K_i = K_i holds exactly when ker K_i is spanned by R_i and R_i restricted to the
    fixed dofs is regular; that is checked once, per block, on a random vector of Im K.

    The fixed dofs' rows and columns are replaced by identity rows in the factored matrix
    rather than removed: with their right-hand side set to zero the solution is zero there, so
    K⁺ x is one contiguous copy, k zeros per subdomain and a solve straight into the output
    array (no gather and scatter of the free dofs).

    Args:
        K: The block-diagonal matrix diag(K_i) of a rank's subdomains.
        kernels: R_i per block, in order (the block sizes are their row counts); a block with
            an empty kernel (no columns) is factored as it is, K_i⁺ = K_i⁻¹.
        factor: PETSc Cholesky package: "cholmod", "mumps" or "petsc" (None: the default of
            :mod:`dolfinx_feti.factor`).
        labels: Names of the blocks for error messages.
    """

    def __init__(self, K: sp.csr_matrix, kernels: Sequence[np.ndarray],
                 factor: str | None = None, labels: Sequence[str] | None = None) -> None:
        """Choose the fixing dofs, factor once, and check K K⁺ K = K per block."""
        labels = list(labels) if labels is not None else [f"block {i}"
                                                          for i in range(len(kernels))]
        sizes = [R.shape[0] for R in kernels]
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        fixed = [choose_fixing_dofs(R) + o for R, o in zip(kernels, self.offsets, strict=False)]
        self.fixed = np.concatenate(fixed) if fixed else np.zeros(0, dtype=np.int64)
        free = np.ones(int(self.offsets[-1]), dtype=bool)
        free[self.fixed] = False
        self.free = np.flatnonzero(free)
        keep = sp.diags(free.astype(float))
        A = (keep @ K @ keep + sp.diags((~free).astype(float))).tocsr()
        A.eliminate_zeros()
        factor = factor or default_factor()
        self._factor = factor
        try:
            self._factorize(A, factor)
        except PETSc.Error:
            self._diagnose(K, kernels, factor, labels)
            raise SolveError(f"the Cholesky factorization ({factor}) of the subdomain matrices "
                             "without their fixing dofs failed") from None
        self._check(K, labels)

    def _factorize(self, A: sp.csr_matrix, factor: str) -> None:
        """Factor A (the blocks with identity rows at the fixing dofs) as one matrix."""
        self._chol = SparseCholesky(A, factor)

    def _diagnose(self, K, kernels, factor: str, labels) -> None:
        """Find the block whose factorization fails, and name it (the rare, slow path)."""
        for i, (R, label) in enumerate(zip(kernels, labels, strict=True)):
            seg = np.arange(self.offsets[i], self.offsets[i + 1])
            keep = np.setdiff1d(np.arange(R.shape[0]), choose_fixing_dofs(R))
            Ki = K[seg][:, seg]
            try:
                SparseCholesky(Ki[keep][:, keep], factor).destroy()
            except PETSc.Error:
                raise SolveError(
                    f"{label}: the Cholesky factorization ({factor}) of the stiffness matrix "
                    "without its fixing dofs failed; the matrix is not positive definite there "
                    "(a mechanism beyond the rigid-body modes, or a non-positive material "
                    "constant)") from None

    def _check(self, K: sp.csr_matrix, labels) -> None:
        v = np.random.default_rng(0).standard_normal(K.shape[0])
        b = K @ v
        y = np.empty_like(b)
        self.solve(b, y)
        r = K @ y - b
        bad = []
        for i in range(len(labels)):
            seg = slice(self.offsets[i], self.offsets[i + 1])
            bn = np.linalg.norm(b[seg])
            err = np.linalg.norm(r[seg]) / bn if bn > 0 else np.inf  # K_i v = 0: K_i = 0
            if not err < 1e-6:
                bad.append((i, err))
        if len(bad) > 1:  # a singular block may spoil the joint solve (MUMPS: NaN everywhere)
            bad = [(i, e) for i, e in bad if not self._block_ok(K, i, v)] or bad
        if bad:
            i, err = bad[0]
            raise SolveError(f"{labels[i]}: K K⁺ K = K fails (relative error {err:.2e}); the "
                             "stiffness matrix has a larger null space than the rigid-body "
                             "modes (a part attached by a single node, or a zero material "
                             "constant)")

    def _block_ok(self, K: sp.csr_matrix, i: int, v: np.ndarray) -> bool:
        """K_i K_i⁺ K_i = K_i with block i factored alone (the rare, slow path)."""
        seg = np.arange(self.offsets[i], self.offsets[i + 1])
        fixed = self.fixed[(self.fixed >= seg[0]) & (self.fixed <= seg[-1])] - seg[0]
        keep = np.setdiff1d(np.arange(seg.size), fixed)
        Ki = K[seg][:, seg].tocsr()
        b = Ki @ v[seg]
        y = np.zeros_like(b)
        try:
            chol = SparseCholesky(Ki[keep][:, keep], self._factor)
        except PETSc.Error:
            return False
        y[keep] = chol.solve(b[keep])
        chol.destroy()
        bn = np.linalg.norm(b)
        return bool(bn > 0 and np.linalg.norm(Ki @ y - b) < 1e-6 * bn)

    def solve(self, rhs: np.ndarray, out: np.ndarray) -> None:
        """out = K⁺ rhs on the whole local primal array (``out`` contiguous float64)."""
        b = self._chol.b.array
        b[:] = rhs
        b[self.fixed] = 0.0
        x = self._chol.x
        x.placeArray(out)
        try:
            self._chol.solve_in_place()
        finally:
            x.resetArray()

    def solve_matrix(self, rhs: np.ndarray) -> np.ndarray:
        """K⁺ applied to the columns of a dense (n × k) array (one batched solve)."""
        b = np.array(rhs, dtype=float)
        b[self.fixed] = 0.0
        return self._chol.solve_matrix(b)

    def destroy(self) -> None:
        """Free the factorization."""
        self._chol.destroy()


class BlockwiseInverse(FixingNodesInverse):
    """The same K⁺ by fixing nodes, with one factorization per block instead of one per rank.

    A right-hand side of one block is then solved with that block's factor alone: FETI-DP's
    Ψ = K_rr⁺ K_rc needs, per subdomain, only the columns of its own corner unknowns, while a
    solve by the rank's joint factor costs the whole rank's triangular solves per column, so
    the columns of all subdomains packed side by side pay for the subdomain with the most
    corners on every other one (docs/benchmarks.md § 23: 30 % of the solves on the graded box).
    Measured there and on the sphere S2, the blocks factored one by one also cost less than
    the joint factor (the ordering of each block alone). An application of K⁺ is then one
    solve per block: a loop over the rank's subdomains (not its dofs).

    Args: as :class:`FixingNodesInverse`.
    """

    def _factorize(self, A: sp.csr_matrix, factor: str) -> None:
        o = self.offsets
        self._chols: list[SparseCholesky] = []
        try:
            for lo, hi in zip(o[:-1], o[1:], strict=True):
                self._chols.append(SparseCholesky(A[lo:hi, lo:hi], factor))
        except PETSc.Error:
            self.destroy()
            raise
        # each block's fixing dofs in its own numbering
        at = np.searchsorted(o, self.fixed, side="right") - 1
        self._fixed_of = [self.fixed[at == b] - o[b] for b in range(len(o) - 1)]

    def solve(self, rhs: np.ndarray, out: np.ndarray) -> None:
        """out = K⁺ rhs on the whole local primal array (``out`` contiguous float64)."""
        o = self.offsets
        for b, chol in enumerate(self._chols):
            lo, hi = o[b], o[b + 1]
            if hi == lo:
                continue
            chol.b.array[:] = rhs[lo:hi]
            chol.b.array[self._fixed_of[b]] = 0.0
            chol.x.placeArray(out[lo:hi])
            try:
                chol.solve_in_place()
            finally:
                chol.x.resetArray()

    def solve_block(self, block: int, rhs: np.ndarray, overwrite: bool = False) -> np.ndarray:
        """K_b⁺ applied to the columns of a dense (n_b × k) array of block ``block`` alone.

        ``overwrite``: ``rhs`` (best column-major float64: no copies) may be changed.
        """
        b = rhs if overwrite else np.array(rhs, dtype=float, order="F")
        b[self._fixed_of[block]] = 0.0
        return self._chols[block].solve_matrix(b)

    def solve_matrix(self, rhs: np.ndarray) -> np.ndarray:
        """K⁺ applied to the columns of a dense (n × k) array (one batched solve per block)."""
        o = self.offsets
        out = np.empty((int(o[-1]), rhs.shape[1]))
        for b in range(len(self._chols)):
            out[o[b]:o[b + 1]] = self.solve_block(b, rhs[o[b]:o[b + 1]])
        return out

    def destroy(self) -> None:
        """Free the factorizations."""
        for chol in self._chols:
            chol.destroy()
        self._chols = []
