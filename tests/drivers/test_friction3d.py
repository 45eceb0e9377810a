"""Friction in 3D: two stacked blocks, the upper one pressed and sheared; Tresca friction (a disc
per contact node, MPGP) against an independent monolithic solve, and the stick/slip conditions."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref
from friction_reference import FrictionReference

import dolfinx_feti as df
from dolfinx_feti.io import meshes

E, NU = 1.0, 0.3
SHIFT = (0.02, 0.01, -0.02)
G = 0.0075  # traction bound: part of the contact slips
RTOL = 1e-10


def blocks(mesh, friction, decomposition=None, obstacle=False):
    if obstacle:  # the lower block clamped; the upper one on the rigid plane z = 0.5
        contact = [df.RigidObstacle("contact_upper", df.Plane((0, 0, 0.5), (0, 0, 1)),
                                    friction=friction)]
        dirichlet = [df.Dirichlet("bottom"), df.Dirichlet("contact_lower"),
                     df.Dirichlet("top", value=SHIFT)]
    else:
        contact = [df.NodeToNode("contact_upper", "contact_lower", friction=friction)]
        dirichlet = [df.Dirichlet("bottom"), df.Dirichlet("top", value=SHIFT)]
    return df.ContactProblem(mesh, df.Elasticity(E, NU), dirichlet=dirichlet, contact=contact,
                             decomposition=decomposition or df.Parts(2))


@pytest.fixture(scope="module")
def mesh():
    return df.build_mesh(meshes.blocks3d, n=3)


@pytest.fixture(scope="module")
def reference(mesh):
    return FrictionReference(mesh, ref.elasticity_forms(E, NU),
                             dirichlet=[("bottom", (0, 0, 0)), ("top", SHIFT)],
                             slave="contact_upper", master="contact_lower",
                             normal=(0.0, 0.0, 1.0), match_axes=(0, 1))


@pytest.fixture(scope="module")
def tresca(mesh):
    return df.solve(blocks(mesh, df.Tresca(G)), rtol=RTOL)


def compare(sol, r, tol=1e-6):
    c = sol.contact
    assert ref.rel_max_diff(sol.nodal_values(), r.u) <= tol
    scale = r.normal_force.max()
    assert np.abs(r.by_node(c.node, c.force) - r.normal_force).max() <= tol * scale
    assert np.abs(r.by_node(c.node, c.tangential_force) - r.tangential_force).max() <= tol * scale
    assert np.abs(r.by_node(c.node, c.slip) - r.slip).max() <= tol * np.abs(r.u).max()


def test_reference_mixes_stick_and_slip(reference):
    r = reference.solve_tresca(G)
    assert r.natural_residual <= 1e-12
    stick = np.linalg.norm(r.tangential_force, axis=1) < r.bound * (1 - 1e-9)
    assert 2 <= stick.sum() <= stick.size - 2


def test_tresca3d_against_reference(tresca, reference):
    assert tresca.report.converged, tresca.report.summary()
    # the default method: FETI-1 (Parts(2): few subdomains per body); each subdomain touches a
    # held face, so no coarse space: MPGP alone (TFETI with SMALBE: tests/setup/test_methods.py)
    assert (tresca.report.method, tresca.report.solver) == ("FETI-1", "mpgp")
    assert tresca.report.extra["friction"]["disc"]
    compare(tresca, reference.solve_tresca(G))


def test_disc_bound_stick_and_slip(tresca, mesh):
    c = tresca.contact
    area = ref.traction_load(mesh, "contact_upper", [1.0])[c.node]
    assert np.allclose(c.slip_bound, G * area, rtol=1e-14, atol=0)
    ft = np.linalg.norm(c.tangential_force, axis=1)
    assert np.all(ft <= c.slip_bound * (1 + 1e-12))
    assert np.abs(c.tangential_force[:, 2]).max() <= 1e-14 * ft.max()  # in the contact plane
    stick, slip = c.state == df.ContactData.STICK, c.state == df.ContactData.SLIP
    assert np.all(stick | slip) and stick.any() and slip.any()
    u = np.abs(tresca.nodal_values()).max()
    assert np.abs(c.slip[stick]).max() <= 1e-8 * u
    s = np.linalg.norm(c.slip[slip], axis=1)
    moving = s > 1e-8 * u
    cos = np.einsum("ij,ij->i", c.slip[slip], c.tangential_force[slip]) / (s * ft[slip])
    assert np.all(cos[moving] <= -1 + 1e-9)
    for key, v in tresca.report.kkt.items():
        assert v <= 1e-8, (key, v)


def test_limits(mesh, reference):
    bonded = df.solve(blocks(mesh, df.Tresca(np.inf)), rtol=RTOL)
    compare(bonded, reference.solve_tresca(np.inf))
    assert np.all(bonded.contact.state == df.ContactData.STICK)
    zero = df.solve(blocks(mesh, df.Tresca(0.0)), rtol=RTOL)
    free = df.solve(blocks(mesh, None), rtol=RTOL)
    assert ref.rel_max_diff(zero.nodal_values(), free.nodal_values()) <= 1e-7


def test_coulomb3d(mesh, reference):
    F = 0.3
    sol = df.solve(blocks(mesh, df.Coulomb(F, rtol=1e-10)), rtol=RTOL)
    assert sol.report.converged, sol.report.summary()
    compare(sol, reference.solve_coulomb(F))
    assert sol.report.extra["friction"]["fixed_point_steps"] >= 2


def test_obstacle3d(mesh):
    sol = df.solve(blocks(mesh, df.Tresca(G), obstacle=True), rtol=RTOL)
    assert sol.report.converged
    r = FrictionReference(mesh, ref.elasticity_forms(E, NU),
                          dirichlet=[("bottom", (0, 0, 0)), ("contact_lower", (0, 0, 0)),
                                     ("top", SHIFT)],
                          slave="contact_upper", normal=(0.0, 0.0, 1.0), point=(0, 0, 0.5))
    compare(sol, r.solve_tresca(G))


def test_unused_expansion_on_discs_is_said(mesh, tresca, reference):
    """MPGP on the discs takes the fixed expansion: another one asked for is reported unused,
    and the solution is the same."""
    sol = df.solve(blocks(mesh, df.Tresca(G)), rtol=RTOL, mprgp_expansion="projcg")
    assert sol.report.converged, sol.report.summary()
    said = [w for w in sol.report.warnings if "mprgp_expansion='projcg' not used" in w]
    assert len(said) == 1, sol.report.warnings
    assert not any("not used" in w for w in tresca.report.warnings)
    compare(sol, reference.solve_tresca(G))
