"""Equality constraints ``D x = 0`` with a small replicated range, and projectors built on them.

``x`` is a distributed PETSc Vec; ``D x`` is a short NumPy array that every rank holds in full
(in FETI, ``D = G = R^T B^T`` has a few rows per floating subdomain). ``D`` itself is stored by
the local rows of ``D^T``, so ``D x`` is one local sparse product and one ``Allreduce``.

Orthonormalization needs a factor of ``D D^T`` (the FETI coarse problem). Small ones are
formed dense and their Cholesky factor is inverted once (``T = L^{-1}`` applied as a dense
product); large ones are assembled sparse (the pattern of ``G G^T`` follows subdomain
adjacency) and factored by a sparse Cholesky, replicated on every rank, whose half solves
apply ``T``. A projection then costs the local products, one ``Allreduce`` of ``m`` numbers and
one coarse solve.
"""

from __future__ import annotations

import copy
from typing import Protocol, runtime_checkable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from mpi4py import MPI
from petsc4py import PETSc

from .shell import python_shell
from .sparse_cholesky import NotPositiveDefinite, sparse_cholesky

# Below this reciprocal condition number of D D^T the Cholesky route is abandoned for an
# eigendecomposition: L^{-1} would amplify rounding in D~ D~^T = I by about 1/rcond.
_CHOLESKY_RCOND = 1e-8
#: Up to this many rows the Cholesky factor of D D^T is inverted once and applied as a product.
_EXPLICIT_INVERSE_MAX = 1024
#: Up to this many rows ``orthonormalize`` takes the dense route (method "auto"); above it the
#: sparse one. Set-up plus 500 projections cross over between m = 200 and 750 depending on the
#: kernel (bench/coarse_problem.py --crossover; docs/benchmarks.md § 10).
DENSE_MAX = 400
ORTHONORMALIZE_METHODS = ("auto", "dense", "sparse")


def _mpi_comm(comm) -> MPI.Comm:
    """Accept either an mpi4py or a petsc4py communicator."""
    return comm.tompi4py() if isinstance(comm, PETSc.Comm) else comm


@runtime_checkable
class EqualityConstraint(Protocol):
    """What the solvers need from ``D``: products with ``D`` and ``D^T``.

    Attributes:
        m: Number of rows of ``D`` (the length of the replicated array ``D x``).
    """

    m: int

    def mult(self, x: PETSc.Vec) -> np.ndarray:
        """Return ``D x``, the same array on every rank (collective)."""
        ...

    def mult_transpose(self, y: np.ndarray, out: PETSc.Vec) -> None:
        """Set ``out = D^T y`` for a replicated ``y`` (local work only)."""
        ...


class RowBlockConstraint:
    """``D`` given by the locally owned rows of ``D^T``.

    Args:
        Dt_local: ``n_local x m`` sparse (or dense) matrix: row ``i`` is row ``i`` of ``D^T`` for
            the ``i``-th locally owned entry of ``x``.
        comm: Communicator of the Vecs it will act on (mpi4py or petsc4py).
    """

    def __init__(self, Dt_local, comm) -> None:
        self.Dt_local = sp.csr_matrix(Dt_local, dtype=np.float64)
        # D x = (D^T)^T x: keep the transpose in CSR too so both products are row-oriented.
        self._D_local = self.Dt_local.T.tocsr()
        self.comm = _mpi_comm(comm)
        self.m = int(self.Dt_local.shape[1])
        if self.comm.allreduce(self.m, op=MPI.MAX) != self.comm.allreduce(self.m, op=MPI.MIN):
            raise ValueError("RowBlockConstraint: the number of columns of Dt_local (m) differs "
                             "between ranks")

    def _check(self, v: PETSc.Vec) -> None:
        if v.getLocalSize() != self.Dt_local.shape[0]:
            raise ValueError(f"RowBlockConstraint: the Vec has {v.getLocalSize()} local entries "
                             f"but Dt_local has {self.Dt_local.shape[0]} rows")

    def mult(self, x: PETSc.Vec) -> np.ndarray:
        """Return ``D x`` (collective)."""
        self._check(x)
        local = np.ascontiguousarray(self._D_local @ x.array_r, dtype=np.float64)
        out = np.empty(self.m)
        self.comm.Allreduce(local, out, op=MPI.SUM)
        return out

    def mult_transpose(self, y: np.ndarray, out: PETSc.Vec) -> None:
        """Set ``out = D^T y``."""
        self._check(out)
        out.array[:] = self.Dt_local @ np.asarray(y, dtype=np.float64)

    def gram(self) -> np.ndarray:
        """Return the dense ``m x m`` matrix ``D D^T``, replicated (collective)."""
        local = np.ascontiguousarray((self._D_local @ self.Dt_local).toarray())
        out = np.empty_like(local)
        self.comm.Allreduce(local, out, op=MPI.SUM)
        return out

    def gram_sparse(self) -> sp.csr_matrix:
        """Return ``D D^T`` as a symmetric sparse matrix, replicated (collective).

        Each rank contributes the product of its own rows; only the nonzeros travel.
        """
        local = (self._D_local @ self.Dt_local).tocoo()
        parts = [_allgatherv(self.comm, a) for a in (local.row.astype(np.int64),
                                                     local.col.astype(np.int64), local.data)]
        A = sp.csr_matrix((parts[2], (parts[0], parts[1])), shape=(self.m, self.m))
        A.sum_duplicates()
        return ((A + A.T) * 0.5).tocsr()


