"""Mortar contact and ties on first-order quadrilateral and hexahedral meshes (issues 11, 12).

Independent checks: exact linear solutions (contact and tie patch tests on non-matching
hexahedral and quadrilateral blocks), node-to-node rows on matching hexahedral meshes, the dual
basis's biorthogonality by an independent quadrature on warped facets, the mortar matrices'
row and column sums, and Hertz's solution (2D on quadrilaterals, 3D on hexahedra, beside the
tetrahedral mortar result).
"""

from __future__ import annotations

import gmsh
import hertz_cases
import numpy as np
import pytest
from test_mortar import check_contact_patch, check_tie_patch, occ_mesh, patch_problem

import dolfinx_feti as df
from dolfinx_feti.constraints import mortar_quad
from dolfinx_feti.constraints.mortar import mortar_coupling, penetration
from dolfinx_feti.errors import InputError
from dolfinx_feti.io.meshes_occ import disk_on_block, sphere_on_block, stacked_blocks
from dolfinx_feti.mesh.topology import facet_normals, nodal_normals_and_areas

# -- the dual basis and the mortar matrices on hand-made facets ---------------------------------

def warped_quads(n: int = 20, warp: float = 0.3, seed: int = 0) -> np.ndarray:
    """Random convex quadrilaterals (tensor order) with their 4th vertex lifted out of plane."""
    rng = np.random.default_rng(seed)
    base = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    P = base + rng.uniform(-0.2, 0.2, (n, 4, 3)) * np.array([1.0, 1.0, 0.0])
    P[:, 3, 2] += warp * rng.uniform(0.5, 1.0, n)
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return P @ R.T  # rotated out of the coordinate planes


def test_dual_basis_is_biorthogonal_on_warped_quads():
    P = warped_quads()
    A, D = mortar_quad.dual_basis(P)
    # Independently: 12 × 12 Gauss points on the reference square.
    g, w = np.polynomial.legendre.leggauss(12)
    g, w = 0.5 * (g + 1.0), 0.5 * w
    xi = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    W = np.outer(w, w).ravel()
    dA = W * mortar_quad.area_element(P, np.broadcast_to(xi, (P.shape[0], *xi.shape)))
    N = mortar_quad.shape(xi)
    psi = np.einsum("qi,fli->fql", N, A)
    G = np.einsum("fq,fqi,qj->fij", dA, psi, N)  # ∫ ψ_i N_j dA
    intN = np.einsum("fq,qj->fj", dA, N)
    assert np.abs(D - intN).max() < 1e-8 * intN.max()
    target = np.einsum("fj,ij->fij", intN, np.eye(4))
    assert np.abs(G - target).max() < 1e-8 * intN.max()
    # Σ_i ψ_i = 1 (so the rows of M reproduce constants).
    assert np.allclose(psi.sum(axis=2), 1.0, atol=1e-12)


def quad_pair(n_s: int, n_m: int, offset: float = 0.0, shake: float = 0.0, seed: int = 0):
    """Two unit squares facing each other (slave at z = 0, master at z = offset) in n × n
    bilinear quadrilaterals (planar, trapezoids when ``shake`` > 0), each closed by one
    hexahedron per facet so that the facets have an outward side. Equal n: the same grid."""

    def grid(n, z, dz):
        rng = np.random.default_rng(seed)
        g = np.linspace(0.0, 1.0, n + 1)
        p = np.array([(a, b) for b in g for a in g])  # x fastest
        inner = (p > 0).all(axis=1) & (p < 1).all(axis=1)
        p[inner] += rng.uniform(-shake, shake, (inner.sum(), 2)) / n
        k = np.arange(n)
        c0 = (k[None, :] + (n + 1) * k[:, None]).ravel()
        quads = np.stack([c0, c0 + 1, c0 + n + 1, c0 + n + 2], axis=1)  # tensor order
        top = np.c_[p, np.full(len(p), z)]
        bottom = np.c_[p, np.full(len(p), z + dz)]
        return np.vstack([top, bottom]), quads, len(p)

    xs, qs, ns_ = grid(n_s, 0.0, -0.1)
    xm, qm, nm_ = grid(n_m, offset, 0.1)
    x = np.vstack([xs, xm])
    hs = np.c_[qs, qs + ns_]
    hm = np.c_[qm, qm + nm_] + 2 * ns_
    return x, np.vstack([hs, hm]), qs, qm + 2 * ns_


