"""Krylov recycling (qp/recycle.py) on plain NumPy/PETSc QPs, no FETI.

A second right-hand side on the same operator is solved from the directions of the first:
the same solution (against an independent active-set reference) in fewer multiplications;
an operator that changed never reuses the old directions; SMALBE's inner solves share their
directions when ρ is the same; a load path whose contact zone grows takes its expansions by the
projected Galerkin step (qp/expansion.py, ``GalerkinExpansion``).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from qp_helpers import (
    MPI_COMM,
    gather,
    kkt,
    make_mat,
    make_vec,
    membrane,
    ownership,
    random_spd,
    ref_box,
    row_block_constraint,
)

from dolfinx_feti.qp import MPRGP, QP, SMALBE
from dolfinx_feti.qp.recycle import PROJECT_TRIES, Recycle

N = 120


def contact_like(seed: int = 3, n: int = N, cond: float = 1e3):
    """An SPD A and a right-hand side; a third of the entries bounded below by 0 (as FETI's
    contact rows), the rest free (the gluing rows)."""
    rng = np.random.default_rng(seed)
    A = random_spd(n, rng, cond=cond)
    b = rng.standard_normal(n)
    lb = np.full(n, -np.inf)
    lb[: n // 3] = 0.0
    return A, b, lb


def solve(solver, A_mat, b, lb, rtol=1e-10):
    qp = QP.create(A_mat, make_vec(b), lb=make_vec(lb), norm_A=float(A_mat.norm(3)))
    x = make_vec(np.zeros_like(b))
    res = solver.solve(qp, x, rtol=rtol)
    assert res.converged, res.reason
    return gather(x), res


@pytest.mark.parametrize("deflate", [True, False])
def test_second_rhs_same_solution_fewer_mults(deflate):
    A, b, lb = contact_like()
    A_mat = make_mat(A)
    rng = np.random.default_rng(7)
    b2 = 1.1 * b + 0.05 * rng.standard_normal(b.size)  # a 10 % load change and some noise
    recycling = MPRGP(reuse=80, deflate=deflate)
    solve(recycling, A_mat, b, lb)
    assert len(recycling.recycle) > 0
    x_warm, res_warm = solve(recycling, A_mat, b2, lb)
    x_cold, res_cold = solve(MPRGP(reuse=0), A_mat, b2, lb)
    ref = ref_box(A, b2, lb, np.full(b.size, np.inf))
    scale = np.linalg.norm(ref)
    assert np.linalg.norm(x_warm - ref) <= 1e-7 * scale
    assert np.linalg.norm(x_cold - ref) <= 1e-7 * scale
    assert res_warm.counts.get("recycle", 0) >= 1
    # the Galerkin steps alone gain little here; with deflated CG a fifth at least
    assert res_warm.hessian_mults < (0.8 if deflate else 1.0) * res_cold.hessian_mults, \
        (res_warm.hessian_mults, res_cold.hessian_mults)


def test_unconstrained_second_rhs_in_the_kept_space():
    """Without bounds the kept directions span the first solve's Krylov space, which holds
    ``b``: the same system with ``2 b`` is solved by the Galerkin step (no product) to the
    first solve's accuracy, up to the rounding of the Gram matrix."""
    A, b, _ = contact_like(cond=30.0, n=200)
    A_mat = make_mat(A)
    solver = MPRGP(reuse=200)
    free = np.full(b.size, -np.inf)
    _, res1 = solve(solver, A_mat, b, free, rtol=1e-12)
    assert len(solver.recycle) == res1.counts["cg"] < b.size  # independent directions
    x2, res2 = solve(solver, A_mat, 2.0 * b, free, rtol=1e-9)
    assert np.linalg.norm(x2 - 2.0 * np.linalg.solve(A, b)) <= 1e-8 * np.linalg.norm(x2)
    kinds = [h["kind"] for h in res2.history]
    assert kinds[1] == "recycle"
    assert res2.history[1]["gP"] <= 1e-9 * res2.history[0]["gP"]
    assert res2.hessian_mults <= 3 < res1.hessian_mults