def _allgatherv(comm: MPI.Comm, a: np.ndarray) -> np.ndarray:
    """The concatenation over ranks of a 1-D array (rank order)."""
    if comm.size == 1:
        return a
    counts = np.array(comm.allgather(a.size))
    out = np.empty(int(counts.sum()), dtype=a.dtype)
    comm.Allgatherv(np.ascontiguousarray(a), [out, counts])
    return out


class OrthonormalConstraint:
    """``D~ = T D`` with ``T`` chosen so that ``D~ D~^T = I`` (``T`` is never applied to ``D``).

    Built by :func:`orthonormalize`. Dense route: ``T = L^{-1}`` (``L L^T = D D^T``) when ``D``
    has full row rank and is well conditioned; otherwise ``T = S^{-1/2} V^T`` from the
    eigenpairs of ``D D^T`` that are kept, so redundant rows disappear and ``m`` is the rank.
    Sparse route: ``T = L^{-1} P`` from a sparse Cholesky factor ``P A P^T = L L^T`` of
    ``A = D D^T`` restricted to the rows ``keep``; the rows left out (one per null vector,
    where the null space is largest) are combinations of the kept ones.

    Attributes:
        base: The original constraint.
        m: Number of rows of ``D~`` (the rank of ``D``).
        rank: Same as ``m``.
        method: ``'cholesky'``, ``'eigen'`` (dense) or ``'sparse'``.
        null_space: ``m_original x k`` orthonormal basis of the null space of ``D^T`` (the row
            combinations that vanish); ``k = 0`` for full row rank.
        rhs_tilde: Transformed right-hand side ``T e`` (when a right-hand side was given).
        inconsistency: ``||N^T e|| / ||e||`` for the null basis ``N``: nonzero means that
            ``D x = e`` has no solution (0 when ``e`` is zero or not given).
    """

    def __init__(self, base: RowBlockConstraint, *, L: np.ndarray | None = None,
                 T: np.ndarray | None = None, null_space: np.ndarray | None = None,
                 factor=None, keep: np.ndarray | None = None) -> None:
        self.base = base
        self._L = L
        self._T = T
        self._factor = factor
        self._keep = keep
        if L is not None and L.shape[0] <= _EXPLICIT_INVERSE_MAX:
            # A small T = L^{-1} applied as a dense product: SciPy's per-call overhead of a
            # triangular solve is several times the arithmetic at these sizes, and T is applied
            # about five times per Hessian product. (L is well conditioned: see orthonormalize.)
            self._T = sla.solve_triangular(L, np.eye(L.shape[0]), lower=True)
            self._L = None
        if factor is not None:
            self.method, self.m = "sparse", int(factor.n)
        else:
            self.method = "cholesky" if L is not None else "eigen"
            self.m = int(L.shape[0] if L is not None else T.shape[0])
        self.rank = self.m
        self.null_space = (null_space if null_space is not None
                           else np.zeros((base.m, 0)))
        self.rhs_tilde: np.ndarray | None = None
        self.inconsistency: float = 0.0

    def with_rhs(self, rhs: np.ndarray) -> OrthonormalConstraint:
        """This constraint with the right-hand side ``D x = rhs`` (a shallow copy).

        Sets ``rhs_tilde`` and ``inconsistency``; the factorization is shared, so a new load
        case of the same ``D`` costs one application of ``T``.
        """
        e = np.asarray(rhs, dtype=np.float64)
        if e.shape != (self.base.m,):
            raise ValueError(f"orthonormalize: rhs has shape {e.shape}, expected "
                             f"({self.base.m},)")
        new = copy.copy(self)
        e_norm = float(np.linalg.norm(e))
        N = self.null_space
        new.inconsistency = (float(np.linalg.norm(N.T @ e)) / e_norm
                             if e_norm > 0 and N.shape[1] else 0.0)
        # T e for the part of e in the range of D: the least-squares e when it is inconsistent
        new.rhs_tilde = self.transform(self._off_null(e))
        return new

    def transform(self, z: np.ndarray) -> np.ndarray:
        """Return ``T z`` for ``z`` in the range of the original ``D``."""
        if self._factor is not None:
            return self._factor.half(z if self._keep is None else z[self._keep])
        if self._L is not None:
            return sla.solve_triangular(self._L, z, lower=True, check_finite=False)
        return self._T @ z

    def _transpose(self, y: np.ndarray) -> np.ndarray:
        """``T^T y`` as factored (on the sparse route: zero on the rows left out)."""
        if self._factor is not None:
            t = self._factor.half_transpose(y)
            if self._keep is None:
                return t
            out = np.zeros(self.base.m)
            out[self._keep] = t
            return out
        if self._L is not None:
            return sla.solve_triangular(self._L, y, lower=True, trans="T",
                                        check_finite=False)
        return self._T.T @ y

    def _off_null(self, a: np.ndarray) -> np.ndarray:
        N = self.null_space
        return a - N @ (N.T @ a) if N.shape[1] else a

    def transform_transpose(self, y: np.ndarray) -> np.ndarray:
        """Return ``T^T y``, the coefficients of ``D~^T y`` in the rows of ``D``.

        They are unique up to the null space of ``D^T``; the ones returned are orthogonal to
        it (the minimum-norm ones).
        """
        return self._off_null(self._transpose(np.asarray(y, dtype=np.float64)))

    def gram_solve(self, r: np.ndarray) -> np.ndarray:
        """Return ``(D D^T)^+ r``: the minimum-norm least-squares solution of ``D D^T a = r``."""
        r = self._off_null(np.asarray(r, dtype=np.float64))
        return self._off_null(self._transpose(self.transform(r)))

    def mult(self, x: PETSc.Vec) -> np.ndarray:
        """Return ``D~ x`` (collective)."""
        return self.transform(self.base.mult(x))

    def mult_transpose(self, y: np.ndarray, out: PETSc.Vec) -> None:
        """Set ``out = D~^T y``."""
        self.base.mult_transpose(self._transpose(np.asarray(y, dtype=np.float64)), out)


