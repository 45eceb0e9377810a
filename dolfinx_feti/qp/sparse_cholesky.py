"""Sparse Cholesky factorizations ``P A Pᵀ = L Lᵀ`` with the half solves ``L⁻¹ P`` and ``Pᵀ L⁻ᵀ``.

An orthonormalizing transform ``T`` with ``T A Tᵀ = I`` needs the factor itself, not only
``A⁻¹``: ``T = L⁻¹ P``. Neither CHOLMOD nor MUMPS exposes half solves through PETSc, so two
back ends are offered:

- :class:`CholmodFactor`: CHOLMOD (SuiteSparse) called directly — supernodal, BLAS-3, the
  library PETSc's ``cholmod`` solver type links to (used only where this PETSc has it).
  Loaded with ``ctypes``; only the public structs ``cholmod_sparse``/``cholmod_dense`` and the
  leading fields of ``cholmod_common`` (unchanged since CHOLMOD 1) are laid out here, and
  every factor is checked numerically (``T A Tᵀ x = x`` on a random ``x``) before use.
- :class:`PetscFactor`: PETSc's own sparse Cholesky (nested-dissection ordering), whose
  ``MatForwardSolve``/``MatBackwardSolve`` are the half solves; slower to factor (no
  supernodes) but always present.

:func:`sparse_cholesky` picks CHOLMOD when the library loads and passes the check.
"""

from __future__ import annotations

import ctypes
import ctypes.util

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from petsc4py import PETSc

from ..factor import available_factors

_CHOLMOD_INT, _CHOLMOD_REAL, _CHOLMOD_DOUBLE = 0, 1, 0
_SYS_A, _SYS_L, _SYS_LT, _SYS_P, _SYS_PT = 0, 4, 5, 7, 8
# cholmod_common's leading fields (CHOLMOD 1 to 5): byte offset, C type, value set by
# cholmod_start. They are all checked before two of them are written (final_asis = 0 and
# final_ll = 1: leave the factor as L Lᵀ; print = 0: no warnings on stderr).
_COMMON_DEFAULTS = (
    (0, ctypes.c_double, 0.0), (8, ctypes.c_double, 1.2), (16, ctypes.c_double, 1.2),
    (24, ctypes.c_size_t, 5), (32, ctypes.c_size_t, 8), (40, ctypes.c_double, 40.0),
    (48, ctypes.c_int, 1), (52, ctypes.c_int, 1), (56, ctypes.c_int, 1), (60, ctypes.c_int, 0),
    (80, ctypes.c_double, 0.8), (88, ctypes.c_double, 0.1), (96, ctypes.c_double, 0.05),
    (104, ctypes.c_size_t, 4), (112, ctypes.c_size_t, 16), (120, ctypes.c_size_t, 48),
    (132, ctypes.c_int, 1), (144, ctypes.c_int, 3))
_OFF_FINAL_ASIS, _OFF_FINAL_LL, _OFF_PRINT = 52, 60, 144
_COMMON_BYTES = 1 << 16  # the struct is a few kB in every CHOLMOD version; be generous


class NotPositiveDefinite(ValueError):
    """The matrix handed to a sparse Cholesky factorization is not (numerically) SPD."""


class _Sparse(ctypes.Structure):
    _fields_ = [("nrow", ctypes.c_size_t), ("ncol", ctypes.c_size_t),
                ("nzmax", ctypes.c_size_t), ("p", ctypes.c_void_p), ("i", ctypes.c_void_p),
                ("nz", ctypes.c_void_p), ("x", ctypes.c_void_p), ("z", ctypes.c_void_p),
                ("stype", ctypes.c_int), ("itype", ctypes.c_int), ("xtype", ctypes.c_int),
                ("dtype", ctypes.c_int), ("sorted", ctypes.c_int), ("packed", ctypes.c_int)]


class _Dense(ctypes.Structure):
    _fields_ = [("nrow", ctypes.c_size_t), ("ncol", ctypes.c_size_t),
                ("nzmax", ctypes.c_size_t), ("d", ctypes.c_size_t), ("x", ctypes.c_void_p),
                ("z", ctypes.c_void_p), ("xtype", ctypes.c_int), ("dtype", ctypes.c_int)]


