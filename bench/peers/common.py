"""Shared pieces of the peer benchmarks (docs/peers.md): meshes, undecomposed assembly, timers.

The undecomposed ("monolithic") problems are assembled by DOLFINx on ``MPI.COMM_SELF`` with the
helpers of ``tests/support/reference.py`` (which read only the mesh arrays of :class:`MeshData`), so
the peers see exactly the same discrete problem as FETI: same mesh, same P1 stiffness, same
lumped tractions, same node normals and gaps for the linearized contact condition.
"""

from __future__ import annotations

import functools
import resource
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

ROOT = Path(__file__).resolve().parents[2]
for _p in (ROOT / "bench", ROOT / "tests" / "support"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

import reference as ref  # noqa: E402  (tests/support/reference.py)

import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402  (bench/problems.py)
from dolfinx_feti.io import meshes  # noqa: E402

# B2, 3D rigid sphere pressed into the quarter cube
SPHERE_R, SPHERE_D, SPHERE_E, SPHERE_NU = 0.5, 0.02, 10.0, 0.3
SPHERE_A = 0.1
SPHERE_F = 4.0 / 3.0 * SPHERE_E / (1 - SPHERE_NU**2) * SPHERE_A * SPHERE_D  # 0.029304
SPHERE_P0 = 3 * SPHERE_F / (2 * np.pi * SPHERE_A**2)  # 1.39916
# B2, 2D Hertz disk on block
HERTZ_E, HERTZ_NU, HERTZ_R, HERTZ_P = 200.0, 0.3, 8.0, 10.0
HERTZ_P0, HERTZ_A = 6.6124, 0.96277

#: Mesh levels: name -> (h, h_far, refine_radius) for the sphere, (h_contact, h_far) for Hertz.
SPHERE_LEVELS = {"S1": (0.02, 0.1, 0.2), "S2": (0.01, 0.1, 0.2), "S3": (0.0065, 0.08, 0.2),
                 "S4": (0.005, 0.08, 0.2)}
HERTZ_LEVELS = {"H1": (0.02, 1.0), "H2": (0.01, 1.0), "H3": (0.007, 1.0)}
#: B1 (two membranes): name -> (n, H), n×n squares per membrane, H×H subdomains (H/h = 16)
B1_LEVELS = {"M1": (64, 1 / 4), "M2": (128, 1 / 8), "M3": (256, 1 / 16)}


def code_state() -> str:
    """The library the numbers were measured with.

    The working tree's commit (``problems.git_state``), unless ``dolfinx_feti`` was imported
    from a ``git archive`` export put first on PYTHONPATH (a shared tree with someone else's
    uncommitted changes): then the commit written into the export's ``COMMIT`` file.
    """
    pkg = Path(df.__file__).resolve().parent
    stamp = pkg.parent / "COMMIT"
    if pkg.parent != ROOT and stamp.exists():
        return f"export of {stamp.read_text().strip()} ({pkg})"
    return P.git_state()


def maxrss_mib() -> float:
    """Peak resident set size of this process so far (MiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


class Clock:
    """t = Clock(); ...; t() -> seconds since creation."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()

    def __call__(self) -> float:
        return time.perf_counter() - self.t0


# ------------------------------------------------------------------------------------------------
# Meshes and FETI problems
# ------------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=2)
def sphere_mesh(level: str) -> df.MeshData:
    h, h_far, rr = SPHERE_LEVELS[level]
    return P.gmsh_mesh(lambda: meshes.rigid_sphere_cube(h, h_far, rr))


def sphere_obstacle() -> df.Sphere:
    return df.Sphere(center=(0.0, 0.0, SPHERE_R - SPHERE_D), radius=SPHERE_R)


def sphere_problem(level: str, parts: int, balance: str = "cells") -> df.ContactProblem:
    return df.ContactProblem(
        sphere_mesh(level), df.Elasticity(SPHERE_E, SPHERE_NU),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry_x", components=[0]),
                   df.Dirichlet("symmetry_y", components=[1])],
        contact=[df.RigidObstacle("top", sphere_obstacle())],
        decomposition=df.Parts(parts, balance=balance))


def hertz_mesh(level: str) -> df.MeshData:
    return P.hertz2d_mesh(*HERTZ_LEVELS[level])


def hertz_problem(level: str, parts: int, balance: str = "cells") -> df.ContactProblem:
    return P.hertz2d(h_contact=HERTZ_LEVELS[level][0], h_far=HERTZ_LEVELS[level][1],
                     decomposition=df.Parts(parts, balance=balance))


def b1_problem(level: str) -> df.ContactProblem:
    return P.b1(*B1_LEVELS[level])


# ------------------------------------------------------------------------------------------------
# Undecomposed problems
# ------------------------------------------------------------------------------------------------