def orthonormalize(con: RowBlockConstraint, rhs: np.ndarray | None = None,
                   rtol: float = 1e-12, method: str = "auto",
                   backend: str = "auto") -> OrthonormalConstraint:
    """Orthonormalize the rows of ``D`` (collective; the factorization is replicated).

    Args:
        con: The constraint ``D``.
        rhs: Optional right-hand side ``e`` of ``D x = e`` to transform alongside.
        rtol: Eigenvalues of ``D D^T`` at or below ``rtol * max eigenvalue`` count as zero (i.e.
            singular values of ``D`` below ``sqrt(rtol) * ||D||``). Used only when the Cholesky
            factor is singular or its reciprocal condition number is below 1e-8.
        method: ``"dense"`` (``D D^T`` formed dense, LAPACK), ``"sparse"`` (sparse ``D D^T``,
            sparse Cholesky; the null space, if any, by shift-invert Lanczos) or ``"auto"``
            (dense up to :data:`DENSE_MAX` rows).
        backend: Sparse Cholesky package of the sparse route (see
            :func:`.sparse_cholesky.sparse_cholesky`).

    Returns:
        The orthonormal constraint, with ``rank``, ``null_space`` and, if ``rhs`` was given,
        ``rhs_tilde`` and ``inconsistency`` set.
    """
    if method not in ORTHONORMALIZE_METHODS:
        raise ValueError(f"orthonormalize: method must be one of {ORTHONORMALIZE_METHODS}, "
                         f"got {method!r}")
    if method == "auto":
        method = "dense" if con.m <= DENSE_MAX else "sparse"
    result = (_orthonormalize_sparse(con, rtol, backend) if method == "sparse"
              else _orthonormalize_dense(con, rtol))
    return result if rhs is None else result.with_rhs(rhs)


