"""Friction on mortar pairs under Newton: a neo-Hookean slider pressed on a block and slid.

The slider [0.5, 1.5] × [1, 1.5] on the block [0, 3] × [0, 1] (structured triangles, the two
meshes apart: no slave node matches a master node but the ends), the block clamped at its
bottom, the slider's top pressed down, then moved sideways. The mortar rows are searched
again on the deformed surfaces at every iterate and the tangential rows act on the slave
node's slip relative to the master material it is paired with, in the step
(drivers/mortar_friction.py). Checked against what does not come from that code:

- full stick on matching meshes (the mortar weights are then δ): the two bodies glued
  (``df.Tie``, the same Newton driver) are the exact answer;
- full stick on the non-matching meshes: no slip in any step, every slave node stays on the
  master material it started on (the relative tangential displacement of the mortar nodes,
  from the displacement alone, below 1e-6 × the slide);
- gross sliding with the block's top held flat (its vertical motion only: the block is
  dragged sideways by the friction): every slave node slips, the tangential over the normal
  force is 𝓕 (Coulomb) or the tangential force is Tresca's bound times the width, to solver
  tolerance, and the slider's top carries the contact force;
- a rigid rotation of the pressed pair: the pressed state turned, up to the square of each
  step's angle (the slip measure's objectivity);
- small loads: the Newton solution tends to the small-deformation mortar friction solution
  like the load squared, with the same stick/slip states;
- the Coulomb conditions from the returned contact data (tests/support/coulomb_kkt.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from coulomb_kkt import check_coulomb, check_stuck_as_tied, check_tresca_sliding, dirichlet_force
from hand_meshes import blocks
from mpi4py import MPI
from newton_small_loads import small_load_ratios

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar import mortar_coupling
from dolfinx_feti.errors import InputError

E, NU = 10.0, 0.3
PRESS = 0.05  # the slider top's downward travel
OPTS = {"rtol": 1e-11, "newton_rtol": 1e-9, "method": "fetidp"}
PAIR = ("upper_bottom", "lower_top")


def slider_mesh(n_slider: int = 7, n_block: int = 10, width: float = 1.0) -> df.MeshData:
    """The block (n_block × 4 cells) and the slider (n_slider × 3), meshed apart."""
    return blocks([{"name": "lower", "n": (n_block, 4), "size": (3.0, 1.0)},
                   {"name": "upper", "n": (n_slider, 3), "origin": (0.5, 1.0),
                    "size": (width, 0.5)}])


@pytest.fixture(scope="module")
def slider():
    return slider_mesh()


def slid(mesh, t: float, friction, flat: bool = False, tied: bool = False,
         slide: float = 0.1) -> df.ContactProblem:
    """Pressed for t <= 1, then its top moved sideways by (t − 1)·``slide``.

    ``flat``: the block's top held vertically; ``tied``: the slider glued to the block.
    """
    shear = max(t - 1.0, 0.0) * slide
    dirichlet = [df.Dirichlet("lower_bottom"),
                 df.Dirichlet("upper_top", (shear, -min(t, 1.0) * PRESS))]
    if flat:
        dirichlet.append(df.Dirichlet("lower_top", 0.0, components=[1]))
    return df.ContactProblem(
        mesh, df.NeoHookean(E, NU), dirichlet=dirichlet,
        contact=[] if tied else [df.Mortar(*PAIR, friction=friction)],
        ties=[df.Tie(*PAIR)] if tied else [], decomposition=df.ByTags())


def top_force(sol) -> np.ndarray:
    """The force of the slider top's Dirichlet condition on the slider (y = 1.5)."""
    return dirichlet_force(sol, lambda x: np.isclose(x[:, 1], 1.5), MPI.COMM_WORLD)


def relative_tangential(mesh, sol) -> np.ndarray:
    """The tangential part of u_j − Σ_k w_jk u_k at the coupled slave nodes, the weights and
    the normals of the deformed surfaces (computed here from the displacement alone)."""
    U = sol.nodal_values()
    y = mesh.x[:, :2] + U
    c = mortar_coupling(y, mesh.cells, mesh.facets(PAIR[0]), mesh.facets(PAIR[1]), None,
                        mesh.cell_type)
    slave = c.slave_nodes[c.coupled]
    rel = U[slave] - c.weights() @ U
    n = c.normals[c.coupled]
    return rel - np.einsum("ij,ij->i", rel, n)[:, None] * n


