"""DOLFINx meshes in (df.from_dolfinx) and Functions out, on the user's own mesh."""

from __future__ import annotations

import types

import dolfinx.fem
import numpy as np
import pytest
import ufl
from dolfinx_models import gmsh_both
from mpi4py import MPI
from scipy.spatial import cKDTree

import dolfinx_feti as df
from dolfinx_feti.io import meshes

COMM = MPI.COMM_WORLD
RTOL = 1e-10
E, NU, P, R = 200.0, 0.3, 10.0, 8.0
TRACTION = (0.0, -P / 2 / R)


def hertz_problem(mesh, **kw):
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"load": TRACTION}, **kw),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.NodeToNode("disk_contact", "block_contact")],
        decomposition=df.Parts(2))


@pytest.fixture(scope="module")
def hertz():
    """The Hertz half model (h = 0.2) read by read_gmsh and by gmshio (distributed)."""
    return gmsh_both(meshes.hertz2d, h_contact=0.2, h_far=2.0, gdim=2)


def test_mesh_data_matches_read_gmsh(hertz):
    data, (msh, ct, ft, names) = hertz
    mine = df.from_dolfinx(msh, ct, ft, names=names)
    assert mine.cell_type == data.cell_type == "triangle"
    assert mine.num_nodes == data.num_nodes and mine.cells.shape == data.cells.shape
    assert mine.body_names == data.body_names
    assert sorted(mine.facet_groups) == sorted(data.facet_groups)
    # the same nodes (DOLFINx's input order is gmsh's node order, as read_gmsh's)
    np.testing.assert_array_equal(mine.x, data.x)
    for name, f in data.facet_groups.items():
        assert {tuple(sorted(r)) for r in mine.facet_groups[name]} == \
            {tuple(sorted(r)) for r in f}
    if COMM.size > 1:  # the DOLFINx mesh really is distributed
        owned = msh.topology.index_map(2).size_local
        assert 0 < owned < data.cells.shape[0]


def test_same_nodal_solution_as_read_gmsh(hertz):
    """from_dolfinx on a distributed mesh = read_gmsh on the same model, to solver tolerance."""
    data, (msh, ct, ft, names) = hertz
    ref = df.solve(hertz_problem(data), rtol=RTOL)
    sol = df.solve(hertz_problem(df.from_dolfinx(msh, ct, ft, names=names)), rtol=RTOL)
    assert ref.report.converged and sol.report.converged
    u_ref, u = ref.nodal_values(), sol.nodal_values()
    # match by coordinates, not by numbering
    dist, j = cKDTree(data.x).query(sol.problem.mesh.x)
    assert dist.max() < 1e-12
    err = np.abs(u - u_ref[j]).max() / np.abs(u_ref).max()
    assert err < 1e-7, err
    assert sol.contact.force.sum() == pytest.approx(ref.contact.force.sum(), rel=1e-8)


def test_solution_lives_on_the_users_mesh(hertz):
    """solution.u is a Function on the user's mesh; UFL norms on it match the energy."""
    _, (msh, ct, ft, names) = hertz
    sol = df.solve(hertz_problem(df.from_dolfinx(msh, ct, ft, names=names)), rtol=RTOL)
    u = sol.u
    assert isinstance(u, dolfinx.fem.Function)
    assert u.function_space.mesh is msh
    # the user's own UFL on the user's mesh and tags
    mu, lmbda = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))

    def eps(w):
        return ufl.sym(ufl.grad(w))

    sigma = 2 * mu * eps(u) + lmbda * ufl.tr(eps(u)) * ufl.Identity(2)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=ft)
    strain = 0.5 * ufl.inner(sigma, eps(u)) * ufl.dx
    work = ufl.inner(ufl.as_vector(TRACTION), u) * ds(names["load"][1])

    def integral(form):
        return COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(form)), op=MPI.SUM)

    energy = integral(strain) - integral(work)
    assert energy == pytest.approx(sol.energy, rel=1e-7)
    assert energy < 0
    # the contact pressure is a Function on the same mesh, positive on the contact surface
    p = sol.pressure_function()
    assert p.function_space.mesh is msh
    assert COMM.allreduce(p.x.array.max(), op=MPI.MAX) == pytest.approx(
        sol.contact.pressure.max())


def test_default_names_and_name_faults(hertz):
    _, (msh, ct, ft, names) = hertz
    plain = df.from_dolfinx(msh, ct, ft)
    assert plain.body_names == ("1", "2")
    assert "11" in plain.facet_groups and plain.group_tags["11"] == 11
    with pytest.raises(df.InputError, match="no such tag"):
        df.from_dolfinx(msh, ct, ft, names={"disk": 7})
    with pytest.raises(df.InputError, match="used twice"):
        df.from_dolfinx(msh, ct, ft, names={"disk": (2, 1), "2": (1, 12)})
    with pytest.raises(df.InputError, match="dimension"):
        df.from_dolfinx(msh, ft, ct)
    with pytest.raises(df.InputError, match="from_dolfinx"):
        df.ContactProblem(msh, df.Elasticity(E, NU))
    # the result of DOLFINx >= 0.10's gmsh reader is taken whole, names included
    whole = types.SimpleNamespace(mesh=msh, cell_tags=ct, facet_tags=ft,
                                  physical_groups={n: g for n, g in names.items()})
    assert df.from_dolfinx(whole).body_names == ("disk", "block")


def test_untagged_cells_and_embedded_meshes():
    import dolfinx.mesh

    msh = dolfinx.mesh.create_unit_square(COMM, 4, 4)
    tdim = msh.topology.dim
    n = msh.topology.index_map(tdim).size_local
    half = dolfinx.mesh.meshtags(msh, tdim, np.arange(n // 2, dtype=np.int32),
                                 np.ones(n // 2, dtype=np.int32))
    with pytest.raises(df.InputError, match="no cell tag"):
        df.from_dolfinx(msh, half, None)
    all_cells = dolfinx.mesh.meshtags(msh, tdim, np.arange(n, dtype=np.int32),
                                      np.ones(n, dtype=np.int32))
    data = df.from_dolfinx(msh, all_cells, None)
    assert data.cells.shape[0] == 32 and data.facet_groups == {}


def test_a_dolfinx_mesh_gathered_on_rank_0_only(hertz):
    """from_dolfinx(..., replicate=False): rank 0 alone holds the arrays; same solution and
    Functions on the user's mesh."""
    _, (msh, ct, ft, names) = hertz
    whole = df.from_dolfinx(msh, ct, ft, names=names)
    held = df.from_dolfinx(msh, ct, ft, names=names, replicate=False)
    if COMM.rank > 0:
        assert held.x.shape[0] == 0 and held.num_nodes == whole.num_nodes
    a = df.solve(hertz_problem(held), rtol=RTOL)
    b = df.solve(hertz_problem(whole), rtol=RTOL)
    assert a.report.converged and a.report.sizes == b.report.sizes
    assert a.u.function_space.mesh is msh
    scale = np.abs(b.u.x.array).max()
    assert np.abs(a.u.x.array - b.u.x.array).max() <= 1e-10 * scale
    assert np.allclose(a.pressure_function().x.array, b.pressure_function().x.array,
                       rtol=1e-9, atol=1e-12 * b.contact.pressure.max())
