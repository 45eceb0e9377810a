"""Shared helpers of the QP tests: distributed PETSc objects from NumPy data, references, KKT.

Every rank builds the same NumPy data from a fixed seed and keeps its own rows, so a
distributed solve can be compared with the serial NumPy reference on every rank. Assertions
use only gathered (replicated) values so that all ranks fail or pass together.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc
from scipy.optimize import lsq_linear

from dolfinx_feti.qp import RowBlockConstraint, python_shell

COMM = PETSc.COMM_WORLD
MPI_COMM: MPI.Comm = COMM.tompi4py()


def ownership(n: int, comm=COMM) -> tuple[int, int]:
    """Rows owned by this rank for a Vec of global size n with PETSc.DECIDE local size."""
    return PETSc.Vec().createMPI((PETSc.DECIDE, n), comm=comm).getOwnershipRange()


def make_vec(values: np.ndarray, comm=COMM) -> PETSc.Vec:
    """Distributed Vec holding the global array ``values``."""
    values = np.asarray(values, dtype=np.float64)
    v = PETSc.Vec().createMPI((PETSc.DECIDE, values.size), comm=comm)
    lo, hi = v.getOwnershipRange()
    v.array[:] = values[lo:hi]
    return v


def make_mat(A, comm=COMM) -> PETSc.Mat:
    """Distributed AIJ Mat: every rank sets its own rows of the (same) global matrix."""
    A = sp.csr_matrix(A)
    n = A.shape[0]
    lo, hi = ownership(n, comm)
    loc = A[lo:hi]
    M = PETSc.Mat().createAIJ(size=((hi - lo, n), (hi - lo, n)),
                              csr=(loc.indptr, loc.indices, loc.data), comm=comm)
    M.assemble()
    return M


def gather(v: PETSc.Vec) -> np.ndarray:
    """The global array of a distributed Vec, on every rank."""
    return np.concatenate(v.getComm().tompi4py().allgather(np.array(v.array_r)))


def gather_local(a: np.ndarray) -> np.ndarray:
    """Concatenate a local array over ranks (ownership order)."""
    return np.concatenate(MPI_COMM.allgather(np.asarray(a)))


def row_block_constraint(D: np.ndarray, comm=COMM) -> RowBlockConstraint:
    """The distributed constraint of a dense ``m x n`` matrix D."""
    lo, hi = ownership(D.shape[1], comm)
    return RowBlockConstraint(sp.csr_matrix(D.T[lo:hi]), comm)


class Counting:
    """Python-shell context that forwards to a Mat and counts its multiplications."""

    def __init__(self, A: PETSc.Mat) -> None:
        self.A = A
        self.calls = 0

    def mult(self, mat, x, y) -> None:
        self.calls += 1
        self.A.mult(x, y)


def counting(A: PETSc.Mat) -> tuple[PETSc.Mat, Counting]:
    """Wrap A in a counting python shell."""
    ctx = Counting(A)
    return python_shell(ctx, A.createVecRight()), ctx


# ---------------------------------------------------------------------------- problem makers

def random_spd(n: int, rng: np.random.Generator, cond: float = 100.0) -> np.ndarray:
    """Dense SPD matrix with eigenvalues log-spaced in [1, cond]."""
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (Q * np.logspace(0, np.log10(cond), n)) @ Q.T


def laplacian_2d(k: int, shift: float = 0.05) -> sp.csr_matrix:
    """Sparse 5-point Laplacian on a k x k grid plus ``shift * I`` (SPD, n = k^2)."""
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(k, k))
    I = sp.eye(k)
    return (sp.kron(I, T) + sp.kron(T, I) + shift * sp.eye(k * k)).tocsr()


# ---------------------------------------------------------------------------- references

def ref_box(A: np.ndarray, b: np.ndarray, l: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Box QP by SciPy's BVLS: with A = L L^T, min ||L^T x - L^{-1} b|| has the same solution.

    Entries with ``l = u`` are eliminated first (BVLS wants ``l < u``).
    """
    A = np.asarray(A)
    x = np.where(l == u, l, 0.0)
    F = l < u
    L = np.linalg.cholesky(A[np.ix_(F, F)])
    c = b[F] - A[np.ix_(F, ~F)] @ x[~F]
    res = lsq_linear(L.T, sla.solve_triangular(L, c, lower=True), bounds=(l[F], u[F]),
                     method="bvls", tol=1e-15, max_iter=10 * len(b))
    x[F] = res.x
    return x