def test_full_stick_equals_the_tied_bodies_on_matching_meshes():
    """𝓕 = 5 on matching meshes (mortar weights δ): every slave node sticks from the first
    step, so the bodies are glued where they met: the solution of the tied bodies."""
    mesh = slider_mesh(n_slider=4, n_block=12)  # the slider's nodes on the block's
    times = [0.5, 1.0, 1.5, 2.0]
    sols = df.solve_path(lambda t: slid(mesh, t, df.Coulomb(5.0)), times, **OPTS)
    check_stuck_as_tied(sols, df.solve(slid(mesh, times[-1], None, tied=True), rtol=1e-12,
                                       newton_rtol=1e-10, method="fetidp"), 5.0)


def test_full_stick_keeps_the_material_master_points(slider):
    """𝓕 = 5, non-matching meshes, a tangential load far below 𝓕N: no slip in any step, and
    at the end every slave node is where the master material it started on went: the
    relative tangential displacement of the mortar nodes is below 1e-6 × the top's travel
    0.1."""
    sols = df.solve_path(lambda t: slid(slider, t, df.Coulomb(5.0)), [0.5, 1.0, 1.5, 2.0],
                         **OPTS)
    assert all(s.report.converged for s in sols)
    for s in sols:
        assert np.all(s.contact.state == 1)
        check_coulomb(s, 5.0)
    fx, fy = sols[-1].total_contact_force
    assert 0.05 < abs(fx / fy) < 1.0  # a real tangential load, below 𝓕
    # measured 1.5e-8, the same at newton_rtol 1e-11 (not the solver's tolerance): the
    # weights of the deformed surfaces change along the path, so the steps' stuck
    # increments, each with its own weights, add up to the total with the last weights
    # only to second order; a slide would give 1e-1 here
    rel = relative_tangential(slider, sols[-1])
    assert np.abs(rel).max() < 1e-6 * 0.1, rel


@pytest.mark.parametrize("coefficient", (0.2, 0.3))
def test_gross_sliding_force_ratio_is_the_coefficient(slider, coefficient):
    """Coulomb, the block's top held flat, the slider slid 0.1 per step over several
    master elements (0.3 wide): every slave node slips, the friction over the normal forces
    is 𝓕 to solver tolerance (−F_x/F_y within 1 %: the normals lean at the lifting rear
    rim), the top's force balances the contact force at every step, the slider has slid."""
    times = [0.5, 1.0, 2.0, 3.0, 4.0, 5.0]
    sols = df.solve_path(lambda t: slid(slider, t, df.Coulomb(coefficient, rtol=1e-10),
                                        flat=True), times, **OPTS)
    assert all(s.report.converged for s in sols)
    for s in sols:
        f = s.total_contact_force  # on the slider
        assert np.abs(top_force(s) + f).max() < 1e-8 * abs(f[1])
        check_coulomb(s, coefficient)
    for s in sols[3:]:  # from a travel of 0.2 on
        assert np.all(s.contact.state == 2)
        c = s.contact
        q = np.linalg.norm(c.tangential_force, axis=1)
        assert abs(q.sum() / c.force.sum() - coefficient) < 1e-8
        # the slider's rear rim lifts: the averaged slave normals next to it lean
        fx, fy = s.total_contact_force
        assert abs(-fx / fy - coefficient) < 1e-2 * coefficient
        assert max(h["iteration"] for h in s.report.extra["newton"]) < 10
    U = sols[-1].nodal_values()
    bottom = np.unique(slider.facets(PAIR[0]))
    top = np.unique(slider.facets(PAIR[1]))
    assert U[bottom, 0].min() > 0.3  # slid over more than one master element (0.3)
    assert U[top, 0].max() < 0.1  # the block was dragged, not carried


