"""Equality constraints: orthonormalization, rank and inconsistency, projectors, operators."""

import numpy as np
import pytest
from qp_helpers import counting, gather, make_mat, make_vec, random_spd, row_block_constraint

from dolfinx_feti.qp import (
    EqualityConstraint,
    Projector,
    homogenize,
    orthonormalize,
    penalized_operator,
    projected_operator,
)


def dense_of(con, n: int) -> np.ndarray:
    """Dense D~ (rows) assembled by applying D~^T to unit vectors."""
    rows = []
    out = make_vec(np.zeros(n))
    for j in range(con.m):
        y = np.zeros(con.m)
        y[j] = 1.0
        con.mult_transpose(y, out)
        rows.append(gather(out))
    return np.array(rows).reshape(con.m, n)


def test_row_block_products():
    rng = np.random.default_rng(0)
    D = rng.standard_normal((5, 23))
    con = row_block_constraint(D)
    assert isinstance(con, EqualityConstraint)
    x = rng.standard_normal(23)
    assert np.allclose(con.mult(make_vec(x)), D @ x, rtol=1e-14, atol=1e-13)
    y = rng.standard_normal(5)
    out = make_vec(np.zeros(23))
    con.mult_transpose(y, out)
    assert np.allclose(gather(out), D.T @ y, rtol=1e-14, atol=1e-13)
    assert np.allclose(con.gram(), D @ D.T, rtol=1e-14, atol=1e-12)


def test_orthonormalize_full_rank_is_cholesky():
    rng = np.random.default_rng(1)
    D = rng.standard_normal((6, 40))
    e = rng.standard_normal(6)
    con = orthonormalize(row_block_constraint(D), rhs=e)
    assert con.method == "cholesky" and con.rank == con.m == 6
    assert con.null_space.shape == (6, 0) and con.inconsistency == 0.0
    Dt = dense_of(con, 40)
    assert np.allclose(Dt @ Dt.T, np.eye(6), atol=1e-13)
    # Same row space, and D~ x = T D x as the matrix-free product says.
    x = rng.standard_normal(40)
    assert np.allclose(con.mult(make_vec(x)), Dt @ x, atol=1e-13)
    assert np.linalg.matrix_rank(np.vstack([D, Dt])) == 6


def test_orthonormalize_redundant_rows():
    rng = np.random.default_rng(2)
    D0 = rng.standard_normal((4, 30))
    # Duplicated and combined rows: rank 4 out of 7 (like redundant gluing at cross points).
    D = np.vstack([D0, D0[1], D0[0] + 2 * D0[3], -D0[2]])
    e_ok = D @ rng.standard_normal(30)
    con = orthonormalize(row_block_constraint(D), rhs=e_ok)
    assert con.method == "eigen" and con.rank == 4
    N = con.null_space
    assert N.shape == (7, 3)
    assert np.allclose(D.T @ N, 0.0, atol=1e-12) and np.allclose(N.T @ N, np.eye(3), atol=1e-12)
    assert con.inconsistency < 1e-12
    Dt = dense_of(con, 30)
    assert np.allclose(Dt @ Dt.T, np.eye(4), atol=1e-12)
    # Minimum-norm solution of D x = e.
    xh = make_vec(np.zeros(30))
    homogenize(con, xh)
    xs = gather(xh)
    assert np.allclose(D @ xs, e_ok, atol=1e-10 * np.linalg.norm(e_ok))
    assert np.allclose(xs, np.linalg.pinv(D) @ e_ok, atol=1e-10 * np.linalg.norm(xs))


def test_inconsistent_rhs_detected():
    rng = np.random.default_rng(3)
    D0 = rng.standard_normal((3, 20))
    D = np.vstack([D0, D0[0]])  # rows 0 and 3 equal: e_0 must equal e_3
    e = D @ rng.standard_normal(20)
    e[3] += 1.0
    con = orthonormalize(row_block_constraint(D), rhs=e)
    assert con.rank == 3
    # The null vector is (e_0 - e_3)/sqrt(2): its share of e is 1/sqrt(2) / ||e||.
    assert con.inconsistency == pytest.approx(1 / np.sqrt(2) / np.linalg.norm(e), rel=1e-10)


def test_homogenize_needs_rhs():
    con = orthonormalize(row_block_constraint(np.eye(3, 10)))
    with pytest.raises(ValueError, match="right-hand side"):
        homogenize(con, make_vec(np.zeros(10)))


def test_projector_and_operators():
    rng = np.random.default_rng(4)
    n, m = 36, 5
    D = rng.standard_normal((m, n))
    con = orthonormalize(row_block_constraint(D))
    Q, _ = np.linalg.qr(D.T)
    P = np.eye(n) - Q @ Q.T
    proj = Projector(con)
    x = rng.standard_normal(n)
    xv, out = make_vec(x), make_vec(np.zeros(n))
    proj.apply(xv, out)
    assert np.allclose(gather(out), P @ x, atol=1e-12)
    proj.apply(xv, xv)  # in place
    assert np.allclose(gather(xv), P @ x, atol=1e-12)
    Pm = proj.as_mat(xv)
    Pm.mult(make_vec(x), out)
    assert np.allclose(gather(out), P @ x, atol=1e-12)

    F = random_spd(n, rng)
    Fc, ctx = counting(make_mat(F))
    rho = 3.0
    PFP = projected_operator(Fc, con, rho)
    PFP.mult(make_vec(x), out)
    assert np.allclose(gather(out), (P @ F @ P + rho * (np.eye(n) - P)) @ x, atol=1e-10)
    assert PFP.getPythonContext().mults == 1 == ctx.calls

    H = penalized_operator(Fc, con, rho)
    H.mult(make_vec(x), out)
    assert np.allclose(gather(out), (F + rho * (np.eye(n) - P)) @ x, atol=1e-10)
    assert H.getPythonContext().mults == 1 and ctx.calls == 2

    # Penalizing P F P on its own constraint gives the fused P F P + rho Q: one product by F,
    # the same values as the generic penalized operator.
    Hf = penalized_operator(projected_operator(Fc, con), con, rho)
    Hf.mult(make_vec(x), out)
    assert np.allclose(gather(out), (P @ F @ P + rho * (np.eye(n) - P)) @ x, atol=1e-10)
    assert Hf.getPythonContext().rho == rho and ctx.calls == 3
    # projected on another constraint: not fused, still P2 F P2 + rho Q
    D2 = rng.standard_normal((m, n))
    other = orthonormalize(row_block_constraint(D2))
    Hg = penalized_operator(projected_operator(Fc, other), con, rho)
    Hg.mult(make_vec(x), out)
    Q2, _ = np.linalg.qr(D2.T)
    P2 = np.eye(n) - Q2 @ Q2.T
    assert np.allclose(gather(out), (P2 @ F @ P2 + rho * (np.eye(n) - P)) @ x, atol=1e-10)
