"""Self-contact (issue 25): one boundary group as slave and master of a Mortar condition.

A C-shaped strip (tests/c_strip.py: a split ring, its whole boundary as the one candidate
group) is closed by a load on each arm until its ends touch. Independent checks: the same mesh
with the strip's halves as two bodies in ordinary two-surface mortar contact between the two
ends (the same rows when the same end is the slave, the discretization's difference when the
other one is), the mirror symmetry of the solution on a mirror-symmetric mesh, and the deformed
geometry (no node of one half inside a cell of the other).
"""

from __future__ import annotations

import numpy as np
import pytest
from c_strip import c_strip
from extruded import extrude

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar import candidate_pairs, mortar_coupling
from dolfinx_feti.mesh.topology import facet_normals, facets_in_cell_order

E, NU, LOAD = 1000.0, 0.3, 0.1  # the load closes the slit (0.02) about 20 times over
H = 0.03


def problem(mesh: df.MeshData, contact) -> df.ContactProblem:
    load = {"load_upper": (0.0, -LOAD), "load_lower": (0.0, LOAD)}
    return df.ContactProblem(mesh, df.Elasticity(E, NU, tractions=load),
                             dirichlet=[df.Dirichlet("back")], contact=[contact],
                             decomposition=df.Parts(4))


@pytest.fixture(scope="module", params=["mirrored", "non-matching"])
def strip(request):
    """The strip as one body and as two, self-contact and both two-body orientations solved."""
    h_lower = None if request.param == "mirrored" else 0.021
    one = c_strip(h=H, h_lower=h_lower)
    two = c_strip(h=H, h_lower=h_lower, two_bodies=True)
    out = {"kind": request.param, "mesh": one,
           "self": df.solve(problem(one, df.Mortar("skin", "skin")), rtol=1e-10)}
    for slave, master in (("end_upper", "end_lower"), ("end_lower", "end_upper")):
        out[slave] = df.solve(problem(two, df.Mortar(slave, master)), rtol=1e-10)
    return out


def _slave_end(sol) -> str:
    y = sol.contact.x[:, 1]
    assert np.all(y > 0) or np.all(y < 0)
    return "end_upper" if y[0] > 0 else "end_lower"


def test_search_pairs_the_ends_once():
    mesh = c_strip(h=H)
    skin = facets_in_cell_order(mesh.cells, mesh.facets("skin"), mesh.cell_type)
    n, _ = facet_normals(mesh.x, mesh.cells, skin, mesh.cell_type)
    d = 0.5  # more than the wall's thickness (0.2): its two sides are candidates
    i, j = candidate_pairs(mesh.x, skin, n, skin, n, d)
    ends = np.flatnonzero(np.isin(skin, mesh.facets("end_upper")).all(axis=1)
                          | np.isin(skin, mesh.facets("end_lower")).all(axis=1))
    assert np.any(~np.isin(i, ends)), "the unfiltered search must see pairs across the wall"
    c = mortar_coupling(mesh.x, mesh.cells, mesh.facets("skin"), mesh.facets("skin"), d,
                        mesh.cell_type, self_contact=True)
    slave, master = c.zones
    ends = {g: np.sort(mesh.facets(g), axis=1) for g in ("end_upper", "end_lower")}
    a, b = ("end_upper", "end_lower") if np.isin(slave, ends["end_upper"]).all() else \
        ("end_lower", "end_upper")
    assert np.array_equal(np.unique(np.sort(slave, axis=1), axis=0), ends[a])
    m = np.unique(np.sort(master, axis=1), axis=0)
    assert np.isin(ends[b].view([("", ends[b].dtype)] * 2), m.view([("", m.dtype)] * 2)).all()
    # Besides the other end, only facets round its inner corner (which the slave end faces).
    xm = mesh.x[m].mean(axis=1)
    assert np.all(np.sign(xm[:, 1]) == np.sign(mesh.x[ends[b]].mean(axis=(0, 1))[1]))
    assert np.all(np.linalg.norm(xm - mesh.x[ends[b]].mean(axis=(0, 1)), axis=1) < 0.25)
    assert not np.intersect1d(slave, master).size  # one orientation; no shared vertex
    assert c.coupled.sum() == np.unique(ends[a]).size  # every slave node of the end: a row


def test_self_contact_equals_two_bodies(strip):
    s = strip["self"]
    assert s.report.converged and not s.report.warnings, s.report.warnings
    slave = _slave_end(s)
    other = "end_lower" if slave == "end_upper" else "end_upper"
    same, flipped = strip[slave], strip[other]
    assert same.report.converged and not same.report.warnings
    u, scale = s.nodal_values(), np.abs(s.nodal_values()).max()
    assert np.abs(u - same.nodal_values()).max() < 1e-7 * scale
    assert np.allclose(s.contact.force, same.contact.force, rtol=1e-6, atol=1e-9 * LOAD)
    assert np.allclose(s.contact.pressure, same.contact.pressure, rtol=1e-6, atol=1e-8)
    f_self, f_flip = s.total_contact_force, flipped.total_contact_force
    assert f_self[1] > 0.1 * LOAD * 0.1  # the ends are pressed together
    if strip["kind"] == "mirrored":  # the other end as slave: the mirror image
        assert np.allclose(f_self * [1, -1], f_flip, rtol=1e-7, atol=1e-9)
    else:  # the other discretization of the same interface
        assert abs(f_self[1] + f_flip[1]) < 1e-2 * abs(f_self[1])


