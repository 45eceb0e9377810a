"""Interface pairs checked before the solve (issue 26): orientation, the gap a tie or a contact
bridges against the facet size, conditions without a row, and round-off gaps taken as 0.

Serially and under ``mpirun -n 2`` (the rows are built on rank 0 from the same data; every
rank must raise, or report, the same).
"""

from __future__ import annotations

import numpy as np
import pytest
from hand_meshes import stacked
from mpi4py import MPI
from scratch import scratch_cwd_fixture

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar_rows import snap_roundoff

scratch_cwd = scratch_cwd_fixture("feti-pairs-")


def two_blocks(mesh, *, contact=(), ties=(), load=(0.0, -0.01), dirichlet=None):
    """Lower block clamped at its bottom, upper block loaded on its top, held in x."""
    return df.ContactProblem(
        mesh, df.Elasticity(E=1.0, nu=0.3, tractions={"upper_top": load}),
        dirichlet=dirichlet if dirichlet is not None else
        [df.Dirichlet("lower_bottom"), df.Dirichlet("upper_left", components=(0,))],
        contact=list(contact), ties=list(ties))


def refused(problem, *words):
    with pytest.raises(df.InputError) as info:
        df.solve(problem, rtol=1e-8)
    msg = str(info.value)
    assert all(w in msg for w in words), msg
    return msg


def test_mortar_surfaces_facing_the_same_way_are_refused_by_name():
    # the upper block's top and the lower block's top both face up: no facet pair faces the
    # other, the search coupled nothing and the solve "converged" doing nothing
    msg = refused(two_blocks(stacked(), contact=[df.Mortar("upper_top", "lower_top")]),
                  "'upper_top'", "'lower_top'", "face the same way")
    assert "inconsistent normals" in msg


def test_a_tie_facing_the_same_way_is_refused_by_name():
    refused(two_blocks(stacked(), ties=[df.Tie("upper_top", "lower_top")]),
            "tie 'upper_top'", "face the same way")


def test_a_tie_across_a_visible_gap_is_warned_with_the_largest_gap():
    # a gap of 1.5 facet sizes: the search distance reaches it, the tie glues across it
    mesh = stacked(4, 3, gap=0.5)
    sol = df.solve(two_blocks(mesh, ties=[df.Tie("upper_bottom", "lower_top",
                                                   search_distance=1.0)]), rtol=1e-8)
    found = [w for w in sol.report.warnings if "bridge gaps up to 0.5 " in w]
    assert len(found) == 1 and "tie 'upper_bottom'" in found[0], sol.report.warnings
    # touching surfaces: no such warning
    sol = df.solve(two_blocks(stacked(4, 3), ties=[df.Tie("upper_bottom", "lower_top")]),
                   rtol=1e-8)
    assert not [w for w in sol.report.warnings if "bridge gaps" in w], sol.report.warnings


def test_a_tie_between_two_faces_of_one_body_is_refused():
    # the lower block's top and bottom, a body-height apart, within a generous search distance
    p = two_blocks(stacked(), ties=[df.Tie("lower_top", "lower_bottom", search_distance=2.0)],
                   dirichlet=[df.Dirichlet("lower_left"), df.Dirichlet("upper_left")])
    refused(p, "tie 'lower_top'", "both surfaces belong to body 'lower'", "two faces of one body")


def test_a_contact_reaching_far_beyond_the_facets_is_warned():
    # search distance 5 across a gap of 6 facet sizes: rows that a default search would not
    # make, and that may reach a far part of the master
    held = [df.Dirichlet("lower_bottom"), df.Dirichlet("upper_top")]
    sol = df.solve(two_blocks(stacked(4, 3, gap=2.0), contact=[df.Mortar(
        "upper_bottom", "lower_top", search_distance=5.0)], dirichlet=held), rtol=1e-8)
    assert any("bridge gaps up to 2 " in w and "search_distance" in w
               for w in sol.report.warnings), sol.report.warnings
    # an open gap within the default search distance: no warning
    sol = df.solve(two_blocks(stacked(4, 3, gap=0.3),
                              contact=[df.Mortar("upper_bottom", "lower_top")], dirichlet=held),
                   rtol=1e-8)
    assert sol.report.sizes["inequality"] > 0
    assert not [w for w in sol.report.warnings if "bridge gaps" in w], sol.report.warnings


def test_a_contact_condition_without_a_row_is_named_in_the_warnings():
    mesh = stacked(4, 3, gap=2.0)  # out of the default search distance's reach
    p = two_blocks(mesh, contact=[df.Mortar("upper_bottom", "lower_top")],
                   dirichlet=[df.Dirichlet("lower_bottom"), df.Dirichlet("upper_top")])
    sol = df.solve(p, rtol=1e-8)
    assert any("mortar contact 'upper_bottom' (slave) / 'lower_top' (master): no row" in w
               for w in sol.report.warnings), sol.report.warnings
    assert sol.report.sizes["inequality"] == 0


def test_round_off_gaps_are_snapped():
    x = np.array([[0.0, 1e6], [3.0, 1e6 + 1.0]])
    gap = np.array([2e-16, -2e-16, 1e-12 * 1e6, 0.25])
    out = snap_roundoff(gap, x)
    assert out[0] == 0.0 and out[1] == 0.0 and out[3] == 0.25
    assert out[2] == 1e-6  # 1e-6 at coordinates 1e6 is data (1e-12 relative), not round-off


@pytest.mark.parametrize("n", [(4, 3), (5, 7), (6, 4)])
def test_touching_mortar_surfaces_without_load_give_exactly_zero(n):
    # exactly touching non-matching surfaces had weighted gaps of ±2e-16 and 70 iterations
    mesh = stacked(*n, height=0.3)
    sol = df.solve(two_blocks(mesh, contact=[df.Mortar("upper_bottom", "lower_top")],
                              load=(0.0, 0.0)), rtol=1e-10)
    assert sol.report.converged
    assert sol.report.iterations == 0, sol.report.iterations
    u = sol.u.x.array
    assert np.all(u == 0.0)
    assert MPI.COMM_WORLD.allreduce(int(np.count_nonzero(u))) == 0
