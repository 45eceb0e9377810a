"""Total BETI solves (``method="tbeti"``) against exact solutions and Total FETI.

Serial and under ``mpirun -n 2`` (the same assertions: the results do not depend on the ranks).
"""

from __future__ import annotations

import numpy as np
import pytest

import dolfinx_feti as df
from dolfinx_feti.bem.models import two_squares

E, NU, P = 10.0, 0.3, 0.7


def grid(H: float, width: float = 2.0) -> df.ByFunction:
    """A regular H×H grid of subdomains over (0, width)×(0, 1)."""
    k = int(round(width / H))
    return df.ByFunction(
        lambda m: (np.floor(m[:, 0] / H) + k * np.floor(m[:, 1] / H)).astype(np.int64))


def scalar_problem(mesh, **kw) -> df.ContactProblem:
    """Two membranes, the left held at x = 0, pressed together by fluxes (no source)."""
    return df.ContactProblem(
        mesh, df.Poisson(0.0, flux={"top_right": -1.0, "top_left": 0.5}),
        dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=grid(0.5), **kw)


def stacked_problem(mesh, contact, top) -> df.ContactProblem:
    """Two stacked blocks on rollers (y = 0 and x = 0), loaded or pushed at the top."""
    dirichlet = [df.Dirichlet("bottom", 0.0, components=(1,)),
                 df.Dirichlet("left", 0.0, components=(0,))]
    forms = df.Elasticity(E, NU)
    if top == "pressure":
        forms = df.Elasticity(E, NU, tractions={"top": (0.0, -P)})
    else:  # a tilted push: contact on part of the interface
        dirichlet.append(df.Dirichlet("top", lambda x: -0.02 + 0.03 * x[:, :1], components=(1,)))
    return df.ContactProblem(mesh, forms, dirichlet=dirichlet, contact=[contact],
                             decomposition=df.Parts(4))


def both(make) -> dict[str, df.Solution]:
    return {m: df.solve(make(), method=m, rtol=1e-10) for m in ("tfeti", "tbeti")}


@pytest.fixture(scope="module")
def scalar_runs():
    out = {}
    for n in (8, 16):
        mesh = df.build_mesh(two_squares, n)
        out[n] = both(lambda mesh=mesh: scalar_problem(mesh))
    return out


def test_scalar_tbeti_converges_to_tfeti(scalar_runs):
    """TBETI and TFETI differ by the discretization error: O(h), under 2 % at h = 1/16."""
    diff = {}
    for n, runs in scalar_runs.items():
        for s in runs.values():
            assert s.report.converged
            assert s.report.kkt["complementarity"] < 1e-8
        a, b = (runs[m].nodal_values()[:, 0] for m in ("tfeti", "tbeti"))
        diff[n] = np.abs(a - b).max() / np.abs(a).max()
    assert diff[16] < 0.01
    assert diff[8] / diff[16] > 1.8
    r = scalar_runs[16]["tbeti"].report
    assert r.method == "TBETI"
    assert r.sizes["boundary_dofs"] == 8 * 4 * 8  # 8 subdomains, 4 × 8 boundary nodes each
    assert r.sizes["dual"] == scalar_runs[16]["tfeti"].report.sizes["dual"]


@pytest.mark.parametrize("kind", ["mortar", "node_to_node"])
def test_contact_patch_test_exact(kind):
    """Uniform pressure through a contact interface: TBETI reproduces the linear solution."""
    mesh = df.build_mesh(two_squares, 4, 6 if kind == "mortar" else 4, stacked=True)
    contact = (df.Mortar("contact_upper", "contact_lower") if kind == "mortar" else
               df.NodeToNode("contact_upper", "contact_lower"))
    s = df.solve(stacked_problem(mesh, contact, "pressure"), method="tbeti", rtol=1e-12)
    assert s.report.converged
    x = mesh.x
    exact = np.stack([NU * (1 + NU) * P / E * x[:, 0], -(1 - NU ** 2) * P / E * x[:, 1]], 1)
    u = s.nodal_values()
    assert np.abs(u - exact).max() <= 1e-9 * np.abs(exact).max()  # inside too
    assert np.allclose(s.contact.pressure, P, rtol=1e-8)


def test_elastic_partial_contact_tbeti_vs_tfeti():
    diff = {}
    for n in (8, 16):
        mesh = df.build_mesh(two_squares, n, stacked=True)
        runs = both(lambda mesh=mesh: stacked_problem(
            mesh, df.NodeToNode("contact_upper", "contact_lower"), "push"))
        for s in runs.values():
            assert s.report.converged
        a, b = (runs[m].nodal_values() for m in ("tfeti", "tbeti"))
        diff[n] = np.abs(a - b).max() / np.abs(a).max()
        active = [set(np.flatnonzero(runs[m].contact.force > 1e-8)) for m in runs]
        assert 0 < len(active[1]) < runs["tbeti"].contact.force.size  # partial contact
        assert len(active[0] ^ active[1]) <= 2  # the same active set up to the rim node(s)
    assert diff[16] < 0.03
    assert diff[8] / diff[16] > 1.8


