"""Friction on mortar pairs under Newton in 3D: the slider of the 2D test extruded, slid.

The slider and the block of tests/drivers/test_newton_mortar_friction.py (meshed apart)
extruded 1 deep into tetrahedra (tests/support/extruded.py), the block clamped at its bottom,
the slider's top pressed 0.05 (y is vertical), then moved along x. Two tangents per slave
node, disc bounds (MPGP); the tangential rows on the slip of the step relative to the master
material (drivers/mortar_friction.py). Checked from the returned data alone: full stick keeps
every slave node on its master material; in gross sliding with the block's top held flat
every slave node slips, Σ|q| = 𝓕Σp to solver tolerance, the Coulomb conditions hold per node
and the slider's top carries the contact force.
"""

from __future__ import annotations

import numpy as np
import pytest
from coulomb_kkt import check_coulomb, dirichlet_force
from extruded import extrude
from hand_meshes import blocks
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar import mortar_coupling

E, NU, PRESS = 10.0, 0.3, 0.05
OPTS = {"rtol": 1e-11, "newton_rtol": 1e-9, "method": "fetidp"}
PAIR = ("upper_bottom", "lower_top")


@pytest.fixture(scope="module")
def slider():
    flat = blocks([{"name": "lower", "n": (7, 3), "size": (3.0, 1.0)},
                   {"name": "upper", "n": (4, 2), "origin": (0.5, 1.0), "size": (1.0, 0.5)}])
    return extrude(flat, 1.0, 3)


def slid(mesh, t: float, friction, flat: bool = False) -> df.ContactProblem:
    """Pressed for t <= 1, then its top moved along x by (t − 1)·0.1."""
    shear = max(t - 1.0, 0.0) * 0.1
    dirichlet = [df.Dirichlet("lower_bottom"),
                 df.Dirichlet("upper_top", (shear, -min(t, 1.0) * PRESS, 0.0))]
    if flat:
        dirichlet.append(df.Dirichlet("lower_top", 0.0, components=[1]))
    return df.ContactProblem(mesh, df.NeoHookean(E, NU), dirichlet=dirichlet,
                             contact=[df.Mortar(*PAIR, friction=friction)],
                             decomposition=df.ByTags())


def test_full_stick_keeps_the_material_master_points(slider):
    """𝓕 = 5: no slip in any step, and at the end the relative tangential displacement of
    every mortar node (weights of the deformed surfaces, from the displacement alone) is
    below 1e-4 × the travel 0.1."""
    sols = df.solve_path(lambda t: slid(slider, t, df.Coulomb(5.0)), [0.5, 1.0, 1.5, 2.0],
                         **OPTS)
    assert all(s.report.converged for s in sols)
    for s in sols:
        assert np.all(s.contact.state == 1)
        check_coulomb(s, 5.0)
    U = sols[-1].nodal_values()
    c = mortar_coupling(slider.x + U, slider.cells, slider.facets(PAIR[0]),
                        slider.facets(PAIR[1]), None, slider.cell_type)
    slave = c.slave_nodes[c.coupled]
    rel = U[slave] - c.weights() @ U
    n = c.normals[c.coupled]
    tangential = rel - np.einsum("ij,ij->i", rel, n)[:, None] * n
    # measured 2.0e-6, the same at newton_rtol 1e-11 and 1.6e-6 / 2.2e-6 in 2 / 8 steps: the
    # weights of the deformed surfaces change along the path (more than in 2D), and the
    # steps' stuck increments, each with its own weights, add up to the total with the last
    # weights only to second order; a slide would give 1e-1 here
    assert np.abs(tangential).max() < 1e-4 * 0.1, tangential
    fx, fy, _ = sols[-1].total_contact_force
    assert 0.05 < abs(fx / fy) < 1.0


def test_gross_sliding_on_the_cone(slider):
    """𝓕 = 0.3, the block's top held flat: from a travel of 0.2 on every slave node slips,
    Σ|q|/Σp = 𝓕 to solver tolerance, the Coulomb conditions (disc bounds) per node, the
    friction force opposes the slide, and the top's force balances the contact force."""
    coefficient = 0.3
    sols = df.solve_path(lambda t: slid(slider, t, df.Coulomb(coefficient, rtol=1e-10),
                                        flat=True), [0.5, 1.0, 2.0, 3.0, 4.0], **OPTS)
    assert all(s.report.converged for s in sols)
    # quadratic to the end: the tangents of a flat slave surface do not swap with round-off
    # (constraints/friction.py, TANGENT_TIE; the last step took 19 iterations before)
    assert all(len(s.report.extra["newton"]) <= 8 for s in sols)
    for s in sols:
        check_coulomb(s, coefficient)
        f = s.total_contact_force
        top = dirichlet_force(s, lambda x: np.isclose(x[:, 1], 1.5), MPI.COMM_WORLD)
        assert np.abs(top + f).max() < 1e-8 * abs(f[1])
    for s in sols[3:]:
        c = s.contact
        assert np.all(c.state == 2)
        q = np.linalg.norm(c.tangential_force, axis=1)
        assert abs(q.sum() / c.force.sum() - coefficient) < 1e-8
        fx, fy, fz = s.total_contact_force
        assert fx < 0 and abs(-fx / fy - coefficient) < 1e-2 * coefficient
        assert abs(fz) < 1e-2 * abs(fx)