class Monolithic:
    """K, f (all nodes, dof = bs·node + c), the Dirichlet mask and the contact rows B u <= g.

    ``B`` has one row per contact node (slave node for node-to-node, obstacle node otherwise);
    ``nodes`` are those nodes, ``normals`` the unit normals used in the rows.
    """

    def __init__(self, mesh, bs, K, f, fixed, B, g, nodes, normals):
        self.mesh, self.bs, self.K, self.f = mesh, bs, K, f
        self.fixed, self.B, self.g = fixed, B.tocsr(), g
        self.nodes, self.normals = nodes, normals
        self.free = np.flatnonzero(~fixed)

    @property
    def ndofs(self) -> int:
        return int(self.free.size)

    def reduced(self):
        """(K_ff, f_f, B_f) with the Dirichlet dofs eliminated (homogeneous)."""
        fr = self.free
        return (self.K[fr][:, fr].tocsr(), self.f[fr], self.B[:, fr].tocsr())

    def force(self, lam: np.ndarray) -> float:
        return float(np.sum(lam))


def sphere_monolithic(level: str) -> Monolithic:
    """The undecomposed quarter cube: ∇φ(x)·u >= −φ(x) at every top node, i.e. −n·u <= φ."""
    mesh = sphere_mesh(level)
    K, f = ref.assemble(mesh, 3, ref.elasticity_forms(SPHERE_E, SPHERE_NU))
    fixed = ref.dirichlet_dofs(mesh, 3, [("bottom", None), ("symmetry_x", [0]),
                                         ("symmetry_y", [1])])
    nodes = np.unique(mesh.facet_groups["top"])
    phi, n = sphere_obstacle().distance(mesh.x[nodes])
    m = nodes.size
    rows = np.repeat(np.arange(m), 3)
    cols = (3 * nodes[:, None] + np.arange(3)).ravel()
    B = sp.csr_matrix((-n.ravel(), (rows, cols)), shape=(m, K.shape[0]))
    return Monolithic(mesh, 3, K, f, fixed, B, phi, nodes, n)


def hertz_monolithic(level: str) -> Monolithic:
    """The undecomposed 2D Hertz model: node-to-node rows (u_m − u_s)·n <= g, n = (0, 1)."""
    mesh = hertz_mesh(level)
    K, f = ref.assemble(mesh, 2, ref.elasticity_forms(HERTZ_E, HERTZ_NU))
    f = f + ref.traction_load(mesh, "load", (0.0, -HERTZ_P / 2 / HERTZ_R))
    fixed = ref.dirichlet_dofs(mesh, 2, [("bottom", None), ("symmetry", [0])])
    pairs = ref.match_pairs(mesh, "disk_contact", "block_contact", (0,), 2, (0.0, 1.0))
    normals = np.tile(pairs.normal, (pairs.slave.size, 1))
    mono = Monolithic(mesh, 2, K, f, fixed, pairs.B, pairs.g, pairs.slave, normals)
    mono.master = pairs.master
    return mono


def b1_monolithic(level: str) -> Monolithic:
    """The undecomposed B1: −Δu = f on each membrane, u_left <= u_right on the interface."""
    mesh = P.membranes_mesh(B1_LEVELS[level][0])
    K, f = ref.assemble(mesh, 1, ref.poisson_forms(ref.membrane_source))
    fixed = ref.dirichlet_dofs(mesh, 1, [("dirichlet", None)])
    pairs = ref.match_pairs(mesh, "contact_left", "contact_right", (1,), 1, None)
    mono = Monolithic(mesh, 1, K, f, fixed, pairs.B, pairs.g, pairs.slave,
                      np.ones((pairs.slave.size, 1)))
    mono.master = pairs.master
    return mono


def kkt(mono: Monolithic, u_full: np.ndarray, lam: np.ndarray) -> dict:
    """Relative KKT residuals of (u, λ) on the undecomposed problem (λ >= 0 per B row)."""
    fr = mono.free
    Bl = mono.B.T @ lam
    res = (mono.K @ u_full - mono.f + Bl)[fr]
    scale = max(np.linalg.norm(mono.f[fr]), np.linalg.norm(Bl[fr]), 1e-300)
    r = mono.B @ u_full - mono.g
    umax = max(np.abs(u_full).max(), 1e-300)
    lmax = max(np.abs(lam).max(), 1e-300)
    return {"stationarity": float(np.linalg.norm(res) / scale),
            "primal": float(max(r.max(), 0.0) / umax),
            "dual": float(max(-lam.min(), 0.0) / lmax),
            "compl": float(np.abs(lam * np.minimum(r, 0)).max() / (lmax * umax))}


# ------------------------------------------------------------------------------------------------
# PETSc helpers
# ------------------------------------------------------------------------------------------------


