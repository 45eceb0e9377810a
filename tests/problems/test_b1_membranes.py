"""B1, Dostál's two membranes: TFETI + SMALBE/MPRGP against BENCHMARKS.md and an independent
monolithic primal–dual active set solve of the same discrete problem
(tests/support/reference.py)."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

import dolfinx_feti as df
from dolfinx_feti.constraints.rows import Kind

RTOL = 1e-10

#: BENCHMARKS.md, B1: n → (energy, u_1(1,1), min u_2, upper end of the contact set on x = 1).
TABLE = {8: (-0.25883957, -0.700625, -0.790104, 0.75),
         16: (-0.26012652, -0.696888, -0.791769, 0.6875)}


def grid(H: float) -> df.ByFunction:
    """A regular H×H grid of subdomains over both membranes, (0,2)×(0,1)."""
    k = int(round(2.0 / H))
    return df.ByFunction(
        lambda m: (np.floor(m[:, 0] / H) + k * np.floor(m[:, 1] / H)).astype(np.int64))


DECOMPOSITIONS = {"bytags": df.ByTags(), "grid4": grid(0.25), "parts3": df.Parts(3)}


def problem(mesh, decomposition) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.Poisson(source=ref.membrane_source),
        dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")],  # u_left − u_right <= 0
        decomposition=decomposition)


@pytest.fixture(scope="module", params=sorted(TABLE))
def n(request):
    return request.param


@pytest.fixture(scope="module")
def mesh(n, root):
    return df.read_gmsh(root / f"meshes/membranes_{n}.msh")


@pytest.fixture(scope="module")
def mono(mesh):
    """The independent monolithic problem and its PDAS solution."""
    P = ref.MonolithicProblem(mesh, 1, ref.poisson_forms(ref.membrane_source),
                              dirichlet=[("dirichlet", None)],
                              contact=("contact_left", "contact_right"), match_axes=(1,))
    return P, P.solve()


@pytest.fixture(scope="module", params=sorted(DECOMPOSITIONS))
def sol(request, mesh):
    return df.solve(problem(mesh, DECOMPOSITIONS[request.param]), rtol=RTOL)


def left_corner(mesh) -> int:
    """The node of the left membrane at (1, 1)."""
    left = np.unique(mesh.cells[mesh.cell_body == mesh.body_names.index("left")])
    hit = left[np.all(np.abs(mesh.x[left] - [1.0, 1.0]) < 1e-12, axis=1)]
    assert hit.size == 1
    return int(hit[0])


def right_nodes(mesh) -> np.ndarray:
    return np.unique(mesh.cells[mesh.cell_body == mesh.body_names.index("right")])


# --- the reference itself against the published table -------------------------------------------


def test_reference_reproduces_table(n, mesh, mono):
    P, r = mono
    energy, u11, minu2, ymax = TABLE[n]
    assert abs(r.energy - energy) <= 1e-8 * abs(energy)
    assert abs(r.u[left_corner(mesh), 0] - u11) <= 1e-6
    assert abs(r.u[right_nodes(mesh), 0].min() - minu2) <= 1e-6
    assert abs(r.lam.sum() - 0.25) <= 1e-13
    y = mesh.x[P.pairs.slave, 1]
    assert np.array_equal(r.lam > 0, y <= ymax + 1e-12)


# --- TFETI ---------------------------------------------------------------------------------------


def test_converged(sol):
    assert sol.report.converged, sol.report.summary()
    assert sol.report.solver == "smalbe"
    assert sol.report.gP_rel <= RTOL


def test_multiplier_sum(sol):
    """Equilibrium of the floating membrane: the contact forces sum to exactly 0.25."""
    assert abs(sol.contact.force.sum() - 0.25) <= 1e-8 * 0.25
    assert abs(sol.total_contact_force[0] - 0.25) <= 1e-8 * 0.25
    assert np.array_equal(sol.multipliers(Kind.CONTACT), sol.contact.force)
    assert sol.contact.force.min() >= 0.0


def test_against_table(n, mesh, sol):
    energy, u11, minu2, _ = TABLE[n]
    assert abs(sol.energy - energy) <= 1e-6 * abs(energy)
    u = sol.nodal_values()[:, 0]
    assert abs(u[left_corner(mesh)] - u11) <= 1e-6
    assert abs(u[right_nodes(mesh)].min() - minu2) <= 1e-6


def test_contact_set(n, mesh, mono, sol):
    """Nodes with a positive force on x = 1: y ∈ [0, ymax] as in the table and the reference."""
    P, r = mono
    c = sol.contact
    closed = c.force > 1e-6 * c.force.max()
    y = c.x[closed, 1]
    ymax = TABLE[n][3]
    assert np.all(np.abs(c.x[:, 0] - 1.0) < 1e-12)
    assert abs(y.min()) < 1e-12 and abs(y.max() - ymax) < 1e-12
    assert np.all(closed == (c.x[:, 1] <= ymax + 1e-12))  # one interval, no holes
    ref_closed = set(P.pairs.slave[r.lam > 0].tolist())
    assert set(c.node[closed].tolist()) == ref_closed


def test_against_monolithic_reference(mono, sol):
    P, r = mono
    u = sol.nodal_values()
    assert ref.rel_max_diff(u, r.u) <= 1e-6
    lam = P.multipliers_from(sol.contact.node, sol.contact.force)
    assert ref.rel_max_diff(lam, r.lam) <= 1e-6
    assert abs(sol.energy - r.energy) <= 1e-8 * abs(r.energy)


def test_pairs_and_energy_independent(mono, sol):
    """The package pairs the same nodes, and its energy is ½uᵀKu − fᵀu with our K and f."""
    P, _ = mono
    partner = dict(zip(P.pairs.slave.tolist(), P.pairs.master.tolist(), strict=True))
    assert [partner[s] for s in sol.contact.node.tolist()] == sol.contact.partner.tolist()
    assert abs(P.energy(sol.nodal_values()) - sol.energy) <= 1e-8 * abs(sol.energy)


def test_independent_kkt(mono, sol):
    P, _ = mono
    mine = P.check(sol.nodal_values(), sol.contact.node, sol.contact.force)
    ref.assert_kkt_agree(mine, sol.report.kkt, tol=1e-8)
    assert sol.report.max_penetration <= 1e-8 * np.abs(sol.nodal_values()).max()


def test_decompositions_agree(root):
    """ByTags and an 8×4 grid of 32 subdomains give the same solution to 1e-8."""
    mesh = df.read_gmsh(root / "meshes/membranes_16.msh")
    a = df.solve(problem(mesh, df.ByTags()), rtol=RTOL)
    b = df.solve(problem(mesh, grid(0.25)), rtol=RTOL)
    assert ref.rel_max_diff(a.nodal_values(), b.nodal_values()) <= 1e-8
    (na, fa), (nb, fb) = ref.forces_by_node(a.contact), ref.forces_by_node(b.contact)
    assert np.array_equal(na, nb)
    assert ref.rel_max_diff(fa, fb) <= 1e-8
