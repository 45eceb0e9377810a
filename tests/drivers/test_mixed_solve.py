"""Bodies of different cell types in one problem (drivers/mixed_solve.py): patch tests, Hertz."""

from __future__ import annotations

import hertz_cases as hertz
import numpy as np
import pytest
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes_occ import disk_on_block, sphere_on_block, stacked_blocks

P, E, NU = 1.0, 1000.0, 0.3  # strains of 1e-3: the deformed surfaces are checked too


def _exact(x: np.ndarray, dim: int) -> np.ndarray:
    """Uniform vertical compression p, free sides: 3D and plane strain."""
    if dim == 3:
        return np.stack([NU * P / E * x[:, 0], NU * P / E * x[:, 1], -P / E * x[:, 2]], 1)
    return np.stack([NU * (1 + NU) * P / E * x[:, 0], -(1 - NU**2) * P / E * x[:, 1]], 1)


def _patch_problem(dim, recombined, tie, decomposition=None):
    mesh = df.build_mesh(stacked_blocks, dim, 0.25, 0.4, recombine=recombined)
    bcs = [df.Dirichlet("bottom", 0.0, components=(dim - 1,)),
           df.Dirichlet("sym0", 0.0, components=(0,))]  # sym0: a group on both meshes
    if dim == 3:
        bcs.append(df.Dirichlet("sym1", 0.0, components=(1,)))
    cond = df.Tie("upper_bottom", "lower_top") if tie else df.Mortar("upper_bottom", "lower_top")
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"top": [0.0] * (dim - 1) + [-P]}), dirichlet=bcs,
        decomposition=decomposition or df.Auto(), **({"ties": [cond]} if tie else
                                                      {"contact": [cond]}))


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("recombined", ["lower", "upper"])
@pytest.mark.parametrize("tie", [True, False], ids=["tie", "contact"])
def test_patch_test_exact(dim, recombined, tie):
    """A quadrilateral/hexahedral block and a triangle/tetrahedral one, non-matching.

    Uniform pressure through the interface: the displacement is the linear field of uniform
    stress on both meshes, the interface traction uniform (contact: the pressure p at every
    slave node; tie: the traction (0, …, −p) on the slave).
    """
    problem = _patch_problem(dim, recombined, tie)
    kinds = {p.cell_type for p in problem.mesh.parts}
    assert kinds == ({"hexahedron", "tetrahedron"} if dim == 3 else
                     {"quadrilateral", "triangle"})
    sol = df.solve(problem, method="tfeti", rtol=1e-12)
    assert sol.report.converged
    assert max(sol.report.kkt.values()) < 1e-10, sol.report.kkt  # the joined system's KKT
    assert sol.report.max_penetration < 1e-10
    assert not sol.report.warnings, sol.report.warnings
    assert sol.report.extra["mortar"][0]["rows"] == sol.coupled[0].rows > 0
    if not tie:  # every node of both surfaces against the other deformed surface
        assert sol.report.extra["mortar"][0]["max_penetration"] < 1e-10
    for body in ("lower", "upper"):
        x, u = sol.displacement(body)
        ex = _exact(x, dim)
        assert np.abs(u - ex).max() < 1e-10 * np.abs(ex).max()
    f = sol.forces(0)
    if tie:
        expect = np.zeros(dim)
        expect[-1] = -P
        assert np.abs(f["pressure"] - expect).max() < 1e-10
    else:
        assert np.abs(f["pressure"] - P).max() < 1e-10
    # the interface force balances the load p on the top of area 1
    total = f["force"].sum(axis=0)[-1] if tie else f["force"].sum()
    assert total == pytest.approx(-P if tie else P, rel=1e-10)


@pytest.mark.parametrize("method", ["tfeti", "feti1"])
def test_more_subdomains_spread_over_the_ranks(method):
    """Several subdomains per mesh (rank after rank in the joined layout): still exact, by
    Total FETI and by FETI-1 (the Dirichlet rows eliminated from the joined system)."""
    problem = _patch_problem(3, "lower", False, df.Parts(3))
    sol = df.solve(problem, method=method, rtol=1e-12)
    assert sol.report.sizes["subdomains"] == 6
    assert sol.report.method == {"tfeti": "TFETI", "feti1": "FETI-1"}[method]
    for body in ("lower", "upper"):
        x, u = sol.displacement(body)
        assert np.abs(u - _exact(x, 3)).max() < 1e-10
    assert np.abs(sol.forces(0)["pressure"] - P).max() < 1e-10