@pytest.mark.parametrize("offset,shake", [(0.0, 0.0), (0.03, 0.0), (0.0, 0.3)])
def test_mortar_matrix_sums_on_quads(offset, shake):
    x, cells, slave, master = quad_pair(5, 8, offset, shake)
    c = mortar_coupling(x, cells, slave, master, cell_type="hexahedron")
    assert c.D.sum() == pytest.approx(1.0, rel=1e-12)  # the rows of D integrate the area
    row = np.asarray(c.M.sum(axis=1)).ravel()
    col = np.asarray(c.M.sum(axis=0)).ravel()
    _, _, Dm = nodal_normals_and_areas(x, cells, master, "hexahedron")
    nodes_m = np.unique(master)
    # Every slave facet is fully covered: Σ_k M_jk = D_j; the master nodes' hat functions are
    # integrated (exactly on rectangles; to the quadrature's error on trapezoids).
    tol = 1e-12 if shake == 0.0 else 1e-6
    assert np.abs(row - c.D).max() < tol * c.D.max()
    if shake == 0.0:
        assert np.abs(col[nodes_m] - Dm).max() < 1e-12 * Dm.max()
    assert c.M.sum() == pytest.approx(1.0, rel=1e-12 if shake == 0.0 else 1e-6)
    assert np.allclose(c.weighted_gap(x), offset, atol=1e-13)


@pytest.mark.parametrize("shake", [0.0, 0.3])
def test_matching_quads_give_diagonal_mortar_matrix(shake):
    x, cells, slave, master = quad_pair(6, 6, shake=shake)
    c = mortar_coupling(x, cells, slave, master, cell_type="hexahedron")
    assert np.array_equal(x[slave], x[master])
    # Master node = slave node + 2·49, and M = diag(D): exactly on rectangles, to the
    # quadrature's error (a rational integrand) on trapezoids.
    M = c.M[:, 98:147].toarray()
    tol = 1e-13 if shake == 0.0 else 1e-6
    assert np.abs(M - np.diag(c.D)).max() < tol * c.D.max()
    assert np.abs(c.coverage - 1.0).max() < tol


# -- patch tests (exact linear solutions) on non-matching structured blocks ---------------------

SIZES = {2: (1 / 10, 1 / 6), 3: (1 / 7, 1 / 4)}  # element sizes 1 : 1.7, 1 : 1.75


@pytest.fixture(scope="module", params=[2, 3])
def blocks(request):
    dim = request.param
    mesh = occ_mesh(stacked_blocks, dim, *SIZES[dim], recombine=True)
    assert mesh.cell_type == ("quadrilateral" if dim == 2 else "hexahedron")
    return dim, mesh


def test_contact_patch_test(blocks):
    check_contact_patch(*blocks, pressure_rtol=1e-10)


def test_tie_patch_test(blocks):
    check_tie_patch(*blocks)


def test_mortar_equals_node_to_node_on_matching_hexahedra():
    """Frictionless and with Tresca friction (whose rows use the same weights)."""
    mesh = occ_mesh(stacked_blocks, 3, 0.25, 0.25, recombine=True)
    load = {"top": (0.2, 0.1, -1.0)}

    def problem(contact):
        return df.ContactProblem(
            mesh, df.Elasticity({"lower": 100.0, "upper": 300.0}, 0.3, tractions=load),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sym0", components=[0]),
                       df.Dirichlet("sym1", components=[1])],
            contact=[contact], decomposition=df.Parts(2))

    for fr in (None, df.Tresca(0.3)):
        a = df.solve(problem(df.Mortar("upper_bottom", "lower_top", friction=fr)), rtol=1e-12)
        b = df.solve(problem(df.NodeToNode("upper_bottom", "lower_top", friction=fr)),
                     rtol=1e-12)
        ub = b.nodal_values()
        assert np.abs(a.nodal_values() - ub).max() < 1e-8 * np.abs(ub).max()
        assert np.allclose(a.total_contact_force, b.total_contact_force, rtol=1e-8)


def test_mortar_on_a_curved_3d_mesh_is_refused_with_the_reason():
    # Degree 2 on first-order hexahedra and tetrahedra is built (test_mortar_p2_3d.py).
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        stacked_blocks(3, *SIZES[3])
        gmsh.model.mesh.setOrder(2)
        mesh = df.read_gmsh(None)
    finally:
        gmsh.finalize()
    assert mesh.geometry_degree == 2
    with pytest.raises(InputError, match="first-order .*curved"):
        df.ContactProblem(mesh, df.Elasticity(100.0, 0.3, degree=2),
                          dirichlet=[df.Dirichlet("bottom")],
                          contact=[df.Mortar("upper_bottom", "lower_top")])


# -- Hertz: 2D on quadrilaterals, 3D on hexahedra beside the tetrahedral mortar result ----------

R, P, E_H, NU_H = 8.0, 10.0, 200.0, 0.3
E_STAR = E_H / (2.0 * (1.0 - NU_H**2))
A_HERTZ = 2.0 * np.sqrt(R * P / (np.pi * E_STAR))
P0_HERTZ = np.sqrt(P * E_STAR / (np.pi * R))


