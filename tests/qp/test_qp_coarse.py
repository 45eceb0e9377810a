"""The sparse coarse problem: sparse Cholesky back ends, and the sparse route of
``orthonormalize`` against the dense one on random and FETI matrices (regular and singular)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from qp_helpers import COMM, gather, make_vec, ownership, row_block_constraint

from dolfinx_feti.qp import Projector, RowBlockConstraint, homogenize, orthonormalize
from dolfinx_feti.qp.sparse_cholesky import (
    NotPositiveDefinite,
    PetscFactor,
    _cholmod,
    sparse_cholesky,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
from coarse_lattice import lattice_gt  # noqa: E402

TOL = 1e-12
BACKENDS = ["petsc"] + (["cholmod"] if _cholmod() is not None else [])


def _rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b))
                 / max(np.linalg.norm(b), 1e-300))


def lattice_constraint(ns: int, dim: int, **kw) -> tuple[RowBlockConstraint, np.ndarray]:
    """The distributed constraint G of a lattice (rows of Gᵀ split over the ranks), and Gᵀ."""
    Gt = lattice_gt(ns, dim, **kw)
    lo, hi = ownership(Gt.shape[0])
    return RowBlockConstraint(Gt[lo:hi], COMM), Gt.toarray()


def random_sparse(m: int, n: int, seed: int, redundant: int = 0) -> np.ndarray:
    """A sparse random m × n matrix; with ``redundant`` > 0, that many rows combine others."""
    rng = np.random.default_rng(seed)
    D = sp.random(m, n, density=0.05, random_state=rng).toarray()
    D[np.arange(m), rng.integers(0, n, m)] += 1.0  # no empty row
    for j in range(redundant):
        a, b = rng.choice(m - redundant, 2, replace=False)
        D[m - 1 - j] = D[a] - 0.5 * D[b]
    return D


@pytest.mark.parametrize("backend", BACKENDS)
def test_sparse_cholesky_halves(backend):
    Gt = lattice_gt(4, 3)
    A = (Gt.T @ Gt).tocsr()
    f = sparse_cholesky(A, backend)
    rng = np.random.default_rng(0)
    x = rng.standard_normal((A.shape[0], 3))
    assert _rel(A @ f.solve(x), x) < 1e-13
    for j in range(3):  # T A Tᵀ = I and Tᵀ T = A⁻¹
        assert _rel(f.half(A @ f.half_transpose(x[:, j])), x[:, j]) < 1e-12
        assert _rel(f.half_transpose(f.half(A @ x[:, j])), x[:, j]) < 1e-12
    exact = 1.0 / np.linalg.cond(A.toarray())
    assert exact * (1 - 1e-2) <= f.rcond() <= 1.0  # an estimate, never below 1/κ (2 % slack)
    f.destroy()
    with pytest.raises(NotPositiveDefinite):
        sparse_cholesky(A - 2 * sp.eye(A.shape[0]) * A.diagonal().max(), backend)


def test_petsc_factor_rcond_is_close():
    A = sp.diags(np.linspace(1.0, 1e4, 50)).tocsr()
    assert PetscFactor(A).rcond() == pytest.approx(1e-4, rel=0.05)


def _compare(con, m_expected_rank, n, seed=0, rhs=None):
    """Sparse vs dense orthonormalization of one constraint: every derived quantity agrees."""
    dense = orthonormalize(con, rhs=rhs, method="dense")
    sparse = orthonormalize(con, rhs=rhs, method="sparse")
    assert sparse.method == "sparse" and dense.rank == sparse.rank == m_expected_rank
    rng = np.random.default_rng(seed)
    x = make_vec(rng.standard_normal(n))
    outs = []
    for c in (dense, sparse):
        out = x.duplicate()
        Projector(c).apply(x, out)
        outs.append(gather(out))
    assert _rel(outs[1], outs[0]) < TOL
    assert abs(np.linalg.norm(sparse.mult(x)) - np.linalg.norm(dense.mult(x))) \
        < TOL * np.linalg.norm(dense.mult(x))
    z = con.mult(x)  # in the range of D
    assert _rel(sparse.gram_solve(z), dense.gram_solve(z)) < TOL
    assert _rel(sparse.transform_transpose(sparse.transform(z)),
                dense.transform_transpose(dense.transform(z))) < TOL
    Nd, Ns = dense.null_space, sparse.null_space
    assert Ns.shape == Nd.shape
    assert np.abs(Ns @ Ns.T - Nd @ Nd.T).max() < 1e-10 if Nd.shape[1] else True
    if rhs is not None:
        assert abs(sparse.inconsistency - dense.inconsistency) < 1e-10
        hs, hd = x.duplicate(), x.duplicate()
        homogenize(sparse, hs)
        homogenize(dense, hd)
        assert _rel(gather(hs), gather(hd)) < TOL
    return dense, sparse


def test_sparse_equals_dense_random_full_rank():
    D = random_sparse(60, 400, seed=1)
    con = row_block_constraint(D)
    e = D @ np.random.default_rng(2).standard_normal(400)
    _, sparse = _compare(con, 60, 400, rhs=e)
    assert sparse.null_space.shape == (60, 0) and sparse.inconsistency == 0.0


def test_sparse_equals_dense_random_redundant():
    D = random_sparse(60, 400, seed=3, redundant=4)
    con = row_block_constraint(D)
    e = D @ np.random.default_rng(4).standard_normal(400)
    _, sparse = _compare(con, 56, 400, rhs=e)
    assert np.abs(D.T @ sparse.null_space).max() < 1e-10
    e_bad = e.copy()
    e_bad[-1] += 1.0  # the last row combines two others: e must too
    dense, sparse = _compare(con, 56, 400, rhs=e_bad)
    assert sparse.inconsistency > 1e-3


@pytest.mark.parametrize("dim,value_size", [(2, 1), (2, 2), (3, 3)])
@pytest.mark.parametrize("clamped", [True, False], ids=["clamped", "floating"])
def test_sparse_equals_dense_feti(dim, value_size, clamped):
    """Lattices of 5² / 3³ subdomains: a clamped face, or none (k rigid motions of the whole
    lattice that no row sees: a singular G Gᵀ)."""
    con, Gt = lattice_constraint(5 if dim == 2 else 3, dim, value_size=value_size,
                                 clamped=clamped)
    m = Gt.shape[1]
    k = 1 if value_size == 1 else (3 if dim == 2 else 6)
    rank = m if clamped else m - k
    e = np.random.default_rng(5).standard_normal(m)
    e_bal = Gt.T @ (Gt @ np.linalg.lstsq(Gt.T @ Gt, e, rcond=None)[0])  # e in Im G
    _, sparse = _compare(con, rank, Gt.shape[0], rhs=e_bal)
    assert sparse.inconsistency < 1e-10
    if not clamped:
        assert np.abs(Gt @ sparse.null_space).max() < 1e-10


def test_auto_switches_at_dense_max(monkeypatch):
    import dolfinx_feti.qp.equality as eq

    con, _ = lattice_constraint(3, 2)
    assert orthonormalize(con).method == "cholesky"
    monkeypatch.setattr(eq, "DENSE_MAX", 8)
    assert orthonormalize(con).method == "sparse"
    with pytest.raises(ValueError, match="method"):
        orthonormalize(con, method="qr")
