"""Small loads under Newton with Coulomb friction: the gap to the linear solution.

The neo-Hookean and the linear (small-deformation) solutions of the same contact problem
differ by O(δ²) at the load δ, with the same stick/slip partition (shared by the 2D and 3D
friction tests of the Newton driver).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from coulomb_kkt import coulomb_violations

import dolfinx_feti as df


def small_load_ratios(problem: Callable, coefficient: float, E: float, nu: float,
                      loads=(1e-3, 2e-3, 4e-3)) -> np.ndarray:
    """max|u_NH(δ) − u_lin(δ)| of consecutive loads, divided (4 for O(δ²) when δ doubles).

    ``problem(δ, material)`` is the ContactProblem at the load δ. Each solution is checked:
    converged, the same stick/slip states in both, partial slip, the Coulomb conditions.
    """
    diffs = []
    for d in loads:
        nl = df.solve(problem(d, df.NeoHookean(E, nu)), rtol=1e-13, newton_rtol=1e-12,
                      method="fetidp")
        lin = df.solve(problem(d, df.Elasticity(E, nu)), rtol=1e-13, method="fetidp")
        assert nl.report.converged and lin.report.converged
        assert np.array_equal(nl.contact.state, lin.contact.state)
        assert 0 < np.count_nonzero(nl.contact.state == 2) < nl.contact.state.size
        v = coulomb_violations(nl, coefficient)
        assert max(v.values()) < 1e-7, v
        diffs.append(np.abs(nl.nodal_values() - lin.nodal_values()).max())
    return np.array(diffs[1:]) / np.array(diffs[:-1])