class _FactorHead(ctypes.Structure):  # the leading fields of cholmod_factor
    _fields_ = [("n", ctypes.c_size_t), ("minor", ctypes.c_size_t)]


_LIB: ctypes.CDLL | None | bool = None


def _cholmod() -> ctypes.CDLL | None:
    """The CHOLMOD library with its prototypes, or None when it cannot be loaded.

    Only where this PETSc has CHOLMOD: then the library found is the one PETSc links, with the
    BLAS of this process. Beside a PETSc without it (DOLFINx 0.11's wheel) a system CHOLMOD
    would reach its BLAS through ``libopenblas.so.0``, a soname the wheel has already loaded
    with its own OpenBLAS, and crash inside it (measured: dtrsm, a segmentation fault).
    """
    global _LIB
    if _LIB is None:
        _LIB = False
        if "cholmod" not in available_factors():
            return None
        name = ctypes.util.find_library("cholmod")
        try:
            lib = ctypes.CDLL(name or "libcholmod.so")
        except OSError:
            return None
        vp, ip = ctypes.c_void_p, ctypes.c_int
        for fn, args, res in (
                ("cholmod_start", [vp], ip), ("cholmod_finish", [vp], ip),
                ("cholmod_analyze", [vp, vp], vp), ("cholmod_factorize", [vp, vp, vp], ip),
                ("cholmod_solve2", [ip, vp, vp, vp, vp, vp, vp, vp, vp], ip),
                ("cholmod_free_factor", [vp, vp], ip), ("cholmod_free_dense", [vp, vp], ip),
                ("cholmod_rcond", [vp, vp], ctypes.c_double)):
            f = getattr(lib, fn, None)
            if f is None:
                return None
            f.argtypes, f.restype = args, res
        _LIB = lib
    return _LIB or None


def _lower_csc(A: sp.spmatrix) -> sp.csc_matrix:
    L = sp.tril(sp.csc_matrix(A, dtype=np.float64), format="csc")
    L.sort_indices()
    return L


