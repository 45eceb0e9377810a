"""Mortar contact and ties on degree-2 spaces in 2D (issue 25): 3-node segments.

Independent checks: the biorthogonality of the dual basis, the mortar matrix against a
brute-force integration (many points per slave segment, each projected onto the master
facets), the exact uniaxial solutions through non-matching interfaces (contact and tie patch
tests, P2 triangles and Q2 quadrilaterals), and node-to-node rows on matching meshes.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from test_mortar import occ_mesh

import dolfinx_feti as df
from dolfinx_feti.constraints import mortar_p2, segment3
from dolfinx_feti.io.meshes_occ import stacked_blocks
from dolfinx_feti.mesh.dofpoints import dof_points

E, NU, P = {"lower": 100.0, "upper": 300.0}, 0.3, 1.0


def test_dual_basis_is_biorthogonal_with_positive_weights():
    s, w = np.polynomial.legendre.leggauss(6)
    s, w = 0.5 + 0.5 * s, 0.5 * w
    N = segment3.shape(s)
    psi = N @ mortar_p2._A.T
    # ∫ ψ_j N_k = δ_jk ∫ N_k, and ∫ N_k = (1/6, 1/6, 2/3) > 0.
    assert np.allclose(np.einsum("q,qj,qk->jk", w, psi, N), np.diag(segment3.WEIGHTS),
                       atol=1e-14)
    assert np.all(segment3.WEIGHTS > 0)
    assert np.allclose(np.einsum("q,qj->j", w, psi), segment3.WEIGHTS, atol=1e-14)


def _brute_force_M(x, slave, master, sp_, mp_, n_s, num_points, n: int) -> np.ndarray:
    """M by the midpoint rule with n points per slave segment, each point projected along
    the slave facet's normal onto whichever master segment its normal line crosses."""
    M = np.zeros((num_points, num_points))
    s = (np.arange(n) + 0.5) / n
    psi = segment3.shape(s) @ mortar_p2._A.T
    for f in range(slave.shape[0]):
        a, b = x[slave[f, 0]], x[slave[f, 1]]
        L = np.linalg.norm(b - a)
        q = a + s[:, None] * (b - a)
        nrm = n_s[f]
        ma, mb = x[master[:, 0]], x[master[:, 1]]
        d = mb - ma  # solve q + t n = ma + eta d for (t, eta), per point and master facet
        det = nrm[0] * (-d[:, 1]) - nrm[1] * (-d[:, 0])
        r = ma[None] - q[:, None]
        eta = (nrm[0] * r[..., 1] - nrm[1] * r[..., 0]) / det
        t = (r[..., 0] * (-d[:, 1]) - r[..., 1] * (-d[:, 0])) / det
        hit = (eta >= 0) & (eta <= 1) & (np.abs(t) < 0.5)
        qi, mi = np.nonzero(hit)
        Nm = segment3.shape(eta[qi, mi])
        vals = (L / n) * psi[qi][:, :, None] * Nm[:, None, :]
        np.add.at(M, (np.repeat(sp_[f][None], qi.size, 0)[:, :, None].repeat(3, 2),
                      mp_[mi][:, None, :].repeat(3, 1)), vals)
    return M


def test_mortar_matrix_against_brute_force_integration():
    mesh = occ_mesh(stacked_blocks, 2, 0.1, 0.17, gap=0.01)
    points = dof_points(mesh, 2)
    from dolfinx_feti.mesh.topology import facet_normals
    slave, master = mesh.facets("upper_bottom"), mesh.facets("lower_top")
    c = mortar_p2.quadratic_coupling(mesh.x, mesh.cells, slave, master, points,
                                     cell_type=mesh.cell_type)
    ns, _ = facet_normals(mesh.x, mesh.cells, slave, mesh.cell_type)
    sp_ = mortar_p2.segment_points(points, slave)
    mp_ = mortar_p2.segment_points(points, master)
    ref = _brute_force_M(mesh.x, slave, master, sp_, mp_, ns, points.num_points, 4000)
    ref = ref[c.slave_nodes]
    assert np.abs(c.M.toarray() - ref).max() < 1e-5 * np.abs(ref).max()
    assert np.allclose(c.coverage, 1.0, atol=1e-12)  # the surfaces cover each other
    assert np.allclose(c.D, sp.csr_matrix(c.M).sum(axis=1).A.ravel(), rtol=1e-12)


def uniaxial_at_points(mesh, points, E_of_body, p=P, nu=NU, lower_height=1.0):
    """The exact displacement of the stacked blocks under pressure p, at the dof points."""
    body = np.zeros(points.num_points, dtype=np.int64)
    for b in range(len(mesh.body_names)):
        body[np.unique(points.cell_points[mesh.cell_body == b])] = b
    x, u = points.x, np.zeros_like(points.x)
    ez1 = -(1 - nu**2) * p / E_of_body["lower"]
    for b, name in enumerate(mesh.body_names):
        m = body == b
        ex, ez = (1 + nu) * nu * p / E_of_body[name], -(1 - nu**2) * p / E_of_body[name]
        u[m, 0] = ex * x[m, 0]
        u[m, 1] = ez * x[m, 1] if name == "lower" else \
            ez1 * lower_height + ez * (x[m, 1] - lower_height)
    return u