def test_summary_has_the_dual_residuals():
    """The report's ||g^P||/||b|| and ||Gλ − e|| are filled (they printed nan): the projected
    gradient within the dual stopping test's rtol, the equality Gλ = e to round-off."""
    problem = _patch_problem(3, "lower", False, df.Parts(2))
    sol = df.solve(problem, method="tfeti", stop_test="dual", rtol=1e-9)
    r = sol.report
    assert r.converged
    assert 0.0 <= r.gP_rel <= 1e-9, r.gP_rel
    assert 0.0 <= r.G_lambda < 1e-10, r.G_lambda
    assert "nan" not in r.summary(), r.summary()


def test_one_function_per_mesh(tmp_path_factory):
    """The displacement as a DOLFINx Function on each mesh, equal to the nodal values."""
    problem = _patch_problem(2, "lower", True)
    sol = df.solve(problem, method="tfeti", rtol=1e-12)
    for k, u in enumerate(sol.u):
        V = u.function_space
        x = V.tabulate_dof_coordinates()[:, :2]
        vals = u.x.array.reshape(-1, 2)
        n = V.dofmap.index_map.size_local
        assert np.abs(vals[:n] - _exact(x[:n], 2)).max() < 1e-10
        assert V.mesh.topology.cell_type.name == problem.mesh.parts[k].cell_type
    folder = MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("mixed")) if
                                  MPI.COMM_WORLD.rank == 0 else None, root=0)
    files = sol.write_xdmf(f"{folder}/u.xdmf")
    assert [f.name for f in files] == ["u_quadrilateral.xdmf", "u_triangle.xdmf"]
    assert all(f.exists() and f.with_suffix(".h5").exists() for f in files)


def test_conditions_refused_by_name():
    mesh = df.build_mesh(stacked_blocks, 2, 0.5, 0.5, recombine="lower")
    forms = df.Elasticity(E, NU)
    with pytest.raises(df.InputError, match=r"NodeToNode\('upper_bottom', 'lower_top'\) joins "
                       "surfaces on meshes of different cell types"):
        df.ContactProblem(mesh, forms, contact=[df.NodeToNode("upper_bottom", "lower_top")])
    with pytest.raises(df.InputError, match="friction and normals='flatter' are not"):
        df.ContactProblem(mesh, forms, contact=[df.Mortar("upper_bottom", "lower_top",
                                                          friction=df.Tresca(0.1))])
    with pytest.raises(df.InputError, match="a surface lies on bodies of several cell types"):
        df.ContactProblem(mesh, forms, ties=[df.Tie("sym0", "lower_top")])
    problem = df.ContactProblem(mesh, forms, ties=[df.Tie("upper_bottom", "lower_top")])
    with pytest.raises(df.InputError, match="solved by df.solve"):
        df.FetiSolver(problem)
    with pytest.raises(df.InputError, match="method='fetidp'.* Total FETI or FETI-1"):
        df.solve(problem, method="fetidp")
    large = df.ContactProblem(mesh, df.NeoHookean(E, NU),
                              ties=[df.Tie("upper_bottom", "lower_top")])
    with pytest.raises(df.InputError, match="large deformation.* not implemented"):
        df.solve(large)


# -- Hertz: a triangle-meshed cylinder on quadrilaterals, a tetrahedral sphere on hexahedra ---

def test_hertz_cylinder_of_triangles_on_a_block_of_quadrilaterals():
    """Plane strain Hertz (half model), the disk of triangles, the block of quadrilaterals.

    The contact half-width within one block element of Hertz's a, the peak pressure within
    3 % of p0 (measured: 2.1 %), the vertical contact force equal to the load.
    """
    h = 0.05
    mesh = df.build_mesh(disk_on_block, h, 1.7 * h, recombine="block")
    assert mesh.cell_types == ("triangle", "quadrilateral")
    sol = df.solve(hertz.disk_problem(mesh), method="tfeti", rtol=1e-8)
    assert sol.report.converged
    pmax, half_width, element = hertz.mixed_figures(sol, mesh, 2)
    assert abs(pmax / hertz.DISK_P0 - 1.0) < 0.03
    assert abs(half_width - hertz.DISK_A) < element, (half_width, hertz.DISK_A, element)
    f = sol.forces(0)
    vertical = (f["force"][:, None] * f["normal"]).sum(axis=0)[1]
    assert vertical == pytest.approx(hertz.DISK_P / 2, rel=1e-6)  # on the flat top of length R


