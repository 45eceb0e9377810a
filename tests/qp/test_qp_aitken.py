"""The extrapolation of SMALBE's slow outer loop (qp/aitken.py) and the choice of 'auto'."""

from __future__ import annotations

import numpy as np
import pytest
from qp_helpers import gather, make_mat, make_vec, row_block_constraint
from test_qp_mpgp import disc_problem, local_discs

from dolfinx_feti.qp import MPGP, QP, SMALBE, orthonormalize
from dolfinx_feti.qp.aitken import CAP, Aitken


def test_geometric_residuals_extrapolated_to_their_sum():
    """Residuals r, q r (q = 0.8, one direction): the step becomes the series' sum 1/(1-q)."""
    a, r = Aitken(), np.array([3.0, -1.0, 2.0])
    assert np.array_equal(a.step(r, 2.0 * r), 2.0 * r)  # no pair yet
    step = a.step(0.8 * r, 1.6 * r)
    assert np.allclose(step, 1.6 * r / (1.0 - 0.8))
    assert a.count == 1
    # the pair is used up: the next residual alone is not extrapolated
    assert np.array_equal(a.step(0.6 * r, 1.2 * r), 1.2 * r)


def test_extrapolation_capped():
    a, r = Aitken(), np.array([1.0, 1.0])
    a.step(r, r)
    assert np.allclose(a.step(0.999 * r, 0.999 * r), CAP * 0.999 * r)


@pytest.mark.parametrize("second", [np.array([1.0, 0.5]) * 0.9,   # turned (cosine 0.95)
                                    np.array([1.0, 0.0]) * 1.1,   # growing
                                    np.array([1.0, 0.0]) * 0.3,   # fast: left to the plain step
                                    np.array([-1.0, 0.0]) * 0.9])  # overshot
def test_plain_step_unless_slow_and_aligned(second):
    a = Aitken()
    a.step(np.array([1.0, 0.0]), np.array([1.0, 0.0]))
    assert np.array_equal(a.step(second, 2.0 * second), 2.0 * second)
    assert a.count == 0


def _smalbe_run(acceleration: str, discs: bool):
    """SMALBE(MPGP) from zero on a random QP with D x = 0 (3 rows): (iterations, mults, x)."""
    A, b, lb, ub, pairs, centre, radius = disc_problem(7, mixed=True)
    rng = np.random.default_rng(7)
    con = orthonormalize(row_block_constraint(rng.standard_normal((3, len(b)))))
    radius = np.maximum(radius, np.linalg.norm(centre, axis=1) + 0.05)  # 0 is feasible
    lb, ub = np.minimum(lb, 0.0), np.maximum(ub, 0.0)
    bv = make_vec(b)
    x = bv.duplicate()
    x.set(0.0)
    qp = QP.create(make_mat(A), bv, lb=make_vec(lb), ub=make_vec(ub), eq=con,
                   discs=local_discs(x, pairs, centre, radius) if discs else None)
    res = SMALBE(MPGP(), rtol=1e-9, acceleration=acceleration).solve(qp, x)
    assert res.converged
    return res.iterations, res.hessian_mults, gather(x)


@pytest.mark.parametrize("discs, chosen", [(True, "search"), (False, "anderson")])
def test_auto_takes_search_on_discs_and_anderson_otherwise(discs, chosen):
    """'auto' is 'search' (qp/dual_search.py) with discs, 'anderson' without."""
    it, mults, x = _smalbe_run("auto", discs)
    it_c, mults_c, x_c = _smalbe_run(chosen, discs)
    assert (it, mults) == (it_c, mults_c) and np.array_equal(x, x_c)
    other = "anderson" if chosen == "search" else "search"
    assert _smalbe_run(other, discs)[:2] != (it, mults)  # the choice is visible in the counts
