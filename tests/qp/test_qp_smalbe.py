"""SMALBE-M on bound and equality constrained QPs, including the FETI-like projected setting."""

import numpy as np
import pytest
from petsc4py import PETSc
from qp_helpers import (
    COMM,
    counting,
    gather,
    kkt,
    make_mat,
    make_vec,
    random_spd,
    ref_active_set,
    row_block_constraint,
)

from dolfinx_feti.qp import (
    QP,
    SMALBE,
    Absolute,
    MaxGradientTest,
    Projector,
    homogenize,
    orthonormalize,
    projected_operator,
    smalbe,
)


def feti_like(seed: int = 0, n: int = 80, m: int = 8):
    """min 1/2 l'Fl - d'l  s.t. l_I >= 0, G l = e, with a known feasible point."""
    rng = np.random.default_rng(seed)
    F = random_spd(n, rng, cond=30.0)
    G = rng.standard_normal((m, n))
    ineq = np.arange(n) < n // 2
    feasible = np.where(ineq, rng.uniform(0.0, 1.0, n), rng.standard_normal(n))
    e = G @ feasible
    d = 3.0 * rng.standard_normal(n)
    lower = np.where(ineq, 0.0, -np.inf)
    return F, G, e, d, lower, feasible


def projected_feti_qp(Fm, G, e, d, comm=COMM):
    """The FETI pipeline's QP: orthonormalize G, homogenize, project.

    Returns ``(P F P, P (d - F l_hat), the constraint, l_hat gathered)`` for the Mat ``Fm``.
    """
    n = len(d)
    con = orthonormalize(row_block_constraint(G, comm), rhs=e)
    assert con.inconsistency < 1e-12
    lam_hat = make_vec(np.zeros(n), comm)
    homogenize(con, lam_hat)
    # Linear term P (d - F l_hat).
    b = make_vec(d, comm)
    tmp = b.duplicate()
    Fm.mult(lam_hat, tmp)
    b.axpy(-1.0, tmp)
    Projector(con).apply(b, b)
    return projected_operator(Fm, con), b, con, gather(lam_hat)


def solve_feti_like(F, G, e, d, lower, comm=COMM, **kw):
    """The FETI pipeline (:func:`projected_feti_qp`), SMALBE on mu = l - l_hat."""
    n = len(d)
    Fm, ctx = counting(make_mat(F, comm))
    A, b, con, lh = projected_feti_qp(Fm, G, e, d, comm)
    ctx.calls = 0
    mu = make_vec(np.zeros(n), comm)
    res = smalbe(A, b, con, mu, lb=make_vec(lower - lh, comm), **kw)
    return gather(mu) + lh, res, ctx, con


def check_M_rule(res, beta=2.0):
    """M is divided by beta exactly when L(x_k, mu_k) < L(x_{k-1}, mu_{k-1}) + rho/2 ||Dx_k||^2."""
    decreases = 0
    for h in res.history:
        if h["L_prev"] is None:
            assert h["M_next"] == h["M"] and not h["M_decreased"]
            continue
        failed = h["L"] < h["L_prev"] + 0.5 * h["rho"] * h["Dx"] ** 2
        assert h["M_decreased"] == failed
        assert h["M_next"] == (h["M"] / beta if failed else h["M"])
        decreases += failed
    for h0, h1 in zip(res.history, res.history[1:], strict=False):
        assert h1["M"] == h0["M_next"]
    return decreases


@pytest.mark.parametrize("expansion", ["fixed", "optimal", "projcg"])
def test_feti_like_against_reference(expansion):
    F, G, e, d, lower, feasible = feti_like()
    ref = ref_active_set(F, d, lower, np.full(len(d), np.inf), G, e, x0=feasible)
    lam, res, ctx, con = solve_feti_like(F, G, e, d, lower, rtol=1e-10,
                                         inner_options={"expansion": expansion})
    assert res.converged and res.reason == "converged"
    assert np.linalg.norm(lam - ref) <= 1e-8 * np.linalg.norm(ref)
    # Hessian multiplications: one F product per application of P F P, norm estimate included.
    assert res.hessian_mults == ctx.calls
    assert res.counts["norm"] > 0
    # KKT of the original problem with the returned multiplier (for the orthonormal G~).
    Q = np.linalg.pinv(G) @ G  # orthogonal projector onto Im G^T
    assert np.linalg.norm(G @ lam - e) <= 1e-9 * np.linalg.norm(e)
    Dt_mu = make_vec(np.zeros(len(d)))
    con.mult_transpose(res.multiplier, Dt_mu)
    # Stationarity of the homogenized projected problem: P(F lam - d) + G~^T mu on the box.
    g_proj = (np.eye(len(d)) - Q) @ (F @ lam - d)
    r = kkt(np.zeros((len(d), len(d))), -g_proj, lam, lower, np.full(len(d), np.inf),
            Dt_mu=gather(Dt_mu))
    assert r["gP"] <= 1e-9 * np.linalg.norm(d) and r["infeas"] <= 1e-14 and r["comp"] <= 1e-8
    check_M_rule(res)


