"""The QP solver objects on a dual QP of FETI, set up from SolverOptions as the solve would.

What ``solve._run_qp`` does today with the functions (``smalbe``, ``mprgp``, ``cg``, absolute
ρ, M, η) and what it will do with the objects (relative options straight from
:class:`~dolfinx_feti.SolverOptions`, one :class:`~dolfinx_feti.qp.QP`) give the same iterates
and F-multiplications, bit for bit, on the B1 membranes (SMALBE + MPRGP, the dual penalty's
MPRGP alone) and a tied pair of blocks (projected CG).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.feti.preconditioner import make_preconditioner
from dolfinx_feti.io import meshes
from dolfinx_feti.qp import (
    CG,
    MPRGP,
    QP,
    SMALBE,
    ProjectedPreconditioner,
    cg,
    mprgp,
    projected_operator,
    smalbe,
)
from dolfinx_feti.qp.mprgp import OPTIONS as MPRGP_OPTIONS
from dolfinx_feti.qp.smalbe import OPTIONS as SMALBE_OPTIONS

MESHES = Path(__file__).resolve().parents[2] / "meshes"
COMM = MPI.COMM_WORLD


def b1_dual(**kwargs):
    mesh = df.read_gmsh(MESHES / "membranes_8.msh")

    def f(x):
        return ufl.conditional(ufl.lt(x[0], 1.0),
                               ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0),
                               ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0))

    problem = df.ContactProblem(mesh, df.Poisson(source=f),
                                dirichlet=[df.Dirichlet("dirichlet")],
                                contact=[df.NodeToNode("contact_left", "contact_right")])
    opts = df.SolverOptions.create(rtol=1e-8, **kwargs)
    qp = df.dual_qp(problem, COMM, factor=opts.factor, norm_rtol=opts.norm_rtol)
    precond = make_preconditioner(opts.preconditioner, qp.primal, opts.factor,
                                  opts.preconditioner_scaling)
    return qp, opts, precond


def run(qp, solve, start: bool = True):
    """Start as the solve does; the iterate, the F-multiplications and the result."""
    x = qp.start() if start else qp.b.duplicate()
    if not start:
        x.set(0.0)
    before = qp.feti.hessian_mults
    res = solve(x)
    return x.array_r.copy(), qp.feti.hessian_mults - before, res


@pytest.mark.parametrize("kwargs", [{}, {"smalbe_acceleration": "none", "smalbe_eta": 0.05,
                                         "mprgp_expansion": "optimal"}])
def test_smalbe_object_on_the_dual_qp(kwargs):
    dual, opts, precond = b1_dual(**kwargs)
    norm_A, o, inner = dual.norm_A, opts.of(SMALBE_OPTIONS), opts.of(MPRGP_OPTIONS)

    def functions(x):  # solve._run_qp today
        return smalbe(dual.A, dual.b, dual.constraint, x, lb=dual.lb, inner="mprgp",
                      rtol=opts.rtol, eq_rtol=opts.eq_rtol or opts.rtol, eq_scale=norm_A,
                      rho=o["rho"] * norm_A, M=o["M"] * norm_A,
                      eta=None if o["eta"] is None else o["eta"] * dual.b.norm(),
                      beta=o["beta"], norm_A=norm_A, inner_options=inner,
                      preconditioner=precond, max_outer=opts.max_outer, max_it=opts.max_it,
                      acceleration=o["acceleration"], depth=o["depth"])

    def objects(x):  # the options as they are: relative to ||PFP|| and ||b||
        solver = SMALBE(MPRGP(**inner), rtol=opts.rtol, eq_rtol=opts.eq_rtol or opts.rtol,
                        eq_scale=norm_A, max_outer=opts.max_outer, max_it=opts.max_it, **o)
        qp = QP.create(dual.A, dual.b, lb=dual.lb, eq=dual.constraint, norm_A=norm_A,
                       preconditioner=precond)
        return solver.solve(qp, x)

    x1, m1, r1 = run(dual, functions)
    x2, m2, r2 = run(dual, objects)
    assert r1.converged and r1.counts == r2.counts and m1 == m2 > 0
    assert np.array_equal(x1, x2) and np.array_equal(r1.multiplier, r2.multiplier)


def test_penalty_and_cg_objects_on_dual_qps():
    dual, opts, precond = b1_dual(qp="penalty")
    rho = opts.of(df.options.PENALTY)["rho"] * dual.norm_A
    Arho = projected_operator(dual.feti.F, dual.constraint, rho=rho)
    pre = ProjectedPreconditioner(precond, dual.constraint, rho)
    inner = opts.of(MPRGP_OPTIONS)
    x1, m1, r1 = run(dual, lambda x: mprgp(
        Arho, dual.b, x, lb=dual.lb, rtol=opts.rtol, max_it=opts.max_it,
        norm_A=max(dual.norm_A, rho), preconditioner=pre, **inner))
    qp = QP.create(Arho, dual.b, lb=dual.lb, norm_A=max(dual.norm_A, rho), preconditioner=pre)
    x2, m2, r2 = run(dual, lambda x: MPRGP(rtol=opts.rtol, max_it=opts.max_it,
                                           **inner).solve(qp, x))
    assert r1.converged and np.array_equal(x1, x2) and m1 == m2 > 0
    assert r1.counts == r2.counts

    mesh = df.build_mesh(meshes.blocks3d, n=3, comm=COMM)
    tied = df.ContactProblem(mesh, df.Elasticity(1.0, 0.3),
                             dirichlet=[df.Dirichlet("bottom"),
                                        df.Dirichlet("top", value=(0.02, 0.01, -0.02))],
                             ties=[df.Tie("contact_upper", "contact_lower")],
                             decomposition=df.Parts(2))
    dual = df.dual_qp(tied, COMM)
    precond = make_preconditioner("lumped", dual.primal, None, "stiffness")
    x1, m1, r1 = run(dual, lambda x: cg(dual.A, dual.b, x, projector=dual.projector,
                                        rtol=1e-8, atol=dual.b_noise,
                                        preconditioner=precond), start=False)
    qp = QP(dual.A, dual.b, eq=dual.constraint, preconditioner=precond)
    x2, m2, r2 = run(dual, lambda x: CG(rtol=1e-8, atol=dual.b_noise).solve(qp, x),
                     start=False)
    assert r1.converged and np.array_equal(x1, x2) and m1 == m2 > 0
