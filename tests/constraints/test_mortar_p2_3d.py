"""Mortar contact and ties on P2 tetrahedra (6-node triangles, transformed basis) and Q2 hexahedra.

Independent checks: the biorthogonality of the dual bases and the positive integrals of the
transformed basis and of the 9-node functions (rules of higher degree than the modules'),
the mortar matrix against brute-force sampling (each point located in the master
triangulation), the exact uniaxial state through a non-matching interface on tetrahedra and
hexahedra (contact with either side as slave, and a tie: the patch tests, serially and on 2
ranks), and mortar = node-to-node on matching tetrahedra.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_mortar import occ_mesh

import dolfinx_feti as df
from dolfinx_feti.constraints import mortar_p2_triangles as p2t
from dolfinx_feti.constraints import mortar_q2_quads as q2
from dolfinx_feti.constraints.mortar_quad import area_element, collapsed_gauss, dual_basis
from dolfinx_feti.io import meshes
from dolfinx_feti.io.meshes_occ import sphere_on_block, stacked_blocks
from dolfinx_feti.mesh.dofpoints import dof_points

E, NU, P = {"lower": 100.0, "upper": 300.0}, 0.3, 1.0


def test_dual_basis_is_biorthogonal_to_the_transformed_basis_with_positive_weights():
    xq, wq = collapsed_gauss(8)  # exact for degree 14
    lam = np.c_[1.0 - xq.sum(axis=1), xq]
    N = p2t.shape(lam)
    Nt = N @ p2t.transformation().T
    psi = N @ p2t._C.T
    assert np.allclose(np.einsum("q,qk->k", wq, N), [0, 0, 0, 1 / 3, 1 / 3, 1 / 3],
                       atol=1e-15)  # the plain vertex functions carry no area
    W = np.einsum("q,qk->k", wq, Nt)
    assert np.allclose(W, [2 / 15] * 3 + [1 / 5] * 3, atol=1e-15) and np.all(W > 0)
    assert np.allclose(np.einsum("q,qj,qk->jk", wq, psi, Nt), np.diag(W), atol=1e-13)
    assert np.allclose(Nt.sum(axis=1), 1.0)  # still a partition of unity


def _brute_force_M(mesh, points, slave, master, n: int) -> np.ndarray:
    """M on horizontal surfaces by midpoint sampling (n² sub-triangles per slave facet), each
    point located in the master triangulation (in x, y: the surfaces are planes z = const)."""
    from matplotlib.tri import Triangulation
    x = mesh.x
    sp6, mp6 = p2t.triangle_points(points, slave), p2t.triangle_points(points, master)
    finder = Triangulation(x[:, 0], x[:, 1], master).get_trifinder()
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    lo = np.stack([i, j], axis=-1)[(i + j) < n]
    up = np.stack([i, j], axis=-1)[(i + j) < n - 1]
    cen = np.vstack([(lo + 1.0 / 3.0) / n, (up + 2.0 / 3.0) / n])
    lam = np.c_[1.0 - cen.sum(axis=1), cen]
    psi = p2t.shape(lam) @ p2t._C.T
    M = np.zeros((points.num_points, points.num_points))
    for f in range(slave.shape[0]):  # a test: facets one at a time
        X = x[slave[f]]
        area = 0.5 * np.linalg.norm(np.cross(X[1] - X[0], X[2] - X[0]))
        p = lam @ X
        t = finder(p[:, 0], p[:, 1])
        assert np.all(t >= 0)
        T = x[master[t]][:, :, :2]  # (Q, 3, 2)
        A = np.stack([T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]], axis=2)
        l12 = np.linalg.solve(A, (p[:, :2] - T[:, 0])[..., None])[..., 0]
        Nm = p2t.shape(np.c_[1.0 - l12.sum(axis=1), l12])
        vals = (area / n**2) * psi[:, :, None] * Nm[:, None, :]  # (Q, 6, 6)
        np.add.at(M, (np.broadcast_to(sp6[f][None, :, None], vals.shape),
                      mp6[t][:, None, :].repeat(6, axis=1)), vals)
    return M


def test_mortar_matrix_against_brute_force_integration():
    mesh = occ_mesh(stacked_blocks, 3, 0.3, 0.45, gap=0.01)
    points = dof_points(mesh, 2)
    slave, master = mesh.facets("upper_bottom"), mesh.facets("lower_top")
    c = p2t.triangle6_coupling(mesh.x, mesh.cells, slave, master, points,
                               cell_type=mesh.cell_type)
    M = c.M.toarray()
    err = []
    for n in (16, 32):
        ref = _brute_force_M(mesh, points, slave, master, n)[c.slave_nodes]
        err.append(np.abs(M - ref).max() / np.abs(ref).max())
    # Midpoint sampling converges to M (exact where no master edge cuts a sub-triangle).
    assert err[1] < 0.6 * err[0] and err[1] < 2e-3, err
    assert np.allclose(c.coverage, 1.0, atol=1e-12)  # the unit squares cover each other
    assert c.D.sum() == pytest.approx(1.0, rel=1e-12)
    assert np.all(c.D > 0)
    assert np.allclose(c.weighted_gap(points.x), 0.01, atol=1e-13)


def _uniaxial(problem, E_of_body, p=P, nu=NU):
    """The exact displacement of the stacked boxes under the pressure p, at the dof points."""
    mesh, pts = problem.mesh, problem.dof_points
    body = np.zeros(pts.num_points, dtype=np.int64)
    for b in range(len(mesh.body_names)):
        body[np.unique(pts.cell_points[mesh.cell_body == b])] = b
    x, u = pts.x, np.zeros_like(pts.x)
    for b, name in enumerate(mesh.body_names):
        m = body == b
        u[m, :2] = nu * p / E_of_body[name] * x[m, :2]
        u[m, 2] = -p / E_of_body[name] * x[m, 2] if name == "lower" else \
            -p / E_of_body["lower"] - p / E_of_body[name] * (x[m, 2] - 1.0)
    return u


def _problem(mesh, E_of_body, contact=(), ties=()):
    return df.ContactProblem(
        mesh, df.Elasticity(E_of_body, NU, tractions={"top": (0.0, 0.0, -P)}, degree=2),
        dirichlet=[df.Dirichlet("bottom", components=[2]), df.Dirichlet("sym0", components=[0]),
                   df.Dirichlet("sym1", components=[1])],
        contact=list(contact), ties=list(ties), decomposition=df.Parts(3))


@pytest.fixture(scope="module", params=["P2 tetrahedra", "Q2 hexahedra"])
def blocks(request):
    """Non-matching stacked boxes: tetrahedra 0.25 / 0.42, or hexahedra 4 / 3 per side."""
    hexes = request.param.startswith("Q2")
    mesh = occ_mesh(stacked_blocks, 3, 0.25, 0.42 if not hexes else 0.34, recombine=hexes)
    assert mesh.cell_type == ("hexahedron" if hexes else "tetrahedron")
    return mesh


@pytest.mark.parametrize("slave", ["upper_bottom", "lower_top"])
def test_contact_patch_test_p2(blocks, slave):
    master = "lower_top" if slave == "upper_bottom" else "upper_bottom"
    problem = _problem(blocks, E, contact=[df.Mortar(slave, master)])
    sol = df.solve(problem, rtol=1e-12)
    assert sol.report.converged and not sol.report.warnings, sol.report.warnings
    exact = _uniaxial(problem, E)
    assert np.abs(sol.nodal_values() - exact).max() < 1e-8 * np.abs(exact).max()
    # Rows at the vertices and the edge points of the slave side, all with the pressure p.
    c = sol.contact
    assert np.array_equal(np.sort(c.node), problem.dof_points.group_points(blocks, slave))
    assert np.any(c.node >= blocks.num_nodes)
    assert np.allclose(c.pressure, P, rtol=1e-8)
    assert np.allclose(sol.smoothed_pressure(), P, rtol=1e-8)
    assert abs(sol.total_contact_force[2]) == pytest.approx(P, rel=1e-8)  # on the slave
    info = sol.report.extra["mortar"][0]
    assert info["uncoupled_slave_nodes"] == 0 and info["rim_rows"] == 0


def test_tie_patch_test_p2(blocks):
    E_tie = {"lower": 100.0, "upper": 100.0}
    problem = _problem(blocks, E_tie, ties=[df.Tie("upper_bottom", "lower_top")])
    sol = df.solve(problem, rtol=1e-12)
    assert sol.report.converged
    exact = _uniaxial(problem, E_tie)
    assert np.abs(sol.nodal_values() - exact).max() < 1e-8 * np.abs(exact).max()


@pytest.mark.parametrize("friction", [None, df.Tresca(0.3)])
def test_p2_mortar_equals_node_to_node_on_matching_tetrahedra(friction):
    """Matching meshes: the mortar rows are the node-to-node rows (both in the basis ũ) under
    a load with shear, so every row's coupling and the transformation must agree; with
    friction the upper block is held sideways by it alone (its tangential rows too)."""
    mesh = df.build_mesh(meshes.blocks3d, n=3)
    sides = [] if friction else [df.Dirichlet("sides_upper", components=[0, 1])]

    def problem(contact):
        return df.ContactProblem(
            mesh, df.Elasticity({"lower": 1000.0, "upper": 500.0}, NU,
                                tractions={"top": (0.1, 0.05, -1.0)}, degree=2),
            dirichlet=[df.Dirichlet("bottom"), *sides], contact=[contact],
            decomposition=df.Parts(3))

    a = df.solve(problem(df.Mortar("contact_upper", "contact_lower", friction=friction)),
                 rtol=1e-12)
    b = df.solve(problem(df.NodeToNode("contact_upper", "contact_lower", friction=friction)),
                 rtol=1e-12)
    assert a.report.converged and b.report.converged
    if friction is not None:  # the friction forces on the upper block carry the shear
        assert np.allclose(a.contact.tangential_force.sum(axis=0), [-0.1, -0.05, 0.0],
                           atol=1e-8)
    ub = b.nodal_values()
    assert np.abs(a.nodal_values() - ub).max() < 1e-8 * np.abs(ub).max()
    order_a, order_b = np.argsort(a.contact.node), np.argsort(b.contact.node)
    assert np.allclose(a.contact.force[order_a], b.contact.force[order_b], rtol=1e-7,
                       atol=1e-9 * np.abs(b.contact.force).max())


def test_q2_dual_basis_is_biorthogonal_on_a_warped_facet():
    """9-node facets: positive weights without a transformation, ψ per (warped) facet."""
    P = np.array([[[0, 0, 0], [1.2, 0, 0.1], [0.1, 0.9, 0], [1.0, 1.1, 0.3]]], dtype=float)
    A, D = dual_basis(P, q2.shape)
    g, w = np.polynomial.legendre.leggauss(12)  # a finer rule than the module's
    g, w = 0.5 * (g + 1.0), 0.5 * w
    xi = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    wq = np.outer(w, w).ravel() * area_element(P, xi[None])[0]
    N = q2.shape(xi)
    assert np.allclose(N.sum(axis=1), 1.0)
    assert np.allclose(q2.shape(q2.NODES), np.eye(9))  # nodal at its points
    assert np.all(D > 0)
    assert np.allclose(np.einsum("q,qj,qk->jk", wq, N @ A[0].T, N), np.diag(D[0]), atol=1e-9)
    # On the unit square: 1/36, 1/9, 4/9 at the vertices, edge points, centre.
    _, D1 = dual_basis(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]], float), q2.shape)
    assert np.allclose(D1[0], [1 / 36] * 4 + [1 / 9] * 4 + [4 / 9], atol=1e-14)


@pytest.mark.parametrize("recombine", [False, True])
def test_contact_patch_test_p2_on_a_distributed_mesh(recombine):
    """read_gmsh(distribute=True): the rows from the cells along the surfaces gathered on
    rank 0; the same forces as on the replicated mesh (and with normals="flatter" on flat
    surfaces, the same too)."""
    forces = []
    for distribute in (False, True):
        mesh = df.build_mesh(stacked_blocks, 3, 0.25, 0.34 if recombine else 0.42,
                             recombine=recombine, distribute=distribute)
        problem = _problem(mesh, E, contact=[df.Mortar("upper_bottom", "lower_top",
                                                       normals="flatter")])
        sol = df.solve(problem, rtol=1e-12)
        assert sol.report.converged
        assert np.allclose(sol.contact.pressure, P, rtol=1e-8)
        forces.append(np.sort(sol.contact.force))
    assert np.allclose(forces[0], forces[1], rtol=1e-10)


def test_sphere_on_block_p2_tetrahedra():
    """3D Hertz with P2 mortar (the sphere as slave): the contact force equals the load, the
    contact radius within one element of Hertz's (bench/hertz3d_mortar_degree.py: +0.014 at
    h 0.3, where P1 at h 0.1, about as many dofs, is 0.046 short)."""
    F, R, E_H, NU_H = 20.0, 8.0, 200.0, 0.3
    h = 0.3
    mesh = df.build_mesh(sphere_on_block, h, 5.0 / 3.0 * h)
    t = F / 4 / (np.pi * R**2 / 4)
    problem = df.ContactProblem(
        mesh, df.Elasticity(E_H, NU_H, tractions={"load": (0.0, 0.0, -t)}, degree=2),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sym_x", components=[0]),
                   df.Dirichlet("sym_y", components=[1])],
        contact=[df.Mortar("sphere_contact", "block_contact")], decomposition=df.Parts(8))
    sol = df.solve(problem, rtol=1e-9)
    assert sol.report.converged and not sol.report.warnings, sol.report.warnings
    p = mesh.x[mesh.facets("load")]
    load = t * 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    assert sol.total_contact_force[2] == pytest.approx(load, rel=1e-7)
    a_hertz = (3 * F * R * 2 * (1 - NU_H**2) / (4 * E_H)) ** (1 / 3)
    c = sol.contact
    r = np.linalg.norm(c.x[:, :2], axis=1)
    radius = r[c.pressure > 1e-6 * c.pressure.max()].max()
    assert abs(radius - a_hertz) < h, (radius, a_hertz)
    assert np.any(c.node[c.pressure > 0] >= mesh.num_nodes)  # edge points carry pressure
