"""Node-to-node contact on P2 tetrahedra (issue 25): rows in the transformed basis.

The 3D contact patch test (two stacked boxes of structured tetrahedra with matching contact
faces, a uniform pressure on top): the exact uniaxial displacement at every dof point and the
nodal forces = p · ∫Ñ_j (∫Ñ = 2|T|/15 at a vertex, |T|/5 at an edge point per facet), serially
and on 2 ranks; with friction (Tresca) the same (nothing slides under a normal load).
"""

from __future__ import annotations

import numpy as np
import pytest

import dolfinx_feti as df
from dolfinx_feti.constraints.contact import surface
from dolfinx_feti.io import meshes

E, NU, P = 100.0, 0.3, 1.0


@pytest.fixture(scope="module")
def blocks():
    return df.build_mesh(meshes.blocks3d, n=3)


@pytest.mark.parametrize("friction", [None, df.Tresca(0.5)])
def test_node_to_node_patch_test_p2_tetrahedra(blocks, friction):
    mesh = blocks
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"top": (0.0, 0.0, -P)}, degree=2),
        dirichlet=[df.Dirichlet("bottom", components=[2]),
                   df.Dirichlet("sides_lower", components=[0, 1]),
                   df.Dirichlet("sides_upper", components=[0, 1])],
        contact=[df.NodeToNode("contact_upper", "contact_lower", friction=friction)],
        decomposition=df.Parts(3))
    sol = df.solve(problem, rtol=1e-12)
    assert sol.report.converged
    x = problem.dof_points.x
    exact = np.zeros_like(x)
    exact[:, 2] = -P / E * (1 + NU) * (1 - 2 * NU) / (1 - NU) * x[:, 2]  # confined: ε_zz
    assert np.abs(sol.nodal_values() - exact).max() < 1e-8 * np.abs(exact).max()
    c = sol.contact
    nodes, _, area = surface(mesh, "contact_upper", problem.dof_points)
    assert np.any(c.node >= mesh.num_nodes) and np.any(c.node < mesh.num_nodes)
    assert np.allclose(c.force, P * area[np.searchsorted(nodes, c.node)], rtol=1e-8)
    assert np.allclose(c.pressure, P, rtol=1e-8)
    assert np.allclose(sol.smoothed_pressure(), P, rtol=1e-8)  # with the transformed basis
    assert sol.total_contact_force[2] == pytest.approx(P * 1.0, rel=1e-8)


def _on_plane(mesh, plane):
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"top": (0.0, 0.0, -P)}, degree=2),
        dirichlet=[df.Dirichlet("sides_lower", components=[0, 1]),
                   df.Dirichlet("sides_upper", components=[0, 1]),
                   df.Dirichlet("contact_lower", components=[2]),
                   df.Dirichlet("contact_upper", components=[2])],
        contact=[df.RigidObstacle("bottom", plane)], decomposition=df.Parts(2))


def test_update_of_an_obstacle_on_p2_tetrahedra(blocks):
    """A plane moved along its normal: the new gaps, as a cold solve; a tilted one: refused."""
    solver = df.FetiSolver(_on_plane(blocks, df.Plane((0, 0, 0.0), (0, 0, 1))), rtol=1e-12)
    solver.solve()
    moved = _on_plane(blocks, df.Plane((0, 0, 0.01), (0, 0, 1)))
    solver.update(moved)
    warm = solver.solve()
    cold = df.solve(moved, rtol=1e-12)
    u = cold.nodal_values()
    assert np.abs(warm.nodal_values() - u).max() < 1e-8 * np.abs(u).max()
    with pytest.raises(df.InputError, match="several nodes"):
        solver.update(_on_plane(blocks, df.Plane((0, 0, 0.0), (0.1, 0, 1))))
