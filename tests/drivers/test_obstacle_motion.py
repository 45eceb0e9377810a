"""Rigid obstacles that turn: friction against the material point of the obstacle's surface.

A :class:`~dolfinx_feti.RigidMotion` (centre, angle) per step of a load path makes the slip
increment of a contact node relative to where the obstacle's surface point went
(drivers/obstacle_motion.py). Checked against mechanics the friction code does not encode:

- a rigid disc pressed onto the block and spun in place: its surface moves, its gaps do not;
  once every contact node slips, the friction force on each node is 𝓕·p along the disc's
  surface velocity ω × (y − c) (the disc drags the block's surface), so the friction torque
  about the centre is 𝓕 Σ p |y − c| (a global balance the rows do not hold), small
  deformation and Newton; in 3D a ball spun about a horizontal axis: torque about the axis
  𝓕 Σ p ρ (ρ the distance from the axis);
- a disc rolling without slip (its translation = radius × the angle it turned), with high
  friction: the block's surface under it sticks and the net tangential force stays near zero
  (free rolling), where the same translation without rotation drags the surface (sliding);
- a disc translated without rotation gives today's result (no motion: the obstacle's
  translation) to round-off.
"""

from __future__ import annotations

import numpy as np
import pytest
from coulomb_kkt import coulomb_violations
from element_models import box
from scipy.spatial.transform import Rotation

import dolfinx_feti as df
from dolfinx_feti.io.meshes_rubber import ironing_block

R, DEPTH, F = 1.0, 0.2, 0.3
CENTER = (3.0, 2.0 + R)
OPTS = {"rtol": 1e-11, "method": "fetidp", "progress": False}


@pytest.fixture(scope="module")
def block():
    return df.build_mesh(ironing_block, lx=6.0, ly=2.0, h_top=0.1, h_far=0.5, gdim=2)


def spun(mesh, t: float, material, center=CENTER, angle_rate: float = 0.5):
    """The block pushed up by DEPTH·min(t, 1) into a fixed disc, which then turns by
    (t − 1)·angle_rate (counter-clockwise)."""
    return df.ContactProblem(
        mesh, material, dirichlet=[df.Dirichlet("bottom", (0.0, DEPTH * min(t, 1.0)))],
        contact=[df.RigidObstacle(
            "top", df.Sphere(center, R), friction=df.Coulomb(F, rtol=1e-10, max_steps=200),
            motion=df.RigidMotion(center, max(t - 1.0, 0.0) * angle_rate))],
        decomposition=df.Parts(2))


def positions(sol, act):
    """The contact nodes' positions: reference (small deformation) or current (Newton)."""
    c = sol.contact
    y = c.x[act, :sol.problem.mesh.gdim]
    if sol.report.extra.get("newton") is not None:
        y = y + sol.nodal_values()[c.node[act]]
    return y


def check_spinning(sol, center, omega, step: float) -> None:
    """Every loaded node slips; q = 𝓕 p along the tangential part of the step's chord of the
    disc's surface point, (R(ω step) − I)(y − c) (2D: along ω × (y − c)); 2D: the torque
    about c is 𝓕 Σ p |y − c|."""
    c = sol.contact
    act = c.force > 0
    assert np.count_nonzero(act) >= 5
    assert np.all(c.state[act] == 2), c.state[act]
    r = positions(sol, act) - np.asarray(center)
    p, q = c.force[act], c.tangential_force[act]
    if r.shape[1] == 2:
        v = np.c_[-r[:, 1], r[:, 0]] * np.sign(omega)
        torque = np.sum(r[:, 0] * q[:, 1] - r[:, 1] * q[:, 0]) * np.sign(omega)
        ref = F * np.sum(p * np.linalg.norm(r, axis=1))
        assert abs(torque - ref) < 1e-8 * ref
    else:
        v = Rotation.from_rotvec(step * np.asarray(omega, dtype=float)).apply(r) - r
        n = c.normal[act]
        v -= np.einsum("ij,ij->i", v, n)[:, None] * n
    v /= np.linalg.norm(v, axis=1)[:, None]
    assert np.abs(q - F * p[:, None] * v).max() < 1e-8 * p.max()
    v = coulomb_violations(sol, F)
    assert max(v.values()) < 1e-8, v


@pytest.mark.parametrize("material", ["linear", "neo-hookean"])
def test_a_disc_spun_in_place_drags_the_surface(block, material):
    mat = df.Elasticity(1.0, 0.3) if material == "linear" else df.NeoHookean(1.0, 0.3)
    opts = OPTS if material == "linear" else {**OPTS, "newton_rtol": 1e-9}
    # turned by 0.5 twice, then back twice: the drag reverses
    sols = df.solve_path(lambda t: spun(block, t if t <= 3.0 else 6.0 - t, mat),
                         [0.5, 1.0, 2.0, 3.0, 4.0, 5.0], **opts)
    assert all(s.report.converged for s in sols)
    check_spinning(sols[3], CENTER, 1.0, 0.5)
    check_spinning(sols[5], CENTER, -1.0, 0.5)