def test_changed_operator_never_reuses():
    """A solve on another operator forgets the directions: it repeats a fresh solver's run."""
    A, b, lb = contact_like()
    A2, _, _ = contact_like(seed=11)
    solver = MPRGP(reuse=80)
    solve(solver, make_mat(A), b, lb)
    x_next, res_next = solve(solver, make_mat(A2), b, lb)
    x_fresh, res_fresh = solve(MPRGP(reuse=80), make_mat(A2), b, lb)
    assert "recycle" not in res_next.counts
    assert res_next.hessian_mults == res_fresh.hessian_mults
    assert np.array_equal(x_next, x_fresh)


def test_bind_keys_by_identity_and_value():
    rec = Recycle(4)
    op, other = object(), object()
    rec.bind((op, 1.0))
    rec.record(np.ones(3), np.ones(3))
    rec.commit(MPI_COMM)
    rec.bind((op, 1.0))
    assert len(rec) == 1  # the same operator and penalty: kept
    rec.bind((op, 2.0))
    assert len(rec) == 0  # another penalty: another Hessian
    rec.record(np.ones(3), np.ones(3))
    rec.commit(MPI_COMM)
    rec.bind((other, 2.0))
    assert len(rec) == 0
    with pytest.raises(ValueError, match="k must be"):
        Recycle(-1)


def test_ring_keeps_the_last_k():
    rec = Recycle(3)
    rec.bind(("op",))
    for i in range(5):
        e = np.zeros(5)
        e[i] = 1.0
        rec.record(e, 2.0 * e)
    rec.commit(MPI_COMM)
    assert len(rec) == 3
    basis = rec.basis(np.zeros(5, dtype=bool), MPI_COMM)
    # WᵀAW of the last three unit vectors with A = 2 I (the Gram matrix kept incrementally)
    d, Ad = basis.galerkin(-np.arange(5.0))
    assert np.allclose(Ad, 2.0 * d)


