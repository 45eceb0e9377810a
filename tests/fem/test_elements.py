"""Lagrange degree 1 and 2 on triangles, quadrilaterals, tetrahedra and hexahedra.

Patch tests: a uniaxial stress state (pressure p on one face, rollers on the opposite face and
on the symmetry planes) has an exact linear displacement, which every element represents:
the solution must be exact to solver tolerance, with decomposition (gluing on vertex, edge and
face dofs), rigid-body kernels, K⁺ and recovery all in the loop. The same with the rollers
replaced by contact against a rigid plane: the contact pressure must then be p everywhere.
"""

from __future__ import annotations

import dolfinx.fem
import element_models as em
import numpy as np
import pytest
import ufl
from dolfinx_models import gmsh_both
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.constraints import Kind

COMM = MPI.COMM_WORLD
E, NU, PRESSURE = 100.0, 0.3, 1.0
RTOL = 1e-12
EXACT = 1e-8  # the asserted relative error of the patch tests


@pytest.fixture(scope="module")
def mesh_of():
    built = {}

    def get(name):
        if name not in built:
            built[name] = {
                "triangle": lambda: df.build_mesh(em.rectangle, quads=False),
                "quadrilateral": lambda: df.build_mesh(em.rectangle, quads=True),
                "tetrahedron": lambda: df.build_mesh(em.box, hexes=False),
                "hexahedron": lambda: df.build_mesh(em.box, hexes=True),
                "distorted-hexahedron": lambda: em.distorted_hexahedra(),
            }[name]()
        return built[name]

    return get


def exact_u(x: np.ndarray) -> np.ndarray:
    """The uniaxial stress state σ = −p e_last e_last (plane strain in 2D)."""
    if x.shape[1] == 2:
        return np.stack([NU * (1 + NU) * PRESSURE / E * x[:, 0],
                         -(1 - NU**2) * PRESSURE / E * x[:, 1]], axis=1)
    return np.stack([NU * PRESSURE / E * x[:, 0], NU * PRESSURE / E * x[:, 1],
                     -PRESSURE / E * x[:, 2]], axis=1)


def uniaxial(mesh, degree, *, contact=False, parts=3):
    d = mesh.gdim
    top, bottom = ("top", "bottom") if d == 2 else ("z1", "z0")
    sym = [df.Dirichlet("left", components=[0])] if d == 2 else \
        [df.Dirichlet("x0", components=[0]), df.Dirichlet("y0", components=[1])]
    load = (0.0,) * (d - 1) + (-PRESSURE,)
    plane = df.Plane((0.0,) * d, (0.0,) * (d - 1) + (1.0,))
    contact_on = [df.RigidObstacle(bottom, plane)] if contact else []
    rollers = [] if contact else [df.Dirichlet(bottom, components=[d - 1])]
    return df.ContactProblem(mesh, df.Elasticity(E, NU, tractions={top: load}, degree=degree),
                             dirichlet=sym + rollers, contact=contact_on,
                             decomposition=df.Parts(parts))


def rel_error(problem, sol) -> float:
    ex = exact_u(problem.dof_points.x)
    return float(np.abs(sol.nodal_values() - ex).max() / np.abs(ex).max())


CELLS = ["triangle", "quadrilateral", "tetrahedron", "hexahedron", "distorted-hexahedron"]


@pytest.mark.parametrize("degree", [1, 2])
@pytest.mark.parametrize("cell", CELLS)
def test_patch(mesh_of, cell, degree):
    mesh = mesh_of(cell)
    problem = uniaxial(mesh, degree)
    sol = df.solve(problem, rtol=RTOL)
    assert sol.report.converged
    assert problem.dof_points.num_points == sol.nodal_values().shape[0]
    if degree == 2:
        assert problem.dof_points.num_points > mesh.num_nodes
    assert rel_error(problem, sol) <= EXACT


