"""Friction under Newton: a neo-Hookean block pressed onto a rigid plane, then sheared.

The friction rows act on the slip increment of each load step in the current configuration
(drivers/newton_friction.py). Checked against what does not come from the friction code:

- full stick (𝓕 large): the block with its bottom clamped (a Dirichlet condition, no contact),
  solved by the same Newton driver, is the exact answer; also when the plane itself slides
  (the nodes stuck to it move with it);
- gross sliding (𝓕 small): every node slips and the tangential over the normal force is 𝓕
  (Coulomb) or the tangential force is the Tresca bound times the width;
- small loads: the Newton solution tends to the linear (small-deformation) Coulomb solution
  like the load squared;
- the Coulomb conditions from the returned contact data (tests/support/coulomb_kkt.py).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from coulomb_kkt import check_coulomb, check_tresca_sliding
from element_models import rectangle
from mpi4py import MPI
from newton_small_loads import small_load_ratios
from path_files import check_xdmf_series

import dolfinx_feti as df
from dolfinx_feti.io.meshes_rubber import ironing_block

E, NU, LX = 10.0, 0.3, 2.0
PRESS = 0.1  # the top's downward travel (10 % of the height)
OPTS = {"rtol": 1e-11, "newton_rtol": 1e-9, "method": "fetidp", "progress": False}


@pytest.fixture(scope="module")
def block():
    return df.build_mesh(rectangle, h=0.3, gdim=2, lx=LX)


def sheared(mesh, t: float, friction, plane_shift: float = 0.0, top_shift: float = 1.0,
            decomposition=None) -> df.ContactProblem:
    """Pressed by the top for t <= 1, then sheared: the top moved by (t − 1)·0.1·top_shift,
    the plane by (t − 1)·0.1·plane_shift."""
    press = min(t, 1.0) * PRESS
    shear = max(t - 1.0, 0.0) * 0.1
    return df.ContactProblem(
        mesh, df.NeoHookean(E, NU),
        dirichlet=[df.Dirichlet("top", (top_shift * shear, -press))],
        contact=[df.RigidObstacle("bottom", df.Plane((plane_shift * shear, 0.0), (0.0, 1.0)),
                                  friction=friction)],
        decomposition=decomposition or df.ByTags())


def clamped(mesh, t: float, plane_shift: float = 0.0, top_shift: float = 1.0):
    """The same block with its bottom held where the plane took it (no contact)."""
    shear = max(t - 1.0, 0.0) * 0.1
    return df.ContactProblem(
        mesh, df.NeoHookean(E, NU),
        dirichlet=[df.Dirichlet("top", (top_shift * shear, -min(t, 1.0) * PRESS)),
                   df.Dirichlet("bottom", (plane_shift * shear, 0.0))],
        decomposition=df.ByTags())


@pytest.mark.parametrize("plane_shift, top_shift", [(0.0, 1.0), (1.0, 0.0)])
def test_full_stick_equals_the_clamped_block(block, plane_shift, top_shift):
    """𝓕 = 2: every node sticks, so the bottom stays where the plane took it: the solution is
    the clamped block's. With the plane sliding under a held top, the nodes go with it."""
    times = [0.5, 1.0, 1.5, 2.0]
    sols = df.solve_path(lambda t: sheared(block, t, df.Coulomb(2.0), plane_shift, top_shift),
                         times, **OPTS)
    assert all(s.report.converged for s in sols)
    ref = df.solve(clamped(block, times[-1], plane_shift, top_shift), rtol=1e-12,
                   newton_rtol=1e-10, method="fetidp")
    assert ref.report.converged
    sol = sols[-1]
    c = sol.contact
    assert np.all(c.state == 1), c.state  # every node sticks
    fx, fy = sol.total_contact_force
    assert fy > 0 and 0.05 < abs(fx) / fy < 2.0  # sheared, below 𝓕N
    U, Ur = sol.nodal_values(), ref.nodal_values()
    assert np.abs(U - Ur).max() < 1e-8 * np.abs(Ur).max()
    bottom = np.abs(sol.problem.mesh.x[:, 1]) < 1e-12
    assert np.abs(U[bottom, 0] - plane_shift * 0.1).max() < 1e-9
    check_coulomb(sol, 2.0)
    assert sol.report.kkt["equilibrium"] < 1e-8