def test_a_ball_spun_in_place_in_3d():
    """A ball pressed into the unit cube's top and spun about an axis along y, 0.5 rad a
    step."""
    cube = df.build_mesh(box, h=0.2, gdim=3)
    center, radius, axis = (0.5, 0.5, 1.0 + 0.8), 0.8, (0.0, 1.0, 0.0)

    def problem(t):
        return df.ContactProblem(
            cube, df.Elasticity(1.0, 0.3),
            dirichlet=[df.Dirichlet("z0", (0.0, 0.0, 0.08 * min(t, 1.0)))],
            contact=[df.RigidObstacle(
                "z1", df.Sphere(center, radius),
                friction=df.Coulomb(F, rtol=1e-10, max_steps=200),
                motion=df.RigidMotion(center, max(t - 1.0, 0.0) * 0.5, axis=axis))],
            decomposition=df.Parts(2))

    # the body's own increment dies out ~10× per step: then the slip is the chord's
    sols = df.solve_path(problem, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0], **OPTS)
    assert all(s.report.converged for s in sols)
    check_spinning(sols[-1], center, np.asarray(axis), 0.5)


def rolled(mesh, t: float, mode: str, coefficient: float = 2.0):
    """Pressed for t <= 1, then the disc's centre moved by (t − 1)·0.1 along x, turning by
    −(t − 1)·0.1/R (rolling), not turning (sliding), or without a motion (today's rule)."""
    s = max(t - 1.0, 0.0) * 0.1
    c = (2.5 + s, 2.0 + R)
    motion = None if mode == "none" else df.RigidMotion(c, -s / R if mode == "roll" else 0.0)
    return df.ContactProblem(
        mesh, df.NeoHookean(1.0, 0.3),
        dirichlet=[df.Dirichlet("bottom", (0.0, DEPTH * min(t, 1.0)))],
        contact=[df.RigidObstacle("top", df.Sphere(c, R),
                                  friction=df.Coulomb(coefficient, rtol=1e-10, max_steps=200),
                                  motion=motion)],
        decomposition=df.Parts(2))


def test_a_rolling_disc_leaves_the_surface_stuck():
    """Rolling without slip (high friction): the loaded nodes stick and the net tangential
    force stays within 2 % of the normal force, while the same translation without rotation
    drags it to more than half of it. Translated without rotation = no motion given."""
    block = df.build_mesh(ironing_block, lx=6.0, ly=2.0, h_top=0.2, h_far=0.5, gdim=2)
    times = [0.5, 1.0, 2.0, 3.0]
    opts = {**OPTS, "newton_rtol": 1e-9}
    roll = df.solve_path(lambda t: rolled(block, t, "roll"), times, **opts)
    slide = df.solve_path(lambda t: rolled(block, t, "slide"), times, **opts)
    plain = df.solve_path(lambda t: rolled(block, t, "none"), times, **opts)
    assert all(s.report.converged for s in roll + slide + plain)
    for sol in roll[2:]:
        c = sol.contact
        act = c.force > 0
        assert np.all(c.state[act] == 1)
        assert abs(c.tangential_force[act, 0].sum()) < 0.02 * c.force.sum()
        assert max(coulomb_violations(sol, 2.0).values()) < 1e-8
    c = slide[-1].contact
    assert c.tangential_force[:, 0].sum() > 0.5 * c.force.sum()
    U, Up = slide[-1].nodal_values(), plain[-1].nodal_values()
    assert np.abs(U - Up).max() < 1e-12 * np.abs(Up).max()


def test_motion_input_errors(block):
    with pytest.raises(df.InputError, match="RigidMotion.center"):
        df.RigidMotion("origin", 0.1)
    with pytest.raises(df.InputError, match="RigidMotion.angle"):
        df.RigidMotion((0.0, 0.0), float("nan"))
    with pytest.raises(df.InputError, match="RigidMotion.axis"):
        df.RigidMotion((0.0, 0.0, 0.0), 0.1, axis=(0.0, 0.0, 0.0))
    with pytest.raises(df.InputError, match="motion must be None or RigidMotion"):
        df.RigidObstacle("top", df.Sphere(CENTER, R), motion=(0.0, 0.1))
    bad = [df.RigidMotion((3.0, 3.0, 0.0), 0.1, axis=(0, 0, 1)),
           df.RigidMotion(CENTER, 0.1, axis=(0, 0, 1))]
    for motion, words in zip(bad, ["has 3 coordinates", "give no axis"], strict=True):
        with pytest.raises(df.InputError, match=words):
            df.ContactProblem(
                block, df.Elasticity(1.0, 0.3), dirichlet=[df.Dirichlet("bottom")],
                contact=[df.RigidObstacle("top", df.Sphere(CENTER, R), friction=df.Tresca(0.1),
                                          motion=motion)])
    cube = df.build_mesh(box, h=0.5, gdim=3)
    with pytest.raises(df.InputError, match="needs its axis"):
        df.ContactProblem(
            cube, df.Elasticity(1.0, 0.3), dirichlet=[df.Dirichlet("z0")],
            contact=[df.RigidObstacle("z1", df.Sphere((0.5, 0.5, 2.0), 1.0),
                                      motion=df.RigidMotion((0.5, 0.5, 2.0), 0.1))])

    def half(t):  # a motion at the first step only
        p = spun(block, t, df.Elasticity(1.0, 0.3))
        if t > 1.0:
            c = p.contact[0]
            p = df.ContactProblem(p.mesh, p.forms, dirichlet=p.dirichlet,
                                  contact=[df.RigidObstacle(c.group, c.obstacle, c.friction)],
                                  decomposition=p.decomposition)
        return p

    with pytest.raises(df.InputError, match="motion given at one step"):
        df.solve_path(half, [1.0, 2.0], **OPTS)