def p2_problem(mesh, E_of_body, contact=(), ties=()):
    return df.ContactProblem(
        mesh, df.Elasticity(E_of_body, NU, tractions={"top": (0.0, -P)}, degree=2),
        dirichlet=[df.Dirichlet("bottom", components=[1]), df.Dirichlet("sym0", components=[0])],
        contact=list(contact), ties=list(ties), decomposition=df.Parts(3))


@pytest.fixture(scope="module", params=["P2 triangles", "Q2 quadrilaterals"])
def blocks(request):
    return occ_mesh(stacked_blocks, 2, 0.1, 0.17, recombine=request.param.startswith("Q2"))


@pytest.mark.parametrize("slave", ["upper_bottom", "lower_top"])
def test_contact_patch_test_p2(blocks, slave):
    master = "lower_top" if slave == "upper_bottom" else "upper_bottom"
    problem = p2_problem(blocks, E, contact=[df.Mortar(slave, master)])
    sol = df.solve(problem, rtol=1e-12)
    assert sol.report.converged and not sol.report.warnings, sol.report.warnings
    exact = uniaxial_at_points(blocks, problem.dof_points, E)
    assert np.abs(sol.nodal_values() - exact).max() < 1e-8 * np.abs(exact).max()
    # Rows at the vertices and the edge points of the slave side, all with the pressure p.
    slave_points = problem.dof_points.group_points(blocks, slave)
    assert np.array_equal(np.sort(sol.contact.node), slave_points)
    assert np.allclose(sol.contact.pressure, P, rtol=1e-8)
    info = sol.report.extra["mortar"][0]
    assert info["uncoupled_slave_nodes"] == 0 and info["rim_rows"] == 0


def test_tie_patch_test_p2(blocks):
    E_tie = {"lower": 100.0, "upper": 100.0}
    problem = p2_problem(blocks, E_tie, ties=[df.Tie("upper_bottom", "lower_top")])
    sol = df.solve(problem, rtol=1e-12)
    assert sol.report.converged
    exact = uniaxial_at_points(blocks, problem.dof_points, E_tie)
    assert np.abs(sol.nodal_values() - exact).max() < 1e-8 * np.abs(exact).max()


def test_p2_mortar_equals_node_to_node_on_matching_meshes():
    mesh = occ_mesh(stacked_blocks, 2, 0.1, 0.1, recombine=True)
    x = mesh.x
    shear = {"top": (0.3, -P)}

    def problem(contact):
        return df.ContactProblem(mesh, df.Elasticity(E, NU, tractions=shear, degree=2),
                                 dirichlet=[df.Dirichlet("bottom"),
                                            df.Dirichlet("sym0", components=[0])],
                                 contact=[contact], decomposition=df.Parts(2))

    assert np.allclose(np.sort(x[np.unique(mesh.facets("upper_bottom")), 0]),
                       np.sort(x[np.unique(mesh.facets("lower_top")), 0]))  # matching
    a = df.solve(problem(df.Mortar("upper_bottom", "lower_top")), rtol=1e-12)
    b = df.solve(problem(df.NodeToNode("upper_bottom", "lower_top")), rtol=1e-12)
    assert np.abs(a.nodal_values() - b.nodal_values()).max() < \
        1e-8 * np.abs(b.nodal_values()).max()
    assert np.allclose(np.sort(a.contact.force), np.sort(b.contact.force), rtol=1e-7,
                       atol=1e-10)


# -- curved segments (a second-order mesh) ------------------------------------------------------