@pytest.mark.parametrize("cell,degree", [(c, k) for c in CELLS for k in (1, 2)])
def test_patch_on_rigid_plane(mesh_of, cell, degree):
    """Frictionless contact on a rigid plane: the same exact state, pressure p everywhere."""
    mesh = mesh_of(cell)
    problem = uniaxial(mesh, degree, contact=True)
    sol = df.solve(problem, rtol=RTOL)
    assert sol.report.converged
    assert rel_error(problem, sol) <= EXACT
    c = sol.contact
    assert np.abs(c.pressure - PRESSURE).max() <= EXACT * PRESSURE
    area = 2.0 if mesh.gdim == 2 else 1.0
    assert sol.total_contact_force[-1] == pytest.approx(PRESSURE * area, rel=EXACT)
    if degree == 2:  # rows on the edge (and face) points of the contact surface too
        assert np.any(c.node >= mesh.num_nodes)


def test_p2_tetrahedra_contact_rows_in_the_transformed_basis(mesh_of):
    """6-node triangles: vertex and edge rows, the edge rows coupling the edge's vertices
    (ũ_e = (u_e − α(u_a + u_b)) / (1 − 2α)), forces in the ratio of ∫Ñ (2/15 : 1/5 per
    facet) under a uniform pressure."""
    mesh = mesh_of("tetrahedron")
    problem = uniaxial(mesh, 2, contact=True)
    sol = df.solve(problem, rtol=RTOL)
    c = sol.contact
    assert np.any(c.node < mesh.num_nodes) and np.any(c.node >= mesh.num_nodes)
    assert np.all(c.force > 0)  # every row carries force: no zero-area vertex
    from dolfinx_feti.constraints.contact import surface
    group = next(b.group for b in problem.contact)
    nodes, _, area = surface(mesh, group, problem.dof_points)
    assert np.allclose(c.force, PRESSURE * area[np.searchsorted(nodes, c.node)], rtol=1e-8)


def test_poisson_degree2_linear_exact(mesh_of):
    mesh = mesh_of("quadrilateral")

    def exact(x):
        return 1.0 + 2.0 * x[:, 0] - 0.5 * x[:, 1]

    problem = df.ContactProblem(
        mesh, df.Poisson(0.0, flux={"right": 2.0}, degree=2),
        dirichlet=[df.Dirichlet(g, exact) for g in ("left", "top", "bottom")],
        decomposition=df.Parts(4))
    sol = df.solve(problem, rtol=RTOL)
    ex = exact(problem.dof_points.x)
    assert np.abs(sol.nodal_values()[:, 0] - ex).max() <= EXACT * np.abs(ex).max()


@pytest.mark.parametrize("cell", ["triangle", "hexahedron"])
def test_gluing_on_every_interface_dof(mesh_of, cell):
    """Degree 2: one gluing row per component at every dof point two subdomains share."""
    mesh = mesh_of(cell)
    problem = uniaxial(mesh, 2, parts=2)
    from serial_setup import build_rows

    from dolfinx_feti.mesh.decompose import decompose

    dec = decompose(mesh, problem.decomposition, 1, problem.dof_points)
    rows = build_rows(problem, dec)
    ptr, _ = dec.node_subdomains()
    shared = np.flatnonzero(np.diff(ptr) == 2)
    assert np.any(shared >= mesh.num_nodes)  # edge (and face) points on the interface
    glued = rows.node[rows.kind == Kind.GLUE]
    fixed = rows.node[rows.kind == Kind.DIRICHLET]
    # every shared point is glued in each component that no Dirichlet row holds
    bs = mesh.gdim
    counts = np.bincount(glued, minlength=problem.dof_points.num_points)[shared]
    held = np.bincount(fixed, minlength=problem.dof_points.num_points)[shared] // 2
    np.testing.assert_array_equal(counts + held, bs)