def test_gross_sliding_under_tresca(slider):
    """Tresca's bound g: the slider's friction force is g times its width (1) in every
    sliding step, every slave node slips."""
    g = 0.1
    sols = df.solve_path(lambda t: slid(slider, t, df.Tresca(g), flat=True),
                         [0.5, 1.0, 2.0, 3.0, 4.0], **OPTS)
    assert all(s.report.converged for s in sols)
    for s in sols[2:]:
        check_tresca_sliding(s, g)  # the friction residuals of the rows of u itself too


def test_small_loads_tend_to_the_linear_mortar_friction(slider):
    """Coulomb 𝓕 = 0.3, the slider's top moved by (δ, −δ) in one step (partial slip): the
    difference to the small-deformation mortar friction solution (``df.Elasticity``, checked
    against a monolithic solve in test_mortar_friction.py) grows like δ² (× 4 per doubling),
    the stick/slip states equal."""
    def problem(d, material):
        return df.ContactProblem(
            slider, material,
            dirichlet=[df.Dirichlet("lower_bottom"), df.Dirichlet("upper_top", (d, -d))],
            contact=[df.Mortar(*PAIR, friction=df.Coulomb(0.3, rtol=1e-12, max_steps=200))],
            decomposition=df.ByTags())

    ratios = small_load_ratios(problem, 0.3, E, NU)
    assert np.all(np.abs(ratios - 4.0) < 0.1), ratios


def rotated(mesh, t: float, step: float, friction) -> df.ContactProblem:
    """Pressed for t <= 1, then the whole pressed state turned rigidly about (1.5, 1) by
    (t − 1)·``step`` (the block's bottom and the slider's top by their Dirichlet conditions)."""
    angle = max(t - 1.0, 0.0) * step
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    centre = np.array([1.5, 1.0])
    press = np.array([0.0, -min(t, 1.0) * PRESS])

    def turned(shift):
        return lambda x: (x[:, :2] + shift - centre) @ R.T + centre - x[:, :2]

    return df.ContactProblem(
        mesh, df.NeoHookean(E, NU),
        dirichlet=[df.Dirichlet("lower_bottom", turned(0.0)),
                   df.Dirichlet("upper_top", turned(press))],
        contact=[df.Mortar(*PAIR, friction=friction)], decomposition=df.ByTags())


@pytest.mark.parametrize("coefficient", (5.0, 0.3))
def test_a_rigid_rotation_gives_no_slip_to_second_order(slider, coefficient):
    """The pressed pair (all stuck at 𝓕 = 5, partial slip at 0.3) turned rigidly in three
    steps: the exact answer is the pressed state turned, and the slip measure is objective up
    to the square of each step's rotation (drivers/mortar_friction.py): the positions and the
    contact force differ from the turned pressed state by at most 1e-6 of the displacement,
    ×4 (within 0.5) when the step's angle doubles; the stick/slip states stay those of the
    pressing."""
    errors = []
    for step in (0.05, 0.1):
        sols = df.solve_path(lambda t, step=step: rotated(slider, t, step, df.Coulomb(
            coefficient, rtol=1e-10)), [0.5, 1.0, 2.0, 3.0, 4.0], **OPTS)
        assert all(s.report.converged for s in sols)
        pressed, last = sols[1], sols[-1]
        angle = 3 * step
        R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        X = slider.x[:, :2]
        expected = (X + pressed.nodal_values() - [1.5, 1.0]) @ R.T + [1.5, 1.0]
        U = last.nodal_values()
        err = np.abs(X + U - expected).max()
        force = np.abs(R @ pressed.total_contact_force - last.total_contact_force).max()
        assert err < 1e-6 * np.abs(U).max() and force < 1e-6 * abs(last.total_contact_force[1])
        assert np.array_equal(last.contact.state, pressed.contact.state)
        check_coulomb(last, coefficient)
        errors.append(err)
    assert abs(errors[1] / errors[0] - 4.0) < 0.5, errors


def test_derivatives_with_friction_refused_by_name(slider):
    """The rows' derivatives with friction are refused by name."""
    with pytest.raises(InputError, match="newton_mortar_derivatives=True"):
        df.solve(slid(slider, 1.0, df.Coulomb(0.3)), newton_mortar_derivatives=True, **OPTS)
