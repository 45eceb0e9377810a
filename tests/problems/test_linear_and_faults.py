"""Problems without contact (projected CG) against a monolithic DOLFINx solve; faults."""

from __future__ import annotations

import dolfinx.fem
import gmsh
import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx_feti as df
from dolfinx_feti import compat


def _square_model(n: int):
    """A unit square "plate" (triangles), groups "left" (x = 0) and "right" (x = 1)."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("plate")
    if MPI.COMM_WORLD.rank == 0:
        s = gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.synchronize()
        edges = gmsh.model.getBoundary([(2, s)], oriented=False)
        left = [e[1] for e in edges if abs(gmsh.model.occ.getCenterOfMass(*e)[0]) < 1e-9]
        right = [e[1] for e in edges if abs(gmsh.model.occ.getCenterOfMass(*e)[0] - 1) < 1e-9]
        gmsh.model.addPhysicalGroup(2, [s], 1)
        gmsh.model.setPhysicalName(2, 1, "plate")
        gmsh.model.addPhysicalGroup(1, left, 11)
        gmsh.model.setPhysicalName(1, 11, "left")
        gmsh.model.addPhysicalGroup(1, right, 12)
        gmsh.model.setPhysicalName(1, 12, "right")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 1.0 / n)
        gmsh.model.mesh.generate(2)
    mesh = df.read_gmsh(None)
    gmsh.model.remove()
    return mesh


@pytest.fixture(scope="module")
def plate():
    return _square_model(12)


def _monolithic(mesh: df.MeshData, E: float, nu: float, traction) -> np.ndarray:
    """Plain DOLFINx solve of the undecomposed plate, clamped on the left (serial, COMM_SELF)."""
    msh = compat.create_mesh(MPI.COMM_SELF, mesh.cells, mesh.x, mesh.cell_type)
    V = compat.function_space(msh, 2)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))

    def eps(w):
        return ufl.sym(ufl.grad(w))

    x = ufl.SpatialCoordinate(msh)
    a = ufl.inner(2 * mu * eps(u) + lmbda * ufl.tr(eps(u)) * ufl.Identity(2), eps(v)) * ufl.dx
    right = ufl.conditional(ufl.gt(x[0], 1 - 1e-9), 1.0, 0.0)
    L = right * ufl.inner(ufl.as_vector(traction), v) * ufl.ds
    dofs = dolfinx.fem.locate_dofs_geometrical(V, lambda p: np.isclose(p[0], 0.0))
    bc = dolfinx.fem.dirichletbc(np.zeros(2), dofs, V)
    uh = compat.solve_linear(a, L, [bc], {"ksp_type": "preonly", "pc_type": "lu"})
    node = compat.node_input_indices(msh)
    geom = compat.cell_geometry_nodes(msh)
    dofs_c = compat.cell_dofs(V)
    out = np.zeros((mesh.num_nodes, 2))
    out[node[geom.ravel()]] = uh.x.array.reshape(-1, 2)[dofs_c.ravel()]
    return out


@pytest.mark.parametrize("decomposition", [df.ByTags(), df.Parts(5), df.Parts(3, "ptscotch")])
def test_glued_plate_matches_monolithic_solve(plate, decomposition):
    """No inequality: the solver is projected CG and reproduces the undecomposed solution."""
    traction = (0.3, -1.0)
    problem = df.ContactProblem(plate, df.Elasticity(100.0, 0.3, tractions={"right": traction}),
                                dirichlet=[df.Dirichlet("left")], decomposition=decomposition)
    sol = df.solve(problem, rtol=1e-12)
    assert sol.report.solver == "cg"
    assert sol.report.converged
    ref = _monolithic(plate, 100.0, 0.3, traction)
    u = sol.nodal_values()
    assert np.abs(u - ref).max() <= 1e-8 * np.abs(ref).max()
    assert sol.report.kkt["equilibrium"] < 1e-9
    assert sol.report.kkt["equality"] < 1e-9


def test_prescribed_displacement(plate):
    """A non-zero Dirichlet value as a function of x: a rigid rotation is reproduced exactly."""
    theta = 1e-3

    def rotation(x):
        return np.stack([-theta * x[:, 1], theta * x[:, 0]], axis=1)

    problem = df.ContactProblem(plate, df.Elasticity(100.0, 0.3),
                                dirichlet=[df.Dirichlet("left", value=rotation)],
                                decomposition=df.Parts(4))
    sol = df.solve(problem, rtol=1e-12)
    assert sol.report.converged
    exact = rotation(plate.x)
    assert np.abs(sol.nodal_values() - exact).max() < 1e-10 * theta


def test_error_on_one_rank_is_raised_on_every_rank(root):
    """A subdomain with NaN data on one rank: every rank raises the same InputError (no hang)."""
    mesh = df.read_gmsh(root / "meshes/blocks3d.msh")

    class NaNOnUpper(df.Elasticity):
        def __call__(self, V, sub):
            a, L = super().__call__(V, sub)
            if sub.body == "upper":
                c = dolfinx.fem.Constant(V.mesh, PETSc.ScalarType(np.nan))
                L = c * ufl.TestFunction(V)[2] * sub.dx()
            return a, L

    problem = df.ContactProblem(mesh, NaNOnUpper(1000.0, 0.3), dirichlet=[df.Dirichlet("bottom")],
                                contact=[df.NodeToNode("contact_upper", "contact_lower")])
    with pytest.raises(df.InputError, match="non-finite"):
        df.solve(problem)