def test_hertz2d_on_quadrilaterals_converges():
    """Disk on block, each meshed on its own in quadrilaterals (gmsh's subdivision of its
    triangles: edges of h/2 and 1.7 h/2)."""
    errors = []
    for h in (0.4, 0.2, 0.1):
        mesh = occ_mesh(disk_on_block, h, 1.7 * h, subdivide=1)
        assert mesh.cell_type == "quadrilateral"
        sol = df.solve(df.ContactProblem(
            mesh, df.Elasticity(E_H, NU_H, tractions={"load": (0.0, -P / 2 / R)}),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
            contact=[df.Mortar("disk_contact", "block_contact")], decomposition=df.Parts(4)),
            rtol=1e-8)
        c = sol.contact
        p0 = c.pressure.max()
        errors.append(abs(p0 / P0_HERTZ - 1.0))
        half_width = c.x[c.pressure > 1e-6 * p0, 0].max()
        load = P / 2 / R * np.linalg.norm(np.diff(mesh.x[mesh.facets("load")], axis=1),
                                          axis=2).sum()
        assert sol.total_contact_force[1] == pytest.approx(load, rel=1e-6)
        assert not sol.report.warnings, sol.report.warnings
    assert errors[0] > errors[1] > errors[2], errors  # the error falls with h
    assert errors[2] < 0.03, errors
    assert abs(half_width - A_HERTZ) < 1.7 * 0.1 / 2  # within one (block) element


def sphere_problem(mesh):
    problem, t = hertz_cases.sphere_problem(mesh)
    sol = df.solve(problem, rtol=1e-9)
    assert sol.report.converged and not sol.report.warnings, sol.report.warnings
    _, area = facet_normals(mesh.x, mesh.cells, mesh.facets("load"), mesh.cell_type)
    assert sol.total_contact_force[2] == pytest.approx(t * area.sum(), rel=1e-8)
    c = sol.contact
    r = np.linalg.norm(c.x[:, :2], axis=1)
    return c.pressure.max(), r[c.pressure > 1e-6 * c.pressure.max()].max()


def test_sphere_on_block_hexahedra_against_tetrahedra():
    """Hexahedra (gmsh's subdivision of tetrahedra of 0.4 / 0.6: edges about 0.2 / 0.3, the
    sphere's quadrilateral facets warped) against tetrahedra of 0.15 / 0.25."""
    a_hertz = (3 * 20.0 * R / (4 * E_STAR)) ** (1 / 3)
    hexes = occ_mesh(sphere_on_block, 0.4, 0.6, subdivide=2)
    assert hexes.cell_type == "hexahedron"
    p0_hex, radius_hex = sphere_problem(hexes)
    p0_tet, radius_tet = sphere_problem(occ_mesh(sphere_on_block, 0.15, 0.25))
    assert abs(radius_hex - a_hertz) < 0.3, (radius_hex, a_hertz)  # within one element
    assert abs(radius_hex - radius_tet) < 0.3, (radius_hex, radius_tet)
    assert abs(p0_hex / p0_tet - 1.0) < 0.03, (p0_hex, p0_tet)


def test_narrow_candidate_surface_on_hexahedra_is_warned_about(blocks):
    """Half of the slave surface named: the rows on its open rim are active (warned)."""
    dim, mesh = blocks
    if dim == 2:
        pytest.skip("the quadrilateral facets' rim and penetration checks are the 3D ones")
    f = mesh.facets("upper_bottom")
    narrow = f[(mesh.x[f][:, :, 0] <= 0.5 + 1e-9).all(axis=1)]
    groups = dict(mesh.facet_groups, narrow=narrow)
    mesh_n = df.MeshData(mesh.x, mesh.cells, mesh.cell_type, mesh.cell_body, mesh.body_names,
                         groups, mesh.node_tags, mesh.group_tags)
    E = {"lower": 100.0, "upper": 300.0}
    sol = df.solve(patch_problem(mesh_n, dim, E, 0.3, 1.0,
                                 contact=[df.Mortar("narrow", "lower_top")]), rtol=1e-10)
    w = sol.report.warnings
    assert any("'narrow'" in s and "rim" in s for s in w), w
    assert sol.report.extra["mortar"][0]["rim_rows"] > 0


def test_penetration_behind_quadrilateral_facets(blocks):
    """The post-solve check's depth on hexahedral facets (split into triangles)."""
    dim, mesh = blocks
    if dim == 2:
        pytest.skip("3D facets")
    nodes = np.unique(mesh.facets("upper_bottom"))
    p = mesh.x[nodes] - [0.0, 0.0, 0.01]
    normals = np.tile([0.0, 0.0, -1.0], (nodes.size, 1))
    depth = penetration(p, normals, mesh.x, mesh.cells, mesh.facets("lower_top"), 0.1,
                        mesh.cell_type)
    assert np.allclose(depth, 0.01, atol=1e-12)
    assert np.all(penetration(p + [0.0, 0.0, 0.02], normals, mesh.x, mesh.cells,
                              mesh.facets("lower_top"), 0.1, mesh.cell_type) == 0.0)