def _orthonormalize_dense(con: RowBlockConstraint, rtol: float) -> OrthonormalConstraint:
    """``D D^T`` dense and replicated: Cholesky, or eigenpairs when (nearly) singular."""
    gram = con.gram()
    gram = 0.5 * (gram + gram.T)
    m = gram.shape[0]
    result = None
    if m > 0 and np.all(np.isfinite(gram)):
        try:
            L = sla.cholesky(gram, lower=True)
            anorm = np.abs(gram).sum(axis=0).max()
            rcond, info = sla.lapack.dpocon(L, anorm, uplo="L")
            if info == 0 and rcond >= _CHOLESKY_RCOND:
                result = OrthonormalConstraint(con, L=L)
        except sla.LinAlgError:
            pass
    if result is None:
        if not np.all(np.isfinite(gram)):
            raise ValueError("orthonormalize: D D^T has non-finite entries")
        w, V = np.linalg.eigh(gram) if m > 0 else (np.zeros(0), np.zeros((0, 0)))
        keep = w > rtol * (w.max() if m > 0 else 0.0)
        if m > 0 and w.max() <= 0.0:
            keep[:] = False
        T = (V[:, keep] / np.sqrt(w[keep])).T
        result = OrthonormalConstraint(con, T=T, null_space=V[:, ~keep])
    return result


def _orthonormalize_sparse(con: RowBlockConstraint, rtol: float,
                           backend: str) -> OrthonormalConstraint:
    """``D D^T`` sparse and replicated, factored by a sparse Cholesky.

    A (nearly) singular ``D D^T`` (the rows of ``D`` dependent: in FETI, a rigid motion that no
    constraint row sees) is handled like a singular stiffness matrix by fixing nodes: the
    eigenvectors with eigenvalues at or below ``rtol * max`` are found by shift-invert Lanczos
    with the factor of ``D D^T + sigma I``; one row per null vector is left out (where the
    null vectors are largest, by pivoted QR), and the rest is factored. The null space is then
    computed exactly from that factor.
    """
    A = con.gram_sparse()
    m = A.shape[0]
    if m == 0 or A.nnz == 0 or not np.all(np.isfinite(A.data)):
        return _orthonormalize_dense(con, rtol)  # nothing to factor, or the dense error
    factor = None
    try:
        factor = sparse_cholesky(A, backend)
        if factor.rcond() >= _CHOLESKY_RCOND:
            return OrthonormalConstraint(con, factor=factor)
    except NotPositiveDefinite:
        pass
    scale = _largest_eigenvalue(A)
    fixed = _null_pivots(A, scale, rtol, backend)
    fixed = con.comm.bcast(fixed, root=0)  # the same rows on every rank, whatever the round-off
    if fixed.size == 0:
        if factor is None:
            raise ValueError("orthonormalize: the sparse Cholesky factorization of D D^T "
                             "failed although no eigenvalue is below rtol * max")
        return OrthonormalConstraint(con, factor=factor)  # regular, if ill conditioned
    if factor is not None:
        factor.destroy()
    keep = np.setdiff1d(np.arange(m), fixed)
    A_kk = A[keep][:, keep]
    try:
        factor = sparse_cholesky(A_kk, backend)
    except NotPositiveDefinite:
        raise ValueError("orthonormalize: D D^T without one row per null vector is still "
                         "singular; its null space could not be separated") from None
    # Exact null vectors: n_J = I, n_keep = -A_kk^{-1} A_kJ; zero Schur complement checks it.
    A_kJ = A[keep][:, fixed].toarray()
    X = factor.solve(A_kJ)
    schur = A[fixed][:, fixed].toarray() - A_kJ.T @ X
    if np.abs(schur).max() > max(np.sqrt(rtol), 1e-6) * scale:
        raise ValueError("orthonormalize: the null space of D D^T found by Lanczos is not "
                         f"exact (Schur complement {np.abs(schur).max():.1e} of {scale:.1e})")
    N = np.zeros((m, fixed.size))
    N[keep] = -X
    N[fixed] = np.eye(fixed.size)
    N, _ = np.linalg.qr(N)
    return OrthonormalConstraint(con, factor=factor, keep=keep, null_space=N)