@pytest.mark.parametrize("parts", (1, 2))
def test_gross_sliding_force_ratio_is_the_coefficient(block, parts):
    """𝓕 = 0.2, the top sheared far: every node slips, −F_x / F_y = 𝓕 to solver tolerance."""
    dec = df.ByTags() if parts == 1 else df.Parts(2)
    # the fixed point's tolerance below the per-node check's 1e-7 (its default is 1e-6)
    sols = df.solve_path(lambda t: sheared(block, t, df.Coulomb(0.2, rtol=1e-9),
                                           decomposition=dec), [0.5, 1.0, 2.0, 3.0], **OPTS)
    assert all(s.report.converged for s in sols)
    sol = sols[-1]
    assert np.all(sol.contact.state[sol.contact.force > 0] == 2)
    fx, fy = sol.total_contact_force
    assert abs(-fx / fy - 0.2) < 1e-8
    check_coulomb(sol, 0.2)
    # quadratic convergence on a plane
    r = [h["residual"] for h in sol.report.extra["newton"]]
    assert all(r1 <= 10 * r0 ** 2 for r0, r1 in zip(r, r[1:], strict=False) if r1 > 1e-12), r


def test_gross_sliding_under_tresca(block):
    """Tresca's bound g: the sliding block's tangential force is g times the width."""
    g = 0.3
    sols = df.solve_path(lambda t: sheared(block, t, df.Tresca(g)), [0.5, 1.0, 2.0, 3.0],
                         **OPTS)
    check_tresca_sliding(sols[-1], g * LX)


def test_small_loads_tend_to_the_linear_coulomb_solution(block):
    """u_NH(δ) − u_lin(δ) = O(δ²) with Coulomb friction (partial slip) in one step."""
    def problem(d, material):
        return df.ContactProblem(
            block, material, dirichlet=[df.Dirichlet("top", (0.5 * d, -d))],
            contact=[df.RigidObstacle("bottom", df.Plane((0.0, 0.0), (0.0, 1.0)),
                                      friction=df.Coulomb(0.3, rtol=1e-12, max_steps=200))],
            decomposition=df.ByTags())

    ratios = small_load_ratios(problem, 0.3, E, NU)
    assert np.all(np.abs(ratios - 4.0) < 0.1), ratios


def test_path_output_of_a_newton_path(block, tmp_path_factory):
    """solve_path writes the XDMF time series and the JSON history (with the Newton history
    per step) of a hyperelastic path, as of a small-deformation one."""
    comm = MPI.COMM_WORLD
    folder = comm.bcast(tmp_path_factory.mktemp("newton_path") if comm.rank == 0 else None)
    times = [0.5, 1.0, 2.0]
    sols = df.solve_path(lambda t: sheared(block, t, df.Coulomb(0.2)), times,
                         xdmf=folder / "path.xdmf", history=folder / "history.json", **OPTS)
    assert all(s.report.converged for s in sols)
    if comm.rank == 0:
        steps = json.loads((folder / "history.json").read_text())["steps"]
        assert [s["time"] for s in steps] == times
        for s, sol in zip(steps, sols, strict=True):
            assert s["newton_iterations"] == len(sol.report.extra["newton"]) >= 1
            assert [h["residual"] for h in s["newton"]] == \
                [h["residual"] for h in sol.report.extra["newton"]]
            assert s["newton"][-1]["residual"] <= 1e-9
            assert s["hessian_mults"] == sol.report.hessian_mults
            assert np.allclose(s["contact_force"], sol.total_contact_force)
            assert s["stick_nodes"] + s["slip_nodes"] == sol.contact.force.size
            assert s["cutbacks"] == 0 and s["substeps"] == [s["time"]]
        check_xdmf_series(folder, len(times))
    comm.barrier()


def test_a_rigid_die_pressed_and_slid():
    """A rigid disc die pressed into the block and slid along it (a small ironing problem,
    bench/ironing.py): the tangents turn with the die's normals, the slip is taken relative
    to the moving die. The Coulomb conditions hold at every step, and while it slides the die
    drags the surface along (the friction force on the block points in its direction)."""
    mesh = df.build_mesh(ironing_block, lx=6.0, ly=2.0, h_top=0.25, h_far=0.5, gdim=2)
    R, depth = 1.0, 0.3

    def problem(t):
        x = 2.0 + max(t - 1.0, 0.0) * 0.5
        return df.ContactProblem(
            mesh, df.NeoHookean(1.0, NU), dirichlet=[df.Dirichlet("bottom")],
            contact=[df.RigidObstacle("top", df.Sphere((x, 2.0 + R - min(t, 1.0) * depth), R),
                                      friction=df.Coulomb(0.3, rtol=1e-10, max_steps=200))],
            decomposition=df.Parts(2))

    sols = df.solve_path(problem, [0.5, 1.0, 1.04, 1.08], **OPTS)
    assert all(s.report.converged for s in sols)
    for sol in sols:
        check_coulomb(sol, 0.3)
    for sol in sols[2:]:
        c = sol.contact
        assert np.count_nonzero(c.state[c.force > 0] == 2) > 0
        assert c.tangential_force[:, 0].sum() > 0.05 * c.force.sum()
