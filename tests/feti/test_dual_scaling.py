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


def _problem(contact: bool) -> df.ContactProblem:
    mesh = df.read_gmsh("meshes/membranes_8.msh")
    grid = df.ByFunction(lambda m: (np.floor(m[:, 0] / 0.25)
                                    + 100 * np.floor(m[:, 1] / 0.25)).astype(np.int64))
    pde = df.Poisson(source=-1.0, k={"left": 1.0, "right": 100.0})  # a coefficient jump
    if contact:
        return df.ContactProblem(mesh, pde, dirichlet=[df.Dirichlet("dirichlet")],
                                 decomposition=grid,
                                 contact=[df.NodeToNode("contact_left", "contact_right")])
    return df.ContactProblem(mesh, pde, decomposition=grid,
                             dirichlet=[df.Dirichlet("dirichlet"), df.Dirichlet("contact_right")])


def _scaling(problem: df.ContactProblem, method: str = "tfeti"):
    """The operands of the method's last primal system and the scaling built from them."""
    op = df.dual_qp(problem, method=method).primal.preconditioner_operands()
    return op, _DualScaling(op.K, op.B, op.row_blocks)


def _residual(op, scaling) -> float:
    """max |Z C x − x| / max |x|, C = B Δ Bᵀ applied matrix-free."""
    B = op.B
    comm = B.getComm().tompi4py()
    x = B.createVecLeft()
    x.array[:] = np.random.default_rng(comm.rank).standard_normal(x.getLocalSize())
    w = B.createVecRight()
    B.multTranspose(x, w)
    w.array[:] *= scaling.delta
    Cx = B.createVecLeft()
    B.mult(w, Cx)
    y = B.createVecLeft()
    scaling.apply(Cx, y)
    worst = comm.allreduce(float(np.abs(y.array_r - x.array_r).max(initial=0.0)), op=MPI.MAX)
    return worst / comm.allreduce(float(np.abs(x.array_r).max(initial=0.0)), op=MPI.MAX)


# (FETI-DP of the glued case has no dual rows on this coarse mesh: every interface node is a
# vertex.)
@pytest.mark.parametrize("contact, method", [(False, "tfeti"), (False, "feti1"),
                                             (True, "tfeti"), (True, "feti1"),
                                             (True, "fetidp")])
def test_exact_inverse(contact, method):
    """Z = (B Δ Bᵀ)⁻¹ to rounding on any number of ranks: gluing and Dirichlet rows form node
    blocks; contact rows join the blocks of their nodes (here at the subdomain cross points of
    the contact line). FETI-1 and FETI-DP remove rows (Dirichlet rows; gluing rows between
    corner copies): their row blocks are the kept rows' ones."""
    op, z = _scaling(_problem(contact), method)
    assert _residual(op, z) < 1e-12


def test_scaling_needs_row_blocks():
    """Without row blocks (a system built by hand) the stiffness scaling is refused, and the
    preconditioner says so and runs with multiplicity scaling."""
    op = df.dual_qp(_problem(False)).primal.preconditioner_operands()
    with pytest.raises(df.SolveError, match="row blocks"):
        _DualScaling(op.K, op.B, None)
    prec = precond.LumpedPreconditioner(op[:3], scaling="stiffness")
    assert prec.scaling == "multiplicity" and "row blocks" in prec.notes[0]
    prec.destroy()


def test_capped_groups_keep_node_blocks(monkeypatch):
    """With MERGE_MAX below the groups' size the couplings are dropped: not exact, still
    symmetric, and the solve with it converges to the same solution."""
    problem = _problem(True)
    exact = df.solve(problem, rtol=1e-10)
    monkeypatch.setattr(precond, "MERGE_MAX", 1)
    op, z = _scaling(problem)
    assert _residual(op, z) > 1e-6
    if op.B.getComm().getSize() == 1:
        Zi, Zj, Zv = z.Z.getValuesCSR()
        Z = sp.csr_matrix((Zv, Zj, Zi), shape=z.Z.getSize())
        assert abs(Z - Z.T).max() < 1e-14
    capped = df.solve(problem, rtol=1e-10)
    assert capped.report.converged
    u, ref = capped.nodal_values(), exact.nodal_values()
    assert np.abs(u - ref).max() <= 1e-7 * np.abs(ref).max()