def _largest_eigenvalue(A: sp.csr_matrix) -> float:
    """``λ_max`` of a symmetric positive semidefinite sparse matrix (Lanczos, 1e-3)."""
    if A.shape[0] < 3:
        return float(np.linalg.eigvalsh(A.toarray()).max())
    return float(spla.eigsh(A, k=1, which="LA", tol=1e-3, v0=np.ones(A.shape[0]),
                            return_eigenvectors=False)[0])


def _null_pivots(A: sp.csr_matrix, scale: float, rtol: float, backend: str) -> np.ndarray:
    """One row index per eigenvector of ``A`` with eigenvalue ``<= rtol * scale`` (sorted).

    Shift-invert Lanczos on ``A + sigma I`` (``sigma = 1e-10 scale``, well above the
    rounding of ``A``) for the smallest eigenpairs, doubling their number until one is
    above the threshold; then column-pivoted QR of the null vectors picks the rows.
    """
    m = A.shape[0]
    sigma = 1e-10 * scale
    shifted = sparse_cholesky(A + sigma * sp.eye(m, format="csr"), backend)
    try:
        op = spla.LinearOperator((m, m), matvec=shifted.solve, dtype=np.float64)
        k = 8
        while True:
            if k >= m - 1:
                w, V = np.linalg.eigh(A.toarray())
            else:
                w, V = spla.eigsh(A, k=k, sigma=-sigma, which="LM", OPinv=op,
                                  v0=np.ones(m), tol=1e-10)
            null = w <= rtol * scale
            if not null.all() or k >= m - 1:
                break
            k *= 2
    finally:
        shifted.destroy()
    N0 = V[:, null]
    if N0.shape[1] == 0:
        return np.zeros(0, dtype=np.int64)
    _, _, piv = sla.qr(N0.T, pivoting=True, mode="economic")
    return np.sort(piv[:N0.shape[1]]).astype(np.int64)


def homogenize(con: OrthonormalConstraint, out: PETSc.Vec) -> None:
    """Set ``out = D~^T e~``: the minimum-norm solution of ``D x = e`` (if ``e`` is consistent).

    Raises:
        ValueError: if ``con`` was built without a right-hand side.
    """
    if con.rhs_tilde is None:
        raise ValueError("homogenize: the constraint has no right-hand side; "
                         "pass rhs= to orthonormalize")
    con.mult_transpose(con.rhs_tilde, out)


