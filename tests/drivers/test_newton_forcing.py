"""Newton's increments with Krylov recycling: the forcing term lets Newton's stop be met.

problems/ironing_path.toml (a rigid die pressed into a neo-Hookean block and slid, Coulomb
0.3) solves its increment QPs to rtol 1e-8 and Coulomb's fixed point to 1e-6, and Newton
to ``newton_rtol`` 1e-9. With the QPs' recycled CG directions and the increments solved to
the user's accuracies, each recycled run ended at another point within its KKT test and its
fixed point's tolerance, and Newton cycled at the equilibrium residual 5.4e-9 at the first
sliding step (25 iterations, 8 cut-backs, the step failed). Newton now asks each increment
for an accuracy tied to its residual (drivers/newton.py ``_forcing``): checked here that the
path converges with the recycling on, in as many Newton iterations as without it, to the
KKT residuals of ``newton_rtol``, and to the same solution as the path without recycling.
"""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref
from ironing_path import die_at

import dolfinx_feti as df
from dolfinx_feti.io.meshes_rubber import ironing_block

#: problems/ironing_path.toml's die positions (pressed, then slid to +x)
MOVES = [(0.0, -0.05), (0.0, -0.1), (0.5, -0.1)]
NEWTON_RTOL = 1e-9


@pytest.fixture(scope="module")
def mesh():
    return df.build_mesh(ironing_block, h_top=0.25, h_far=0.75)


def _path(mesh, **kwargs) -> list[df.Solution]:
    return df.solve_path(lambda t: die_at(mesh, MOVES[int(t)]), range(len(MOVES)), rtol=1e-8,
                         newton_rtol=NEWTON_RTOL, method="feti1", progress=False, **kwargs)


@pytest.fixture(scope="module")
def paths(mesh):
    return _path(mesh), _path(mesh, mprgp_reuse=0)


def test_recycled_increments_converge(paths):
    """With the recycling on (the default) every step converges without a cut-back, its
    KKT residuals (Coulomb's bound aside: the fixed point's own tolerance) within
    ``newton_rtol``, in no more Newton iterations than without recycling; the last
    increments were asked for more than the user's rtol."""
    recycled, plain = paths
    for k, (sol, base) in enumerate(zip(recycled, plain, strict=True)):
        rep = sol.report
        assert rep.converged, (k, rep.reason, [h["residual"] for h in rep.extra["newton"]])
        assert rep.extra["cutbacks"] == 0 and rep.extra["substeps"] == [float(k)]
        assert rep.extra["options"]["mprgp_reuse"] > 0
        worst = max(v for key, v in rep.kkt.items() if key != "coulomb_bound")
        assert worst <= NEWTON_RTOL, (k, rep.kkt)
        assert rep.extra["newton_iterations"] <= base.report.extra["newton_iterations"], k
    hist = recycled[-1].report.extra["newton"]
    assert hist[0]["qp_rtol"] == 1e-8 and hist[-1]["qp_rtol"] < 1e-8
    assert hist[-1]["coulomb_rtol"] < 1e-6
    # the recycling saved F-multiplications over the path
    assert sum(s.report.hessian_mults for s in recycled) < \
        sum(s.report.hessian_mults for s in plain)


def test_recycled_increments_same_solution(paths):
    """The path with the recycling equals the path without it (two runs of the same KKT
    tests: within their tolerances)."""
    for sol, base in zip(*paths, strict=True):
        assert ref.rel_max_diff(sol.nodal_values(), base.nodal_values()) <= 1e-6
        assert np.allclose(sol.total_contact_force, base.total_contact_force, rtol=1e-6,
                           atol=1e-9)
