"""The Coulomb conditions checked on a returned solution, from its contact data alone.

Independent of the solver's own residuals: per contact node the normal force p >= 0, the
friction force q with |q| <= 𝓕 p, where the node sticks no slip, where it slips |q| = 𝓕 p and
the slip opposite to q.
"""

from __future__ import annotations

import numpy as np
from mpi4py.MPI import SUM

from dolfinx_feti.constraints.rows import Kind


def coulomb_violations(sol, coefficient: float) -> dict[str, float]:
    """The largest violation of each Coulomb condition, relative (forces to max p, slips to ‖u‖∞).

    Returns:
        ``bound``: max (|q| − 𝓕p)⁺ / max p; ``slipping``: max ||q| − 𝓕p| / max p over the
        slipping nodes with p > 0; ``stick_slip``: max |s| / ‖u‖∞ over the sticking nodes;
        ``direction``: max (|q||s| + q·s) / (max p ‖u‖∞) over the slipping nodes (zero iff s is
        opposite to q).
    """
    c = sol.contact
    p = c.force
    q = c.tangential_force
    s = c.slip
    pmax = max(float(p.max()), 1e-300)
    umax = max(float(np.abs(sol.nodal_values()).max()), 1e-300)
    nq = np.linalg.norm(q, axis=1)
    ns = np.linalg.norm(s, axis=1)
    stick = c.state == 1
    slipping = (c.state == 2) & (p > 0)
    return {
        "bound": float(np.max(np.maximum(nq - coefficient * p, 0.0))) / pmax,
        "slipping": float(np.max(np.abs(nq - coefficient * p)[slipping], initial=0.0)) / pmax,
        "stick_slip": float(np.max(ns[stick], initial=0.0)) / umax,
        "direction": float(np.max((nq * ns + np.einsum("ij,ij->i", q, s))[slipping],
                                  initial=0.0)) / (pmax * umax),
    }


def check_coulomb(sol, coefficient: float, tol: float = 1e-7) -> None:
    """Every Coulomb condition of :func:`coulomb_violations` within ``tol``."""
    v = coulomb_violations(sol, coefficient)
    assert v["bound"] < tol and v["slipping"] < tol, v
    assert v["stick_slip"] < tol and v["direction"] < tol, v


def check_stuck_as_tied(sols, tied, coefficient: float) -> None:
    """A converged load path whose contact nodes all stick at its end equals the bodies glued
    (``tied``, the solution of the same last step with a tie) to 1e-8, and satisfies the
    Coulomb conditions at every step."""
    assert all(s.report.converged for s in sols)
    sol = sols[-1]
    assert np.all(sol.contact.state == 1)
    U, Uref = sol.nodal_values(), tied.nodal_values()
    assert np.abs(U - Uref).max() < 1e-8 * np.abs(Uref).max()
    for s in sols:
        check_coulomb(s, coefficient)


def check_tresca_sliding(sol, bound_force: float) -> None:
    """A converged solution in gross sliding under Tresca along −x: every node slips, the
    friction force is −``bound_force`` (the traction bound times the width) along x, and the
    solver's friction residuals are at round-off."""
    assert sol.report.converged
    assert np.all(sol.contact.state == 2)
    assert abs(sol.total_contact_force[0] + bound_force) < 1e-8 * bound_force
    assert sol.report.kkt["friction_feasibility"] < 1e-10
    assert sol.report.kkt["friction_complementarity"] < 1e-8


def dirichlet_force(sol, where, comm) -> np.ndarray:
    """The force the Dirichlet conditions exert on the body at the nodes ``where(x)`` picks,
    −Σ λ_D per component (the Lagrangian's +λ(Bu − c): a row's force on the body is −Bᵀλ);
    collective."""
    own = sol.rows.own
    lam = sol.lam.array_r * own.scale
    rows = np.flatnonzero(own.kind == Kind.DIRICHLET)
    picked = where(sol.problem.mesh.x[own.node[rows]])
    comp = own.e_comp[np.searchsorted(own.e_row, rows)]  # one entry per Dirichlet row
    gdim = sol.problem.mesh.gdim
    out = np.array([lam[rows[picked & (comp == j)]].sum() for j in range(gdim)])
    return -comm.allreduce(out, op=SUM)