def ref_active_set(A: np.ndarray, b: np.ndarray, l: np.ndarray, u: np.ndarray,
                   D: np.ndarray | None = None, e: np.ndarray | None = None,
                   x0: np.ndarray | None = None, max_it: int = 1000) -> np.ndarray:
    """Dense primal active-set method for ``min 1/2 x'Ax - b'x, l <= x <= u, D x = e``.

    Needs a feasible start ``x0`` and ``A`` positive definite on ``ker D``. Redundant rows of
    ``D`` are handled by least-squares KKT solves. Independent of the code under test.
    """
    A = np.asarray(A)
    n = len(b)
    D = np.zeros((0, n)) if D is None else np.asarray(D)
    x = np.zeros(n) if x0 is None else np.array(x0, dtype=float)
    assert np.all(x >= l) and np.all(x <= u)
    m = D.shape[0]
    work = (x <= l) | (x >= u)
    scale = max(1.0, np.abs(b).max())
    for _ in range(max_it):
        g = A @ x - b
        F = ~work
        nf = int(F.sum())
        K = np.zeros((nf + m, nf + m))
        K[:nf, :nf] = A[np.ix_(F, F)]
        K[:nf, nf:] = D[:, F].T
        K[nf:, :nf] = D[:, F]
        rhs = np.concatenate([-g[F], np.zeros(m)])
        sol = np.linalg.lstsq(K, rhs, rcond=1e-12)[0]
        s = np.zeros(n)
        s[F] = sol[:nf]
        if np.linalg.norm(s) <= 1e-14 * (1.0 + np.linalg.norm(x)):
            # Stationary on the working face: check the signs of the bound multipliers.
            y = np.linalg.lstsq(D[:, F].T, -g[F], rcond=1e-12)[0] if m else np.zeros(0)
            r = g + D.T @ y  # bound multipliers: >= 0 at lower, <= 0 at upper
            at_l = work & (x <= l)
            at_u = work & (x >= u) & ~at_l
            viol = np.where(at_l, -r, 0.0) + np.where(at_u, r, 0.0)
            viol[l == u] = 0.0
            i = int(np.argmax(viol))
            if viol[i] <= 1e-13 * scale:
                return x
            work[i] = False
            continue
        # Largest step towards the face minimizer that stays feasible.
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(s < 0, (l - x) / s, np.where(s > 0, (u - x) / s, np.inf))
        t[work] = np.inf
        j = int(np.argmin(t))
        if t[j] >= 1.0:
            x = x + s
        else:
            x = x + t[j] * s
            x[j] = l[j] if s[j] < 0 else u[j]
            work[j] = True
    raise RuntimeError("reference active set did not converge")


# ---------------------------------------------------------------------------- checks

def kkt(A: np.ndarray, b: np.ndarray, x: np.ndarray, l: np.ndarray, u: np.ndarray,
        Dt_mu: np.ndarray | None = None) -> dict[str, float]:
    """KKT residuals of a box QP (with an optional equality term ``D^T mu`` in the gradient).

    Returns the projected gradient norm, the largest bound violation and the largest
    complementarity product (bound multiplier times distance to its bound).
    """
    g = A @ x - b
    if Dt_mu is not None:
        g = g + Dt_mu
    at_l, at_u = x <= l, x >= u
    phi = np.where(at_l | at_u, 0.0, g)
    beta = np.where(at_l & ~at_u, np.minimum(g, 0), np.where(at_u & ~at_l, np.maximum(g, 0), 0))
    with np.errstate(invalid="ignore"):
        dist_l = np.where(np.isfinite(l), x - l, np.inf)
        dist_u = np.where(np.isfinite(u), u - x, np.inf)
        comp_l = np.where(np.isfinite(l), np.maximum(g, 0) * np.minimum(dist_l, 1e300), 0.0)
        comp_u = np.where(np.isfinite(u), np.maximum(-g, 0) * np.minimum(dist_u, 1e300), 0.0)
    return {
        "gP": float(np.linalg.norm(phi + beta)),
        "infeas": float(max(0.0, np.max(l - x), np.max(x - u))),
        "comp": float(np.max(comp_l + comp_u, initial=0.0)),
        "natural": float(np.linalg.norm(x - np.clip(x - g, l, u))),
    }


# ---------------------------------------------------------------------------- preconditioners

class Diagonal:
    """``y = d * x`` for a global array ``d``: with ``d = 1 / diag(A)`` the Jacobi
    preconditioner, as a plain object with ``mult(x, y)`` (no PETSc Mat)."""

    def __init__(self, d: np.ndarray, like: PETSc.Vec) -> None:
        lo, hi = like.getOwnershipRange()
        self.d = np.asarray(d, dtype=np.float64)[lo:hi]
        self.calls = 0

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        self.calls += 1
        y.array[:] = self.d * x.array_r


class GlobalSolve:
    """Callable ``f(x, y)``: ``y = solve(x)`` on the gathered global vector (any rank count).

    ``solve`` maps a global NumPy array to a global NumPy array, e.g. a factorization of a
    matrix near the Hessian.
    """

    def __init__(self, solve) -> None:
        self.solve = solve
        self.calls = 0

    def __call__(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        self.calls += 1
        lo, hi = y.getOwnershipRange()
        y.array[:] = self.solve(gather(x))[lo:hi]


def obstacle(k: int, load: float = -30.0):
    """Membrane ``-Laplace u = f`` (u = 0 on the boundary of the unit square) over an obstacle
    ``u >= psi``: 5-point stencil on a k x k grid, about 60% of the bounds active."""
    h = 1.0 / (k + 1)
    A = laplacian_2d(k, shift=0.0) / h**2
    xs = np.arange(1, k + 1) * h
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    psi = -0.05 - 0.5 * ((X - 0.5) ** 2 + (Y - 0.5) ** 2) - 0.1 * np.sin(6 * X) ** 2
    return A.tocsr(), np.full(k * k, load), psi.ravel(), np.full(k * k, np.inf)


def scaled(A, rng: np.random.Generator, decades: float = 2.0):
    """``S A S`` with a random positive diagonal ``S`` spanning ``decades`` decades."""
    s = 10.0 ** rng.uniform(0, decades, A.shape[0])
    if sp.issparse(A):
        return (sp.diags(s) @ A @ sp.diags(s)).tocsr()
    return (A * s[:, None]) * s[None, :]


def membrane(m: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """The 5-point Laplacian of an ``m × m`` grid (held on its boundary) and a paraboloid
    obstacle below it: pushed down by a growing uniform load, the contact zone grows by rings
    of nodes, as a contact zone on a load path."""
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(m, m))
    A = (sp.kron(sp.identity(m), T) + sp.kron(T, sp.identity(m))).tocsr() * (m + 1) ** 2
    t = np.arange(1, m + 1) / (m + 1)
    X, Y = np.meshgrid(t, t)
    return A, (-0.05 - 2.0 * ((X - 0.5) ** 2 + (Y - 0.5) ** 2)).ravel()