def test_redundant_rows_general_A():
    """D with redundant rows, A not of the form P A P: the inner norm is given explicitly."""
    rng = np.random.default_rng(5)
    n = 60
    A = random_spd(n, rng, cond=20.0)
    D0 = rng.standard_normal((5, n))
    D = np.vstack([D0, D0[2], D0[0] - D0[4]])
    b = 3.0 * rng.standard_normal(n)
    l, u = np.full(n, -0.2), np.full(n, 0.25)
    l[::3], u[::4] = -np.inf, np.inf
    ref = ref_active_set(A, b, l, u, D, np.zeros(len(D)), x0=np.zeros(n))
    con = orthonormalize(row_block_constraint(D))
    assert con.rank == 5
    norm_A = float(np.linalg.eigvalsh(A).max())
    rho = 2.0 * norm_A
    x = make_vec(np.zeros(n))
    res = smalbe(make_mat(A), make_vec(b), con, x, lb=make_vec(l), ub=make_vec(u), rtol=1e-11,
                 norm_A=norm_A, rho=rho, inner_options={"norm_A": norm_A + rho})
    assert res.converged
    xs = gather(x)
    assert np.linalg.norm(xs - ref) <= 1e-8 * np.linalg.norm(ref)
    Dt_mu = make_vec(np.zeros(n))
    con.mult_transpose(res.multiplier, Dt_mu)
    r = kkt(A, b, xs, l, u, Dt_mu=gather(Dt_mu))
    assert r["gP"] <= 1e-10 * np.linalg.norm(b) and r["infeas"] == 0.0 and r["comp"] <= 1e-9
    assert np.linalg.norm(D @ xs) <= 1e-10 * np.linalg.norm(b)
    assert res.counts["norm"] == 0
    f = 0.5 * xs @ A @ xs - b @ xs
    assert res.objective == pytest.approx(f, rel=1e-9)


def test_M_update_rule_both_ways():
    """Reference defaults (M = 100 ||A||) make M drop several times; M = ||A|| keeps it."""
    F, G, e, d, lower, _ = feti_like(seed=1)
    _, res, _, _ = solve_feti_like(F, G, e, d, lower, rtol=1e-8)
    assert res.converged
    assert check_M_rule(res) > 0
    _, res2, _, _ = solve_feti_like(F, G, e, d, lower, rtol=1e-8, rho=300.0, M=1e-3)
    assert res2.converged
    assert check_M_rule(res2) == 0


def test_non_convergence_reported():
    F, G, e, d, lower, _ = feti_like(seed=2, n=40, m=4)
    _, res, _, _ = solve_feti_like(F, G, e, d, lower, rtol=1e-12, max_it=5)
    assert not res.converged and res.reason == "max_it" and res.iterations == 5
    _, res, _, _ = solve_feti_like(F, G, e, d, lower, rtol=1e-12, max_outer=1)
    assert not res.converged and res.reason == "max_outer" and res.outer_iterations == 1
    with pytest.raises(ValueError, match="inner_options"):
        solve_feti_like(F, G, e, d, lower, inner_options={"rtol": 1.0})


def test_same_on_self_and_world():
    F, G, e, d, lower, _ = feti_like(seed=3, n=50, m=5)
    runs = [solve_feti_like(F, G, e, d, lower, comm=comm, rtol=1e-9)
            for comm in (PETSc.COMM_SELF, COMM)]
    (l1, r1, _, _), (l2, r2, _, _) = runs
    assert r1.converged and r2.converged
    assert r1.outer_iterations == r2.outer_iterations
    assert np.linalg.norm(l1 - l2) <= 1e-9 * np.linalg.norm(l1)
    assert np.allclose(r1.multiplier, r2.multiplier, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 4])
def test_anderson_against_reference(seed):
    """The accelerated multiplier update reaches the same KKT point as the reference."""
    F, G, e, d, lower, feasible = feti_like(seed=seed)
    ref = ref_active_set(F, d, lower, np.full(len(d), np.inf), G, e, x0=feasible)
    lam, res, ctx, _ = solve_feti_like(F, G, e, d, lower, rtol=1e-10, acceleration="anderson")
    assert res.converged
    assert np.linalg.norm(lam - ref) <= 1e-8 * np.linalg.norm(ref)
    assert np.linalg.norm(G @ lam - e) <= 1e-9 * np.linalg.norm(e)
    assert res.hessian_mults == ctx.calls


