"""The Coulomb conditions checked on a returned solution, from its contact data alone.

Independent of the solver's own residuals: per contact node the normal force p >= 0, the
friction force q with |q| <= 𝓕 p, where the node sticks no slip, where it slips |q| = 𝓕 p and
the slip opposite to q.
"""

from __future__ import annotations

import numpy as np


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