def _brute_force_curved(X_s: np.ndarray, X_m: np.ndarray, sp_, mp_, num_points: int,
                        n: int = 300, n_eta: int = 600) -> np.ndarray:
    """M of curved segments by sampling: n points per slave segment (midpoint rule in s, with
    the Jacobian), each normal line intersected with every master parabola sampled at n_eta
    points (the sign change of the cross product, interpolated linearly), the dual basis from
    a 6-point rule of its own."""
    M = np.zeros((num_points, num_points))
    s = (np.arange(n) + 0.5) / n
    g, gw = np.polynomial.legendre.leggauss(8)
    g, gw = 0.5 + 0.5 * g, 0.5 * gw
    eta_grid = np.linspace(0.0, 1.0, n_eta)
    Nm_grid = segment3.shape(eta_grid)
    for f in range(X_s.shape[0]):
        X = X_s[f]
        Jg = np.linalg.norm(segment3.dshape(g) @ X, axis=1)
        Ng = segment3.shape(g)
        Me = np.einsum("q,q,qi,qj->ij", gw, Jg, Ng, Ng)
        A = np.diag(np.einsum("q,q,qk->k", gw, Jg, Ng)) @ np.linalg.inv(Me)
        p = segment3.shape(s) @ X
        t = segment3.dshape(s) @ X
        J = np.linalg.norm(t, axis=1)
        nrm = np.stack([t[:, 1], -t[:, 0]], axis=1) / J[:, None]
        psi = segment3.shape(s) @ A.T
        curves = np.einsum("ek,mkd->med", Nm_grid, X_m)  # (masters, n_eta, 2)
        r = curves[None] - p[:, None, None]  # (n, masters, n_eta, 2)
        cr = r[..., 0] * nrm[:, None, None, 1] - r[..., 1] * nrm[:, None, None, 0]
        along = np.einsum("qmed,qd->qme", r, nrm)
        ch = (np.sign(cr[..., :-1]) != np.sign(cr[..., 1:])) & (np.abs(along[..., :-1]) < 0.5)
        qi, mi, ei = np.nonzero(ch)
        c0, c1 = cr[qi, mi, ei], cr[qi, mi, ei + 1]
        eta = eta_grid[ei] + (eta_grid[ei + 1] - eta_grid[ei]) * c0 / (c0 - c1)
        vals = (J[qi] / n)[:, None, None] * psi[qi][:, :, None] * \
            segment3.shape(eta)[:, None, :]
        rows = np.broadcast_to(sp_[f][None, :, None], vals.shape)
        cols = np.broadcast_to(mp_[mi][:, None, :], vals.shape)
        np.add.at(M, (rows, cols), vals)
    return M


def curved_disk_on_block(*args, **kwargs):
    from dolfinx_feti.io.meshes_occ import disk_on_block
    groups = disk_on_block(*args, **kwargs)
    import gmsh
    gmsh.model.mesh.setOrder(2)
    return groups


@pytest.mark.parametrize("slave,master", [("disk_contact", "block_contact"),
                                          ("block_contact", "disk_contact")])
def test_curved_mortar_matrix_against_sampling(slave, master):
    mesh = occ_mesh(curved_disk_on_block, 0.5, 0.85, h_far=2.0, refine=2.0)
    points = dof_points(mesh, 2)
    fs, fm = mesh.facets(slave), mesh.facets(master)
    c = mortar_p2.quadratic_coupling(mesh.x, mesh.cells, fs, fm, points, search_distance=0.3,
                                     cell_type=mesh.cell_type)
    sp_, mp_ = mortar_p2.segment_points(points, fs), mortar_p2.segment_points(points, fm)
    # The slave segments that reach x < 1.5 (so every segment of a slave point at x < 1 is
    # among them), the master segments that reach x < 3.
    near = points.x[sp_][:, :, 0].min(axis=1) < 1.5
    near_m = points.x[mp_][:, :, 0].min(axis=1) < 3.0
    ref = _brute_force_curved(points.x[sp_[near]], points.x[mp_[near_m]], sp_[near],
                              mp_[near_m], points.num_points)
    rows = np.isin(c.slave_nodes, sp_[near]) & (points.x[c.slave_nodes, 0] < 1.0)
    got = c.M.toarray()[rows]
    want = ref[c.slave_nodes[rows]]
    assert np.abs(got).max() > 0.01
    assert np.abs(got - want).max() < 2e-3 * np.abs(want).max()


def test_curved_path_on_straight_segments_equals_the_straight_one():
    from dolfinx_feti.constraints import mortar_p2_curved
    mesh = occ_mesh(stacked_blocks, 2, 0.1, 0.17, gap=0.01)
    points = dof_points(mesh, 2)
    from dolfinx_feti.constraints.mortar import candidate_pairs
    from dolfinx_feti.mesh.topology import facet_normals
    fs, fm = mesh.facets("upper_bottom"), mesh.facets("lower_top")
    ns, _ = facet_normals(mesh.x, mesh.cells, fs, mesh.cell_type)
    nm, _ = facet_normals(mesh.x, mesh.cells, fm, mesh.cell_type)
    i, j = candidate_pairs(mesh.x, fs, ns, fm, nm, 0.3)
    sp_, mp_ = mortar_p2.segment_points(points, fs), mortar_p2.segment_points(points, fm)
    r, c, v, _ = mortar_p2._pair_integrals(mesh.x, fs, fm, sp_, mp_, i, j)
    straight = sp.csr_matrix((v, (r, c)), shape=(points.num_points,) * 2).toarray()
    A, _ = mortar_p2_curved.dual_coefficients(points.x[sp_])
    vals, ok = mortar_p2_curved.pair_integrals(points.x[sp_[i]], points.x[mp_[j]], A[i])
    r2 = np.repeat(sp_[i[ok]], 3, axis=1).ravel()
    c2 = np.tile(mp_[j[ok]], (1, 3)).ravel()
    curved = sp.csr_matrix((vals[ok].ravel(), (r2, c2)), shape=(points.num_points,) * 2)
    assert np.abs(curved.toarray() - straight).max() < 1e-12 * np.abs(straight).max()
