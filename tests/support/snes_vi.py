"""An independent reference for large-deformation contact: PETSc SNES VI on the whole mesh.

The same neo-Hookean energy on the same mesh and space as the FETI solve, assembled by DOLFINx
on one rank (``MPI.COMM_SELF``), minimized by PETSc's reduced-space active-set Newton for
variational inequalities (``vinewtonrsls``) with the rigid plane y >= y_plane as a bound on the
vertical displacement of every node, and the Dirichlet values as equal bounds. The load is
applied in steps, each from the last solution.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc
from scipy.spatial import cKDTree

from dolfinx_feti import compat


def neo_hookean(mu: float, lmbda: float) -> Callable:
    def psi(F):
        J = ufl.det(F)
        d = F.ufl_shape[0]
        return mu / 2 * (ufl.tr(F.T * F) - d) - mu * ufl.ln(J) + lmbda / 2 * ufl.ln(J) ** 2
    return psi


def snes_vi(mesh, psi: Callable, fixed: Callable[[np.ndarray, float], tuple], y_plane: float,
            loads: Sequence[float], rtol: float = 1e-14, factor: str | None = None):
    """Minimize ∫ψ(I + ∇u) s.t. the bounds, for each load of ``loads`` in turn.

    Args:
        mesh: The MeshData (first order).
        psi: ψ(F) in UFL.
        fixed: ``fixed(X, load) -> (mask, values)``, per blocked dof (X its node's coordinates
            repeated per component, n × gdim, and the component), which dofs are prescribed.
        y_plane: The rigid plane's height (the last coordinate): x_last + u_last >= y_plane.
        loads: The load values, in order.
        rtol: SNES's relative tolerance on the residual norm.
        factor: The LU package of each Newton step (PETSc's own when None; e.g. "mumps").

    Returns:
        (coordinates of the nodes (n, gdim), displacements (n, gdim), residual R = ∂Π/∂u per
        node (n, gdim)) at the last load, and SNES's iteration counts.
    """
    gdim = mesh.gdim
    msh = compat.create_mesh(MPI.COMM_SELF, mesh.cells, mesh.x, mesh.cell_type, 1)
    V = compat.function_space(msh, gdim, 1)
    u = compat.function(V, "u")
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    F = ufl.variable(ufl.Identity(gdim) + ufl.grad(u))
    Pi = psi(F) * ufl.dx(domain=msh)
    R = ufl.derivative(Pi, u, v)
    Jf = ufl.derivative(R, u, du)
    X = V.tabulate_dof_coordinates()[:, :gdim]
    n = X.shape[0] * gdim
    Xb = np.repeat(X, gdim, axis=0)
    comp = np.tile(np.arange(gdim), X.shape[0])

    def residual(snes, x, f):
        u.x.array[:] = x.array_r
        b = compat.assemble_vector(R)
        f.array[:] = b.array_r
        b.destroy()

    A = compat.assemble_matrix(Jf)

    def jacobian(snes, x, J, P):
        u.x.array[:] = x.array_r
        new = compat.assemble_matrix(Jf)
        P.zeroEntries()
        P.axpy(1.0, new, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        new.destroy()

    x = PETSc.Vec().createSeq(n, comm=MPI.COMM_SELF)
    f = x.duplicate()
    its = []
    for load in loads:
        lb = np.full(n, -PETSc.INFINITY)
        ub = np.full(n, PETSc.INFINITY)
        last = comp == gdim - 1
        lb[last] = y_plane - Xb[last, gdim - 1]
        mask, values = fixed(Xb, comp, load)
        lb[mask] = ub[mask] = values
        xl, xu = x.duplicate(), x.duplicate()
        xl.array[:], xu.array[:] = lb, ub
        x.array[:] = np.clip(x.array_r, lb, ub)
        snes = PETSc.SNES().create(MPI.COMM_SELF)
        snes.setType("vinewtonrsls")
        snes.setFunction(residual, f)
        snes.setJacobian(jacobian, A)
        snes.setVariableBounds(xl, xu)
        snes.setTolerances(atol=0.0, rtol=rtol, stol=0.0, max_it=100)
        snes.getKSP().setType("preonly")
        snes.getKSP().getPC().setType("lu")
        if factor is not None:
            snes.getKSP().getPC().setFactorSolverType(factor)
        snes.solve(None, x)
        if snes.getConvergedReason() <= 0:
            raise RuntimeError(f"SNES VI did not converge at load {load}: reason "
                               f"{snes.getConvergedReason()}")
        its.append(snes.getIterationNumber())
        snes.destroy()
        xl.destroy()
        xu.destroy()
    residual(None, x, f)
    out = (X, x.array_r.reshape(-1, gdim).copy(), f.array_r.reshape(-1, gdim).copy())
    for obj in (x, f, A):
        obj.destroy()
    return (*out, its)


def match(X_ref: np.ndarray, X: np.ndarray) -> np.ndarray:
    """For each point of X, the index of the same point in X_ref (to round-off)."""
    dist, idx = cKDTree(X_ref).query(X)
    assert dist.max() < 1e-10, dist.max()
    return idx