def test_refusals_by_name():
    mesh = df.build_mesh(two_squares, 2, stacked=True)
    base = dict(dirichlet=[df.Dirichlet("bottom")], decomposition=df.Parts(2))
    cases = {
        "body force": df.ContactProblem(mesh, df.Elasticity(E, NU, body_force=(0.0, -1.0)),
                                        **base),
        "source": df.ContactProblem(mesh, df.Poisson(1.0), **base),
        "forms function": df.ContactProblem(mesh, lambda V, sub: None, value_size=1, **base),
        "degree": df.ContactProblem(mesh, df.Elasticity(E, NU, degree=2), **base),
    }
    words = {"body force": "body force", "source": "source", "forms function": "df.Elasticity",
             "degree": "degree 1"}
    for name, problem in cases.items():
        with pytest.raises(df.InputError, match=words[name]):
            df.solve(problem, method="tbeti")


def test_hertz2d_tbeti_vs_tfeti_and_hertz(root):
    """B2 (2D Hertz, half model): the same active set, pressure peak within 1 % of Hertz."""
    import test_hertz2d as h2

    mesh = df.read_gmsh(root / "meshes/hertz2d.msh")
    runs = both(lambda: h2.problem(mesh, df.ByTags()))
    for s in runs.values():
        assert s.report.converged
    a, b = (runs[m].nodal_values() for m in ("tfeti", "tbeti"))
    assert np.abs(a - b).max() < 0.01 * np.abs(a).max()
    active = [np.flatnonzero(runs[m].contact.force > 1e-8) for m in ("tfeti", "tbeti")]
    np.testing.assert_array_equal(active[0], active[1])
    assert abs(runs["tbeti"].contact.pressure.max() / h2.P0_HERTZ - 1) < 0.01


def test_3d_refused_by_name(root):
    mesh = df.read_gmsh(root / "meshes/blocks3d.msh")
    problem = df.ContactProblem(mesh, df.Elasticity(E, NU), decomposition=df.Parts(2),
                                dirichlet=[df.Dirichlet(sorted(mesh.facet_groups)[0])])
    with pytest.raises(df.InputError, match="2D only"):
        df.solve(problem, method="tbeti")


def test_tresca_friction_tbeti_vs_tfeti():
    """B4 (a block pressed and sheared on a foundation) with Tresca friction, node-to-node and
    on a rigid plane: the total normal and friction forces of TBETI approach TFETI's."""
    import test_friction as tf

    from dolfinx_feti.io import meshes

    gaps = {}
    plane = df.Plane((0.0, 0.0), (0.0, 1.0))
    for n in (6, 12):
        mesh = df.build_mesh(meshes.tresca2d, n=n)
        problems = {
            "pair": lambda mesh=mesh: tf.b4(mesh, df.Tresca(tf.G), df.Parts(4)),
            "plane": lambda mesh=mesh: df.ContactProblem(
                mesh, df.Elasticity(tf.E, tf.NU), decomposition=df.Parts(2),
                dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("foundation_sides"),
                           df.Dirichlet("foundation_top"), df.Dirichlet("top", value=tf.SHIFT)],
                contact=[df.RigidObstacle("block_bottom", plane, friction=df.Tresca(tf.G))])}
        for name, make in problems.items():
            runs = both(make)
            forces = {}
            for m, s in runs.items():
                assert s.report.converged
                c = s.contact
                slip = c.state == df.ContactData.SLIP  # |λ_T| = g there
                assert np.allclose(np.abs(c.tangential_force[slip, 0]), c.slip_bound[slip])
                assert 0 < np.sum(c.state == df.ContactData.STICK) < c.node.size
                forces[m] = np.array([c.force.sum(), c.tangential_force[:, 0].sum()])
            gaps[name, n] = np.abs(forces["tbeti"] / forces["tfeti"] - 1).max()
    for name in ("pair", "plane"):
        assert gaps[name, 12] < 0.01
        assert gaps[name, 12] < gaps[name, 6]


def test_distributed_mesh_same_solution():
    """A mesh spread over the ranks (``distribute=True``) gives the replicated mesh's solve."""
    runs = [df.solve(scalar_problem(df.build_mesh(two_squares, 8, distribute=d)),
                     method="tbeti", rtol=1e-10) for d in (False, True)]
    assert runs[0].report.hessian_mults == runs[1].report.hessian_mults
    assert runs[0].energy == pytest.approx(runs[1].energy, rel=1e-9)
    np.testing.assert_allclose(runs[1].multipliers(), runs[0].multipliers(), atol=1e-9)


@pytest.mark.parametrize("quads", [False, True])
def test_unstructured_patch_test_exact(quads):
    """Uniaxial tension of a rectangle on rollers, unstructured triangles or quadrilaterals:
    TBETI gives the linear solution (the subdomains' polygons are general here)."""
    import element_models as em

    mesh = df.build_mesh(em.rectangle, quads=quads, h=0.2)
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"right": (P, 0.0)}),
        dirichlet=[df.Dirichlet("left", 0.0, components=(0,)),
                   df.Dirichlet("bottom", 0.0, components=(1,))], decomposition=df.Parts(4))
    s = df.solve(problem, method="tbeti", rtol=1e-12)
    assert s.report.converged
    x = mesh.x
    exact = np.stack([(1 - NU ** 2) * P / E * x[:, 0], -NU * (1 + NU) * P / E * x[:, 1]], 1)
    assert np.abs(s.nodal_values() - exact).max() <= 1e-9 * np.abs(exact).max()
