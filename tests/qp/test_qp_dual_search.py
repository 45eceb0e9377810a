"""SMALBE's secant search of the dual along a stagnating residual (qp/dual_search.py).

The unit tests drive :class:`DualSearch` with residuals of a linear model
``D x(mu) = H (mu* - mu)``; the solver test is a bound- and equality-constrained QP built by
hand whose equality has a nearly singular direction once the bounds are active (a sum over
many variables of which only one stays free, as the few sticking rows near gross sliding), on
which SMALBE's outer loop stagnates: 'search' must cut the outer iterations of 'aitken' and
reach the same KKT point.
"""

from __future__ import annotations

import numpy as np
import pytest
from qp_helpers import gather, kkt, make_mat, make_vec, row_block_constraint

from dolfinx_feti.qp import MPRGP, QP, SMALBE, orthonormalize
from dolfinx_feti.qp.aitken import Aitken
from dolfinx_feti.qp.dual_search import FIRST, GROW, NOISE, DualSearch


def _outer_loop(acc, H: np.ndarray, mu_star: np.ndarray, rho: float, n: int,
                tol: float) -> tuple[int, np.ndarray]:
    """Outer iterations of ``mu += acc.step(r, rho r)``, ``r = H (mu* - mu)``, until |r| < tol."""
    mu = np.zeros_like(mu_star)
    for k in range(n):
        r = H @ (mu_star - mu)
        if np.linalg.norm(r) < tol:
            return k, mu
        mu = mu + acc.step(r, rho * r)
    return n, mu


@pytest.mark.parametrize("case", ["diagonal", "rotated"])
def test_linear_ridge_found_in_few_outer_iterations(case):
    """One slow eigenvalue (plain contraction 0.998 / 0.999) and fast ones: the root.

    The start direction keeps a few per cent of the fast modes, which a move by a large factor
    along it excites more than it reduces ``phi``: without the correction of the direction by
    the residual across it the search ended on the turned residual again and again (464 outer
    iterations on the diagonal case). Measured: 33 / 151 against Aitken's 1 891 / 3 545 and
    the plain update's 8 051 on the diagonal case.
    """
    if case == "diagonal":
        H, mu_star = np.diag([0.002, 0.6, 0.9]), np.array([50.0, 1.0, -2.0])
    else:
        rng = np.random.default_rng(0)
        Q = np.linalg.qr(rng.standard_normal((6, 6)))[0]
        H, mu_star = Q @ np.diag([0.001, 0.2, 0.5, 0.7, 0.9, 1.0]) @ Q.T, \
            10.0 * rng.standard_normal(6)
    k_search, mu = _outer_loop(DualSearch(), H, mu_star, 1.0, 5000, 1e-8)
    k_aitken, _ = _outer_loop(Aitken(), H, mu_star, 1.0, 5000, 1e-8)
    assert np.allclose(mu, mu_star, rtol=0, atol=1e-4)
    assert k_search <= 200 and 10 * k_search <= k_aitken, (k_search, k_aitken)


def test_several_slow_modes_searched_conjugate():
    """Three slow eigenvalues (plain contraction 0.9997–0.99) among eight: with the conjugation
    of a search to the last one that found its root, fewer outer iterations on every seed.

    Measured (with / without): 114 / 236, 189 / 569, 191 / 454, 838 / 4 029, 180 / 379;
    Aitken 4 815 – 7 655.
    """
    for seed in range(1, 6):
        rng = np.random.default_rng(seed)
        Q = np.linalg.qr(rng.standard_normal((8, 8)))[0]
        ev = np.r_[10.0 ** rng.uniform(-3.5, -2.0, 3), rng.uniform(0.2, 1.0, 5)]
        H, mu_star = Q @ np.diag(ev) @ Q.T, 10.0 * rng.standard_normal(8)
        k = {}
        for conjugate in (True, False):
            search = DualSearch(conjugate=conjugate)
            k[conjugate], mu = _outer_loop(search, H, mu_star, 1.0, 50000, 1e-8)
            assert np.allclose(mu, mu_star, rtol=0, atol=1e-3)
            assert (search.conjugated > 0) == conjugate
        assert k[True] < k[False], (seed, k)


def test_start_with_aitken_factor_and_plain_across():
    """An aligned pair shrinking by q starts the search: 1/(1-q) along r, capped at FIRST."""
    a, d = DualSearch(), np.array([1.0, 0.0, 0.0])
    assert np.array_equal(a.step(d, 2.0 * d), 2.0 * d)  # no pair yet
    r = 0.95 * d
    assert np.allclose(a.step(r, 2.0 * r), 2.0 * r * min(1.0 / 0.05, FIRST))
    assert a.count == 1


