"""B2, 2D Hertz contact (half model): TFETI against an independent monolithic solve and Hertz."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

import dolfinx_feti as df

RTOL = 1e-10
R, P, E, NU = 8.0, 10.0, 200.0, 0.3
E_STAR = E / (2.0 * (1.0 - NU**2))
A_HERTZ = 2.0 * np.sqrt(R * P / (np.pi * E_STAR))  # 0.96277
P0_HERTZ = np.sqrt(P * E_STAR / (np.pi * R))  # 6.6124
H_CONTACT = 0.05
TRACTION = (0.0, -P / 2 / R)  # half of P on the half model, over the flat top of length R

DECOMPOSITIONS = {"bytags": df.ByTags(), "parts3": df.Parts(3)}


def problem(mesh, decomposition) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"load": TRACTION}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.NodeToNode("disk_contact", "block_contact")],
        decomposition=decomposition)


@pytest.fixture(scope="module")
def mesh(root):
    return df.read_gmsh(root / "meshes/hertz2d.msh")


@pytest.fixture(scope="module")
def mono(mesh):
    Pm = ref.MonolithicProblem(mesh, 2, ref.elasticity_forms(E, NU), tractions={"load": TRACTION},
                               dirichlet=[("bottom", None), ("symmetry", [0])],
                               contact=("disk_contact", "block_contact"), match_axes=(0,),
                               normal=(0.0, 1.0))
    return Pm, Pm.solve()


@pytest.fixture(scope="module")
def sols(mesh):
    return {k: df.solve(problem(mesh, d), rtol=RTOL) for k, d in DECOMPOSITIONS.items()}


@pytest.fixture(scope="module", params=sorted(DECOMPOSITIONS))
def sol(request, sols):
    return sols[request.param]


def lumped_length(mesh, group: str) -> np.ndarray:
    """∫ of each node's hat function over the group (computed here), indexed by node."""
    return ref.traction_load(mesh, group, [1.0])


def test_reference_certificate(mono):
    Pm, r = mono
    assert max(r.certificate.values()) <= ref.CERT_TOL
    assert abs(r.lam.sum() - P / 2) <= 1e-12 * P / 2
    assert np.allclose(Pm.pairs.g, Pm.mesh.x[Pm.pairs.slave, 1], rtol=0, atol=1e-15)


def test_converged(sol):
    assert sol.report.converged, sol.report.summary()
    assert sol.report.gP_rel <= RTOL


def test_against_monolithic_reference(mono, sol):
    Pm, r = mono
    assert ref.rel_max_diff(sol.nodal_values(), r.u) <= 1e-6
    lam = Pm.multipliers_from(sol.contact.node, sol.contact.force)
    assert ref.rel_max_diff(lam, r.lam) <= 1e-6
    assert abs(sol.energy - r.energy) <= 1e-8 * abs(r.energy)
    assert set(Pm.pairs.slave[r.lam > 0].tolist()) == \
        set(sol.contact.node[sol.contact.force > 1e-6 * sol.contact.force.max()].tolist())


def test_total_contact_force(sol):
    """The disk floats vertically: its equilibrium fixes the total contact force at P/2."""
    F = sol.total_contact_force
    assert abs(F[1] - P / 2) <= 1e-8 * P / 2
    assert abs(F[0]) <= 1e-12 * P  # master normal (0, 1): no horizontal component
    assert np.allclose(sol.contact.normal, [0.0, 1.0], rtol=0, atol=1e-14)


def test_pressure_against_hertz(mesh, sol):
    c = sol.contact
    length = lumped_length(mesh, "disk_contact")[c.node]
    assert np.allclose(c.pressure, c.force / length, rtol=1e-12, atol=0)
    peak = c.pressure.max()
    assert abs(peak - P0_HERTZ) <= 0.05 * P0_HERTZ
    # The peak sits next to the axis (x = 0 or 0.05): node-to-node forces are lumped per node.
    assert c.x[np.argmax(c.pressure), 0] <= H_CONTACT + 1e-12
    a_h = c.x[c.force > 1e-6 * c.force.max(), 0].max()
    assert abs(a_h - A_HERTZ) <= H_CONTACT


def test_no_penetration(sol):
    umax = np.abs(sol.nodal_values()).max()
    assert sol.contact.gap.min() >= -1e-8 * umax
    assert sol.report.max_penetration <= 1e-8 * umax


def test_pairs_and_energy_independent(mono, sol):
    Pm, _ = mono
    partner = dict(zip(Pm.pairs.slave.tolist(), Pm.pairs.master.tolist(), strict=True))
    assert [partner[s] for s in sol.contact.node.tolist()] == sol.contact.partner.tolist()
    # gap after deformation, recomputed here: g − B u
    u = sol.nodal_values().ravel()
    gap = Pm.pairs.g - Pm.pairs.B @ u
    mine = dict(zip(Pm.pairs.slave.tolist(), gap.tolist(), strict=True))
    assert np.allclose([mine[s] for s in sol.contact.node.tolist()], sol.contact.gap,
                       rtol=0, atol=1e-9 * np.abs(u).max())
    assert abs(Pm.energy(sol.nodal_values()) - sol.energy) <= 1e-8 * abs(sol.energy)


def test_independent_kkt(mono, sol):
    Pm, _ = mono
    mine = Pm.check(sol.nodal_values(), sol.contact.node, sol.contact.force)
    ref.assert_kkt_agree(mine, sol.report.kkt, tol=1e-8)


def test_decompositions_agree(sols):
    a, b = sols["bytags"], sols["parts3"]
    assert ref.rel_max_diff(a.nodal_values(), b.nodal_values()) <= 1e-8
    (na, fa), (nb, fb) = ref.forces_by_node(a.contact), ref.forces_by_node(b.contact)
    assert np.array_equal(na, nb)
    assert ref.rel_max_diff(fa, fb) <= 1e-8