def test_smalbe_inner_solves_share_directions():
    """SMALBE's inner Hessian A + ρDᵀD is one operator for a given ρ: a second solve of the
    same equality-constrained QP with a new b reuses the first's directions and agrees with
    a solve without them."""
    n, m = 90, 3
    rng = np.random.default_rng(5)
    A, b, lb = contact_like(seed=5, n=n, cond=200.0)
    D = np.linalg.qr(rng.standard_normal((n, m)))[0].T
    D[:, : n // 3] = 0.0  # the equality acts on the free entries only
    D = np.linalg.qr(D.T)[0].T
    A_mat, eq = make_mat(A), row_block_constraint(D)
    b2 = 1.1 * b + 0.05 * rng.standard_normal(n)

    def run(solver, rhs):
        qp = QP.create(A_mat, make_vec(rhs), lb=make_vec(lb), eq=eq, norm_A=np.linalg.norm(A, 2))
        x = make_vec(np.zeros(n))
        res = solver.solve(qp, x)
        assert res.converged, res.reason
        return gather(x), res

    warm = SMALBE(MPRGP(reuse=80), rtol=1e-9)
    run(warm, b)
    x_w, res_w = run(warm, b2)
    x_c, res_c = run(SMALBE(MPRGP(reuse=0), rtol=1e-9), b2)
    assert np.linalg.norm(x_w - x_c) <= 1e-6 * np.linalg.norm(x_c)
    assert np.linalg.norm(D @ x_w) <= 1e-7 * np.linalg.norm(x_c)
    assert res_w.hessian_mults < res_c.hessian_mults, (res_w.hessian_mults,
                                                       res_c.hessian_mults)


def obstacle_path(project: bool, steps: int = 5, m: int = 32):
    """The membrane pushed onto the obstacle by the loads 4 · 1.1^k, each step warm from the
    last on one recycling solver: the solutions, the multiplications and the projected
    Galerkin steps of each step."""
    A, lo = membrane(m)
    A_mat, norm_A = make_mat(A), float(sp.linalg.norm(A, 1))
    solver = MPRGP(reuse=80, project=project)
    x = make_vec(np.zeros(A.shape[0]))
    xs, mults, counts = [], [], []
    for k in range(steps):
        b = np.full(A.shape[0], -4.0 * 1.1**k)
        res = solver.solve(QP.create(A_mat, make_vec(b), lb=make_vec(lo), norm_A=norm_A), x,
                           rtol=1e-8)
        assert res.converged, res.reason
        xs.append((gather(x), b))
        mults.append(res.hessian_mults)
        counts.append({"galerkin": res.counts.get("galerkin", 0)})
    return A, lo, xs, mults, counts


def test_galerkin_expansion_fewer_mults_on_a_growing_contact_zone():
    """With the projected Galerkin step the warm steps reach the same solutions (their KKT
    conditions, and the solutions without it) in fewer multiplications, every one counted
    (a rejected projection's too)."""
    A, lo, with_, m_with, counts = obstacle_path(True)
    _, _, without, m_without, _ = obstacle_path(False)
    Ad = A.toarray()
    for (x1, b), (x0, _) in zip(with_, without, strict=True):
        res = kkt(Ad, b, x1, lo, np.full(b.size, np.inf))
        assert res["gP"] <= 1e-7 * np.linalg.norm(b), res
        assert np.linalg.norm(x1 - x0) <= 1e-7 * np.linalg.norm(x0)
    assert m_with[0] == m_without[0]  # the first solve has nothing recycled
    assert sum(r["galerkin"] for r in counts) >= 1  # the projected Galerkin steps were taken
    assert sum(m_with[1:]) < 0.95 * sum(m_without[1:]), (m_with, m_without)


def test_galerkin_expansion_needs_recycled_directions():
    """Without recycling ``project`` changes nothing: the same iterates and counts."""
    A, b, lb = contact_like(seed=4)
    A_mat = make_mat(A)
    x1, r1 = solve(MPRGP(reuse=0, project=True), A_mat, b, lb)
    x0, r0 = solve(MPRGP(reuse=0, project=False), A_mat, b, lb)
    assert r1.hessian_mults == r0.hessian_mults and np.array_equal(x1, x0)
    assert "rejected" not in r1.counts


def test_galerkin_expansion_not_in_smalbe_inner_solves():
    """SMALBE's inner solves (cut short by its outer test) keep the solver's own expansion."""
    n, m = 90, 3
    rng = np.random.default_rng(4)
    A, b, lb = contact_like(seed=4, n=n, cond=200.0)
    D = np.linalg.qr(rng.standard_normal((n, m)))[0].T
    A_mat, eq = make_mat(A), row_block_constraint(D)

    def run(project):
        solver = SMALBE(MPRGP(reuse=80, project=project), rtol=1e-9)
        x = make_vec(np.zeros(n))
        res = solver.solve(QP.create(A_mat, make_vec(b), lb=make_vec(lb), eq=eq,
                                     norm_A=np.linalg.norm(A, 2)), x)
        assert res.converged, res.reason
        return gather(x), res

    (x1, r1), (x0, r0) = run(True), run(False)
    assert r1.counts.get("recycle", 0) >= 1  # faces did start from recycled directions
    assert "galerkin" not in r1.counts and r1.hessian_mults == r0.hessian_mults
    assert np.array_equal(x1, x0)


def test_grow_keeps_the_pairs_in_order_and_clear_shrinks():
    """A full ring grown keeps its pairs (oldest first) and their Gram matrix; new pairs go
    after them; a new operator starts again with the first capacity."""
    rng = np.random.default_rng(2)
    n = 8
    A = random_spd(n, rng, cond=10.0)
    rec = Recycle(3)
    rec.bind(("op",))
    ws = [rng.standard_normal(n) for _ in range(7)]
    for w in ws[:5]:  # the ring wraps: the last three are kept
        rec.record(w, A @ w)
    rec.commit(MPI_COMM)
    g = rng.standard_normal(n)
    before = rec.basis(np.zeros(n, dtype=bool), MPI_COMM).galerkin(g)
    rec.grow(5)
    assert rec.k == 5 and len(rec) == 3
    after = rec.basis(np.zeros(n, dtype=bool), MPI_COMM).galerkin(g)
    assert np.allclose(before[0], after[0]) and np.allclose(before[1], after[1])
    for w in ws[5:]:
        rec.record(w, A @ w)
    rec.commit(MPI_COMM)
    assert len(rec) == 5
    # the Gram matrix kept incrementally equals the one of the five kept directions
    W = np.array([w / np.linalg.norm(w) for w in ws[2:]]).T
    d, Ad = rec.basis(np.zeros(n, dtype=bool), MPI_COMM).galerkin(g)
    c = np.linalg.solve(W.T @ A @ W, -W.T @ g)
    assert np.allclose(d, W @ c) and np.allclose(Ad, A @ d)
    rec.grow(4)  # never fewer
    assert rec.k == 5
    rec.clear()
    assert rec.k == 3 and len(rec) == 0


def test_inexact_galerkin_step_does_not_stall_deflated_cg():
    """Two nearly dependent kept directions (Gram matrix of condition ~1e9, kept above
    GRAM_RTOL) and a right-hand side in their span: the Galerkin step leaves ~1e-8 of the
    gradient, all in span W, which deflated CG cannot reduce (its directions are rounding:
    106 products here against 83 cold, and in bench/ironing.py's step 44 ``||g^P||`` stood
    still for 4 997 CG steps to max_it). The deflation is dropped where it loses the descent
    (``counts['undeflated']``; 40 products) and the solve takes no more products than a cold
    one, to the same solution."""
    n = 60
    rng = np.random.default_rng(5)
    A = random_spd(n, rng, cond=100.0)
    A_mat = make_mat(A)
    lo, hi = ownership(n)
    w1, w2 = rng.standard_normal(n), rng.standard_normal(n)
    solver = MPRGP(reuse=10)
    solver.recycle.bind((A_mat,))
    for w in (w1, w1 + 1e-4 * w2):
        solver.recycle.record(w[lo:hi], (A @ w)[lo:hi])
    solver.recycle.commit(MPI_COMM)
    b = A @ (w1 + 0.5 * w2)
    free = np.full(n, -np.inf)
    x_warm, res_warm = solve(solver, A_mat, b, free, rtol=1e-13)
    x_cold, res_cold = solve(MPRGP(reuse=0), A_mat, b, free, rtol=1e-13)
    kinds = [h["kind"] for h in res_warm.history]
    assert kinds[1] == "recycle"
    assert res_warm.hessian_mults <= res_cold.hessian_mults, \
        (res_warm.hessian_mults, res_cold.hessian_mults)
    assert res_warm.counts.get("undeflated", 0) >= 1
    ref = np.linalg.solve(A, b)
    assert np.linalg.norm(x_warm - ref) <= 1e-10 * np.linalg.norm(ref)


def test_projected_expansion_goes_on_only_while_it_pays():
    """The projected Galerkin expansion is tried PROJECT_TRIES times; then only while at least
    half of the tries were kept (each rejected try is a product spent for nothing)."""
    rejected, kept = Recycle(4), Recycle(4)
    for i in range(PROJECT_TRIES):
        assert rejected.project_pays() and kept.project_pays()
        rejected.projected(i == 0)
        kept.projected(i != 0)
    assert not rejected.project_pays()
    assert kept.project_pays()
    rejected.clear()  # the record outlives a new operator: it is the problem's, not the store's
    assert not rejected.project_pays()
    for _ in range(PROJECT_TRIES):
        kept.projected(False)
    assert not kept.project_pays()  # 7 of 16 kept
