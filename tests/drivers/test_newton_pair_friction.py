"""Friction on node-to-node pairs under Newton: a neo-Hookean block pressed on another, sheared.

Two blocks meshed apart with matching nodes on their common side (``stacked_blocks``); the
lower one held at its bottom, the upper one moved at its top. The tangential rows act on the
slip of the slave node relative to its master node in each load step, in the tangents of the
deformed master surface (drivers/newton_friction.py). Checked against what does not come from
the friction code:

- full stick (𝓕 large): the two blocks glued (``df.Tie``, the same Newton driver) are the
  exact answer;
- gross sliding: with the master surface held flat (its vertical motion only; it is carried
  sideways by the lower block's shear) the tangential over the normal force is 𝓕 (Coulomb),
  or the tangential force is Tresca's bound times the width, and the forces at the upper
  block's top balance the contact forces at every step;
- small loads: the Newton solution tends to the small-deformation (``df.Elasticity``) pair
  friction solution like the load squared, with the same stick/slip states;
- the Coulomb conditions from the returned contact data (tests/support/coulomb_kkt.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from coulomb_kkt import (
    check_coulomb,
    check_stuck_as_tied,
    check_tresca_sliding,
    dirichlet_force,
)
from element_models import stacked_blocks
from mpi4py import MPI
from newton_small_loads import small_load_ratios

import dolfinx_feti as df
from dolfinx_feti.drivers.newton import check_newton_problem

E, NU, LX = 10.0, 0.3, 2.0
PRESS = 0.1  # the top's downward travel (5 % of the stack's height)
OPTS = {"rtol": 1e-11, "newton_rtol": 1e-9, "method": "fetidp", "progress": False}


@pytest.fixture(scope="module")
def stack():
    return df.build_mesh(stacked_blocks, gdim=2)


def sheared(mesh, t: float, friction, flat: bool = False, tied: bool = False,
            decomposition=None) -> df.ContactProblem:
    """Pressed by the top for t <= 1, then its top moved sideways by (t − 1)·0.1.

    ``flat``: the lower block's top held vertically (it moves sideways with the lower block);
    ``tied``: the blocks glued instead of in contact.
    """
    shear = max(t - 1.0, 0.0) * 0.1
    dirichlet = [df.Dirichlet("bottom"), df.Dirichlet("top", (shear, -min(t, 1.0) * PRESS))]
    if flat:
        dirichlet.append(df.Dirichlet("lower_top", 0.0, components=[1]))
    pair = ("upper_bottom", "lower_top")
    return df.ContactProblem(
        mesh, df.NeoHookean(E, NU), dirichlet=dirichlet,
        contact=[] if tied else [df.NodeToNode(*pair, friction=friction)],
        ties=[df.Tie(*pair)] if tied else [],
        decomposition=decomposition or df.ByTags())


def top_force(sol) -> np.ndarray:
    """The force of the top's Dirichlet condition on the upper block (y = 2)."""
    return dirichlet_force(sol, lambda x: np.isclose(x[:, 1], 2.0), MPI.COMM_WORLD)


def test_full_stick_equals_the_tied_blocks(stack):
    """𝓕 = 5: every pair sticks from the first step on, so the blocks are glued where they
    met: the solution of the tied blocks."""
    times = [0.5, 1.0, 1.5, 2.0]
    sols = df.solve_path(lambda t: sheared(stack, t, df.Coulomb(5.0)), times, **OPTS)
    check_stuck_as_tied(sols, df.solve(sheared(stack, times[-1], None, tied=True), rtol=1e-12,
                                       newton_rtol=1e-10, method="fetidp"), 5.0)


@pytest.mark.parametrize("parts", (1, 2))
def test_gross_sliding_force_ratio_is_the_coefficient(stack, parts):
    """𝓕 = 0.2, the master surface held flat, the top sheared far: every pair slips, the
    friction over the normal force is 𝓕 to solver tolerance, the top's force balances the
    contact force at every step, and the lower block's top is dragged along."""
    dec = df.ByTags() if parts == 1 else df.Parts(2)
    sols = df.solve_path(lambda t: sheared(stack, t, df.Coulomb(0.2, rtol=1e-10), flat=True,
                                           decomposition=dec), [0.5, 1.0, 2.0, 3.0], **OPTS)
    assert all(s.report.converged for s in sols)
    for s in sols:
        f = s.total_contact_force  # on the upper block
        assert np.abs(top_force(s) + f).max() < 1e-8 * abs(f[1])
        check_coulomb(s, 0.2)
    sol = sols[-1]
    assert np.all(sol.contact.state == 2)
    fx, fy = sol.total_contact_force
    assert abs(-fx / fy - 0.2) < 1e-8
    U = sol.nodal_values()
    lower_top = np.flatnonzero(np.isclose(stack.x[:, 1], 1.0))
    lower_top = lower_top[np.isin(lower_top, sol.contact.partner)]
    assert U[lower_top, 0].min() > 0.05  # the master side moves: slip is relative to it
    # quadratic convergence once the surface is flat
    r = [h["residual"] for h in sol.report.extra["newton"]]
    assert all(r1 <= 10 * r0 ** 2 for r0, r1 in zip(r, r[1:], strict=False) if r1 > 1e-12), r


def test_gross_sliding_under_tresca(stack):
    """Tresca's bound g: the sliding block's friction force is g times the width."""
    g = 0.3
    sols = df.solve_path(lambda t: sheared(stack, t, df.Tresca(g), flat=True),
                         [0.5, 1.0, 2.0, 3.0, 4.0], **OPTS)
    check_tresca_sliding(sols[-1], g * LX)


def test_small_loads_tend_to_the_linear_pair_friction(stack):
    """u_NH(δ) − u_lin(δ) = O(δ²) with Coulomb friction (partial slip) on the pair, the master
    surface free to deform (its normals turn), in one step."""
    def problem(d, material):
        return df.ContactProblem(
            stack, material, dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", (d, -d))],
            contact=[df.NodeToNode("upper_bottom", "lower_top",
                                   friction=df.Coulomb(0.3, rtol=1e-12, max_steps=200))],
            decomposition=df.ByTags())

    ratios = small_load_ratios(problem, 0.3, E, NU)
    assert np.all(np.abs(ratios - 4.0) < 0.1), ratios


def test_sheared_on_a_deforming_master(stack):
    """The lower block free to deform under the pair (its surface's normals turn): pressed,
    then slid into gross sliding; the Coulomb conditions per pair at every step."""
    sols = df.solve_path(lambda t: sheared(stack, t, df.Coulomb(0.2, rtol=1e-10)),
                         [0.5, 1.0, 2.0, 3.0], **OPTS)
    assert all(s.report.converged for s in sols)
    for s in sols:
        check_coulomb(s, 0.2)
        f = s.total_contact_force
        assert np.abs(top_force(s) + f).max() < 1e-8 * abs(f[1])
    c = sols[-1].contact
    assert np.all(c.state == 2)
    assert np.abs(c.normal[:, 0]).max() > 1e-3  # the master surface turned


def test_mortar_with_pair_friction_refused_by_name(stack):
    """Friction on mortar pairs beside friction on node-to-node pairs under Newton is not
    built: refused before any set-up."""
    problem = df.ContactProblem(
        stack, df.NeoHookean(E, NU),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", (0.0, -PRESS))],
        contact=[df.Mortar("upper_bottom", "lower_top", friction=df.Tresca(1.0)),
                 df.NodeToNode("left", "bottom", friction=df.Tresca(1.0))])
    with pytest.raises(df.InputError, match="friction on mortar pairs together"):
        check_newton_problem(problem)
