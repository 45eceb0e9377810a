"""The undecomposed contact problem as bounds, for SNES VI and the linear floors, on 1+ ranks.

The contact rows B u <= g of a FETI problem (obstacle rows −n·u <= φ, node-to-node rows, or the
library's own dual-mortar rows) are turned into bounds by a change of unknowns u = T w: at the
node each row constrains (its *pivot*: the obstacle or slave node), the node's unknowns are
rotated into a frame (q, t1, t2) with q along the row's coefficients on that node, and the
q-component is replaced by z = −B_i u. Row i is then the bound z_i >= −g_i, and the gradient of
the energy at z_i is the row's multiplier. This needs each pivot node in one row only and no
row to touch another row's pivot node: true for obstacle rows, node-to-node pairs and dual
mortar (the slave side of a row is its own node alone). The Dirichlet conditions at a pivot
node must be frame components (true for the symmetry planes of the cases here: t1 ∝ e_z × q).

:class:`Bounded` holds the reduced A = Tᵀ K T, b = Tᵀ f and the bounds; :func:`snes_vi` solves
it by PETSc's vinewtonrsls with MUMPS Cholesky, and :func:`floor` solves the same system with
the active set of a reference fixed (MUMPS Cholesky or CG + GAMG with the rigid body modes as
near-null space), on ``comm`` (each rank holds the global SciPy matrices, PETSc gets the rows
it owns).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

_PEERS = str(Path(__file__).resolve().parent / "peers")
if _PEERS not in sys.path:
    sys.path.insert(0, _PEERS)
from common import frames, solver_ksp  # noqa: E402  (bench/peers/common.py)


class Bounded:
    """min ½ wᵀA w − bᵀw s.t. w >= lower, the contact problem in the unknowns w (u = T w).

    Args:
        K: Stiffness (bs·N square, dof = bs·node + component), f the load.
        fixed: Mask of the Dirichlet dofs (homogeneous).
        B: Contact rows (m × bs·N), g their right-hand sides; ``pivot`` the node of each row.
        bs: Components per node.
        x: Node coordinates (for the rigid body modes of GAMG).
    """

    def __init__(self, K: sp.csr_matrix, f: np.ndarray, fixed: np.ndarray, B: sp.csr_matrix,
                 g: np.ndarray, pivot: np.ndarray, bs: int, x: np.ndarray) -> None:
        n = K.shape[0]
        N = n // bs
        # entries at Dirichlet dofs multiply zero: dropped, so a row's direction at its pivot
        # node is a tangent of the fixed components (a half model's symmetry node)
        B = sp.csr_matrix(B @ sp.diags((~fixed).astype(float)))
        B.eliminate_zeros()
        self.bs, self.x, self.B, self.g, self.pivot = bs, x, B, g, pivot
        if np.unique(pivot).size != pivot.size:
            raise ValueError("a pivot node carries two rows")
        pdofs = (bs * pivot[:, None] + np.arange(bs)).ravel()
        is_p = np.zeros(n, dtype=bool)
        is_p[pdofs] = True
        Bc = B.tocoo()
        at_own = (Bc.col // bs) == pivot[Bc.row]
        if np.any(is_p[Bc.col[~at_own]]):
            raise ValueError("a row touches another row's pivot node")
        a = np.zeros((pivot.size, bs))
        a[Bc.row[at_own], Bc.col[at_own] % bs] = Bc.data[at_own]
        na = np.linalg.norm(a, axis=1)
        if np.any(na == 0):
            raise ValueError("a row has no entry at its pivot node")
        self.Q = frames(a / na[:, None])
        self.na = na
        # u at pivot node i: Qᵀ (v_q, v_t...), v_q = (−z_i − rest_i·u)/|a_i|
        rest = sp.csr_matrix((Bc.data[~at_own], (Bc.row[~at_own], Bc.col[~at_own])),
                             shape=B.shape)
        rr = rest.tocoo()
        # T entries: identity off the pivot nodes
        other = np.flatnonzero(~is_p)
        r_list, c_list, v_list = [other], [other], [np.ones(other.size)]
        m = pivot.size
        for c in range(bs):
            ucol = bs * pivot + c
            q_c = self.Q[:, 0, c]
            r_list.append(ucol)  # z_i sits at w-dof bs·pivot (component 0)
            c_list.append(bs * pivot)
            v_list.append(-q_c / na)
            r_list.append(ucol[rr.row])
            c_list.append(rr.col)
            v_list.append(-q_c[rr.row] * rr.data / na[rr.row])
            for k in range(1, bs):
                r_list.append(ucol)
                c_list.append(bs * pivot + k)
                v_list.append(self.Q[:, k, c])
        T = sp.csr_matrix((np.concatenate(v_list), (np.concatenate(r_list),
                                                    np.concatenate(c_list))), shape=(n, n))
        T.eliminate_zeros()
        # Dirichlet: at a pivot node, a fixed component must be one tangent of its frame
        fixed_w = fixed.copy()
        fixed_w[pdofs] = False
        fp = fixed.reshape(N, bs)[pivot]
        for i, c in zip(*np.nonzero(fp), strict=True):
            k = np.flatnonzero(np.abs(self.Q[i, :, c]) > 1e-12)
            if k.size != 1 or k[0] == 0:
                raise ValueError(f"pivot node {pivot[i]}: Dirichlet component {c} is not a "
                                 "tangent of its frame")
            fixed_w[bs * pivot[i] + k[0]] = True
        self.T, self.n = T, n
        self.free = np.flatnonzero(~fixed_w)
        Tf = T[:, self.free].tocsr()
        self.Tf = Tf
        self.A = (Tf.T @ K @ Tf).tocsr()
        self.A.sort_indices()
        self.b = Tf.T @ f
        pos = -np.ones(n, dtype=np.int64)
        pos[self.free] = np.arange(self.free.size)
        self.zpos = pos[bs * pivot]
        assert np.all(self.zpos >= 0)
        self.lower = np.full(self.free.size, -1e20)
        self.lower[self.zpos] = -g
        self.m = m

    def to_w(self, u: np.ndarray) -> np.ndarray:
        """T⁻¹ u restricted to the free w (the rigid modes for GAMG)."""
        bs, p = self.bs, self.pivot
        w = u.copy()
        un = u.reshape(-1, bs)[p]
        v = np.einsum("mkc,mc->mk", self.Q, un)
        v[:, 0] = -(self.B @ u)
        w.reshape(-1, bs)[p] = v
        return w[self.free]

    def to_u(self, w: np.ndarray) -> np.ndarray:
        return self.Tf @ w

    def multipliers(self, w: np.ndarray) -> np.ndarray:
        """λ_i = ∂/∂z_i (½wᵀAw − bᵀw), clipped at 0."""
        return np.maximum((self.A @ w - self.b)[self.zpos], 0.0)

    def rigid_modes_w(self) -> np.ndarray:
        """The rigid body modes of the whole mesh, mapped to w (columns, free w)."""
        bs, x = self.bs, self.x
        N = x.shape[0]
        modes = []
        for c in range(bs):
            u = np.zeros((N, bs))
            u[:, c] = 1.0
            modes.append(u.ravel())
        pairs = [(0, 1)] if bs == 2 else [(0, 1), (1, 2), (0, 2)]
        for a_, b_ in pairs:
            u = np.zeros((N, bs))
            u[:, a_] = -x[:, b_]
            u[:, b_] = x[:, a_]
            modes.append(u.ravel())
        return np.column_stack([self.to_w(u) for u in modes])


# ------------------------------------------------------------------------------------------------
# PETSc on comm: rows split in contiguous blocks
# ------------------------------------------------------------------------------------------------


def _range(n: int, comm) -> tuple[int, int]:
    size, rank = comm.size, comm.rank
    cuts = [n * r // size for r in range(size + 1)]
    return cuts[rank], cuts[rank + 1]


def petsc_mat(A: sp.csr_matrix, comm):
    from petsc4py import PETSc

    n = A.shape[0]
    lo, hi = _range(n, comm)
    loc = A[lo:hi].tocsr()
    loc.sort_indices()
    M = PETSc.Mat().createAIJ(size=((hi - lo, n), (hi - lo, n)),
                              csr=(loc.indptr.astype(PETSc.IntType),
                                   loc.indices.astype(PETSc.IntType), loc.data), comm=comm)
    M.assemble()
    return M


def petsc_vec(a: np.ndarray, comm):
    from petsc4py import PETSc

    lo, hi = _range(a.size, comm)
    v = PETSc.Vec().createMPI((hi - lo, a.size), comm=comm)
    v.array[:] = a[lo:hi]
    return v


def gather(v, comm) -> np.ndarray:
    """A distributed PETSc Vec as a global array on every rank."""
    return np.concatenate(comm.allgather(v.array_r.copy()))


def _ksp(M, method: str, comm, modes: np.ndarray | None, bs: int, rtol: float):
    near_null = None
    if method == "gamg":  # the rigid body modes, orthonormal
        from petsc4py import PETSc

        Qm, _ = np.linalg.qr(modes)
        vecs = [petsc_vec(Qm[:, k], comm) for k in range(Qm.shape[1])]
        near_null = PETSc.NullSpace().create(vectors=vecs, comm=comm)
    return solver_ksp(M, method, comm, bs, rtol, near_null=near_null)


def floor(bp: Bounded, w_ref: np.ndarray, method: str, comm=MPI.COMM_WORLD,
          rtol: float = 1e-10) -> dict:
    """The linear solve with the reference's active rows fixed at their bound (the floor).

    Returns the wall time (submatrix extraction, set-up and solve; the max over the ranks),
    the iterations and the largest difference from ``w_ref`` relative to max |w_ref|.
    """
    comm.Barrier()
    t0 = time.perf_counter()
    active = np.zeros(bp.b.size, dtype=bool)
    active[bp.zpos] = w_ref[bp.zpos] <= bp.lower[bp.zpos] + 1e-12 * max(
        1.0, np.abs(bp.lower[bp.zpos]).max())
    r = np.flatnonzero(~active)
    a = np.flatnonzero(active)
    Arr = bp.A[r][:, r].tocsr()
    rhs = bp.b[r] - bp.A[r][:, a] @ bp.lower[a]
    M = petsc_mat(Arr, comm)
    modes = bp.rigid_modes_w()[r] if method == "gamg" else None
    ksp = _ksp(M, method, comm, modes, bp.bs, rtol)
    bv = petsc_vec(rhs, comm)
    xv = bv.duplicate()
    ksp.solve(bv, xv)
    x = gather(xv, comm)
    comm.Barrier()
    t = time.perf_counter() - t0
    its = ksp.getIterationNumber()
    for o in (ksp, M, bv, xv):
        o.destroy()
    w = bp.lower.copy()
    w[r] = x
    dev = float(np.abs(w - w_ref).max() / max(np.abs(w_ref).max(), 1e-300))
    return {"t": comm.allreduce(t, op=MPI.MAX), "its": its, "ndofs": int(r.size),
            "dev": dev}


def snes_vi(bp: Bounded, rtol: float, comm=MPI.COMM_WORLD, start_closed: bool = False
            ) -> dict:
    """PETSc vinewtonrsls (defaults otherwise), MUMPS Cholesky; (w, u, λ, time, counts).

    ``start_closed``: start from every contact row closed (one MUMPS solve for the rest,
    counted in the time) — a body held only by the contact leaves the first Newton system
    singular from w = 0.
    """
    from petsc4py import PETSc

    comm.Barrier()
    t0 = time.perf_counter()
    A = petsc_mat(bp.A, comm)
    A.setOption(PETSc.Mat.Option.SPD, True)
    b = petsc_vec(bp.b, comm)
    x, r = b.duplicate(), b.duplicate()
    x.set(0.0)
    xl, xu = petsc_vec(bp.lower, comm), petsc_vec(np.full(bp.b.size, 1e20), comm)
    if start_closed:
        x0 = np.zeros(bp.b.size)
        x0[bp.zpos] = bp.lower[bp.zpos]
        rest = np.setdiff1d(np.arange(bp.b.size), bp.zpos)
        M = petsc_mat(bp.A[rest][:, rest].tocsr(), comm)
        ksp = _ksp(M, "mumps", comm, None, bp.bs, 0.0)
        bv = petsc_vec(bp.b[rest] - bp.A[rest] @ x0, comm)
        xv = bv.duplicate()
        ksp.solve(bv, xv)
        x0[rest] = gather(xv, comm)
        for o in (ksp, M, bv, xv):
            o.destroy()
        lo, hi = _range(bp.b.size, comm)
        x.array[:] = x0[lo:hi]

    def residual(snes, X, F):
        A.mult(X, F)
        F.axpy(-1.0, b)

    snes = PETSc.SNES().create(comm)
    snes.setType("vinewtonrsls")
    snes.setFunction(residual, r)
    snes.setJacobian(lambda snes, X, J, Pm: None, A, A)
    snes.setVariableBounds(xl, xu)
    snes.setTolerances(rtol=rtol, atol=1e-50, stol=0.0, max_it=100)
    ksp = snes.getKSP()
    ksp.setType("preonly")
    ksp.getPC().setType("cholesky")
    ksp.getPC().setFactorSolverType("mumps")
    snes.solve(None, x)
    w = gather(x, comm)
    comm.Barrier()
    t = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    out = {"t": t, "its": snes.getIterationNumber(), "reason": int(snes.getConvergedReason()),
           "w": w, "u": bp.to_u(w), "lam": bp.multipliers(w)}
    for o in (snes, A, b, x, r, xl, xu):
        o.destroy()
    return out