def test_forms_on_another_space_are_refused(mesh_of):
    mesh = mesh_of("triangle")

    def forms(V, sub):
        W = compat.function_space(V.mesh, 1, 2)  # not the V given
        u, v = ufl.TrialFunction(W), ufl.TestFunction(W)
        return ufl.inner(ufl.grad(u), ufl.grad(v)) * sub.dx(), v * sub.dx()

    problem = df.ContactProblem(mesh, forms, value_size=1, dirichlet=[df.Dirichlet("left")])
    with pytest.raises(df.InputError, match="other than the one the library gives"):
        df.solve(problem)
    with pytest.raises(df.InputError, match="degree"):
        df.ContactProblem(mesh, df.Poisson(1.0, degree=3), dirichlet=[df.Dirichlet("left")])
    with pytest.raises(df.InputError, match="degree=2 given"):
        df.ContactProblem(mesh, df.Poisson(1.0, degree=1), dirichlet=[df.Dirichlet("left")],
                          degree=2)


@pytest.fixture(scope="module")
def quads_dolfinx():
    return gmsh_both(em.rectangle, quads=True, gdim=2)


def test_degree2_on_the_users_quadrilateral_mesh(quads_dolfinx):
    """from_dolfinx + degree 2: solution.u is a Q2 Function on the user's mesh, exact."""
    _, (msh, ct, ft, names) = quads_dolfinx
    mesh = df.from_dolfinx(msh, ct, ft, names=names)
    assert mesh.cell_type == "quadrilateral"
    sol = df.solve(uniaxial(mesh, 2, contact=True), rtol=RTOL)
    u = sol.u
    assert u.function_space.mesh is msh
    assert compat.space_degree(u.function_space) == 2
    # the user's UFL: the error against the exact field, and the energy
    x = ufl.SpatialCoordinate(msh)
    ex = ufl.as_vector([NU * (1 + NU) * PRESSURE / E * x[0], -(1 - NU**2) * PRESSURE / E * x[1]])

    def integral(form):
        return COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(form)), op=MPI.SUM)

    err = np.sqrt(integral(ufl.inner(u - ex, u - ex) * ufl.dx))
    assert err <= EXACT * np.sqrt(integral(ufl.inner(ex, ex) * ufl.dx))
    mu, lmbda = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    eps = ufl.sym(ufl.grad(u))
    strain = 0.5 * ufl.inner(2 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(2), eps)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=ft)
    work = -PRESSURE * u[1] * ds(names["top"][1])
    assert integral(strain * ufl.dx) - integral(work) == pytest.approx(sol.energy, rel=1e-9)


def test_degree2_xdmf_and_von_mises(mesh_of, tmp_path_factory):
    """XDMF of a Q2 solution (vertex values), von Mises = p in the uniaxial state."""
    from dolfinx_feti.results.postprocess import output_functions

    mesh = mesh_of("quadrilateral")
    sol = df.solve(uniaxial(mesh, 2), rtol=RTOL)
    _, vm = output_functions(sol)
    # plane strain uniaxial σ_yy = −p, σ_zz = −ν p: von Mises = p sqrt(1 − ν + ν²)
    expect = PRESSURE * np.sqrt(1 - NU + NU**2)
    assert np.abs(vm.x.array - expect).max() <= 1e-8
    path = COMM.bcast(tmp_path_factory.mktemp("xdmf") if COMM.rank == 0 else None)
    sol.write_xdmf(path / "q2.xdmf")
    assert (path / "q2.xdmf").exists() and (path / "q2.h5").exists()


# ------------------------------------------------------------------------------------------
# Second-order (curved) meshes: isoparametric degree 2
# ------------------------------------------------------------------------------------------

CURVED = {"triangle": (em.plate_with_hole, {}), "quadrilateral": (em.plate_with_hole,
                                                                   {"quads": True}),
          "tetrahedron": (em.box_with_hole, {}), "hexahedron": (em.box_with_hole,
                                                                {"hexes": True})}


def linear_field(x: np.ndarray) -> np.ndarray:
    A = np.array([[1e-3, 2e-3, 0.0], [-5e-4, 3e-3, 1e-3], [0.0, 1e-3, -2e-3]])
    d = x.shape[1]
    return x @ A[:d, :d].T + np.array([1e-3, -2e-3, 5e-4])[:d]


