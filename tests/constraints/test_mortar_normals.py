"""The normals of mortar rows at kinks and fillets (issue 25): ``Mortar(normals="flatter")``.

A flat punch with filleted corners on a block under a normal load with shear, sticking by
Tresca friction: the force balance of the punch says that the contact forces sum to the
applied load. With the slave's averaged normals (the punch as slave) the fillet's rows tilt,
the normal forces carry part of the shear and the friction forces sum to less than it; with
the flatter side's normals (the block's) the friction forces sum to the shear and the normal
forces to the normal load, to the solver's accuracy — and with the punch as master the
block's own (slave) normals are kept.
"""

from __future__ import annotations

import numpy as np
import pytest
from filleted_punch import filleted_punch

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar import mortar_coupling
from dolfinx_feti.constraints.mortar_normals import flatter_normals
from dolfinx_feti.constraints.mortar_p2 import quadratic_coupling
from dolfinx_feti.io.meshes_occ import disk_on_block, sphere_on_block
from dolfinx_feti.mesh.dofpoints import dof_points

TAU, P, TOP = 0.2, 1.0, 2.0 - 2 * 0.4  # the punch's top line: its width less the fillets


@pytest.fixture(scope="module")
def punch():
    return df.build_mesh(filleted_punch)


def _solve(mesh, slave, master, normals):
    problem = df.ContactProblem(
        mesh, df.Elasticity(100.0, 0.3, tractions={"load": (TAU, -P)}),
        dirichlet=[df.Dirichlet("bottom")],
        contact=[df.Mortar(slave, master, friction=df.Tresca(0.5), normals=normals)],
        decomposition=df.Parts(4))
    sol = df.solve(problem, rtol=1e-10)
    assert sol.report.converged and not sol.report.warnings, sol.report.warnings
    return sol


def test_friction_forces_sum_to_the_shear_with_the_flatter_normals(punch):
    shear, load = TAU * TOP, P * TOP
    sol = _solve(punch, "punch_contact", "block_contact", "flatter")
    c = sol.contact
    assert np.allclose(c.normal, [0.0, 1.0], atol=1e-12)  # the block's normal (toward the punch)
    ft = c.tangential_force.sum(axis=0)
    assert ft[0] == pytest.approx(-shear, rel=1e-8) and abs(ft[1]) < 1e-10
    assert c.force.sum() == pytest.approx(load, rel=1e-8)
    active = c.force > 1e-8 * c.force.max()
    assert np.abs(c.x[active, 0]).max() > 0.6 + 0.02  # the contact reaches onto the fillets
    # The slave's averaged normals: the same total force, split otherwise.
    tilted = _solve(punch, "punch_contact", "block_contact", "slave").contact
    assert np.allclose((tilted.force[:, None] * tilted.normal).sum(axis=0)
                       + tilted.tangential_force.sum(axis=0), [-shear, load], rtol=1e-7)
    miss = abs(tilted.tangential_force.sum(axis=0)[0] + shear) / shear
    assert miss > 0.01, miss  # the normal forces carry part of the shear


def test_the_slave_normals_stay_where_the_slave_is_flatter(punch):
    """The punch as master: the block (slave) is the flat side; its normals are kept."""
    shear, load = TAU * TOP, P * TOP
    a = _solve(punch, "block_contact", "punch_contact", "flatter").contact
    b = _solve(punch, "block_contact", "punch_contact", "slave").contact
    assert np.allclose(a.normal, [0.0, -1.0], atol=1e-12)
    assert np.allclose(a.force, b.force, rtol=1e-7, atol=1e-9 * b.force.max())
    assert a.tangential_force.sum(axis=0)[0] == pytest.approx(shear, rel=1e-8)
    assert a.force.sum() == pytest.approx(load, rel=1e-8)


def test_a_sphere_on_a_flat_block_takes_the_block_normal():
    mesh = df.build_mesh(sphere_on_block, 0.4, 0.6, 3.0)
    slave, master = "sphere_contact", "block_contact"
    c = mortar_coupling(mesh.x, mesh.cells, mesh.facets(slave), mesh.facets(master),
                        search_distance=0.5, cell_type=mesh.cell_type)
    normals, take = flatter_normals(mesh, slave, master, c)
    assert np.all(take[c.coupled]) and np.any(c.coupled)  # every row: the block's normal
    assert np.allclose(normals[take], [0.0, 0.0, -1.0], atol=1e-12)
    assert np.array_equal(normals[~take], c.normals[~take])
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0)


@pytest.mark.parametrize("degree", [1, 2])
def test_a_disk_on_a_flat_block_takes_the_block_normal_at_every_point(degree):
    """2D, 3-node segments too: an edge point lies on one segment only, yet it bends as its
    segment's ends do, so vertices and edge points alike take the block's normal."""
    mesh = df.build_mesh(disk_on_block, 0.2, 0.34)
    points = dof_points(mesh, degree)
    slave, master = mesh.facets("disk_contact"), mesh.facets("block_contact")
    if degree == 1:
        c = mortar_coupling(mesh.x, mesh.cells, slave, master, cell_type=mesh.cell_type)
    else:
        c = quadratic_coupling(mesh.x, mesh.cells, slave, master, points,
                               cell_type=mesh.cell_type)
    normals, take = flatter_normals(mesh, "disk_contact", "block_contact", c,
                                    None if degree == 1 else points)
    assert np.all(take[c.coupled]) and c.coupled.sum() > 5
    assert np.allclose(normals[c.coupled], [0.0, -1.0], atol=1e-12)