def test_factor_grows_while_the_sign_holds_and_the_direction_is_corrected():
    """phi barely falls: the next move is GROW times the last factor along the corrected d.

    The residual across d after the move t along d is read as the fast part of d that the
    move excited (``-d_fast t / rho``): the new direction is ``d + rho r_across / t``.
    """
    rho, a, d = 3.0, DualSearch(), np.array([1.0, 0.0])
    a.step(d, rho * d)
    a.step(0.99 * d, rho * 0.99 * d)  # starts with factor FIRST (1/(1 - 0.99) = 100 capped)
    t = FIRST * rho * 0.99
    r = np.array([0.985, 0.1])  # phi -0.5 %: the secant asks for far more than GROW * FIRST
    step = a.step(r, rho * r)
    d_new = np.array([1.0, rho * 0.1 / t])
    d_new /= np.linalg.norm(d_new)
    phi = float(d_new @ r)
    assert np.allclose(step, rho * r + (GROW * FIRST - 1.0) * rho * phi * d_new)
    assert a.count == 2


def test_overshoot_goes_back_to_the_secant_root():
    """phi changed sign beyond the noise: mu moves to the root of the secant of the two points."""
    a, d = DualSearch(), np.array([0.0, 1.0])
    a.step(d, d)
    a.step(0.9 * d, 0.9 * d)  # factor 1/(1 - 0.9) = 10: the move t = 10 * 0.9 = 9 along d
    phi1 = -0.45  # the secant root of (0, 0.9), (9, -0.45) is at t = 6: 3 back
    step = a.step(np.array([0.2, phi1]), np.array([0.2, phi1]))
    assert np.allclose(step, [0.2, -3.0])
    assert a.back == 1


@pytest.mark.parametrize("r", [np.array([0.0, -0.5 * NOISE * 0.9]),  # a sign change in noise
                               np.array([1.0, 0.2])])  # turned away from d
def test_search_ends_on_noise_or_a_turned_residual(r):
    a, d = DualSearch(), np.array([0.0, 1.0])
    a.step(d, d)
    a.step(0.9 * d, 0.9 * d)
    assert np.array_equal(a.step(r, 2.0 * r), 2.0 * r)
    assert a.count == 1 and a.back == 0


def ridge_qp(nb: int = 300, nf: int = 20, seed: int = 3):
    """``min 1/2 x^T A x - b^T x``, ``x_i <= 1`` on ``nb`` rows, ``D x = 0`` (3 rows).

    ``b`` pushes the ``nb`` bounded rows onto their bound; ``D``'s first row sums them and the
    one free row 0, so at the solution only row 0 carries it: its share ``1/(nb + 1)`` of that
    row is the nearly singular direction. Two more rows act on ``nf`` free rows (fast modes).
    """
    rng = np.random.default_rng(seed)
    n = 1 + nb + nf
    C = rng.standard_normal((n, n)) * 0.1 / np.sqrt(n)
    A = np.eye(n) + C @ C.T
    D = np.zeros((3, n))
    D[0, :1 + nb] = 1.0
    D[1:, 1 + nb:] = rng.standard_normal((2, nf))
    b = np.full(n, 3.0)
    b[0] = -(nb - 1.0)
    b[1 + nb:] = rng.standard_normal(nf)
    ub = np.full(n, np.inf)
    ub[1:1 + nb] = 1.0
    return A, b, np.full(n, -np.inf), ub, D


def _ridge_solve(acceleration: str):
    A, b, lb, ub, D = ridge_qp()
    con = orthonormalize(row_block_constraint(D))
    bv = make_vec(b)
    x = bv.duplicate()
    x.set(0.0)
    qp = QP.create(make_mat(A), bv, lb=make_vec(lb), ub=make_vec(ub), eq=con)
    res = SMALBE(MPRGP(), rtol=1e-8, acceleration=acceleration, max_outer=2000,
                 max_it=100000).solve(qp, x)
    Dt_mu = bv.duplicate()
    con.mult_transpose(res.multiplier, Dt_mu)
    return res, gather(x), gather(Dt_mu)


def test_smalbe_search_cuts_the_stagnating_outer_loop():
    """'search' against 'aitken' on the ridge QP: far fewer outer iterations, the same KKT point.

    Measured: 30 outer iterations against 159 ('none' 246; the search without its corrections
    of the direction 76).
    """
    A, b, lb, ub, D = ridge_qp()
    out = {}
    for acc in ("aitken", "search"):
        res, x, Dt_mu = _ridge_solve(acc)
        assert res.converged, (acc, res.reason)
        k = kkt(A, b, x, lb, ub, Dt_mu=Dt_mu)
        assert k["gP"] <= 1e-6 * np.linalg.norm(b) and k["infeas"] == 0.0, (acc, k)
        assert k["comp"] <= 1e-6 * np.linalg.norm(b), (acc, k)
        assert np.abs(D @ x).max() <= 1e-6 * np.linalg.norm(b), acc
        out[acc] = res.outer_iterations, x
    assert int((out["search"][1] >= ub - 1e-12).sum()) >= 250  # the bounds carry the sum
    assert 4 * out["search"][0] <= out["aitken"][0], (out["search"][0], out["aitken"][0])
    xa, xs = out["aitken"][1], out["search"][1]
    assert np.abs(xs - xa).max() <= 1e-5 * np.abs(xa).max()