def petsc_mat(A: sp.csr_matrix):
    from petsc4py import PETSc

    A = sp.csr_matrix(A)
    A.sort_indices()
    M = PETSc.Mat().createAIJ(size=A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                                 A.indices.astype(PETSc.IntType), A.data),
                              comm=PETSc.COMM_SELF)
    M.assemble()
    return M


def petsc_vec(a: np.ndarray):
    from petsc4py import PETSc

    return PETSc.Vec().createWithArray(np.array(a, dtype=PETSc.ScalarType), comm=PETSc.COMM_SELF)


def rigid_modes(x: np.ndarray, dofs: np.ndarray, bs: int):
    """Rigid body modes of the dofs ``dofs`` (bs·node + c) as a PETSc NullSpace."""
    from petsc4py import PETSc

    node, comp = dofs // bs, dofs % bs
    X = x[node]
    modes = []
    for c in range(bs):
        modes.append((comp == c).astype(float))
    if bs == 1:
        pass  # the constants
    elif bs == 2:
        modes.append(np.where(comp == 0, -X[:, 1], X[:, 0]))
    else:
        for (a, b) in ((0, 1), (1, 2), (0, 2)):
            v = np.zeros(dofs.size)
            v[comp == a] = -X[comp == a, b]
            v[comp == b] = X[comp == b, a]
            modes.append(v)
    Q, _ = np.linalg.qr(np.column_stack(modes))  # orthonormal, as PETSc's NullSpace wants
    vecs = [petsc_vec(Q[:, k]) for k in range(Q.shape[1])]
    return PETSc.NullSpace().create(vectors=vecs, comm=PETSc.COMM_SELF)


def frames(q: np.ndarray) -> np.ndarray:
    """(m, d, d) orthonormal frames with rows (q, t1[, t2]); 3D: t1 ∝ e_z × q (e_x if q ∥ e_z)."""
    m, d = q.shape
    Q = np.zeros((m, d, d))
    Q[:, 0] = q
    if d == 2:
        Q[:, 1] = np.column_stack([-q[:, 1], q[:, 0]])
        return Q
    t1 = np.cross(np.array([0.0, 0.0, 1.0]), q)
    nt = np.linalg.norm(t1, axis=1)
    axial = nt < 1e-12
    t1[~axial] /= nt[~axial, None]
    t1[axial] = [1.0, 0.0, 0.0]
    Q[:, 1] = t1
    Q[:, 2] = np.cross(q, t1)
    return Q


def solver_ksp(M, method: str, comm, bs: int, rtol: float, near_null=None):
    """A KSP on the SPD matrix M with the linear floors' settings every bench shares.

    "mumps": Cholesky; "gamg": CG + GAMG with ``near_null`` (the rigid body modes) as its
    near-null space.
    """
    from petsc4py import PETSc

    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(M)
    pc = ksp.getPC()
    M.setOption(PETSc.Mat.Option.SPD, True)
    if method == "mumps":
        ksp.setType("preonly")
        pc.setType("cholesky")
        pc.setFactorSolverType("mumps")
    elif method == "gamg":
        M.setNearNullSpace(near_null)
        ksp.setType("cg")
        ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        ksp.setTolerances(rtol=rtol, max_it=5000)
        pc.setType("gamg")
        opts = PETSc.Options()
        opts["pc_gamg_threshold"] = 0.01 if bs == 3 else 0.02
        opts["mg_levels_ksp_type"] = "chebyshev"
        opts["mg_levels_pc_type"] = "jacobi"
        ksp.setFromOptions()
    else:
        raise ValueError(method)
    return ksp


def linear_solve(A: sp.csr_matrix, b: np.ndarray, method: str, x_coords=None, dofs=None,
                 bs: int = 3, rtol: float = 1e-10) -> tuple[np.ndarray, dict]:
    """Solve A x = b by "mumps" (Cholesky) or "gamg" (CG + GAMG with rigid body modes).

    Returns (x, info) with info the times of setup (matrix conversion excluded) and solve.
    """
    from petsc4py import PETSc

    M = petsc_mat(A)
    bv = petsc_vec(b)
    xv = bv.duplicate()
    if method == "gamg":
        M.setBlockSize(1)
    ksp = solver_ksp(M, method, PETSc.COMM_SELF, bs, rtol,
                     near_null=rigid_modes(x_coords, dofs, bs) if method == "gamg" else None)
    t = Clock()
    ksp.setUp()
    t_setup = t()
    ksp.solve(bv, xv)
    t_all = t()
    info = {"t_setup": t_setup, "t": t_all, "its": ksp.getIterationNumber(),
            "reason": int(ksp.getConvergedReason())}
    x = xv.array.copy()
    for o in (ksp, M, bv, xv):
        o.destroy()
    return x, info
