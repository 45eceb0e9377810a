"""Recycled directions carried across a small change of the operator (qp/recycle.py, ``carry``).

A moving curved obstacle turns the contact rows a little at every step: F is another operator,
near the last. The stored pairs (w, A_old w) are kept as stale ones: the Galerkin steps take
their coefficients from the old Gram matrix, the deflation is approximate, the gradient errs by
(A − A_old) d until a fresh one, and every stop is tested on a fresh gradient. Checked here: the
same solutions as a cleared store (and the KKT conditions of the new operator) in fewer
products; a large change clears the store after one product (the guard); the bookkeeping.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from qp_helpers import MPI_COMM, gather, kkt, make_mat, make_vec, membrane

from dolfinx_feti.qp import MPRGP, QP
from dolfinx_feti.qp.recycle import CARRY_RTOL, Recycle


def turned(A: sp.csr_matrix, m: int, eps: float) -> sp.csr_matrix:
    """``D A D`` with ``D = 1 + eps x`` (x the grid's first coordinate): rows scaled as a
    contact row's coefficients by the cosine of a turning normal."""
    t = np.arange(1, m + 1) / (m + 1)
    X, _ = np.meshgrid(t, t)
    D = sp.diags(1.0 + eps * X.ravel())
    return (D @ A @ D).tocsr()


def moving_path(carry: bool, eps: float = 1e-3, steps: int = 5, m: int = 24):
    """The membrane pushed onto the obstacle by the loads 4 · 1.1^k with the operator turned
    by ``k eps`` at step k, each step warm from the last on one recycling solver whose store is
    carried (``carry``) or cleared at each change: the solutions, operators and counts."""
    A0, lo = membrane(m)
    solver = MPRGP(reuse=80)
    x = make_vec(np.zeros(A0.shape[0]))
    out = []
    for k in range(steps):
        A = turned(A0, m, k * eps)
        if k:
            solver.recycle.carry() if carry else solver.recycle.clear()
        A_mat = make_mat(A)
        b = np.full(A.shape[0], -4.0 * 1.1**k)
        res = solver.solve(QP.create(A_mat, make_vec(b), lb=make_vec(lo),
                                     norm_A=float(sp.linalg.norm(A, 1))), x, rtol=1e-8)
        assert res.converged, res.reason
        out.append((A, b, gather(x), res))
    return lo, out, solver.recycle


def test_carried_store_same_solutions_fewer_products():
    lo, carried, rec = moving_path(True)
    _, cleared, _ = moving_path(False)
    for (A, b, x1, _), (_, _, x0, _) in zip(carried, cleared, strict=True):
        res = kkt(A.toarray(), b, x1, lo, np.full(b.size, np.inf))
        assert res["gP"] <= 1e-7 * np.linalg.norm(b), res
        assert np.linalg.norm(x1 - x0) <= 1e-7 * np.linalg.norm(x0)
    assert rec.stats["carried"] == len(carried) - 1 and rec.stats["carry_refused"] == 0
    assert 0.0 < rec.change <= CARRY_RTOL
    assert all(r.counts.get("recycle", 0) >= 1 for *_, r in carried[1:])
    with_ = [r.hessian_mults for *_, r in carried]
    without = [r.hessian_mults for *_, r in cleared]
    assert with_[0] == without[0]
    assert sum(with_[1:]) < 0.9 * sum(without[1:]), (with_, without)


def test_large_change_clears_after_one_product():
    """A store carried to a very different operator is cleared by the guard: the solve is a
    fresh solver's run plus the guard's product, with the same iterates."""
    m = 16
    A0, lo = membrane(m)
    A1 = turned(A0, m, 0.8)
    b = np.full(A0.shape[0], -4.0)

    def run(solver, A):
        x = make_vec(np.zeros(A.shape[0]))
        res = solver.solve(QP.create(make_mat(A), make_vec(b), lb=make_vec(lo),
                                     norm_A=float(sp.linalg.norm(A, 1))), x, rtol=1e-8)
        assert res.converged
        return gather(x), res

    solver = MPRGP(reuse=80)
    run(solver, A0)
    solver.recycle.carry()
    x_next, r_next = run(solver, A1)
    x_fresh, r_fresh = run(MPRGP(reuse=80), A1)
    assert solver.recycle.stats["carry_refused"] == 1 and solver.recycle.change > CARRY_RTOL
    assert "recycle" not in r_next.counts
    assert r_next.hessian_mults == r_fresh.hessian_mults + 1
    assert np.array_equal(x_next, x_fresh)


def test_carry_bookkeeping():
    """An empty store is not carried; a carried one is stale until its columns are replaced
    by exact pairs; a key of another form clears it."""
    rec = Recycle(2)
    rec.carry()
    rec.bind((object(),))
    assert len(rec) == 0 and not rec.stale
    op, other = object(), object()
    rec.bind((op,))
    rec.record(np.ones(3), 2.0 * np.ones(3))
    rec.commit(MPI_COMM)
    rec.carry()
    rec.bind((other,))
    assert len(rec) == 1 and rec.stale and not rec.checked
    assert rec.check(2.01 * np.ones(3) / np.sqrt(3 * MPI_COMM.size), MPI_COMM)  # 0.5 % off
    assert not rec.stale and rec.checked  # the guard's product made the column exact
    rec.carry()
    rec.bind((op,))
    for k in range(2):  # two new pairs overwrite the stale one
        rec.record(np.arange(3.0) + k, np.arange(3.0) + 2 * k)
    assert rec.stale
    rec.commit(MPI_COMM)
    assert len(rec) == 2 and not rec.stale
    rec.bind((op, 1.0))
    rec.record(np.ones(3), np.ones(3))
    rec.commit(MPI_COMM)
    rec.carry()
    rec.bind((other, 2.0))  # SMALBE's inner Hessian with a new penalty: carried, the guard
    assert len(rec) == 1 and rec.stale  # measures the whole change
    rec.carry()
    rec.bind((op,))  # a key of another form: cleared
    assert len(rec) == 0


def test_swap_replaces_the_stale_column_of_the_largest_weight():
    """A Galerkin step's exact pair takes the place of the stale column it weighs most; the
    Gram matrix's row and column of it are the exact ones; exact columns are never replaced."""
    n = 4
    A_old, A_new = np.diag([1.0, 2.0, 3.0, 4.0]), np.diag([1.0, 2.0, 3.0, 4.4])
    rec = Recycle(3)
    rec.bind((object(),))
    for w in (np.eye(n)[0] + np.eye(n)[3], np.eye(n)[1]):
        w = w / np.sqrt(MPI_COMM.size)  # each rank holds the same rows: unit over the ranks
        rec.record(w, A_old @ w)
    rec.commit(MPI_COMM)
    rec.carry()
    rec.bind((object(),))
    basis = rec.basis(np.zeros(n, dtype=bool), MPI_COMM)
    assert basis.stale
    c = np.array([2.0, 0.5])
    d = basis.W @ c
    assert rec.swap(c, d, A_new @ d, MPI_COMM)
    basis = rec.basis(np.zeros(n, dtype=bool), MPI_COMM)
    assert basis.stale  # column 1 still of A_old
    W, AW = basis.W, basis.AW
    assert np.allclose(W[:, 0], d / np.sqrt(MPI_COMM.allreduce(float(d @ d), op=MPI.SUM)))
    assert np.allclose(AW[:, 0], A_new @ W[:, 0])
    C = MPI_COMM.allreduce(W.T @ AW, op=MPI.SUM)
    assert np.allclose(rec._C[:2, 0], C[:2, 0]) and np.allclose(rec._C[0, :2], C[:2, 0])
    assert not rec.swap(np.array([1.0, 0.0]), d, A_new @ d, MPI_COMM)  # 0 is exact now
