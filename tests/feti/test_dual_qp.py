"""The dual QP handed out by ``dual_qp``: our own SMALBE on it reproduces ``solve``, and its
solution satisfies the QP's KKT conditions computed from the handed-out objects alone."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.qp import smalbe

RTOL = 1e-10


@pytest.fixture(scope="module")
def problem(root):
    mesh = df.read_gmsh(root / "meshes/membranes_8.msh")
    H = 0.25
    return df.ContactProblem(
        mesh, df.Poisson(source=ref.membrane_source), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")],
        decomposition=df.ByFunction(
            lambda m: (np.floor(m[:, 0] / H) + 8 * np.floor(m[:, 1] / H)).astype(np.int64)))


@pytest.fixture(scope="module")
def solved(problem):
    qp = df.dual_qp(problem)
    x = qp.start()
    res = smalbe(qp.A, qp.b, qp.constraint, x, lb=qp.lb, rtol=RTOL, norm_A=qp.norm_A,
                 eq_scale=qp.norm_A, rho=1.1 * qp.norm_A, M=qp.norm_A, max_outer=1000)
    return qp, x, res


def test_sizes_and_bounds(problem, solved):
    qp, _, _ = solved
    assert qp.constraint.m == 32  # one constant per floating subdomain: all 32 in Total FETI
    n_ineq = int(qp.rows.contact.inequality.sum())
    assert qp.feti.comm.allreduce(int(np.isfinite(qp.lb.array_r).sum())) == n_ineq == 9
    assert qp.norm_A > 0 and np.isfinite(qp.norm_A)


def test_same_multipliers_as_solve(problem, solved):
    qp, x, res = solved
    assert res.converged
    lam = qp.multipliers(x)
    sol = df.solve(problem, rtol=RTOL)
    diff = np.linalg.norm(lam.array_r - sol.lam.array_r)
    scale = sol.lam.norm()
    assert qp.feti.comm.allreduce(diff**2) ** 0.5 <= 1e-7 * scale


def test_kkt_of_the_qp(solved):
    """x ≥ lb, G̃x = 0, and A x − b + G̃ᵀμ is ≥ 0 at the bound and 0 elsewhere."""
    qp, x, res = solved
    comm = qp.feti.comm
    g = qp.b.duplicate()
    qp.A.mult(x, g)
    g.axpy(-1.0, qp.b)
    corr = qp.b.duplicate()
    qp.constraint.mult_transpose(res.multiplier, corr)
    g.axpy(1.0, corr)
    scale = qp.b.norm()
    xa, lb, ga = x.array_r, qp.lb.array_r, g.array_r
    at_bound = np.isfinite(lb) & (xa - lb <= 1e-12 * max(1.0, np.abs(lb).max(initial=0.0)))
    assert comm.allreduce(float(np.min(xa - lb, initial=np.inf)), op=MPI.MIN) >= -1e-14
    assert np.linalg.norm(qp.constraint.mult(x)) <= 1e-8 * scale / qp.norm_A
    free_res = comm.allreduce(float(np.sum(ga[~at_bound] ** 2))) ** 0.5
    assert free_res <= 1e-8 * scale
    worst = comm.allreduce(float(np.min(ga[at_bound], initial=np.inf)), op=MPI.MIN)
    assert worst >= -1e-8 * scale
    # the solution is a minimizer: no worse than the feasible start
    assert qp.objective(x) <= qp.objective(qp.start()) + 1e-14



def test_multiplier_estimate_at_the_solution(solved):
    """At the solution the least-squares multiplier is SMALBE's μ."""
    qp, x, res = solved
    mu = qp.multiplier_estimate(x)
    assert mu.shape == res.multiplier.shape
    assert np.linalg.norm(mu - res.multiplier) <= 1e-6 * np.linalg.norm(res.multiplier)


def test_multiplier_estimate_is_least_squares(solved):
    """Away from the solution: G̃ᵀμ balances the gradient off the bound as well as it can.

    The normal equations of min ‖g_F + (G̃ᵀμ)_F‖ over the rows F off the bound: the residual
    on F is orthogonal to every row of G restricted to F.
    """
    qp, x, _ = solved
    comm = qp.feti.comm
    y = qp.start()
    y.axpby(0.5, 0.5, x)  # halfway from the default start: rows on and off the bound
    lb = qp.lb.array_r
    free = ~(np.isfinite(lb) & (y.array_r <= lb))
    assert comm.allreduce(int((~free).sum())) > 0
    mu = qp.multiplier_estimate(y)
    g = qp.b.duplicate()
    qp.A.mult(y, g)
    g.axpy(-1.0, qp.b)
    size = comm.allreduce(float(np.sum(g.array_r[free] ** 2))) ** 0.5
    corr = qp.b.duplicate()
    qp.constraint.mult_transpose(mu, corr)
    r = g.array_r[free] + corr.array_r[free]
    Gt = qp.constraint.base.Dt_local[np.flatnonzero(free)]
    normal = comm.allreduce(Gt.T @ r)
    scale = comm.allreduce(float(abs(Gt).max()) if Gt.nnz else 0.0, op=MPI.MAX)
    assert size > 0 and np.abs(normal).max() <= 1e-10 * scale * size
    # and not a trivial μ: without it the residual is not orthogonal
    assert np.abs(comm.allreduce(Gt.T @ g.array_r[free])).max() > 1e-6 * scale * size
