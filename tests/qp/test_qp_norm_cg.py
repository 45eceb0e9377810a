"""Lanczos norm estimate and (projected) CG."""

import numpy as np
import pytest
from petsc4py import PETSc
from qp_helpers import (
    COMM,
    counting,
    gather,
    laplacian_2d,
    make_mat,
    make_vec,
    random_spd,
    row_block_constraint,
)

from dolfinx_feti.qp import Projector, cg, estimate_norm, orthonormalize, projected_operator


@pytest.mark.parametrize("case", ["dense", "laplacian", "clustered", "psd"])
def test_lanczos_norm(case):
    rng = np.random.default_rng(10)
    if case == "dense":
        A = random_spd(50, rng, cond=1e4)
    elif case == "laplacian":
        A = laplacian_2d(15).toarray()
    elif case == "clustered":  # top eigenvalue separated by 1e-3 relative only
        Q, _ = np.linalg.qr(rng.standard_normal((60, 60)))
        A = (Q * np.r_[np.linspace(0.1, 0.999, 59), 1.0]) @ Q.T
    else:  # singular PSD, like P F P
        B = rng.standard_normal((40, 25))
        A = B @ B.T
    lmax = np.linalg.eigvalsh(A).max()
    Ac, ctx = counting(make_mat(A))
    rtol = 1e-4
    est = estimate_norm(Ac, make_vec(np.zeros(len(A))), rtol=rtol)
    assert est.iterations == ctx.calls <= 100
    # A Ritz value: never above ||A||; below it by no more than a few rtol from a random start,
    # except inside a tight cluster at the top, where the change test may stop before the
    # cluster is resolved (shortfall up to the cluster width, 1e-3 here): alpha_bar = 1.95/value
    # is still below 2/||A|| then.
    assert est.value <= lmax * (1 + 1e-12)
    assert est.value >= lmax * (1 - (1.1e-3 if case == "clustered" else 3 * rtol))
    assert 1.95 / est.value < 2.0 / lmax
    assert est.residual >= 0.0


@pytest.mark.parametrize("case", ["perturbed", "new_top"])
def test_lanczos_from_a_nearby_ritz_vector(case):
    """A start from the Ritz vector of a nearby operator: fewer steps, the same estimate.

    ``perturbed``: a small symmetric change (as new rows of B with turned normals give P F P);
    ``new_top``: the change adds an eigenvalue above the old top, along a direction orthogonal
    to the guess — still found (the random start is in the start too).
    """
    rng = np.random.default_rng(14)
    n = 200
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    lam = np.r_[np.linspace(0.01, 0.6, n - 1), 1.0]
    A0 = (Q * lam) @ Q.T
    first = estimate_norm(make_mat(A0), make_vec(np.zeros(n)), rtol=1e-4, ritz=True)
    y = gather(first.vector)
    assert np.linalg.norm(y) == pytest.approx(1.0, rel=1e-10)
    assert abs(y @ Q[:, -1]) > 0.99  # it is the top eigenvector
    if case == "perturbed":
        E = rng.standard_normal((n, n)) * 1e-3
        A1 = A0 + (E + E.T) / 2
    else:
        A1 = A0 + 1.5 * np.outer(Q[:, 0], Q[:, 0])  # λ = 1.51 where the guess has none
    lmax = np.linalg.eigvalsh(A1).max()
    cold = estimate_norm(make_mat(A1), make_vec(np.zeros(n)), rtol=1e-4)
    Ac, ctx = counting(make_mat(A1))
    warm = estimate_norm(Ac, make_vec(np.zeros(n)), rtol=1e-4, guess=first.vector)
    assert warm.iterations == ctx.calls
    assert lmax * (1 - 3e-4) <= warm.value <= lmax * (1 + 1e-12)
    if case == "perturbed":
        assert warm.iterations < cold.iterations


def test_lanczos_same_on_self_and_world():
    A = laplacian_2d(12).toarray()
    vals = []
    for comm in (PETSc.COMM_SELF, COMM):
        est = estimate_norm(make_mat(A, comm), make_vec(np.zeros(len(A)), comm), rtol=1e-6)
        vals.append((est.value, est.iterations))
    assert vals[0][1] == vals[1][1]
    assert vals[0][0] == pytest.approx(vals[1][0], rel=1e-12)


def test_cg_plain():
    A = laplacian_2d(10)
    b = np.random.default_rng(11).standard_normal(A.shape[0])
    Ac, ctx = counting(make_mat(A))
    x = make_vec(np.zeros_like(b))
    res = cg(Ac, make_vec(b), x, rtol=1e-12)
    assert res.converged and res.reason == "rtol"
    assert res.hessian_mults == ctx.calls == res.iterations + 1
    ref = np.linalg.solve(A.toarray(), b)
    assert np.linalg.norm(gather(x) - ref) <= 1e-10 * np.linalg.norm(ref)
    assert res.gP_norm <= 1e-12 * np.linalg.norm(b)


def test_cg_projected_and_max_it():
    rng = np.random.default_rng(12)
    n, m = 50, 6
    F = random_spd(n, rng, cond=20.0)
    G = rng.standard_normal((m, n))
    con = orthonormalize(row_block_constraint(G))
    P = np.eye(n) - np.linalg.pinv(G) @ G
    b = rng.standard_normal(n)
    A = projected_operator(make_mat(F), con)
    x = make_vec(rng.standard_normal(n))  # not in Im P: projected first
    res = cg(A, make_vec(b), x, projector=Projector(con), rtol=1e-12)
    assert res.converged
    xs = gather(x)
    # Solution of min 1/2 x'Fx - b'x on ker G, from the KKT system.
    K = np.block([[F, G.T], [G, np.zeros((m, m))]])
    ref = np.linalg.solve(K, np.r_[b, np.zeros(m)])[:n]
    assert np.linalg.norm(xs - ref) <= 1e-10 * np.linalg.norm(ref)
    assert np.linalg.norm(G @ xs) <= 1e-12 * np.linalg.norm(xs)
    assert np.linalg.norm(P @ (b - F @ xs)) <= 1e-11 * np.linalg.norm(P @ b)

    res = cg(A, make_vec(b), make_vec(np.zeros(n)), projector=Projector(con), rtol=1e-12,
             max_it=4)
    assert not res.converged and res.reason == "max_it" and res.iterations == 4
