"""The peer solvers on the undecomposed problems of :mod:`common` (docs/peers.md).

Each ``run_*`` returns a dict with the nodal displacement ``u`` (all dofs, bs·node + c), the
multipliers ``lam`` per contact row of ``mono.B``, the wall time ``t`` (from the assembled
sparse matrices: assembly is not counted for any method) and method-specific counters.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from common import Clock, linear_solve, petsc_mat, petsc_vec
from common import frames as common_frames

# ------------------------------------------------------------------------------------------------
# The floor: a linear solve of the same mesh, contact set fixed
# ------------------------------------------------------------------------------------------------


def floor_sphere(mono, u_ref: np.ndarray, active: np.ndarray, method: str) -> dict:
    """Linear elasticity with the final contact nodes clamped to the reference displacement."""
    fixed = mono.fixed.copy()
    cdofs = (mono.bs * mono.nodes[active][:, None] + np.arange(mono.bs)).ravel()
    fixed[cdofs] = True
    free = np.flatnonzero(~fixed)
    ub = np.zeros(mono.K.shape[0])
    ub[cdofs] = u_ref[cdofs]
    t = Clock()
    A = mono.K[free][:, free].tocsr()
    b = mono.f[free] - mono.K[free] @ ub
    t_extract = t()
    x, info = linear_solve(A, b, method, mono.mesh.x, free, mono.bs)
    u = ub.copy()
    u[free] = x
    info.update(t_extract=t_extract, ndofs=int(free.size), u=u)
    return info


def floor_glued(mono, method: str) -> dict:
    """Linear elasticity of the two bodies glued at every contact pair (slave dofs = master's)."""
    bs, n = mono.bs, mono.K.shape[0]
    s = (bs * mono.nodes[:, None] + np.arange(bs)).ravel()
    m = (bs * mono.master[:, None] + np.arange(bs)).ravel()
    target = np.arange(n)
    target[s] = m
    keep = np.setdiff1d(np.arange(n), s)
    keep = keep[~mono.fixed[keep]]
    col = -np.ones(n, dtype=np.int64)
    col[keep] = np.arange(keep.size)
    c = col[target]
    ok = c >= 0
    Pm = sp.csr_matrix((np.ones(ok.sum()), (np.flatnonzero(ok), c[ok])), shape=(n, keep.size))
    t = Clock()
    A = (Pm.T @ mono.K @ Pm).tocsr()
    b = Pm.T @ mono.f
    t_extract = t()
    x, info = linear_solve(A, b, method, mono.mesh.x, keep, bs)
    info.update(t_extract=t_extract, ndofs=int(keep.size), u=Pm @ x)
    return info


# ------------------------------------------------------------------------------------------------
# SNES vinewtonrsls on the obstacle problem in node frames (bounds on the normal components)
# ------------------------------------------------------------------------------------------------


class _Bounded:
    """The contact problem in new dofs w (u = T w) where each contact row is a bound w_i >= −g_i.

    Subclasses give T, the Dirichlet mask in w and the w-dof of each contact row; this builds
    the reduced A = Tᵀ K T, b = Tᵀ f and the lower bounds that SNES VI needs.
    """

    def _setup(self, mono, T: sp.csr_matrix, fixed_w: np.ndarray, bound_dofs: np.ndarray,
               g: np.ndarray) -> None:
        n = T.shape[1]
        self.T = T
        self.free = np.flatnonzero(~fixed_w)
        Tf = T[:, self.free]
        self.A = (Tf.T @ mono.K @ Tf).tocsr()
        self.b = Tf.T @ mono.f
        lower = np.full(n, -1e20)
        lower[bound_dofs] = -g
        self.lower = lower[self.free]
        pos = -np.ones(n, dtype=np.int64)
        pos[self.free] = np.arange(self.free.size)
        self.normal_pos = pos[bound_dofs]  # position of the bounded w of each contact row
        assert np.all(self.normal_pos >= 0)
        self.Tf = Tf


class Rotated(_Bounded):
    """The obstacle problem in rotated dofs w (u = T w): the constraint is w_n >= −φ."""

    def __init__(self, mono) -> None:
        bs, N = mono.bs, mono.mesh.num_nodes
        assert bs == 3
        frames = np.tile(np.eye(3), (N, 1, 1))
        frames[mono.nodes] = common_frames(mono.normals)
        # u_node = Qᵀ w_node: T has blocks Qᵀ
        r = (3 * np.arange(N)[:, None, None] + np.arange(3)[None, :, None]) * np.ones((1, 1, 3))
        c = (3 * np.arange(N)[:, None, None] + np.arange(3)[None, None, :]) * np.ones((1, 3, 1))
        T = sp.csr_matrix((np.transpose(frames, (0, 2, 1)).ravel(),
                           (r.ravel().astype(np.int64), c.ravel().astype(np.int64))),
                          shape=(3 * N, 3 * N))
        T.eliminate_zeros()
        # Dirichlet u_c = 0 must be a single rotated component (true by the choice of t1)
        fixed_u = mono.fixed.reshape(N, 3)
        fixed_w = np.zeros((N, 3), dtype=bool)
        for node, comp in zip(*np.nonzero(fixed_u), strict=True):
            colc = frames[node][:, comp]
            k = np.flatnonzero(np.abs(colc) > 1e-12)
            assert k.size == 1, f"node {node}: Dirichlet component {comp} not a frame component"
            fixed_w[node, k[0]] = True
        self._setup(mono, T, fixed_w.ravel(), 3 * mono.nodes, mono.g)


class Relative(_Bounded):
    """Node-to-node pairs with normal e_y: the master's u_y replaced by w = −(u_m − u_s)·e_y.

    Row i of B is c·u_m + (the rest); u_m = (−w_i − rest)/c, so B_i u <= g_i is w_i >= −g_i
    and the multiplier is the gradient at w_i, as in :class:`Rotated`.
    """

    def __init__(self, mono) -> None:
        n, bs = mono.K.shape[0], mono.bs
        assert np.allclose(mono.normals, [0.0, 1.0])
        m = bs * mono.master + 1
        assert not mono.fixed[m].any(), "a master's normal dof is a Dirichlet dof"
        B = mono.B.tocoo()
        at_m = B.col == m[B.row]
        c = B.data[at_m][np.argsort(B.row[at_m])]
        R = sp.csr_matrix((np.where(at_m, 1.0, B.data), (B.row, B.col)), shape=B.shape)
        Rc = (sp.diags(-1.0 / c) @ R).tocoo()  # row i of T at dof m_i; w_i sits in column m_i
        other = np.setdiff1d(np.arange(n), m)
        T = sp.csr_matrix((np.r_[np.ones(other.size), Rc.data],
                           (np.r_[other, m[Rc.row]], np.r_[other, Rc.col])), shape=(n, n))
        T.eliminate_zeros()
        self._setup(mono, T, mono.fixed.copy(), m, mono.g)
        self.start_closed = True


def run_snes_vi(mono, rot: _Bounded, rtol: float, factor: str = "mumps") -> dict:
    """PETSc SNES vinewtonrsls (defaults otherwise), MUMPS Cholesky on the reduced systems.

    A floating body (2D Hertz's disk, held only by the contact) leaves the first Newton system
    singular from x = 0; ``rot.start_closed`` starts instead from every contact row closed
    (w = −g, one MUMPS solve for the rest, counted in the time).
    """
    from petsc4py import PETSc

    A = petsc_mat(rot.A)
    A.setOption(PETSc.Mat.Option.SPD, True)
    b = petsc_vec(rot.b)
    x, r = b.duplicate(), b.duplicate()
    x.set(0.0)
    xl, xu = petsc_vec(rot.lower), petsc_vec(np.full(rot.b.size, 1e20))
    t = Clock()
    if getattr(rot, "start_closed", False):
        x0 = np.zeros(rot.b.size)
        x0[rot.normal_pos] = rot.lower[rot.normal_pos]
        rest = np.setdiff1d(np.arange(rot.b.size), rot.normal_pos)
        x0[rest], _ = linear_solve(rot.A[rest][:, rest].tocsr(),
                                   rot.b[rest] - rot.A[rest] @ x0, "mumps")
        x.array[:] = x0

    def residual(snes, X, F):
        A.mult(X, F)
        F.axpy(-1.0, b)

    snes = PETSc.SNES().create(PETSc.COMM_SELF)
    snes.setType("vinewtonrsls")
    snes.setFunction(residual, r)
    snes.setJacobian(lambda snes, X, J, Pm: None, A, A)
    snes.setVariableBounds(xl, xu)
    snes.setTolerances(rtol=rtol, atol=1e-50, stol=0.0, max_it=100)
    ksp = snes.getKSP()
    ksp.setType("preonly")
    ksp.getPC().setType("cholesky")
    ksp.getPC().setFactorSolverType(factor)
    snes.solve(None, x)
    elapsed = t()
    w = x.array.copy()
    A.mult(x, r)
    grad = r.array - rot.b  # = λ at the active normal components (A w − b = Bᵀλ rotated)
    lam = np.maximum(grad[rot.normal_pos], 0.0)
    out = {"t": elapsed, "its": snes.getIterationNumber(), "reason": int(snes.getConvergedReason()),
           "lin_its": snes.getLinearSolveIterations(), "u": rot.Tf @ w, "lam": lam}
    for o in (snes, A, b, x, r, xl, xu):
        o.destroy()
    return out


# ------------------------------------------------------------------------------------------------
# Penalty: semismooth Newton on ½uᵀKu − fᵀu + ε/2 Σ (Bu − g)₊², MUMPS Cholesky
# ------------------------------------------------------------------------------------------------


def run_penalty(mono, eps: float, max_it: int = 50) -> dict:
    """Newton steps until the penetrating set repeats (exact minimizer of the penalty energy)."""
    K, f, B = mono.reduced()
    g = mono.g
    # the initially penetrating nodes; all closed if none (the floating disk needs contact)
    active = g < 0 if np.any(g < 0) else np.ones(g.size, dtype=bool)
    t = Clock()
    its = 0
    u = np.zeros(K.shape[0])
    while its < max_it:
        its += 1
        BA = B[active]
        A = (K + eps * (BA.T @ BA)).tocsr()
        u, _ = linear_solve(A, f + eps * (BA.T @ g[active]), "mumps")
        new = (B @ u - g) > 0
        if np.array_equal(new, active):
            break
        active = new
    elapsed = t()
    lam = eps * np.maximum(B @ u - g, 0.0)
    full = np.zeros(mono.K.shape[0])
    full[mono.free] = u
    return {"t": elapsed, "its": its, "u": full, "lam": lam}


# ------------------------------------------------------------------------------------------------
# General-purpose QP solvers on the undecomposed primal QP
# ------------------------------------------------------------------------------------------------


def run_clarabel(mono, tol: float) -> dict:
    import clarabel

    K, f, B = mono.reduced()
    Pm = sp.triu(K, format="csc")
    A = B.tocsc()
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = tol
    settings.tol_gap_rel = tol
    settings.tol_feas = tol
    settings.tol_ktratio = min(1e-6, tol)
    settings.max_iter = 500
    t = Clock()
    solver = clarabel.DefaultSolver(Pm, -f, A, mono.g, [clarabel.NonnegativeConeT(A.shape[0])],
                                    settings)
    sol = solver.solve()
    elapsed = t()
    full = np.zeros(mono.K.shape[0])
    full[mono.free] = np.asarray(sol.x)
    return {"t": elapsed, "its": int(sol.iterations), "status": str(sol.status), "u": full,
            "lam": np.asarray(sol.z)}


def run_osqp(mono, tol: float, time_limit: float = 30.0) -> dict:
    import osqp

    K, f, B = mono.reduced()
    Pm = sp.triu(K, format="csc")
    A = B.tocsc()
    prob = osqp.OSQP()
    t = Clock()
    prob.setup(Pm, -f, A, np.full(A.shape[0], -np.inf), mono.g, eps_abs=tol, eps_rel=tol,
               max_iter=1_000_000, time_limit=time_limit, verbose=False, polishing=True)
    res = prob.solve()
    elapsed = t()
    full = np.zeros(mono.K.shape[0])
    full[mono.free] = np.asarray(res.x)
    return {"t": elapsed, "its": int(res.info.iter), "status": str(res.info.status),
            "u": full, "lam": np.maximum(np.asarray(res.y), 0.0)}
