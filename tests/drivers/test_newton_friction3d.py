"""Friction under Newton in 3D: a neo-Hookean box pressed onto a rigid plane, then slid.

The tangential rows of the two tangents act on the slip increment of each load step
(drivers/newton_friction.py); the slip bounds are discs. Checked against what does not come
from the friction code:

- full stick (𝓕 large): the box with its bottom clamped where the plane took it (a Dirichlet
  condition, no contact) is the exact answer;
- gross sliding at an angle to the axes: once the sliding is steady (the slip increments of a
  step all parallel), the friction force over the normal force is 𝓕 in both tangential
  directions, antiparallel to the slide (Coulomb), or the Tresca bound times the area;
- small loads: the Newton solution tends to the linear (small-deformation) Coulomb solution
  like the load squared;
- Newton converges quadratically near the solution (Tresca, stick: a plane's tangents do not
  turn).
"""

from __future__ import annotations

import numpy as np
import pytest
from coulomb_kkt import check_coulomb
from element_models import box
from newton_small_loads import small_load_ratios

import dolfinx_feti as df

E, NU = 10.0, 0.3
PRESS = 0.1  # the top's downward travel (10 % of the height)
OPTS = {"rtol": 1e-11, "newton_rtol": 1e-9, "method": "fetidp", "progress": False}
#: The slide at 30° to x: t = 1 pressed, then per unit of t a slide of 0.1; the steps after
#: t = 2 slide 1.0 each (steady sliding is reached geometrically, ~10× per such step).
ANGLE = np.deg2rad(30.0)
SLIDE_TIMES = [0.5, 1.0, 2.0] + [2.0 + 10.0 * k for k in range(1, 8)]


@pytest.fixture(scope="module")
def cube():
    return df.build_mesh(box, h=0.5, gdim=3)


def slid(mesh, t: float, friction, angle: float = ANGLE) -> df.ContactProblem:
    """The top pressed down by PRESS·min(t, 1), then moved by (t − 1)·0.1 along the angle."""
    s = max(t - 1.0, 0.0) * 0.1
    return df.ContactProblem(
        mesh, df.NeoHookean(E, NU),
        dirichlet=[df.Dirichlet("z1", (s * np.cos(angle), s * np.sin(angle),
                                       -min(t, 1.0) * PRESS))],
        contact=[df.RigidObstacle("z0", df.Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
                                  friction=friction)],
        decomposition=df.Parts(2))


def quadratic(sol) -> None:
    """r_{k+1} <= 10 r_k² down to 1e-10, below which the residual is the QPs' accuracy (rtol
    1e-11 of the total displacement)."""
    r = [h["residual"] for h in sol.report.extra["newton"]]
    assert all(r1 <= 10 * r0 ** 2 for r0, r1 in zip(r, r[1:], strict=False) if r1 > 1e-10), r


def test_full_stick_equals_the_clamped_box(cube):
    """𝓕 = 5: every node sticks from the first touch (the bottom lies on the plane), so the
    bottom stays where it was while the box is pressed and slid at an angle: the solution is
    that of the box with its bottom clamped (no contact)."""
    times = [0.5, 1.0, 1.5, 2.0]
    sols = df.solve_path(lambda t: slid(cube, t, df.Coulomb(5.0)), times, **OPTS)
    assert all(s.report.converged for s in sols)
    s = 1.0 * 0.1
    ref = df.solve(df.ContactProblem(
        cube, df.NeoHookean(E, NU),
        dirichlet=[df.Dirichlet("z1", (s * np.cos(ANGLE), s * np.sin(ANGLE), -PRESS)),
                   df.Dirichlet("z0", (0.0, 0.0, 0.0))],
        decomposition=df.Parts(2)), rtol=1e-12, newton_rtol=1e-10, method="fetidp")
    assert ref.report.converged
    sol = sols[-1]
    c = sol.contact
    assert np.all(c.state[c.force > 0] == 1)  # a node without normal force has no bound
    F = sol.total_contact_force
    assert F[2] > 0 and 0.05 < np.hypot(F[0], F[1]) / F[2] < 2.0  # slid, below 𝓕N
    U, Ur = sol.nodal_values(), ref.nodal_values()
    assert np.abs(U - Ur).max() < 1e-8 * np.abs(Ur).max()
    check_coulomb(sol, 5.0)
    for s in sols:
        quadratic(s)


def test_gross_sliding_at_an_angle_under_coulomb(cube):
    """𝓕 = 0.2, the top slid at 30° far beyond the stick limit: every node slips, and once the
    sliding is steady F_x / F_z = −𝓕 cos 30°, F_y / F_z = −𝓕 sin 30° to 1e-8."""
    f = 0.2
    sols = df.solve_path(lambda t: slid(cube, t, df.Coulomb(f, rtol=1e-12, max_steps=200)),
                         SLIDE_TIMES, **OPTS)
    assert all(s.report.converged for s in sols)
    sol = sols[-1]
    c = sol.contact
    assert np.all(c.state[c.force > 0] == 2)
    F = sol.total_contact_force
    assert np.abs(F[:2] / F[2] + f * np.array([np.cos(ANGLE), np.sin(ANGLE)])).max() < 1e-8
    check_coulomb(sol, f, 1e-9)
    # the slip of the last step along the slide
    s = c.slip[c.force > 0]
    d = np.array([np.cos(ANGLE), np.sin(ANGLE), 0.0])
    assert np.abs(s / np.linalg.norm(s, axis=1)[:, None] - d).max() < 1e-6


def test_gross_sliding_under_tresca(cube):
    """Tresca's bound g: the steadily sliding box's friction force is g times the area,
    opposite to the slide, and Newton converges quadratically."""
    g = 0.3
    sols = df.solve_path(lambda t: slid(cube, t, df.Tresca(g)), SLIDE_TIMES, **OPTS)
    assert all(s.report.converged for s in sols)
    sol = sols[-1]
    assert np.all(sol.contact.state == 2)
    F = sol.total_contact_force
    assert np.abs(F[:2] + g * np.array([np.cos(ANGLE), np.sin(ANGLE)])).max() < 1e-8 * g
    assert sol.report.kkt["friction_feasibility"] < 1e-10
    assert sol.report.kkt["friction_complementarity"] < 1e-8
    for s in sols:
        quadratic(s)


def test_small_loads_tend_to_the_linear_coulomb_solution(cube):
    """u_NH(δ) − u_lin(δ) = O(δ²) with Coulomb friction (partial slip) in one step."""
    def problem(d, material):
        return df.ContactProblem(
            cube, material, dirichlet=[df.Dirichlet("z1", (0.5 * d, 0.2 * d, -d))],
            contact=[df.RigidObstacle("z0", df.Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
                                      friction=df.Coulomb(0.3, rtol=1e-12, max_steps=200))],
            decomposition=df.Parts(2))

    ratios = small_load_ratios(problem, 0.3, E, NU)
    assert np.all(np.abs(ratios - 4.0) < 0.1), ratios