def test_symmetric_configuration_symmetric_solution(strip):
    if strip["kind"] != "mirrored":
        pytest.skip("the mirror image needs the mirrored mesh")
    s, mesh = strip["self"], strip["mesh"]
    x = mesh.x
    key = {tuple(p): k for k, p in enumerate(np.round(x, 9))}
    mirror = np.array([key[(p[0], -p[1] + 0.0)] for p in np.round(x, 9)])
    u = s.nodal_values()
    assert np.abs(u[mirror] * [1, -1] - u).max() < 1e-7 * np.abs(u).max()
    # The pressure on the slave end equals the pressure on the other end with it as slave.
    other = strip["end_lower" if _slave_end(s) == "end_upper" else "end_upper"].contact
    a = np.argsort(s.contact.x[:, 0])
    b = np.argsort(other.x[:, 0])
    assert np.allclose(s.contact.x[a, 0], other.x[b, 0])
    assert np.allclose(s.contact.pressure[a], other.pressure[b], rtol=1e-6, atol=1e-8)
    assert (s.contact.force > 1e-6 * s.contact.force.max()).sum() >= 3  # a patch, not a point


def _inside(p: np.ndarray, tri: np.ndarray, tol: float) -> np.ndarray:
    """Whether each point lies inside one of the triangles (n, 3, 2) by more than tol (bary)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    d = p[:, None, :] - a[None]
    l1 = (d[..., 0] * (c[:, 1] - a[:, 1]) - d[..., 1] * (c[:, 0] - a[:, 0])) / det
    l2 = ((b[:, 0] - a[:, 0]) * d[..., 1] - (b[:, 1] - a[:, 1]) * d[..., 0]) / det
    return (np.minimum(np.minimum(l1, l2), 1.0 - l1 - l2) > tol).any(axis=1)


def test_no_penetration_anywhere(strip):
    s, mesh = strip["self"], strip["mesh"]
    xd = mesh.x + s.nodal_values()
    upper = mesh.x[mesh.cells].mean(axis=1)[:, 1] > 0
    skin = np.unique(mesh.facets("skin"))
    for half in (upper, ~upper):
        own = np.unique(mesh.cells[half])
        others = np.setdiff1d(skin, own)  # the other half's surface (the back's nodes are shared)
        tol = 1e-6 if strip["kind"] == "mirrored" else 1e-2  # mortar holds the gap weakly
        assert not _inside(xd[others], xd[mesh.cells[half]], tol).any()
    assert s.report.extra["mortar"][0]["max_penetration"] < 1e-2 * H


def test_tie_with_itself_is_refused():
    mesh = c_strip(h=0.05)
    with pytest.raises(df.InputError, match="with itself"):
        df.ContactProblem(mesh, df.Elasticity(E, NU), dirichlet=[df.Dirichlet("back")],
                          ties=[df.Tie("skin", "skin")])


def test_self_contact_p2_equals_two_bodies():
    """Degree 2 (rows at vertices and edge points), non-matching ends."""
    load = {"load_upper": (0.0, -LOAD), "load_lower": (0.0, LOAD)}

    def p2(mesh, contact):
        return df.ContactProblem(mesh, df.Elasticity(E, NU, tractions=load, degree=2),
                                 dirichlet=[df.Dirichlet("back")], contact=[contact],
                                 decomposition=df.Parts(4))

    one, two = c_strip(h=0.06, h_lower=0.045), c_strip(h=0.06, h_lower=0.045, two_bodies=True)
    s = df.solve(p2(one, df.Mortar("skin", "skin")), rtol=1e-10)
    slave = _slave_end(s)
    other = "end_lower" if slave == "end_upper" else "end_upper"
    t = df.solve(p2(two, df.Mortar(slave, other)), rtol=1e-10)
    assert s.report.converged and not s.report.warnings, s.report.warnings
    u = t.nodal_values()
    assert np.abs(s.nodal_values() - u).max() < 1e-7 * np.abs(u).max()
    assert np.allclose(s.contact.pressure, t.contact.pressure, rtol=1e-6, atol=1e-8)
    assert (s.contact.force > 0).sum() >= 3


def test_self_contact_p2_tetrahedra_equals_two_bodies():
    """3D, degree 2: the strip extruded into tetrahedra (6-node triangles: the transformed
    dual basis, the slave's own entries in ũ only — the master entries of one surface with
    itself are not transformed), non-matching ends; the caps held in z."""
    load = {"load_upper": (0.0, -LOAD, 0.0), "load_lower": (0.0, LOAD, 0.0)}

    def p2(mesh, contact):
        return df.ContactProblem(mesh, df.Elasticity(E, NU, tractions=load, degree=2),
                                 dirichlet=[df.Dirichlet("back"),
                                            df.Dirichlet("caps", components=[2])],
                                 contact=[contact], decomposition=df.Parts(4))

    one = extrude(c_strip(h=0.06, h_lower=0.045), 0.1, 2, with_caps=("skin",))
    two = extrude(c_strip(h=0.06, h_lower=0.045, two_bodies=True), 0.1, 2, with_caps=("skin",))
    s = df.solve(p2(one, df.Mortar("skin", "skin")), rtol=1e-10)
    assert s.report.converged and not s.report.warnings, s.report.warnings
    slave = _slave_end(s)
    other = "end_lower" if slave == "end_upper" else "end_upper"
    t = df.solve(p2(two, df.Mortar(slave, other)), rtol=1e-10)
    u = t.nodal_values()
    assert np.abs(s.nodal_values() - u).max() < 1e-7 * np.abs(u).max()
    assert np.allclose(s.contact.pressure, t.contact.pressure, rtol=1e-6, atol=1e-8)
    assert (s.contact.force > 0).sum() >= 3 and np.any(s.contact.node >= one.num_nodes)


def test_report_warns_when_the_search_misses_the_contact():
    """A search distance below the slit: no rows; the load closes the slit by 0.025 > 0.02."""
    mesh = c_strip(h=H)
    load = {"load_upper": (0.0, -0.0067), "load_lower": (0.0, 0.0067)}
    problem = df.ContactProblem(mesh, df.Elasticity(E, NU, tractions=load),
                                dirichlet=[df.Dirichlet("back")],
                                contact=[df.Mortar("skin", "skin", search_distance=0.01)],
                                decomposition=df.Parts(4))
    sol = df.solve(problem, rtol=1e-10)
    assert sol.report.extra["mortar"][0]["rows"] == 0
    assert any("'skin'" in w and "penetrate" in w for w in sol.report.warnings), \
        sol.report.warnings


def test_force_balance_with_the_back_clamped():
    """The strip cut through its back and clamped on both faces of the cut, the load on the
    upper arm only: the lower half is loaded by the contact alone, so the reaction of its
    clamp (the Dirichlet multipliers) equals the contact force, and the two clamps carry the
    load."""
    from dolfinx_feti.constraints.rows import Kind

    mesh = c_strip(h=H, cut=True)
    P = 0.02
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"load_upper": (0.0, -P)}),
        dirichlet=[df.Dirichlet("cut_upper"), df.Dirichlet("cut_lower")],
        contact=[df.Mortar("skin", "skin")], decomposition=df.Parts(4))
    sol = df.solve(problem, rtol=1e-12)
    assert sol.report.converged and not sol.report.warnings, sol.report.warnings
    own = sol.rows.own
    comp = np.zeros(own.size, dtype=np.int64)
    comp[own.e_row] = own.e_comp
    mine = own.kind == Kind.DIRICHLET
    node, comp, force = (np.concatenate(sol.comm.allgather(a[mine])) for a in
                         (own.node, comp, sol.lam.array_r * own.scale))
    reaction = {g: force[np.isin(node, np.unique(mesh.facets(g))) & (comp == 1)].sum()
                for g in ("cut_upper", "cut_lower")}
    f = mesh.facets("load_upper")
    load = P * np.linalg.norm(mesh.x[f[:, 0]] - mesh.x[f[:, 1]], axis=1).sum()
    R = sol.total_contact_force
    assert R[1] > 0.05 * load  # the ends touch (at the outer corner: the upper end rotates)
    assert abs(R[1] + reaction["cut_lower"]) < 1e-8 * load
    assert abs(reaction["cut_upper"] + reaction["cut_lower"] + load) < 1e-8 * load


def test_self_contact_with_coulomb_friction_equals_two_bodies():
    """Unequal loads on the arms make the ends slide against each other: Coulomb friction on
    the self-contact rows, against the same on the two-body rows (non-matching ends)."""
    load = {"load_upper": (0.0, -LOAD), "load_lower": (0.0, 0.5 * LOAD)}

    def problem_with(mesh, contact):
        return df.ContactProblem(mesh, df.Elasticity(E, NU, tractions=load),
                                 dirichlet=[df.Dirichlet("back")], contact=[contact],
                                 decomposition=df.Parts(4))

    one, two = c_strip(h=H, h_lower=0.021), c_strip(h=H, h_lower=0.021, two_bodies=True)
    fr = df.Coulomb(0.3)
    s = df.solve(problem_with(one, df.Mortar("skin", "skin", friction=fr)), rtol=1e-10)
    slave = _slave_end(s)
    other = "end_lower" if slave == "end_upper" else "end_upper"
    t = df.solve(problem_with(two, df.Mortar(slave, other, friction=fr)), rtol=1e-10)
    assert s.report.converged and not s.report.warnings, s.report.warnings
    u = t.nodal_values()
    assert np.abs(s.nodal_values() - u).max() < 1e-7 * np.abs(u).max()
    assert np.abs(s.contact.tangential_force).max() > 0.1 * s.contact.force.max() * 0.3
