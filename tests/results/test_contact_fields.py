"""The smoothed contact pressure (issue 25): the force over the area of each node's patch.

Independent checks: the surface mass matrices against closed forms and the lumped areas the
contact rows use; a uniform pressure (patch tests) reproduced exactly; Hertz's pressure on
unstructured tetrahedra (a sphere on a block, mortar): the smoothed field is closer to it than
the nodal force over the lumped area.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from test_mortar import (
    E_STAR,
    SPHERE_F,
    SPHERE_R,
    occ_mesh,
    patch_problem,
    sphere_problem,
    uniaxial,
)
from test_mortar_p2 import p2_problem

import dolfinx_feti as df
from dolfinx_feti.constraints.contact import surface
from dolfinx_feti.io.meshes_occ import sphere_on_block, stacked_blocks
from dolfinx_feti.mesh.dofpoints import dof_points
from dolfinx_feti.mesh.topology import facets_in_cell_order
from dolfinx_feti.results.contact_fields import surface_mass


@pytest.mark.parametrize("dim,recombine,degree", [(2, False, 1), (2, False, 2), (2, True, 2),
                                                  (3, False, 1), (3, True, 1), (3, True, 2)])
def test_surface_mass_rows_sum_to_the_lumped_areas(dim, recombine, degree):
    mesh = occ_mesh(stacked_blocks, dim, 0.34, 0.5, recombine=recombine)
    points = dof_points(mesh, degree)
    facets = facets_in_cell_order(mesh.cells, mesh.facets("lower_top"), mesh.cell_type)
    M = surface_mass(points.x, points.facet_points(mesh, facets), mesh.cell_type, degree,
                     points.num_points)
    nodes, _, area = surface(mesh, "lower_top", points)
    assert np.allclose(np.asarray(M.sum(axis=1)).ravel()[nodes], area, rtol=1e-12)
    assert M.sum() == pytest.approx(1.0, rel=1e-12)  # the unit square (segment) of the top
    assert abs(M - M.T).max() < 1e-15
    if dim == 3 and not recombine:  # P1 triangles: |T|/12 (1 + δ_ij)
        f = facets[0]
        xv = mesh.x[f]
        A = 0.5 * np.linalg.norm(np.cross(xv[1] - xv[0], xv[2] - xv[0]))
        one = surface_mass(points.x, f[None], mesh.cell_type, 1, points.num_points)
        assert np.allclose(one[f][:, f].toarray(), A / 12 * (np.ones((3, 3)) + np.eye(3)))


def test_uniform_pressure_is_reproduced():
    mesh = occ_mesh(stacked_blocks, 3, 0.25, 0.42)
    E, nu, p = {"lower": 100.0, "upper": 300.0}, 0.3, 1.0
    sol = df.solve(patch_problem(mesh, 3, E, nu, p,
                                 contact=[df.Mortar("upper_bottom", "lower_top")]), rtol=1e-12)
    exact = uniaxial(mesh, 3, p, E, nu)
    assert np.abs(sol.nodal_values() - exact).max() < 1e-8 * np.abs(exact).max()
    assert np.allclose(sol.smoothed_pressure(), p, rtol=1e-8)
    fn = sol.pressure_function(smoothed=True)  # the same values as a Function on the mesh
    values = fn.x.array[: fn.function_space.dofmap.index_map.size_local]
    assert fn.name == "contact_pressure_smoothed"
    assert np.isclose(sol.comm.allreduce(values.max(), op=MPI.MAX), p, rtol=1e-8)
    mesh2 = occ_mesh(stacked_blocks, 2, 0.1, 0.17)  # degree 2: vertices and edge points
    sol2 = df.solve(p2_problem(mesh2, E, contact=[df.Mortar("upper_bottom", "lower_top")]),
                    rtol=1e-12)
    assert np.allclose(sol2.smoothed_pressure(), 1.0, rtol=1e-8)


def test_smoothed_pressure_is_closer_to_hertz_on_tetrahedra():
    mesh = occ_mesh(sphere_on_block, 0.15, 0.25)
    F, R3 = SPHERE_F, SPHERE_R
    sol = df.solve(sphere_problem(mesh)[0], rtol=1e-9)
    a = (3 * F * R3 / (4 * E_STAR)) ** (1 / 3)
    p0 = 3 * F / (2 * np.pi * a**2)
    c = sol.contact
    r = np.linalg.norm(c.x[:, :2], axis=1)
    inner = r < 0.8 * a
    hertz = p0 * np.sqrt(1 - r[inner] ** 2 / a**2)

    def rms(p):
        return np.sqrt(np.mean((p[inner] - hertz) ** 2)) / p0

    smooth = sol.smoothed_pressure()
    # Measured: 6.7 % (force / lumped area) and 2.1 % (smoothed) RMS over 36 nodes.
    assert rms(smooth) < 0.5 * rms(c.pressure)
    assert rms(smooth) < 0.03
    assert smooth.shape == c.pressure.shape
