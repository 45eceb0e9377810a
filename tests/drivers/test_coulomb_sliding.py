"""Coulomb friction near gross sliding and the fixed point's stopping test.

- Cattaneo–Mindlin (the floating disk of tests/drivers/test_friction_cm.py) at Q/(𝓕P) = 0.95
  and 0.99: the stick zone c = a √(1 − Q/(𝓕P)) shrinks to a few elements, the tangential
  equilibrium of the disk becomes nearly singular; the solve converges, the contact forces
  balance the load and the Coulomb conditions hold on the returned solution (checked from its
  contact data, tests/support/coulomb_kkt.py).
- The fixed point cannot stall at the inner tolerance: with zero initial gaps Coulomb's problem
  is positively homogeneous, so the load scaled by 0.2 or 5 must give the scaled solution in the
  same number of fixed-point steps (it took 46 steps instead of 7 when the steps stopped on
  the change of g against the inner solver's dual test).
"""

from __future__ import annotations

import numpy as np
import pytest
from coulomb_kkt import coulomb_violations
from test_friction_cm import A_HERTZ, F, H, P, cattaneo_problem, half_width
from test_mortar import occ_mesh

import dolfinx_feti as df
from dolfinx_feti.io import meshes
from dolfinx_feti.io.meshes_occ import punch_on_block, stacked_blocks

RTOL = 1e-8


@pytest.fixture(scope="module")
def disk_mesh():
    return df.build_mesh(meshes.hertz2d_full, h_contact=H)


@pytest.fixture(scope="module", params=[0.95, 0.99])
def near_sliding(request, disk_mesh):
    ratio = request.param
    Q = ratio * F * P
    return ratio, Q, df.solve(cattaneo_problem(disk_mesh, Q), rtol=RTOL)


def test_near_gross_sliding_converges(near_sliding):
    ratio, Q, sol = near_sliding
    rep = sol.report
    assert rep.converged, rep.summary()
    fr = rep.extra["friction"]
    assert fr["fixed_point_converged"] and fr["fixed_point_steps"] <= 15
    assert fr["coulomb_residual"] <= fr["rtol"]
    assert rep.stopping["test"] == "kkt" and rep.stopping["met"]
    assert rep.kkt["coulomb_bound"] <= fr["rtol"]
    assert np.allclose(sol.total_contact_force, [-Q, P], rtol=0, atol=1e-6 * P)


def test_near_gross_sliding_coulomb_conditions(near_sliding):
    ratio, Q, sol = near_sliding
    v = coulomb_violations(sol, F)
    assert v["bound"] <= 1e-6 and v["slipping"] <= 1e-6, v
    assert v["stick_slip"] <= 1e-6 and v["direction"] <= 1e-6, v


def test_near_gross_sliding_stick_zone(near_sliding):
    ratio, Q, sol = near_sliding
    c = sol.contact
    x = c.x[:, 0]
    stick = c.state == df.ContactData.STICK
    c_theory = A_HERTZ * np.sqrt(1.0 - ratio)
    c_h = half_width(x, stick, H) if np.any(stick) else 0.0
    assert abs(c_h - c_theory) <= 2 * H, (c_h, c_theory)
    slip = (c.force > 1e-8 * c.force.max()) & ~stick
    assert slip.sum() >= 2 * stick.sum()  # nearly all of the contact slips


SHIFT = (0.02, -0.02)


@pytest.fixture(scope="module")
def blocks():
    return occ_mesh(stacked_blocks, 2, 0.1, 0.17)


def blocks_problem(mesh, factor):
    return df.ContactProblem(
        mesh, df.Elasticity(21.19, 0.277),
        dirichlet=[df.Dirichlet("bottom"),
                   df.Dirichlet("top", value=tuple(factor * s for s in SHIFT))],
        contact=[df.Mortar("upper_bottom", "lower_top", friction=df.Coulomb(0.3))],
        decomposition=df.Parts(2))


def test_fixed_point_does_not_stall_on_scaled_loads(blocks):
    """Scaled by a power of 2 the solve is the same in floating point: the same steps.

    Scaled by 0.2 or 5 it is the same only up to round-off, which the QP solver's active-set
    decisions amplify: its gradient tests leave the scaled ones from the 9th on (history
    § 33), and whether the second fixed-point step's QP, at the loose inner accuracy 1e-2,
    takes 0 iterations (then g does not change, r = 0 and the fixed point goes straight to
    the tight inner accuracy) or 1 decides 4 or 7 steps. Those scalings are checked on the
    solution and for a stall (at most two steps more than at 1; the stall took 46 steps).
    """
    factors = (1.0, 0.25, 4.0, 0.2, 5.0)
    sols = {f: df.solve(blocks_problem(blocks, f), rtol=RTOL) for f in factors}
    steps = {f: s.report.extra["friction"]["fixed_point_steps"] for f, s in sols.items()}
    for f, s in sols.items():
        assert s.report.converged, s.report.summary()
        assert s.report.extra["friction"]["fixed_point_converged"]
        v = coulomb_violations(s, 0.3)
        assert max(v.values()) <= 1e-6, (f, v)
    exact = {f: (steps[f], sols[f].report.hessian_mults) for f in (1.0, 0.25, 4.0)}
    assert len(set(exact.values())) == 1, exact
    assert max(steps.values()) <= steps[1.0] + 2, steps  # fewer is no stall
    u1 = sols[1.0].nodal_values()
    umax = np.abs(u1).max()
    for f in (0.2, 5.0):  # Coulomb's problem with zero gaps is positively homogeneous
        assert np.abs(sols[f].nodal_values() / f - u1).max() <= 1e-6 * umax
        assert np.abs(sols[f].contact.tangential_force / f
                      - sols[1.0].contact.tangential_force).max() \
            <= 1e-6 * sols[1.0].contact.force.max()