def test_hertz_sphere_of_tetrahedra_on_a_block_of_hexahedra():
    """3D Hertz (quarter model): a tetrahedral hemisphere on a graded hexahedral block.

    The contact radius within one block element of Hertz's a (measured: 1.007 against 1.030,
    elements 0.29 there), the peak pressure within 3 % of p0 (measured −0.6 %), the vertical
    contact force equal to the load on the sphere's flat top.
    """
    mesh = df.build_mesh(sphere_on_block, 0.25, 0.15, recombine="block")
    assert mesh.cell_types == ("tetrahedron", "hexahedron")
    problem, t = hertz.sphere_problem(mesh, df.Parts(4))
    sol = df.solve(problem, method="tfeti", rtol=1e-9)
    assert sol.report.converged
    pmax, radius, element = hertz.mixed_figures(sol, mesh, 3)
    assert abs(pmax / hertz.SPHERE_P0 - 1.0) < 0.03, pmax / hertz.SPHERE_P0
    assert not sol.report.warnings, sol.report.warnings  # no node through the other surface
    assert abs(radius - hertz.SPHERE_A) < element, (radius, hertz.SPHERE_A, element)
    sphere = mesh.parts[mesh.part_of_body("sphere")]
    v = sphere.x[sphere.facets("load")]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum()
    f = sol.forces(0)
    vertical = (f["force"][:, None] * f["normal"]).sum(axis=0)[2]
    assert vertical == pytest.approx(t * area, rel=1e-6)


def test_distributed_equals_serial():
    """The solve over the ranks equals each rank's own serial solve (Hertz 2D, an active set).

    Under ``mpirun -n 2`` the first solve is spread over two ranks, the second is one rank's
    alone (the mesh is held whole on every rank).
    """
    mesh = df.build_mesh(disk_on_block, 0.2, 0.34, recombine="block")
    problem = hertz.disk_problem(mesh)
    spread = df.solve(problem, method="tfeti", rtol=1e-10)
    alone = df.solve(problem, comm=MPI.COMM_SELF, method="tfeti", rtol=1e-10)
    for k in range(len(mesh.parts)):
        a, b = spread.nodal_values(k), alone.nodal_values(k)
        assert np.abs(a - b).max() < 1e-7 * np.abs(b).max()
    fa, fb = spread.forces(0), alone.forces(0)
    np.testing.assert_array_equal(fa["node"], fb["node"])
    assert np.abs(fa["force"] - fb["force"]).max() < 1e-6 * fb["force"].max()


@pytest.mark.parametrize("dim", [2, 3])
def test_rigid_obstacle_under_the_lower_body(dim):
    """Conditions within one mesh as before: the hexahedral (quadrilateral) block on a rigid
    plane instead of a Dirichlet base, the tetrahedral (triangle) block on it by mortar
    contact: the same exact linear field, both interfaces at the uniform pressure p.
    """
    mesh = df.build_mesh(stacked_blocks, dim, 0.25, 0.4, recombine="lower")
    bcs = [df.Dirichlet("sym0", 0.0, components=(0,))]
    if dim == 3:
        bcs.append(df.Dirichlet("sym1", 0.0, components=(1,)))
    plane = df.Plane([0.0] * dim, [0.0] * (dim - 1) + [1.0])
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"top": [0.0] * (dim - 1) + [-P]}), dirichlet=bcs,
        contact=[df.RigidObstacle("bottom", plane), df.Mortar("upper_bottom", "lower_top")])
    assert len(problem.mixed.problems[0].contact) == 1 and len(problem.mixed.across) == 1
    sol = df.solve(problem, method="tfeti", rtol=1e-12)
    assert sol.report.converged and sol.report.max_penetration < 1e-10
    for body in ("lower", "upper"):
        x, u = sol.displacement(body)
        ex = _exact(x, dim)
        assert np.abs(u - ex).max() < 1e-9 * np.abs(ex).max()
    assert np.abs(sol.forces(0)["pressure"] - P).max() < 1e-9
