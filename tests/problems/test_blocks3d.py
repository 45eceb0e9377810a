"""Two stacked 3D blocks pressed by a uniform traction: equilibrium, non-penetration, KKT, and
agreement with an independent monolithic solve."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

import dolfinx_feti as df

RTOL = 1e-10
E, NU = 1000.0, 0.3
TRACTION = (0.0, 0.0, -1.0)
LOAD = 1.0  # |traction| × area of the top face (1 × 1)

#: "free": the upper block may slide and turn in its plane (3 rigid motions left undetermined,
#: unloaded); "constrained": its sides are held in x and y.
VARIANTS = {"free": [], "constrained": [("sides_upper", [0, 1])]}


def problem(mesh, variant: str, decomposition=None) -> df.ContactProblem:
    extra = [df.Dirichlet(g, components=c) for g, c in VARIANTS[variant]]
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"top": TRACTION}),
        dirichlet=[df.Dirichlet("bottom"), *extra],
        contact=[df.NodeToNode("contact_upper", "contact_lower")],
        decomposition=decomposition or df.ByTags())


def monolithic(mesh, variant: str, extra_fixed=()) -> ref.MonolithicProblem:
    return ref.MonolithicProblem(
        mesh, 3, ref.elasticity_forms(E, NU), tractions={"top": TRACTION},
        dirichlet=[("bottom", None), *VARIANTS[variant]],
        contact=("contact_upper", "contact_lower"), match_axes=(0, 1), normal=(0.0, 0.0, 1.0),
        extra_fixed=extra_fixed)


@pytest.fixture(scope="module")
def mesh(root):
    return df.read_gmsh(root / "meshes/blocks3d.msh")


@pytest.fixture(scope="module")
def sols(mesh):
    return {v: df.solve(problem(mesh, v), rtol=RTOL) for v in VARIANTS}


@pytest.fixture(scope="module", params=sorted(VARIANTS))
def variant(request):
    return request.param


@pytest.fixture(scope="module")
def checker(mesh, variant):
    """The variant's own K, f and rows (no extra support): for the KKT check."""
    return monolithic(mesh, variant)


def upper_nodes(mesh) -> np.ndarray:
    return np.unique(mesh.cells[mesh.cell_body == mesh.body_names.index("upper")])


def node_at(mesh, nodes, p) -> int:
    hit = nodes[np.all(np.abs(mesh.x[nodes] - p) < 1e-12, axis=1)]
    assert hit.size == 1
    return int(hit[0])


@pytest.fixture(scope="module")
def mono(mesh, variant):
    """Reference solution. For "free", the three in-plane rigid motions of the upper block are
    removed by supports that carry no reaction: u_x, u_y at (0,0,1) and u_y at (1,0,1)."""
    extra = ()
    if variant == "free":
        up = upper_nodes(mesh)
        a, b = node_at(mesh, up, (0, 0, 1)), node_at(mesh, up, (1, 0, 1))
        extra = (3 * a, 3 * a + 1, 3 * b + 1)
    Pm = monolithic(mesh, variant, extra)
    r = Pm.solve()
    if extra:  # the artificial supports carry no force
        reaction = (Pm.K @ r.u.ravel() - Pm.f + Pm.pairs.B.T @ r.lam)[list(extra)]
        assert np.abs(reaction).max() <= 1e-12 * LOAD
    return Pm, r


def test_converged(sols, variant):
    s = sols[variant]
    assert s.report.converged, s.report.summary()
    assert s.report.gP_rel <= RTOL
    assert any("rigid motion" in w for w in s.report.warnings) == (variant == "free")


def test_equilibrium(sols, variant):
    """The upper block floats vertically: the contact forces balance the load exactly."""
    F = sols[variant].total_contact_force
    assert abs(F[2] - LOAD) <= 1e-8 * LOAD
    assert np.abs(F[:2]).max() <= 1e-12 * LOAD
    assert abs(sols[variant].contact.force.sum() - LOAD) <= 1e-8 * LOAD


def test_no_penetration(sols, variant):
    s = sols[variant]
    umax = np.abs(s.nodal_values()).max()
    assert s.contact.gap.min() >= -1e-8 * umax
    assert s.report.max_penetration <= 1e-8 * umax


def test_reference_equilibrium(mono):
    _, r = mono
    assert abs(r.lam.sum() - LOAD) <= 1e-13 * LOAD


def test_against_monolithic_reference(mesh, mono, sols, variant):
    """Equal to the reference; for "free" up to a rigid in-plane motion of the upper block."""
    Pm, r = mono
    s = sols[variant]
    u = s.nodal_values()
    d = u - r.u
    if variant == "free":
        up = upper_nodes(mesh)
        x = mesh.x[up]
        zero, one = np.zeros(up.size), np.ones(up.size)
        modes = np.stack([np.stack([one, zero, zero], 1), np.stack([zero, one, zero], 1),
                          np.stack([-x[:, 1], x[:, 0], zero], 1)], axis=-1).reshape(-1, 3)
        coef, *_ = np.linalg.lstsq(modes, d[up].ravel(), rcond=None)
        d[up] -= (modes @ coef).reshape(-1, 3)
    assert np.abs(d).max() <= 1e-6 * np.abs(r.u).max()
    lam = Pm.multipliers_from(s.contact.node, s.contact.force)
    assert ref.rel_max_diff(lam, r.lam) <= 1e-6
    assert abs(s.energy - r.energy) <= 1e-8 * abs(r.energy)


def test_pairs_and_energy_independent(checker, sols, variant):
    s = sols[variant]
    partner = dict(zip(checker.pairs.slave.tolist(), checker.pairs.master.tolist(), strict=True))
    assert [partner[n] for n in s.contact.node.tolist()] == s.contact.partner.tolist()
    assert np.allclose(s.contact.normal, [0.0, 0.0, 1.0], rtol=0, atol=1e-14)
    assert abs(checker.energy(s.nodal_values()) - s.energy) <= 1e-8 * abs(s.energy)


def test_independent_kkt(checker, sols, variant):
    s = sols[variant]
    mine = checker.check(s.nodal_values(), s.contact.node, s.contact.force)
    ref.assert_kkt_agree(mine, s.report.kkt, tol=1e-8)


def test_decompositions_agree(mesh, sols):
    """ByTags and Parts(2) (four subdomains) agree to 1e-8 on the constrained variant."""
    a = sols["constrained"]
    b = df.solve(problem(mesh, "constrained", df.Parts(2)), rtol=RTOL)
    assert b.report.sizes["subdomains"] == 4
    assert ref.rel_max_diff(b.nodal_values(), a.nodal_values()) <= 1e-8
    (na, fa), (nb, fb) = ref.forces_by_node(a.contact), ref.forces_by_node(b.contact)
    assert np.array_equal(na, nb)
    assert ref.rel_max_diff(fb, fa) <= 1e-8
