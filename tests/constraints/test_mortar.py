"""Mortar contact and ties between independently meshed bodies (issue 11).

Independent checks: exact linear solutions (contact and tie patch tests), node-to-node rows on
matching meshes, a brute-force integration of the mortar matrices, a monolithic active-set
solve with the same rows (tests/support/reference.py), and Hertz's solutions in 2D and 3D.
"""

from __future__ import annotations

import gmsh
import hertz_cases
import numpy as np
import pytest
import reference as ref
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401 - sp.linalg.norm

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar import mortar_coupling
from dolfinx_feti.constraints.mortar_rows import mortar_contact_rows
from dolfinx_feti.io.meshes_occ import disk_on_block, sphere_on_block, stacked_blocks


def occ_mesh(model, *args, subdivide: int = 0, quads: bool = False, **kwargs) -> df.MeshData:
    """A model meshed by gmsh; ``quads``: recombined 2D, ``subdivide=2``: all hexahedra."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        if quads:
            gmsh.option.setNumber("Mesh.RecombineAll", 1)
            gmsh.option.setNumber("Mesh.Algorithm", 8)  # frontal-Delaunay for quadrilaterals
        if subdivide:
            gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", subdivide)
        model(*args, **kwargs)
        return df.read_gmsh(None)
    finally:
        gmsh.finalize()


# -- the mortar matrices, on hand-made surfaces (no DOLFINx) ------------------------------------

def flat_pair(n_s: int, n_m: int, offset: float = 0.0, seed: int = 0):
    """Two unit squares facing each other (slave at z = 0, master at z = offset), triangulated
    independently (jittered grids), each closed by one tetrahedron per facet so that the
    facets have an outward side."""
    from scipy.spatial import Delaunay

    def square(n):  # the same seed for both: equal n gives the same triangulation
        rng = np.random.default_rng(seed)
        g = np.linspace(0.0, 1.0, n + 1)
        p = np.array([(a, b) for a in g for b in g])
        inner = (p > 0).all(axis=1) & (p < 1).all(axis=1)
        p[inner] += rng.uniform(-0.25, 0.25, (inner.sum(), 2)) / n
        return p, Delaunay(p).simplices

    ps, ts = square(n_s)
    pm, tm = square(n_m)
    xs = np.c_[ps, np.zeros(len(ps))]
    xm = np.c_[pm, np.full(len(pm), offset)]
    apex_s = np.c_[xs[ts].mean(axis=1)[:, :2], np.full(len(ts), -0.1)]
    apex_m = np.c_[xm[tm].mean(axis=1)[:, :2], np.full(len(tm), offset + 0.1)]
    x = np.vstack([xs, xm, apex_s, apex_m])
    ns, nm = len(xs), len(xm)
    slave = ts
    master = tm + ns
    cells = np.vstack([np.c_[slave, ns + nm + np.arange(len(ts))],
                       np.c_[master, ns + nm + len(ts) + np.arange(len(tm))]])
    return x, cells, slave, master


def test_matching_surfaces_give_diagonal_mortar_matrix():
    x, cells, slave, master = flat_pair(6, 6)
    assert np.array_equal(x[:49], x[49:98]) and np.array_equal(slave + 49, master)
    c = mortar_coupling(x, cells, slave, master)
    M = c.M[:, 49:98].toarray()
    partner = np.arange(49)
    assert np.allclose(M, np.diag(c.D)[:, partner], atol=1e-13 * c.D.max())
    assert np.allclose(c.coverage, 1.0, atol=1e-12)


@pytest.mark.parametrize("offset", [0.0, 0.03])
def test_constants_areas_and_gaps_non_matching(offset):
    x, cells, slave, master = flat_pair(7, 12, offset)
    c = mortar_coupling(x, cells, slave, master)
    assert c.D.sum() == pytest.approx(1.0, rel=1e-12)  # the rows of D integrate the area
    assert np.allclose(np.asarray(c.M.sum(axis=1)).ravel(), c.D, rtol=1e-11)  # constants
    assert c.M.sum() == pytest.approx(1.0, rel=1e-12)
    # The weighted gap is the distance between the planes (0 for coincident ones).
    assert np.allclose(c.weighted_gap(x), offset, atol=1e-13)


def brute_force_M(x, slave, master, n=24):
    """M_jk by midpoint sampling of each slave triangle (n² sub-triangles), master shape
    functions by locating each point in the master triangulation (coincident planes)."""
    from matplotlib.tri import Triangulation
    tri = Triangulation(x[:, 0], x[:, 1], master)
    finder = tri.get_trifinder()
    rows, cols, vals = [], [], []
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    keep = i + j < n
    lo = np.stack([i[keep], j[keep]], axis=1)
    up = np.stack([i, j], axis=-1)[(i + j) < n - 1]
    cen = np.vstack([(lo + 1.0 / 3.0) / n, (up + 2.0 / 3.0) / n])  # barycentres (l1, l2)
    w = np.full(cen.shape[0], 1.0 / n**2)
    for f in slave:
        a, b, cc = x[f]
        area = 0.5 * np.linalg.norm(np.cross(b - a, cc - a))
        lam = np.c_[1 - cen.sum(axis=1), cen]
        p = lam @ x[f]
        psi = 4.0 * lam - 1.0
        t = finder(p[:, 0], p[:, 1])
        assert np.all(t >= 0)
        for q in range(p.shape[0]):
            mv = master[t[q]]
            T = x[mv][:, :2]
            A = np.c_[T[1] - T[0], T[2] - T[0]]
            l12 = np.linalg.solve(A, p[q, :2] - T[0])
            Nm = np.r_[1 - l12.sum(), l12]
            for s_ in range(3):
                rows += [f[s_]] * 3
                cols += mv.tolist()
                vals += (area * w[q] * psi[q, s_] * Nm).tolist()
    return sp.csr_matrix((vals, (rows, cols)), shape=(x.shape[0], x.shape[0]))


def test_mortar_matrix_against_brute_force_integration():
    x, cells, slave, master = flat_pair(3, 5, seed=3)
    c = mortar_coupling(x, cells, slave, master)
    M = c.M.toarray()
    # Midpoint sampling converges to M: exact where the integrand is smooth, not on the
    # sub-triangles cut by master edges.
    err = []
    for n in (24, 48):
        ref_M = brute_force_M(x, slave, master, n)[c.slave_nodes].toarray()
        err.append(np.abs(M - ref_M).max() / np.abs(ref_M).max())
    assert err[1] < 0.5 * err[0] and err[1] < 5e-4, err


# -- patch tests (exact linear solutions) --------------------------------------------------------

def uniaxial(mesh, dim, p, E_of_body, nu, lower_height=1.0):
    """Exact displacement of two stacked blocks under pressure p on top: σ_zz = −p."""
    x = mesh.x
    u = np.zeros((mesh.num_nodes, dim))
    for b, name in enumerate(mesh.body_names):
        E = E_of_body[name]
        ex, ez = ((1 + nu) * nu * p / E, -(1 - nu**2) * p / E) if dim == 2 else \
            (nu * p / E, -p / E)
        nodes = np.unique(mesh.cells[mesh.cell_body == b])
        u[nodes, :dim - 1] = ex * x[nodes, :dim - 1]
        if name == "lower":
            u[nodes, -1] = ez * x[nodes, -1]
        else:
            E1 = E_of_body["lower"]
            ez1 = -(1 - nu**2) * p / E1 if dim == 2 else -p / E1
            u[nodes, -1] = ez1 * lower_height + ez * (x[nodes, -1] - lower_height)
    return u


def patch_problem(mesh, dim, E, nu, p, contact=(), ties=()):
    t = [0.0] * (dim - 1) + [-p]
    bcs = [df.Dirichlet("bottom", components=[dim - 1]), df.Dirichlet("sym0", components=[0])]
    if dim == 3:
        bcs.append(df.Dirichlet("sym1", components=[1]))
    return df.ContactProblem(mesh, df.Elasticity(E, nu, tractions={"top": tuple(t)}),
                             dirichlet=bcs, contact=list(contact), ties=list(ties),
                             decomposition=df.Parts(3))


SIZES = {2: (0.1, 0.17), 3: (0.25, 0.42)}  # element sizes 1 : 1.7


@pytest.fixture(scope="module", params=[2, 3])
def blocks(request):
    dim = request.param
    return dim, occ_mesh(stacked_blocks, dim, *SIZES[dim])


def check_contact_patch(dim, mesh, pressure_rtol):
    """Stacked blocks in mortar contact under uniform pressure: the exact uniaxial state."""
    E, nu, p = {"lower": 100.0, "upper": 300.0}, 0.3, 1.0
    sol = df.solve(patch_problem(mesh, dim, E, nu, p,
                                 contact=[df.Mortar("upper_bottom", "lower_top")]), rtol=1e-12)
    assert sol.report.converged
    exact = uniaxial(mesh, dim, p, E, nu)
    assert np.abs(sol.nodal_values() - exact).max() < 1e-8 * np.abs(exact).max()
    assert np.allclose(sol.contact.pressure, p, rtol=pressure_rtol)  # uniform contact pressure
    info = sol.report.extra["mortar"][0]
    assert info["uncoupled_slave_nodes"] == 0 and info["rim_rows"] == 0
    assert not sol.report.warnings


def check_tie_patch(dim, mesh):
    """Stacked blocks tied by mortar rows under uniform pressure: the exact uniaxial state."""
    E, nu, p = {"lower": 100.0, "upper": 100.0}, 0.3, 1.0
    sol = df.solve(patch_problem(mesh, dim, E, nu, p,
                                 ties=[df.Tie("upper_bottom", "lower_top")]), rtol=1e-12)
    assert sol.report.converged and sol.report.solver == "cg"
    exact = uniaxial(mesh, dim, p, E, nu)
    assert np.abs(sol.nodal_values() - exact).max() < 1e-8 * np.abs(exact).max()


def test_contact_patch_test(blocks):
    check_contact_patch(*blocks, pressure_rtol=1e-8)


def test_tie_patch_test(blocks):
    check_tie_patch(*blocks)


def test_tie_cantilever_against_conforming_mesh():
    """A cantilever from two non-matching parts against one conforming mesh of the same size."""
    nonconf = occ_mesh(stacked_blocks, 2, 0.1, 0.17, width=0.5, height=2.0)

    def conforming():
        gmsh.model.add("conforming")
        occ = gmsh.model.occ
        a = occ.addRectangle(0.0, 0.0, 0.0, 0.5, 2.0)
        b = occ.addRectangle(0.0, 2.0, 0.0, 0.5, 2.0)
        occ.fragment([(2, a)], [(2, b)])
        occ.synchronize()
        gmsh.model.mesh.setSize(gmsh.model.getEntities(0), 0.13)
        gmsh.model.addPhysicalGroup(2, [a, b], 1)
        gmsh.model.setPhysicalName(2, 1, "beam")
        ents = gmsh.model.getEntitiesInBoundingBox(-1e-7, -1e-7, -1, 0.5 + 1e-7, 1e-7, 1, 1)
        gmsh.model.addPhysicalGroup(1, [t for _, t in ents], 11)
        gmsh.model.setPhysicalName(1, 11, "bottom")
        ents = gmsh.model.getEntitiesInBoundingBox(-1e-7, 4 - 1e-7, -1, 0.5 + 1e-7, 4 + 1e-7, 1, 1)
        gmsh.model.addPhysicalGroup(1, [t for _, t in ents], 14)
        gmsh.model.setPhysicalName(1, 14, "top")
        gmsh.model.mesh.generate(2)

    conf = occ_mesh(conforming)
    load = {"top": (0.05, 0.0)}  # a shear load on the free end: bending
    a = df.solve(df.ContactProblem(nonconf, df.Elasticity(100.0, 0.3, tractions=load),
                                   dirichlet=[df.Dirichlet("bottom")],
                                   ties=[df.Tie("upper_bottom", "lower_top")]), rtol=1e-10)
    b = df.solve(df.ContactProblem(conf, df.Elasticity(100.0, 0.3, tractions=load),
                                   dirichlet=[df.Dirichlet("bottom")]), rtol=1e-10)
    tip_a = a.nodal_values()[np.isclose(nonconf.x[:, 1], 4.0), 0].mean()
    tip_b = b.nodal_values()[np.isclose(conf.x[:, 1], 4.0), 0].mean()
    # Euler–Bernoulli for reference: q·w·L³/(3 E' I), E' = E/(1 − ν²) (plane strain).
    eb = 0.05 * 0.5 * 4.0**3 / (3 * 100.0 / (1 - 0.09) * 0.5**3 / 12)
    assert abs(tip_a - tip_b) < 0.02 * abs(tip_b), (tip_a, tip_b)
    assert abs(tip_b - eb) < 0.1 * eb  # both are P1 discretizations of the same beam


# -- matching meshes: mortar rows are node-to-node rows -----------------------------------------

def test_mortar_equals_node_to_node_on_matching_meshes_2d():
    mesh = occ_mesh(stacked_blocks, 2, 0.1, 0.1)
    E, nu = {"lower": 100.0, "upper": 300.0}, 0.3
    load = {"top": (0.2, -1.0)}

    def problem(contact):
        return df.ContactProblem(mesh, df.Elasticity(E, nu, tractions=load),
                                 dirichlet=[df.Dirichlet("bottom"),
                                            df.Dirichlet("sym0", components=[0])],
                                 contact=[contact], decomposition=df.Parts(2))

    for fr in (None, df.Tresca(0.5)):
        a = df.solve(problem(df.Mortar("upper_bottom", "lower_top", friction=fr)), rtol=1e-12)
        b = df.solve(problem(df.NodeToNode("upper_bottom", "lower_top", friction=fr)),
                     rtol=1e-12)
        ua, ub = a.nodal_values(), b.nodal_values()
        assert np.abs(ua - ub).max() < 1e-8 * np.abs(ub).max()
        fa, fb = ref.forces_by_node(a.contact), ref.forces_by_node(b.contact)
        assert np.array_equal(fa[0], fb[0])
        assert np.allclose(fa[1], fb[1], rtol=1e-8, atol=1e-10 * np.abs(fb[1]).max())


def test_mortar_equals_node_to_node_on_matching_meshes_3d(root):
    mesh = df.read_gmsh(root / "meshes/blocks3d.msh")

    def problem(contact):
        return df.ContactProblem(
            mesh, df.Elasticity(E={"lower": 1000.0, "upper": 500.0}, nu=0.3,
                                tractions={"top": (0.0, 0.0, -1.0)}),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sides_upper", components=[0, 1])],
            contact=[contact], decomposition=df.Parts(4))

    a = df.solve(problem(df.Mortar("contact_upper", "contact_lower")), rtol=1e-12)
    b = df.solve(problem(df.NodeToNode("contact_upper", "contact_lower")), rtol=1e-12)
    ub = b.nodal_values()
    assert np.abs(a.nodal_values() - ub).max() < 1e-8 * np.abs(ub).max()


# -- Hertz 2D: a monolithic reference with the same rows, and convergence -----------------------

R, P, E_H, NU_H = 8.0, 10.0, 200.0, 0.3
E_STAR = E_H / (2.0 * (1.0 - NU_H**2))
A_HERTZ = 2.0 * np.sqrt(R * P / (np.pi * E_STAR))
P0_HERTZ = np.sqrt(P * E_STAR / (np.pi * R))


def hertz_problem(mesh, slave="disk_contact", decomposition=None):
    return hertz_cases.disk_problem(mesh, slave, decomposition)


@pytest.fixture(scope="module")
def hertz_meshes():
    return {h: occ_mesh(disk_on_block, h, 1.7 * h) for h in (0.2, 0.1, 0.05)}


def test_monolithic_reference_with_the_same_rows(hertz_meshes):
    mesh = hertz_meshes[0.2]
    problem = hertz_problem(mesh)
    sol = df.solve(problem, rtol=1e-10)
    # The same mortar rows on an undecomposed mesh: every node in "subdomain" 0.
    n = mesh.num_nodes
    rows, _ = mortar_contact_rows(mesh, problem.contact[0], 0, np.arange(n + 1),
                                  np.zeros(n, dtype=np.int32), 2)
    B = sp.csr_matrix((rows.e_coef / rows.scale[rows.e_row],
                       (rows.e_row, 2 * rows.e_node + rows.e_comp)), shape=(rows.size, 2 * n))
    pairs = ref.Pairs(slave=rows.node, master=rows.node, normal=None, B=B,
                      g=rows.rhs / rows.scale)
    mono = ref.MonolithicProblem(mesh, 2, ref.elasticity_forms(E_H, NU_H),
                                 tractions={"load": (0.0, -P / 2 / R)},
                                 dirichlet=[("bottom", None), ("symmetry", [0])], contact=pairs)
    r = mono.solve()
    u = sol.nodal_values()
    assert np.abs(u - r.u).max() < 1e-6 * np.abs(r.u).max()
    nodes, forces = ref.forces_by_node(sol.contact)
    lam = mono.multipliers_from(nodes, forces)
    assert np.abs(lam - r.lam).max() < 1e-6 * np.abs(r.lam).max()
    cert = mono.check(u, nodes, forces)
    assert max(cert.values()) < 1e-6, cert


def test_hertz2d_converges_to_hertz(hertz_meshes):
    errors = []
    for _h, mesh in sorted(hertz_meshes.items(), reverse=True):
        sol = df.solve(hertz_problem(mesh), rtol=1e-8)
        c = sol.contact
        p0 = c.pressure.max()
        errors.append(abs(p0 / P0_HERTZ - 1.0))
        active = c.x[c.pressure > 1e-6 * p0, 0]
        half_width = active.max()
        # The vertical contact force balances the (discrete) load on the half model.
        load = P / 2 / R * np.linalg.norm(np.diff(mesh.x[mesh.facets("load")], axis=1),
                                          axis=2).sum()
        assert sol.total_contact_force[1] == pytest.approx(load, rel=1e-6)
        assert not sol.report.warnings, sol.report.warnings
        info = sol.report.extra["mortar"][0]
        assert info["uncoupled_slave_nodes"] > 0  # the whole arc is the candidate surface
    assert errors[0] > errors[1] > errors[2], errors  # the error falls with h
    assert errors[2] < 0.03, errors
    assert abs(half_width - A_HERTZ) < 0.05 * 1.7  # within one (block) element


def test_narrow_candidate_surface_is_warned_about(hertz_meshes):
    """The contact zone is wider than the declared slave surface: the report must say so."""
    mesh = hertz_meshes[0.1]
    f = mesh.facets("disk_contact")
    narrow = f[(mesh.x[f][:, :, 0] <= 0.45).all(axis=1)]
    groups = dict(mesh.facet_groups, narrow=narrow)
    mesh_n = df.MeshData(mesh.x, mesh.cells, mesh.cell_type, mesh.cell_body, mesh.body_names,
                         groups, mesh.node_tags, mesh.group_tags)
    sol = df.solve(hertz_problem(mesh_n, slave="narrow"), rtol=1e-8)
    assert any("'narrow'" in w and "rim" in w for w in sol.report.warnings), sol.report.warnings
    assert sol.report.extra["mortar"][0]["rim_rows"] > 0
    full = df.solve(hertz_problem(mesh), rtol=1e-8)
    assert not full.report.warnings


# -- 3D Hertz -----------------------------------------------------------------------------------

SPHERE_F, SPHERE_R = 20.0, 8.0


def sphere_problem(mesh) -> tuple[df.ContactProblem, float]:
    """The quarter model of a sphere on a block under the force SPHERE_F, and its traction."""
    return hertz_cases.sphere_problem(mesh)


def test_sphere_on_block_3d():
    mesh = occ_mesh(sphere_on_block, 0.15, 0.25)
    F, R3 = SPHERE_F, SPHERE_R
    problem, t = sphere_problem(mesh)
    sol = df.solve(problem, rtol=1e-9)
    assert sol.report.converged
    p = mesh.x[mesh.facets("load")]
    load = t * 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    assert sol.total_contact_force[2] == pytest.approx(load, rel=1e-8)
    a_hertz = (3 * F * R3 / (4 * E_STAR)) ** (1 / 3)
    c = sol.contact
    r = np.linalg.norm(c.x[:, :2], axis=1)
    radius = r[c.pressure > 1e-6 * c.pressure.max()].max()
    assert abs(radius - a_hertz) < 0.25, (radius, a_hertz)  # within one element
    assert not sol.report.warnings, sol.report.warnings


def test_tie_rows_are_nearly_orthonormal(blocks):
    """Unit-norm tie rows: B Bᵀ stays well conditioned (docs/theory.md: why they are not
    orthonormalized); worst with the finer side as slave."""
    from dolfinx_feti.constraints.mortar_rows import tie_rows
    dim, mesh = blocks
    n = mesh.num_nodes
    for slave, master in (("upper_bottom", "lower_top"), ("lower_top", "upper_bottom")):
        rows, _ = tie_rows(mesh, df.Tie(slave, master), 0, np.arange(n + 1),
                           np.zeros(n, dtype=np.int32), np.zeros((n, dim), dtype=bool), dim)
        B = sp.csr_matrix((rows.e_coef, (rows.e_row, dim * rows.e_node + rows.e_comp)),
                          shape=(rows.size, dim * n))
        assert np.allclose(sp.linalg.norm(B, axis=1), 1.0)
        ev = np.linalg.eigvalsh((B @ B.T).toarray())
        assert ev.max() / ev.min() < (2.0 if slave == "upper_bottom" else 5.0)
