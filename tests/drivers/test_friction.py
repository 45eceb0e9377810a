"""Friction in 2D (B4: a block pressed on a foundation and sheared): Tresca and Coulomb against an
independent monolithic solve, the stick/slip conditions, the limits g → 0 and g → ∞."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref
from friction_reference import FrictionReference
from scipy.optimize import minimize

import dolfinx_feti as df
from dolfinx_feti.constraints import Kind
from dolfinx_feti.io import meshes

E, NU = 21.19, 0.277  # the seed's material
SHIFT = (0.02, -0.02)  # the block's top: sheared and pressed
G = 0.1  # Tresca traction bound: about half of the contact slips
RTOL = 1e-10
DECOMPOSITIONS = {"bytags": df.ByTags(), "parts3": df.Parts(3)}


def b4(mesh, friction, decomposition=None):
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=SHIFT)],
        contact=[df.NodeToNode("block_bottom", "foundation_top", friction=friction)],
        decomposition=decomposition or df.ByTags())


@pytest.fixture(scope="module")
def mesh():
    return df.build_mesh(meshes.tresca2d, n=6)


@pytest.fixture(scope="module")
def reference(mesh):
    return FrictionReference(mesh, ref.elasticity_forms(E, NU),
                             dirichlet=[("bottom", (0.0, 0.0)), ("top", SHIFT)],
                             slave="block_bottom", master="foundation_top", normal=(0.0, 1.0))


@pytest.fixture(scope="module")
def tresca(mesh):
    return {k: df.solve(b4(mesh, df.Tresca(G), d), rtol=RTOL) for k, d in DECOMPOSITIONS.items()}


def umax(sol):
    return np.abs(sol.nodal_values()).max()


def compare(sol, r, tol=1e-6):
    """u, normal force, tangential force and slip per node against the reference."""
    c = sol.contact
    assert ref.rel_max_diff(sol.nodal_values(), r.u) <= tol
    scale = max(r.normal_force.max(), 1e-300)
    assert np.abs(r.by_node(c.node, c.force) - r.normal_force).max() <= tol * scale
    ft = r.by_node(c.node, c.tangential_force)
    assert np.abs(ft - r.tangential_force).max() <= tol * scale
    slip = r.by_node(c.node, c.slip)
    assert np.abs(slip - r.slip).max() <= tol * np.abs(r.u).max()


def test_reference_certificate(reference):
    r = reference.solve_tresca(G)
    assert r.natural_residual <= 1e-12
    stick = np.linalg.norm(r.tangential_force, axis=1) < r.bound * (1 - 1e-9)
    assert 2 <= stick.sum() <= stick.size - 2  # a real mix of stick and slip


def test_reference_against_scipy(reference):
    """The dense dual solved by a general-purpose bound-constrained method (L-BFGS-B)."""
    S, d = reference.S, reference.d
    g = G * reference.area
    k = reference.k
    bounds = [(0.0, None)] * k + [(-gi, gi) for gi in g]
    res = minimize(lambda y: (0.5 * y @ S @ y - d @ y, S @ y - d), np.zeros(2 * k), jac=True,
                   method="L-BFGS-B", bounds=bounds,
                   options={"ftol": 1e-16, "gtol": 1e-14, "maxiter": 20000, "maxcor": 50})
    lam = reference.solve_tresca(G).lam
    assert np.abs(res.x - lam).max() <= 1e-6 * np.abs(lam).max()


@pytest.mark.parametrize("dec", sorted(DECOMPOSITIONS))
def test_tresca_against_reference(tresca, reference, dec):
    sol = tresca[dec]
    assert sol.report.converged, sol.report.summary()
    # the default method: FETI-1 (few subdomains per body); both bodies held and no subdomain
    # floating, so no coarse space: MPRGP alone (TFETI with SMALBE: tests/setup/test_methods.py)
    assert (sol.report.method, sol.report.solver) == ("FETI-1", "mprgp")
    compare(sol, reference.solve_tresca(G))
    assert sol.report.sizes["tangential"] == sol.contact.node.size
    assert sol.report.extra["friction"]["model"] == "tresca"


@pytest.mark.parametrize("dec", sorted(DECOMPOSITIONS))
def test_bound_stick_and_slip(tresca, mesh, dec):
    sol = tresca[dec]
    c = sol.contact
    length = ref.traction_load(mesh, "block_bottom", [1.0])[c.node]
    assert np.allclose(c.slip_bound, G * length, rtol=1e-14, atol=0)
    ft = np.linalg.norm(c.tangential_force, axis=1)
    assert np.all(ft <= c.slip_bound * (1 + 1e-12))
    assert np.allclose(c.tangential_traction, c.tangential_force / length[:, None], rtol=1e-14)
    assert np.allclose(c.tangential_force[:, 1], 0.0, atol=1e-14 * ft.max())  # along the surface
    stick, slip = c.state == df.ContactData.STICK, c.state == df.ContactData.SLIP
    assert np.all(stick | slip) and 2 <= stick.sum() <= stick.size - 2
    # stick ⇔ |λ_T| < g; there the relative slip vanishes
    assert np.all(ft[stick] < c.slip_bound[stick]) and np.all(ft[slip] >= c.slip_bound[slip]
                                                                * (1 - 1e-12))
    assert np.abs(c.slip[stick]).max() <= 1e-8 * umax(sol)
    # slip nodes slip opposite to the friction force on them (the slip is along λ_T)
    s = np.linalg.norm(c.slip[slip], axis=1)
    moving = s > 1e-8 * umax(sol)
    assert moving.sum() >= slip.sum() - 1
    cos = np.einsum("ij,ij->i", c.slip[slip], c.tangential_force[slip]) / (s * ft[slip])
    assert np.all(cos[moving] <= -1 + 1e-9)
    # the shear (+x) drags the block's bottom along +x where it slips
    assert np.all(c.slip[slip][moving, 0] > 0)
    k = sol.report.kkt
    for key in ("dual_feasibility", "primal_feasibility", "equality", "complementarity",
                "friction_feasibility", "friction_complementarity", "equilibrium"):
        assert k[key] <= 1e-8, (key, k[key])


def test_decompositions_agree(tresca):
    a, b = tresca["bytags"], tresca["parts3"]
    assert ref.rel_max_diff(a.nodal_values(), b.nodal_values()) <= 1e-8
    oa, ob = np.argsort(a.contact.node), np.argsort(b.contact.node)
    assert np.array_equal(a.contact.state[oa], b.contact.state[ob])


def test_rows_of_a_node_are_consecutive(tresca):
    share = tresca["parts3"].rows  # the contact and friction rows are on every rank
    rows = share.contact
    t = np.flatnonzero(rows.kind == Kind.TANGENT)
    n = np.flatnonzero(rows.inequality)
    assert t.size == n.size
    # 2D: normal row, then the tangential row (global indices)
    assert np.array_equal(share.contact_index[t], share.contact_index[n] + 1)
    assert np.array_equal(rows.node[t], rows.node[n])
    assert np.allclose(rows.scale[t], 1 / np.sqrt(2))
    assert np.allclose(np.einsum("ij,ij->i", rows.normal[t], rows.normal[n]), 0.0)


def test_limit_g_zero_is_frictionless(mesh):
    free = df.solve(b4(mesh, None), rtol=RTOL)
    zero = df.solve(b4(mesh, df.Tresca(0.0)), rtol=RTOL)
    assert free.contact.state is None and free.rows.contact.tangential.sum() == 0
    assert ref.rel_max_diff(zero.nodal_values(), free.nodal_values()) <= 1e-7
    assert np.abs(zero.contact.force - free.contact.force).max() <= 1e-7 * free.contact.force.max()
    assert np.all(zero.contact.state == df.ContactData.SLIP)
    assert np.abs(zero.contact.tangential_force).max() == 0.0


def test_limit_g_infinite_is_bonded(mesh, reference):
    inf = df.solve(b4(mesh, df.Tresca(np.inf)), rtol=RTOL)
    big = df.solve(b4(mesh, df.Tresca(1e6)), rtol=RTOL)
    r = reference.solve_tresca(np.inf)  # the tangential rows as equalities
    compare(inf, r)
    compare(big, r)
    assert np.all(inf.contact.state == df.ContactData.STICK)
    assert np.abs(inf.contact.slip).max() <= 1e-8 * umax(inf)


def test_tresca_bound_as_function(mesh, reference):
    """g(x) = G (1 + x/4): a bound that varies along the surface."""
    sol = df.solve(b4(mesh, df.Tresca(lambda x: G * (1 + x[:, 0] / 4))), rtol=RTOL)
    xs = mesh.x[reference.slave, 0]
    r = reference.solve_bound(G * (1 + xs / 4) * reference.area)
    compare(sol, r)


def test_coulomb_against_reference(mesh, reference):
    F = 0.3
    sol = df.solve(b4(mesh, df.Coulomb(F, rtol=1e-10)), rtol=RTOL)
    rep = sol.report
    assert rep.converged, rep.summary()
    info = rep.extra["friction"]
    assert info["model"] == "coulomb" and info["fixed_point_converged"]
    assert 2 <= info["fixed_point_steps"] == len(info["steps"]) <= 30
    assert info["steps"][-1]["change"] <= 1e-10
    r = reference.solve_coulomb(F)
    compare(sol, r, tol=1e-6)
    c = sol.contact
    assert np.allclose(c.slip_bound, F * c.force, rtol=1e-8, atol=1e-8 * c.force.max())
    stick = c.state == df.ContactData.STICK
    assert 1 <= stick.sum() < stick.size


def test_coulomb_max_steps_reported(mesh):
    sol = df.solve(b4(mesh, df.Coulomb(0.3, rtol=1e-14, max_steps=2)), rtol=1e-8)
    assert not sol.report.converged
    assert sol.report.reason == "coulomb_max_steps"
    assert sol.report.extra["friction"]["fixed_point_steps"] == 2


def test_obstacle_friction(mesh):
    """The block alone on a rigid plane y = 0, with Tresca friction (the foundation is clamped
    and takes no part)."""
    plane = df.Plane((0.0, 0.0), (0.0, 1.0))
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("foundation_sides"),
                   df.Dirichlet("foundation_top"), df.Dirichlet("top", value=SHIFT)],
        contact=[df.RigidObstacle("block_bottom", plane, friction=df.Tresca(G))],
        decomposition=df.Parts(2))
    sol = df.solve(problem, rtol=RTOL)
    assert sol.report.converged
    r = FrictionReference(mesh, ref.elasticity_forms(E, NU),
                          dirichlet=[("bottom", (0, 0)), ("foundation_sides", (0, 0)),
                                     ("foundation_top", (0, 0)), ("top", SHIFT)],
                          slave="block_bottom", normal=(0.0, 1.0), point=(0.0, 0.0))
    compare(sol, r.solve_tresca(G))
    assert np.allclose(sol.rows.contact.scale[sol.rows.contact.tangential], 1.0)
    c = sol.contact
    assert 1 <= np.sum(c.state == df.ContactData.STICK) < c.node.size


def test_invalid_friction_input(mesh):
    with pytest.raises(df.InputError, match=">= 0"):
        df.Tresca(-1.0)
    with pytest.raises(df.InputError, match="number"):
        df.Tresca("a lot")
    with pytest.raises(df.InputError, match="coefficient"):
        df.Coulomb(-0.1)
    with pytest.raises(df.InputError, match="max_steps"):
        df.Coulomb(0.3, max_steps=0)
    with pytest.raises(df.InputError, match="friction must be"):
        b4(mesh, 0.3)
    with pytest.raises(df.InputError, match="shape"):
        df.solve(b4(mesh, df.Tresca(lambda x: np.ones((x.shape[0], 2)))))
    with pytest.raises(df.InputError, match=">= 0"):
        df.solve(b4(mesh, df.Tresca(lambda x: -np.ones(x.shape[0]))))
    membranes = df.build_mesh(meshes.membranes, 2)
    with pytest.raises(df.InputError, match="vector"):
        df.ContactProblem(membranes, df.Poisson(-1.0), dirichlet=[df.Dirichlet("dirichlet")],
                          contact=[df.NodeToNode("contact_right", "contact_left",
                                                 friction=df.Tresca(1.0))])
