"""Friction on node-to-node pairs under Newton in 3D: two neo-Hookean boxes pressed, sheared.

The 2D stack of ``stacked_blocks`` extruded into tetrahedra (tests/support/extruded.py):
matching nodes on the common side y = 1, the lower box held at its bottom, the upper one
moved at its top, 𝓕 = 0.2 at 30° to x. Checked as in 2D (tests/drivers/
test_newton_pair_friction.py): full stick is the solution of the boxes fused into one
conforming mesh (their extruded walls are triangulated differently, so a mortar ``df.Tie``
is not the nodal glue here), in gross
sliding the Coulomb conditions hold per pair (two tangents, disc bounds) and the forces at the
upper box's top balance the contact forces.
"""

from __future__ import annotations

import numpy as np
import pytest
from coulomb_kkt import coulomb_violations, dirichlet_force
from element_models import stacked_blocks
from extruded import extrude
from mpi4py import MPI

import dolfinx_feti as df

E, NU, ANGLE = 10.0, 0.3, np.pi / 6
OPTS = {"rtol": 1e-11, "newton_rtol": 1e-9, "method": "fetidp", "progress": False}


@pytest.fixture(scope="module")
def stack():
    return extrude(df.build_mesh(stacked_blocks, n=3, gdim=2), 1.0, 3)


def sheared(mesh, t: float, friction, flat: bool = False):
    """Pressed 0.1 by the top for t <= 1, then its top moved by (t − 1)·0.1 at ANGLE to x
    (``flat``: the lower box's top held vertically)."""
    s = max(t - 1.0, 0.0) * 0.1
    dirichlet = [df.Dirichlet("bottom"),
                 df.Dirichlet("top", (s * np.cos(ANGLE), -min(t, 1.0) * 0.1, s * np.sin(ANGLE)))]
    if flat:
        dirichlet.append(df.Dirichlet("lower_top", 0.0, components=[1]))
    return df.ContactProblem(
        mesh, df.NeoHookean(E, NU), dirichlet=dirichlet,
        contact=[df.NodeToNode("upper_bottom", "lower_top", friction=friction)],
        decomposition=df.ByTags())


def fused(mesh: df.MeshData) -> tuple[df.MeshData, np.ndarray]:
    """The two boxes as one conforming mesh: the upper box's interface nodes replaced by the
    lower box's at the same place (the glued boxes, with no contact nor tie rows; the
    interface groups left out), and each node of ``mesh``'s number in it."""
    lower = np.unique(mesh.facet_groups["lower_top"])
    upper = np.unique(mesh.facet_groups["upper_bottom"])
    near = np.linalg.norm(mesh.x[upper][:, None] - mesh.x[lower][None], axis=2)
    to = np.arange(mesh.x.shape[0])
    to[upper] = lower[np.argmin(near, axis=1)]
    keep = np.ones(mesh.x.shape[0], dtype=bool)
    keep[upper] = False
    new = np.cumsum(keep) - 1
    renum = new[to]
    groups = {k: renum[f] for k, f in mesh.facet_groups.items()
              if k not in ("lower_top", "upper_bottom")}
    return df.MeshData(x=mesh.x[keep], cells=renum[mesh.cells], cell_type=mesh.cell_type,
                       cell_body=mesh.cell_body, body_names=mesh.body_names,
                       facet_groups=groups, node_tags=np.arange(1, keep.sum() + 1),
                       group_tags={k: v for k, v in mesh.group_tags.items() if k in groups
                                   or k in mesh.body_names}), renum


def top_force(sol) -> np.ndarray:
    """The force of the top's Dirichlet condition on the upper block (y = 2)."""
    return dirichlet_force(sol, lambda x: np.isclose(x[:, 1], 2.0), MPI.COMM_WORLD)


def test_full_stick_equals_the_fused_boxes(stack):
    """𝓕 = 5: every pair sticks, so the boxes are glued where they met: one mesh."""
    times = [0.5, 1.0, 1.5, 2.0]
    sols = df.solve_path(lambda t: sheared(stack, t, df.Coulomb(5.0)), times, **OPTS)
    assert all(s.report.converged for s in sols)
    one, renum = fused(stack)
    s = max(times[-1] - 1.0, 0.0) * 0.1
    ref = df.solve(df.ContactProblem(
        one, df.NeoHookean(E, NU), dirichlet=[df.Dirichlet("bottom"), df.Dirichlet(
            "top", (s * np.cos(ANGLE), -0.1, s * np.sin(ANGLE)))], decomposition=df.ByTags()),
        rtol=1e-12, newton_rtol=1e-10, method="fetidp")
    assert ref.report.converged
    assert np.all(sols[-1].contact.state == 1)
    U, Uref = sols[-1].nodal_values(), ref.nodal_values()[renum]
    assert np.abs(U - Uref).max() < 1e-8 * np.abs(Uref).max()


def test_gross_sliding_coulomb_conditions_and_balance(stack):
    """𝓕 = 0.2, the master surface held flat: the top slid at 30° until every pair slips;
    the Coulomb conditions per pair and the force balance at every step; the friction force
    over the normal force tends to 𝓕 as the slip directions align with the slide."""
    sols = df.solve_path(lambda t: sheared(stack, t, df.Coulomb(0.2, rtol=1e-10), flat=True),
                         [0.5, 1.0, 2.0, 3.0, 4.0], **OPTS)
    assert all(s.report.converged for s in sols)
    for s in sols:
        v = coulomb_violations(s, 0.2)
        assert max(v.values()) < 1e-7, v
        f = s.total_contact_force
        assert np.abs(top_force(s) + f).max() < 1e-8 * abs(f[1])
    sol = sols[-1]
    assert np.all(sol.contact.state == 2)
    fx, fy, fz = sol.total_contact_force
    assert abs(np.hypot(fx, fz) / fy - 0.2) < 2e-3  # the slips not yet all parallel
    assert abs(np.arctan2(fz, fx) - (ANGLE - np.pi)) < 0.1  # against the slide