# -- the punch of the issue: a steel punch with a filleted edge on an aluminium block, mortar --

PRESSURE, MU = 0.1, 0.3


@pytest.fixture(scope="module")
def punch_mesh():
    return df.build_mesh(punch_on_block, h_punch=0.3, h_block=0.5)


def punch_problem(mesh, ratio, scale=1.0, half=False, friction="coulomb"):
    """The punch pressed by p and pushed by ratio·𝓕·p; ``friction`` None: frictionless."""
    p = scale * PRESSURE
    dirichlet = [df.Dirichlet("bottom")]
    if half:
        dirichlet.append(df.Dirichlet("symmetry", components=(1,)))
    return df.ContactProblem(
        mesh, df.Elasticity({"punch": 210.0, "block": 70.0}, {"punch": 0.3, "block": 0.33},
                            tractions={"load": (ratio * MU * p, 0.0, -p)}),
        dirichlet=dirichlet,
        contact=[df.Mortar("punch_contact", "block_contact",
                           friction=df.Coulomb(MU) if friction else None)],
        decomposition=df.Parts(2))


def check_punch(sol, ratio: float) -> float:
    """The punch's force balance at the lateral load ratio·𝓕N and the Coulomb conditions;
    returns the normal force N."""
    fx, fy, N = sol.total_contact_force
    assert abs(fx + ratio * MU * N) <= 1e-6 * N and abs(fy) <= 1e-6 * N
    v = coulomb_violations(sol, MU)
    assert max(v.values()) <= 1e-5, v
    return N


@pytest.mark.parametrize("scale", [1.0])
def test_punch_fixed_point_stops(punch_mesh, scale):
    """The lateral load 0.5 𝓕N: the fixed point used to stall at the inner tolerance.

    (The load scaled by 0.2 converges on DOLFINx 0.5.2's mesh but not on 0.11's within 20 000
    F-multiplications: its first Tresca step after the bonded one is the open problem of
    docs/friction.md, "Near gross sliding".)
    """
    # the first Tresca step after the bonded one is the slow one (docs/friction.md: near gross
    # sliding); its budget is not what this test is about
    sol = df.solve(punch_problem(punch_mesh, 0.5, scale), max_it=20000)
    rep = sol.report
    assert rep.converged, rep.summary()
    fr = rep.extra["friction"]
    assert fr["fixed_point_converged"] and fr["fixed_point_steps"] <= 12
    N = check_punch(sol, 0.5)  # the traction times the (polygonal) load face
    assert N > 0.95 * scale * PRESSURE * np.pi


@pytest.fixture(scope="module")
def punch_mesh_medium():
    return df.build_mesh(punch_on_block, h_punch=0.2, h_block=0.35)


def test_punch_at_07_within_ten_frictionless(punch_mesh_medium):
    """0.7·𝓕N on the full punch (h = 0.2/0.35): ≤ 10× the frictionless F-multiplications.

    Most tangential pairs turn on their circles, where the face's Hessian has the curvature
    terms ξ/r ≫ ||F|| that the preconditioner in face now scales by (qp/mpgp_steps). Before:
    39 004 F-multiplications (182× the frictionless 214) on DOLFINx 0.5.2's mesh, not
    converged within 20 000 iterations on 0.11's; now 1 481 and 1 710.
    """
    mesh = punch_mesh_medium
    # the frictionless count without Krylov recycling, which the disc solve cannot use
    base = df.solve(punch_problem(mesh, 0.0, friction=None), method="tfeti", mprgp_reuse=0)
    assert base.report.converged
    sol = df.solve(punch_problem(mesh, 0.7), method="tfeti", max_it=20000)
    rep = sol.report
    assert rep.converged and rep.extra["friction"]["fixed_point_converged"], rep.summary()
    assert rep.hessian_mults <= 10 * base.report.hessian_mults, (
        rep.hessian_mults, base.report.hessian_mults)
    check_punch(sol, 0.7)


def test_punch_near_gross_sliding_first_steps_loose(punch_mesh_medium):
    """0.99·𝓕N on the full punch (h = 0.2/0.35, FETI-1): ≤ 6× the frictionless solve.

    The first two Coulomb steps on discs (bonded, then the first Tresca step) run at the inner
    accuracy ``ETA_MAX_DISCS`` = 1: they only feed the next bounds their normal forces, and
    solving the punch's weakly held tangential equilibrium to 1e-2 there took most of the
    solve. Measured (F-multiplications against the frictionless solve with recycling, 1e-2
    before): DOLFINx 0.5.2 1 401 → 284 against 128; 0.11 3 708 → 278 against 116.
    """
    from dolfinx_feti.drivers.friction import ETA_MAX, ETA_MAX_DISCS

    mesh = punch_mesh_medium
    base = df.solve(punch_problem(mesh, 0.0, friction=None))
    assert base.report.converged
    sol = df.solve(punch_problem(mesh, 0.99), max_it=20000)
    rep = sol.report
    fr = rep.extra["friction"]
    assert rep.converged and fr["fixed_point_converged"], rep.summary()
    assert ETA_MAX_DISCS > ETA_MAX  # discs loosen more than intervals (2D)
    assert [s["inner_rtol"] for s in fr["steps"][:2]] == [ETA_MAX_DISCS] * 2
    assert rep.hessian_mults <= 6 * base.report.hessian_mults, (
        rep.hessian_mults, base.report.hessian_mults)
    check_punch(sol, 0.99)