class Projector:
    """``P = I - D~^T D~``: the orthogonal projector onto ``ker D`` (for orthonormal ``D~``)."""

    def __init__(self, con: EqualityConstraint) -> None:
        self.con = con
        self._work: PETSc.Vec | None = None

    def _tmp(self, like: PETSc.Vec) -> PETSc.Vec:
        if self._work is None or self._work.getSizes() != like.getSizes():
            self._work = like.duplicate()
        return self._work

    def apply(self, x: PETSc.Vec, out: PETSc.Vec) -> None:
        """Set ``out = P x`` (``out`` may be ``x``)."""
        z = self.con.mult(x)
        tmp = self._tmp(x)
        self.con.mult_transpose(z, tmp)
        if out.handle != x.handle:
            x.copy(out)
        out.axpy(-1.0, tmp)

    def apply_complement(self, x: PETSc.Vec, out: PETSc.Vec) -> None:
        """Set ``out = Q x = D~^T D~ x``."""
        self.con.mult_transpose(self.con.mult(x), out)

    def as_mat(self, template_vec: PETSc.Vec) -> PETSc.Mat:
        """Return ``P`` as a PETSc Mat of type python shaped like ``template_vec``."""
        return python_shell(_ProjectorCtx(self), template_vec)


class _ProjectorCtx:
    def __init__(self, projector: Projector) -> None:
        self.projector = projector

    def mult(self, mat, x, y) -> None:
        self.projector.apply(x, y)

    multTranspose = mult  # noqa: N815 (PETSc's name); P is symmetric


class _ProjectedOperatorCtx:
    """``y = P A P x + rho Q x`` with one multiplication by ``A`` (counted in ``mults``)."""

    def __init__(self, A: PETSc.Mat, con: EqualityConstraint, rho: float) -> None:
        self.A, self.con, self.rho = A, con, float(rho)
        self.mults = 0
        self._w: PETSc.Vec | None = None
        self._v: PETSc.Vec | None = None

    def mult(self, mat, x, y) -> None:
        if self._w is None:
            self._w, self._v = x.duplicate(), x.duplicate()
        w, v = self._w, self._v
        z = self.con.mult(x)
        self.con.mult_transpose(z, w)
        w.aypx(-1.0, x)  # w = P x
        self.A.mult(w, v)
        self.mults += 1
        # P v + rho Q x = v + D~^T (rho D~ x - D~ v): one transpose product for both terms.
        self.con.mult_transpose(self.rho * z - self.con.mult(v), y)
        y.axpy(1.0, v)

    multTranspose = mult  # noqa: N815


class _PenalizedOperatorCtx:
    """``y = A x + rho D^T D x`` with one multiplication by ``A`` (counted in ``mults``)."""

    def __init__(self, A: PETSc.Mat, con: EqualityConstraint, rho: float) -> None:
        self.A, self.con, self.rho = A, con, float(rho)
        self.mults = 0
        self._w: PETSc.Vec | None = None

    def mult(self, mat, x, y) -> None:
        if self._w is None:
            self._w = x.duplicate()
        self.A.mult(x, y)
        self.mults += 1
        if self.rho != 0.0:
            self.con.mult_transpose(self.rho * self.con.mult(x), self._w)
            y.axpy(1.0, self._w)

    multTranspose = mult  # noqa: N815


def projected_operator(A: PETSc.Mat, con: EqualityConstraint, rho: float = 0.0) -> PETSc.Mat:
    """Return the shell ``P A P + rho Q`` (``Q = D~^T D~``) for an orthonormal ``con``.

    The number of multiplications by ``A`` made through it is
    ``mat.getPythonContext().mults``.
    """
    vec = A.createVecRight()
    return python_shell(_ProjectedOperatorCtx(A, con, rho), vec)


def penalized_operator(A: PETSc.Mat, con: EqualityConstraint, rho: float) -> PETSc.Mat:
    """Return the shell ``A + rho D^T D`` (SMALBE's inner Hessian).

    Counts its multiplications by ``A`` like :func:`projected_operator`. When ``A`` is itself
    ``projected_operator(F, con)`` (``P F P``, as in FETI) the result is
    ``projected_operator(F, con, rho)``: the same operator, but ``D~ x`` is computed once per
    product instead of twice (one reduction over the ranks less per multiplication).
    """
    ctx = A.getPythonContext() if A.getType() == PETSc.Mat.Type.PYTHON else None
    if isinstance(ctx, _ProjectedOperatorCtx) and ctx.con is con and ctx.rho == 0.0:
        return projected_operator(ctx.A, con, ctx.rho + rho)
    vec = A.createVecRight()
    return python_shell(_PenalizedOperatorCtx(A, con, rho), vec)
