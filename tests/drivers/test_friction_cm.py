"""Cattaneo–Mindlin: 2D Hertz contact with Coulomb friction and a tangential load Q < 𝓕P.

A disk (R = 8) on a block, both E = 200, ν = 0.3 (elastically similar: the normal and the
tangential problems decouple), the full model :func:`dolfinx_feti.io.meshes.hertz2d_full`. The
disk's flat top carries the traction (Q, −P)/(2R) plus a linear normal part that cancels the
moment of Q about the contact point, so the pressure stays Hertzian. The disk floats: only the
contact (and friction) holds it. Theory: a central stick zone of half-width
c = a √(1 − Q/(𝓕P)), a = 2 √(R P / (π E*)), slip outside.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl

import dolfinx_feti as df
from dolfinx_feti.io import meshes

R, P, E, NU, F = 8.0, 10.0, 200.0, 0.3, 0.4
H = 0.1
E_STAR = E / (2.0 * (1.0 - NU**2))
A_HERTZ = 2.0 * np.sqrt(R * P / (np.pi * E_STAR))


def load(Q):
    m = 3.0 * Q / (2.0 * R**2)  # ∫ x·m x dx over [−R, R] = Q R: no moment about the origin

    def traction(x):
        return ufl.as_vector((Q / (2 * R), -P / (2 * R) + m * x[0]))

    return traction


@pytest.fixture(scope="module")
def mesh():
    return df.build_mesh(meshes.hertz2d_full, h_contact=H)


def cattaneo_problem(mesh, Q: float) -> df.ContactProblem:
    """The floating disk under (Q, −P), Coulomb friction 𝓕 on node-to-node contact."""
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"load": load(Q)}),
        dirichlet=[df.Dirichlet("bottom")],
        contact=[df.NodeToNode("disk_contact", "block_contact", friction=df.Coulomb(F))],
        decomposition=df.Parts(2))


@pytest.fixture(scope="module", params=[0.3, 0.7])
def case(request, mesh):
    Q = request.param * F * P
    return Q, df.solve(cattaneo_problem(mesh, Q), rtol=1e-8)


def half_width(x, inside, h):
    """Half the extent of the nodes ``inside``, extended by h/2 at each end (the midpoint to
    the first node outside)."""
    xi = x[inside]
    return 0.5 * (xi.max() - xi.min()) + 0.5 * h


def test_converged_and_balanced(case):
    Q, sol = case
    rep = sol.report
    assert rep.converged, rep.summary()
    assert rep.extra["friction"]["fixed_point_converged"]
    # the floating disk: the contact forces balance the load
    assert np.allclose(sol.total_contact_force, [-Q, P], rtol=0, atol=1e-6 * P)


def test_stick_zone_cattaneo_mindlin(case):
    Q, sol = case
    c = sol.contact
    x = c.x[:, 0]
    pressed = c.force > 1e-8 * c.force.max()
    a_h = half_width(x, pressed, H)
    assert abs(a_h - A_HERTZ) <= 2 * H
    stick = c.state == df.ContactData.STICK
    c_h = half_width(x, stick, H)
    c_theory = A_HERTZ * np.sqrt(1.0 - Q / (F * P))
    assert abs(c_h - c_theory) <= 2 * H, (c_h, c_theory)
    assert abs(0.5 * (x[stick].max() + x[stick].min())) <= H  # centred
    # slip zone: |q| = 𝓕 p, the friction force against Q (the disk is pushed along +x)
    slip = pressed & ~stick
    ft = c.tangential_force[:, 0]
    # |q| = 𝓕 p to the fixed point's own test: the slip bound of the last Tresca solve is
    # 𝓕 p of the previous one, and the steps stop when max|g_k − 𝓕 p_k| <= 1e-6 max p_k.
    err = np.linalg.norm(np.abs(ft[slip]) - F * c.force[slip])
    assert err <= 1e-6 * np.linalg.norm(F * c.force[pressed])
    assert np.all(ft[slip] < 0) and np.all(c.slip[slip, 0] >= 0)
    assert np.all(np.abs(ft) <= c.slip_bound * (1 + 1e-12))