class CholmodFactor:
    """``P A Pᵀ = L Lᵀ`` by CHOLMOD (supernodal where it pays), with half solves.

    Args:
        A: Symmetric positive definite matrix (only its lower triangle is read).

    Raises:
        NotPositiveDefinite: When a pivot is not positive.
        OSError: When CHOLMOD cannot be loaded.
    """

    def __init__(self, A: sp.spmatrix) -> None:
        lib = _cholmod()
        if lib is None:
            raise OSError("CHOLMOD (libcholmod) could not be loaded")
        self._lib = lib
        self.n = int(A.shape[0])
        self._common = ctypes.create_string_buffer(_COMMON_BYTES)
        self._c = ctypes.cast(self._common, ctypes.c_void_p)
        self._L = ctypes.c_void_p()
        self._X, self._Y, self._E = ctypes.c_void_p(), ctypes.c_void_p(), ctypes.c_void_p()
        lib.cholmod_start(self._c)
        if any(t.from_buffer(self._common, off).value != v for off, t, v in _COMMON_DEFAULTS):
            self.destroy()
            raise OSError("CHOLMOD: cholmod_common is not laid out as expected")
        for off, value in ((_OFF_FINAL_ASIS, 0), (_OFF_FINAL_LL, 1), (_OFF_PRINT, 0)):
            ctypes.c_int.from_buffer(self._common, off).value = value
        low = _lower_csc(A)
        indptr = low.indptr.astype(np.int32)
        indices = low.indices.astype(np.int32)
        data = np.ascontiguousarray(low.data)
        S = _Sparse(nrow=self.n, ncol=self.n, nzmax=max(data.size, 1),
                    p=indptr.ctypes.data, i=indices.ctypes.data, nz=None, x=data.ctypes.data,
                    z=None, stype=-1, itype=_CHOLMOD_INT, xtype=_CHOLMOD_REAL,
                    dtype=_CHOLMOD_DOUBLE, sorted=1, packed=1)
        self._L = ctypes.c_void_p(lib.cholmod_analyze(ctypes.byref(S), self._c))
        if not self._L.value:
            self.destroy()
            raise MemoryError("CHOLMOD: the symbolic analysis failed")
        ok = lib.cholmod_factorize(ctypes.byref(S), self._L, self._c)
        head = _FactorHead.from_address(self._L.value)
        if not ok or head.minor < head.n:
            minor = int(head.minor)
            self.destroy()
            raise NotPositiveDefinite(f"CHOLMOD: pivot {minor} of {self.n} is not positive")

    def rcond(self) -> float:
        """``(min Lᵢᵢ / max Lᵢᵢ)²``: CHOLMOD's cheap estimate, never below the true ``1/κ(A)``.

        A singular positive semidefinite ``A`` gives a pivot of the size of the rounding, so
        an estimate of order ε; a regular one an estimate at least ``λ_min / λ_max``.
        """
        return float(self._lib.cholmod_rcond(self._L, self._c))

    def _solve(self, system: int, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        rhs = np.asfortranarray(b.reshape(self.n, -1))
        B = _Dense(nrow=self.n, ncol=rhs.shape[1], nzmax=rhs.size, d=self.n,
                   x=rhs.ctypes.data, z=None, xtype=_CHOLMOD_REAL, dtype=_CHOLMOD_DOUBLE)
        ok = self._lib.cholmod_solve2(system, self._L, ctypes.byref(B), None,
                                      ctypes.byref(self._X), None, ctypes.byref(self._Y),
                                      ctypes.byref(self._E), self._c)
        if not ok:
            raise MemoryError("CHOLMOD: solve failed")
        X = _Dense.from_address(self._X.value)
        out = np.ctypeslib.as_array(ctypes.cast(X.x, ctypes.POINTER(ctypes.c_double)),
                                    shape=(rhs.size,)).copy()
        return out.reshape(b.shape, order="F") if b.ndim == 2 else out

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A⁻¹ b`` (``b`` a vector or an ``n × k`` block)."""
        return self._solve(_SYS_A, b)

    def half(self, b: np.ndarray) -> np.ndarray:
        """``L⁻¹ P b``."""
        return self._solve(_SYS_L, self._solve(_SYS_P, b))

    def half_transpose(self, y: np.ndarray) -> np.ndarray:
        """``Pᵀ L⁻ᵀ y``."""
        return self._solve(_SYS_PT, self._solve(_SYS_LT, y))

    def destroy(self) -> None:
        """Free CHOLMOD's memory (idempotent)."""
        if getattr(self, "_c", None) is None:
            return
        for h in (self._X, self._Y, self._E):
            if h.value:
                self._lib.cholmod_free_dense(ctypes.byref(h), self._c)
        if self._L.value:
            self._lib.cholmod_free_factor(ctypes.byref(self._L), self._c)
        self._lib.cholmod_finish(self._c)
        self._c = None

    def __del__(self) -> None:
        self.destroy()


class PetscFactor:
    """``A = Pᵀ Uᵀ D U P`` by PETSc's sparse Cholesky (nested dissection), with half solves.

    ``MatForwardSolve`` applies ``(Uᵀ D^½)⁻¹`` (with the permutation) and ``MatBackwardSolve``
    ``(D^½ U)⁻¹``: the two halves of ``A⁻¹``.

    Raises:
        NotPositiveDefinite: When the factorization fails.
    """

    def __init__(self, A: sp.spmatrix) -> None:
        A = sp.csr_matrix(A, dtype=np.float64)
        A.sort_indices()
        self.n = int(A.shape[0])
        self._csr = A
        self._A = PETSc.Mat().createAIJ(size=A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                                         A.indices.astype(PETSc.IntType),
                                                         A.data), comm=PETSc.COMM_SELF)
        self._A.setOption(PETSc.Mat.Option.SPD, True)
        self._ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        self._ksp.setOperators(self._A)
        self._ksp.setType("preonly")
        pc = self._ksp.getPC()
        pc.setType("cholesky")
        pc.setFactorSolverType("petsc")
        pc.setFactorOrdering("nd")
        try:
            self._ksp.setUp()
        except PETSc.Error:
            self.destroy()
            raise NotPositiveDefinite("PETSc Cholesky: the matrix is not positive definite") \
                from None
        self._F = pc.getFactorMatrix()
        self._b, self._x = self._A.createVecs()
        try:  # PETSc records a failed pivot instead of raising; a half solve refuses D < 0
            ok = _halves_ok(self, A)
        except PETSc.Error:
            ok = False
        if not ok:
            self.destroy()
            raise NotPositiveDefinite("PETSc Cholesky: the matrix is not positive definite")

    def rcond(self) -> float:
        """``λ_min / λ_max`` of ``A`` by two Lanczos estimates (PETSc gives no pivots)."""
        if self.n < 3:
            return float(1.0 / np.linalg.cond(self._csr.toarray()))
        v0 = np.ones(self.n)
        inv = spla.LinearOperator((self.n, self.n), matvec=self.solve, dtype=np.float64)
        big = spla.eigsh(self._csr, k=1, which="LA", tol=1e-2, v0=v0,
                         return_eigenvectors=False)[0]
        inv_big = spla.eigsh(inv, k=1, which="LA", tol=1e-2, v0=v0,
                             return_eigenvectors=False)[0]
        return float(1.0 / (big * inv_big))

    def _apply(self, fn, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        cols = b.reshape(self.n, -1)
        out = np.empty_like(cols)
        for j in range(cols.shape[1]):
            self._b.array[:] = cols[:, j]
            fn(self._b, self._x)
            out[:, j] = self._x.array_r
        return out.reshape(b.shape)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A⁻¹ b``."""
        return self._apply(self._ksp.solve, b)

    def half(self, b: np.ndarray) -> np.ndarray:
        """The forward half: ``T b`` with ``T A Tᵀ = I``."""
        return self._apply(self._F.solveForward, b)

    def half_transpose(self, y: np.ndarray) -> np.ndarray:
        """The backward half: ``Tᵀ y``."""
        return self._apply(self._F.solveBackward, y)

    def destroy(self) -> None:
        """Free the PETSc objects (idempotent)."""
        for name in ("_ksp", "_A", "_b", "_x"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.destroy()
                setattr(self, name, None)


def _halves_ok(factor, A: sp.spmatrix) -> bool:
    """``T A Tᵀ x = x`` and ``Tᵀ T A x = x`` on a random ``x``: the factor is usable."""
    x = np.random.default_rng(1).standard_normal(factor.n)
    with np.errstate(all="ignore"):
        y = factor.half(A @ factor.half_transpose(x))
        z = factor.solve(A @ x)
        return bool(np.linalg.norm(y - x) <= 1e-6 * np.linalg.norm(x)
                    and np.linalg.norm(z - x) <= 1e-6 * np.linalg.norm(x))


def sparse_cholesky(A: sp.spmatrix, backend: str = "auto"):
    """Factor an SPD matrix for solves and half solves.

    Args:
        A: The matrix (symmetric positive definite, ``n ≥ 1``).
        backend: ``"cholmod"``, ``"petsc"`` or ``"auto"`` (CHOLMOD when it loads and its factor
            passes the check, else PETSc).

    Returns:
        A factor with ``n``, ``solve(b)``, ``half(b)`` (``T b``), ``half_transpose(y)``
        (``Tᵀ y``), ``rcond()`` (an estimate of ``1/κ(A)``, never below it) and
        ``destroy()``, where ``Tᵀ T = A⁻¹``.

    Raises:
        NotPositiveDefinite: When ``A`` is not numerically positive definite.
    """
    if backend not in ("auto", "cholmod", "petsc"):
        raise ValueError(f"sparse_cholesky: unknown backend {backend!r}")
    if backend in ("auto", "cholmod") and (backend == "cholmod" or _cholmod() is not None):
        try:
            factor = CholmodFactor(A)
        except OSError:
            if backend == "cholmod":
                raise
        else:
            if backend == "cholmod" or _halves_ok(factor, A):
                return factor
            factor.destroy()
    return PetscFactor(A)


__all__ = ["CholmodFactor", "NotPositiveDefinite", "PetscFactor", "sparse_cholesky"]