def test_anderson_cuts_a_slow_outer_loop():
    """With a small rho the plain update contracts slowly; the secant memory does not."""
    F, G, e, d, lower, feasible = feti_like(seed=1)
    norm_F = float(np.linalg.eigvalsh(F).max())
    runs = {acc: solve_feti_like(F, G, e, d, lower, rtol=1e-10, rho=0.05 * norm_F,
                                 M=0.01 * norm_F, acceleration=acc)
            for acc in ("none", "anderson")}
    (l0, r0, _, _), (l1, r1, _, _) = runs["none"], runs["anderson"]
    assert r0.converged and r1.converged
    assert r1.outer_iterations < r0.outer_iterations / 2
    assert np.linalg.norm(l1 - l0) <= 1e-8 * np.linalg.norm(l0)


def test_anderson_same_on_self_and_world():
    F, G, e, d, lower, _ = feti_like(seed=3, n=50, m=5)
    runs = [solve_feti_like(F, G, e, d, lower, comm=comm, rtol=1e-9, acceleration="anderson")
            for comm in (PETSc.COMM_SELF, COMM)]
    (l1, r1, _, _), (l2, r2, _, _) = runs
    assert r1.converged and r2.converged
    assert r1.outer_iterations == r2.outer_iterations
    assert np.linalg.norm(l1 - l2) <= 1e-9 * np.linalg.norm(l1)


def test_acceleration_validated():
    F, G, e, d, lower, _ = feti_like(seed=2, n=40, m=4)
    with pytest.raises(ValueError, match="acceleration"):
        solve_feti_like(F, G, e, d, lower, acceleration="nesterov")
    with pytest.raises(ValueError, match="depth"):
        solve_feti_like(F, G, e, d, lower, acceleration="anderson", depth=0)


def test_rho_growth_cuts_a_slow_outer_loop():
    """rho_growth: ρ doubles after each outer iteration that cut ||Dx|| by less than half.

    With a small ρ and the plain update the outer loop contracts slowly; growing ρ on the slow
    iterations reaches the same solution in far fewer outer iterations, the F-multiplications
    counted through the rebuilt inner operator.
    """
    F, G, e, d, lower, feasible = feti_like(seed=1)
    ref = ref_active_set(F, d, lower, np.full(len(d), np.inf), G, e, x0=feasible)
    norm_F = float(np.linalg.eigvalsh(F).max())
    runs = {g: solve_feti_like(F, G, e, d, lower, rtol=1e-10, rho=0.05 * norm_F,
                               M=0.01 * norm_F, rho_growth=g, rho_max=2.0 * norm_F)
            for g in (None, 2.0)}
    (_, r0, _, _), (l1, r1, ctx, _) = runs[None], runs[2.0]
    assert r0.converged and r1.converged
    assert r1.outer_iterations < r0.outer_iterations / 2
    assert np.linalg.norm(l1 - ref) <= 1e-8 * np.linalg.norm(ref)
    assert r1.hessian_mults == ctx.calls
    assert all(h["rho"] == 0.05 * norm_F for h in r0.history)
    h = r1.history
    grown = 0
    for k in range(len(h) - 1):
        slow = h[k]["Dx"] > 0.5 * (h[k - 1]["Dx"] if k else np.inf)
        expect = min(2.0 * h[k]["rho"], 2.0 * norm_F) if slow else h[k]["rho"]
        assert h[k + 1]["rho"] == pytest.approx(expect, rel=1e-15)
        grown += h[k + 1]["rho"] > h[k]["rho"]
    assert grown >= 2


def test_history_records_where_the_callers_bounds_stand():
    """With a caller's test (the KKT stop's), each outer record holds the weighted gradient
    of its last inner iterate against ``test_tol`` and ``eq_tol``: the last meets both, one
    before missed one of them; without a test the records have no such entries."""
    F, G, e, d, lower, _ = feti_like(seed=3)
    A, b, con, lh = projected_feti_qp(make_mat(F, COMM), G, e, d)
    qp = QP.create(A, b, lb=make_vec(lower - lh, COMM), eq=con)
    weight = np.linspace(0.5, 2.0, len(d))[slice(*b.getOwnershipRange())]
    test = MaxGradientTest(weight, 1e-8 * b.norm(), COMM.tompi4py(), 1e-9 * b.norm())
    res = SMALBE(M=Absolute(1.0), rho=Absolute(10.0)).solve(qp, b.duplicate(), test=test)
    assert res.converged and res.outer_iterations > 1
    last = res.history[-1]
    assert last["test_gP"] == test.last <= last["test_tol"] == test.tol
    assert last["Dx"] <= last["eq_tol"] == test.eq_tol
    assert any(h["test_gP"] > h["test_tol"] or h["Dx"] > h["eq_tol"] for h in res.history[:-1])
    plain = SMALBE(M=Absolute(1.0), rho=Absolute(10.0), rtol=1e-8).solve(qp, b.duplicate())
    assert plain.converged and all("test_gP" not in h for h in plain.history)
