"""The local stiffness scaling Z ≈ (B Δ Bᵀ)⁻¹: exact block inverses, exact on gluing and
Dirichlet rows, the same blocks on any number of ranks."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.feti import precond
from dolfinx_feti.feti.precond import _DualScaling, _inverse_blocks


def test_inverse_blocks_of_a_random_block_matrix():
    rng = np.random.default_rng(0)
    n = 40
    key = rng.integers(0, 9, n)  # blocks of sizes 0..~8, rows interleaved
    A = rng.standard_normal((n, n))
    A = A @ A.T + n * np.eye(n)
    same = key[:, None] == key[None, :]
    r, c = np.nonzero(same)
    rows = 1000 + np.arange(n)  # global row numbers
    zr, zc, zv, singular = _inverse_blocks(rows[r], rows[c], A[r, c], key[r])
    assert not singular
    Z = sp.csr_matrix((zv, (zr - 1000, zc - 1000)), shape=(n, n)).toarray()
    assert np.allclose(Z, np.linalg.inv(np.where(same, A, 0.0)), atol=1e-13)


def test_inverse_blocks_flags_a_singular_block():
    A = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 2.0]])
    r, c = np.nonzero(A)
    assert _inverse_blocks(r, c, A[r, c], np.array([0, 0, 1])[r])[3]


def _dual_problem(contact: bool) -> df.DualQP:
    mesh = df.read_gmsh("meshes/membranes_8.msh")
    grid = df.ByFunction(lambda m: (np.floor(m[:, 0] / 0.25)
                                    + 100 * np.floor(m[:, 1] / 0.25)).astype(np.int64))
    pde = df.Poisson(source=-1.0, k={"left": 1.0, "right": 100.0})  # a coefficient jump
    if contact:
        return df.dual_qp(df.ContactProblem(
            mesh, pde, dirichlet=[df.Dirichlet("dirichlet")], decomposition=grid,
            contact=[df.NodeToNode("contact_left", "contact_right")]))
    return df.dual_qp(df.ContactProblem(
        mesh, pde, decomposition=grid,
        dirichlet=[df.Dirichlet("dirichlet"), df.Dirichlet("contact_right")]))


def _residual(feti, scaling) -> float:
    """max |Z C x − x| / max |x|, C = B Δ Bᵀ applied matrix-free."""
    x = feti.d.duplicate()
    x.array[:] = np.random.default_rng(feti.comm.rank).standard_normal(x.getLocalSize())
    w = feti.B.createVecRight()
    feti.B.multTranspose(x, w)
    w.array[:] *= scaling.delta
    Cx = feti.d.duplicate()
    feti.B.mult(w, Cx)
    y = feti.d.duplicate()
    scaling.apply(Cx, y)
    worst = feti.comm.allreduce(float(np.abs(y.array_r - x.array_r).max(initial=0.0)),
                                op=MPI.MAX)
    return worst / feti.comm.allreduce(float(np.abs(x.array_r).max()), op=MPI.MAX)


@pytest.mark.parametrize("contact", [False, True], ids=["glued", "contact"])
def test_exact_inverse(contact):
    """Z = (B Δ Bᵀ)⁻¹ to rounding on any number of ranks: gluing and Dirichlet rows form node
    blocks; contact rows join the blocks of their nodes (here at the subdomain cross points of
    the contact line)."""
    feti = _dual_problem(contact).feti
    assert _residual(feti, _DualScaling(feti)) < 1e-12


def test_capped_groups_keep_node_blocks(monkeypatch):
    """With MERGE_MAX below the groups' size the couplings are dropped: not exact, still
    symmetric, and the solve with it converges to the same solution."""
    qp = _dual_problem(True)
    exact = df.solve(qp.feti.problem, rtol=1e-10)
    monkeypatch.setattr(precond, "MERGE_MAX", 1)
    feti = qp.feti
    z = _DualScaling(feti)
    assert _residual(feti, z) > 1e-6
    if feti.comm.size == 1:
        Zi, Zj, Zv = z.Z.getValuesCSR()
        Z = sp.csr_matrix((Zv, Zj, Zi), shape=z.Z.getSize())
        assert abs(Z - Z.T).max() < 1e-14
    capped = df.solve(feti.problem, rtol=1e-10)
    assert capped.report.converged
    u, ref = capped.nodal_values(), exact.nodal_values()
    assert np.abs(u - ref).max() <= 1e-7 * np.abs(ref).max()
