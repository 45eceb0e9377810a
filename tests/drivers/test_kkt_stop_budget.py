"""What the KKT stop's bounds cost: the accepted solution is not grossly over-solved, the
bound of ‖G̃x‖ takes few F-multiplications, and the bound during the iterations covers the
contact forces (2D Hertz in 4 parts, mortar, rtol 1e-6).

Measured before the gradient bound in force units (history § 31): the accepted check's
largest residual 0.17 / 0.70 / 0.051 rtol (TFETI / FETI-1 / FETI-DP), the outer iterations
spent on ‖G̃x‖ alone 3 + 10 + 2 of 84 + 104 + 102 F-multiplications (5.2 %). With the bound
of ‖G̃x‖ 10× tighter (emulated by dividing ``eq_tol``) the residuals fall to 0.022 / 0.018 /
0.15 rtol and ‖G̃x‖ alone takes 10.7 %; 100× tighter: 0.0021 / 0.011 / 0.15, 11.9 %. With the
force bound (``python bench/stop_budget.py --problems hertz --rtols 1e-6``, history § 33):
0.16 / 0.27 / 0.99 rtol, ‖G̃x‖ alone 1 + 2 + 0 of 85 + 105 + 97. The factors below fail those
and hold today with the margins stated at each.
"""

from __future__ import annotations

from pathlib import Path

import hertz_cases as hc
import pytest
from mpi4py import MPI

import dolfinx_feti as df

ROOT = Path(__file__).resolve().parents[2]
RTOL = 1e-6
METHODS = ("tfeti", "feti1", "fetidp")
#: The accepted check's largest residual is at least rtol / OVER_SOLVE (before the force bound
#: ≥ rtol / 22: FETI-DP 0.051 rtol, 0.047 on two ranks and on DOLFINx 0.11; today ≥ rtol / 7).
OVER_SOLVE = 50.0
#: ‖G̃x‖ alone takes at most this share of the F-multiplications (5.2 % before the force
#: bound; 3.7 % on two ranks, 4.1 % on DOLFINx 0.11; with it 1.0 %).
EQUALITY_SHARE = 0.08
#: The first check's largest residual is at most this many rtol: the gradient bound covers the
#: contact forces (today 0.16 / 0.27 / 1.0; without the force part FETI-DP's first check
#: failed on ``violation_force`` at 28 rtol, history § 31).
FIRST_CHECK = 2.0


def equality_only(history: list[dict]) -> int:
    """F-multiplications of SMALBE outer iterations after one whose gradient met its bound
    (only ‖G̃x‖ was left), over all runs (``k`` restarts at 0 after a failed check)."""
    spent = 0
    for before, rec in zip(history, history[1:], strict=False):
        if rec["k"] > 0 and before["test_gP"] <= before["test_tol"]:
            spent += rec["hessian_mults"]
    return spent


@pytest.fixture(scope="module")
def solves():
    comm = MPI.COMM_WORLD
    problem = hc.disk_problem(df.read_gmsh(ROOT / "meshes/disk_on_block.msh", comm=comm))
    out = {}
    for method in METHODS:
        rep = df.solve(problem, comm=comm, method=method, rtol=RTOL).report
        history = comm.bcast(rep.extra["history"] if comm.rank == 0 else None, root=0)
        assert 0 < len(history) < 50  # the report keeps the last 50: these are all
        out[method] = (rep, history)
    return out


@pytest.mark.parametrize("method", METHODS)
def test_the_accepted_solution_is_not_grossly_over_solved(solves, method):
    rep, _ = solves[method]
    assert rep.stopping["met"]
    accepted = rep.stopping["history"][-1]
    largest = max(accepted["primal"], accepted["equilibrium"])
    assert largest == pytest.approx(max(rep.kkt.values()), rel=1e-12)
    assert RTOL / OVER_SOLVE <= largest <= RTOL


def test_the_bound_of_the_coarse_equality_costs_few_f_multiplications(solves):
    spent = sum(equality_only(h) for _, h in solves.values())
    total = sum(rep.hessian_mults for rep, _ in solves.values())
    assert all("test_gP" in rec for _, h in solves.values() for rec in h)
    assert spent <= EQUALITY_SHARE * total


@pytest.mark.parametrize("method", METHODS)
def test_the_first_check_meets_the_contact_forces(solves, method):
    rep, _ = solves[method]
    first = rep.stopping["history"][0]
    assert max(first["primal"], first["equilibrium"]) <= FIRST_CHECK * RTOL