@pytest.mark.parametrize("cell", sorted(CURVED))
def test_curved_patch(cell):
    """Any linear field is exact on curved cells (Dirichlet on every boundary)."""
    model, kwargs = CURVED[cell]
    mesh = df.build_mesh(model, **kwargs)
    assert mesh.cell_type == cell and mesh.geometry_degree == 2
    groups = [g for g in ("outer", "hole") if g in mesh.facet_groups]
    problem = df.ContactProblem(mesh, df.Elasticity(E, NU),  # degree 2 from the mesh
                                dirichlet=[df.Dirichlet(g, linear_field) for g in groups],
                                decomposition=df.Parts(3))
    assert problem.degree == 2
    x = problem.dof_points.x
    if "hole" in groups:  # the edge points of the hole lie on its circle, not on chords
        on = problem.dof_points.group_points(mesh, "hole")
        centre, radius = ((0.5, 0.5), 0.2) if mesh.gdim == 3 else ((1.0, 0.5), 0.25)
        r = np.hypot(x[on, 0] - centre[0], x[on, 1] - centre[1])
        assert np.abs(r - radius).max() < 1e-12
    sol = df.solve(problem, rtol=RTOL)
    ex = linear_field(x)
    assert np.abs(sol.nodal_values() - ex).max() <= EXACT * np.abs(ex).max()
    with pytest.raises(df.InputError, match="second order.*degree-2"):
        df.ContactProblem(mesh, df.Elasticity(E, NU, degree=1),
                          dirichlet=[df.Dirichlet(g) for g in groups])


def test_curved_mesh_from_dolfinx():
    """A curved gmshio mesh: the same data as read_gmsh, the solution on it exact."""
    data, (msh, ct, ft, names) = gmsh_both(em.plate_with_hole, gdim=2)
    mesh = df.from_dolfinx(msh, ct, ft, names=names)
    assert mesh.geometry_degree == 2
    np.testing.assert_array_equal(mesh.x, data.x)
    np.testing.assert_allclose(df.mesh.dofpoints.dof_points(mesh, 2).x,
                               df.mesh.dofpoints.dof_points(data, 2).x, rtol=0, atol=1e-15)
    problem = df.ContactProblem(mesh, df.Elasticity(E, NU), decomposition=df.Parts(3),
                                dirichlet=[df.Dirichlet(g, linear_field)
                                           for g in ("outer", "hole")])
    sol = df.solve(problem, rtol=RTOL)
    u = sol.u
    assert u.function_space.mesh is msh and compat.space_degree(u.function_space) == 2
    x = ufl.SpatialCoordinate(msh)
    ex = ufl.as_vector([1e-3 * x[0] + 2e-3 * x[1] + 1e-3, -5e-4 * x[0] + 3e-3 * x[1] - 2e-3])
    err = COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(
        ufl.inner(u - ex, u - ex) * ufl.dx)), op=MPI.SUM)
    assert np.sqrt(err) <= 1e-10


def test_hertz_p2_on_curved_mesh():
    """2D Hertz with P2: on the curved mesh the pressure is within 0.5 % of Hertz's.

    On the straight-sided mesh of the same model the disk's edge dof points lie on chords,
    inside the circle by the sagitta h²/8R: that geometric gap error dominates, and the
    pressure oscillates between vertex and edge points (bench/hertz_degree.py).
    """
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
    import hertz_degree as hd

    curved = hd.run(0.2, 2, True, COMM)
    straight = hd.run(0.2, 2, False, COMM)
    assert curved["converged"] and straight["converged"]
    assert abs(curved["peak_error"]) < 5e-3 and curved["rms_error"] < 5e-3
    assert curved["rms_error"] < 0.1 * straight["rms_error"]
    assert abs(curved["total_force"] - hd.P / 2) < 1e-8 * hd.P
