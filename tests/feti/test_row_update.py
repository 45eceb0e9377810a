"""A row update (a moved curved obstacle: new contact coefficients, same K) against a fresh
set-up of the new problem.

``FetiSolver.update`` of a circle that moved sideways changes B only. The chain it builds
shares everything of K with the set-up's — the held K of FETI-1, FETI-DP's K_rr, K_rc, K_rr⁺,
Ψ and S_cc, the kernel R — and for an unchanged load also K⁺f, yet its operators (B of the
dualized system, G, F, d, b), its ‖P F P‖ estimate and its solution equal those of a new
``FetiSolver`` of the moved problem.
"""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx_feti as df
from dolfinx_feti.feti.corners import CornerSystem
from dolfinx_feti.feti.system import BlockSystem, local_csr
from dolfinx_feti.qp import estimate_norm

RTOL = 1e-10
METHODS = ("tfeti", "feti1", "fetidp")


@pytest.fixture(scope="module")
def hertz_mesh(root):
    return df.read_gmsh(root / "meshes/hertz2d.msh")


def on_circle(mesh, dx: float, dy: float) -> df.ContactProblem:
    """The Hertz disk on a rigid circle at (dx, −40 + dy), the block held, four subdomains."""
    return df.ContactProblem(
        mesh, df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -10.0 / 2 / 8.0)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.RigidObstacle("disk_contact", df.Sphere((dx, -40.0 + dy), 40.0))],
        decomposition=df.Parts(4))


def global_random(vec, seed: int = 3) -> np.ndarray:
    """A random vector of ``vec``'s global length, this rank's slice (rank-independent)."""
    lo, hi = vec.getOwnershipRange()
    return np.random.default_rng(seed).standard_normal(vec.getSize())[lo:hi]


def rel(a: np.ndarray, b: np.ndarray, comm) -> float:
    num = comm.allreduce(float(np.abs(a - b).max(initial=0.0)), op=MPI.MAX)
    den = comm.allreduce(float(np.abs(b).max(initial=0.0)), op=MPI.MAX)
    return num / max(den, 1e-300)


@pytest.fixture(scope="module", params=METHODS)
def updated(request, hertz_mesh):
    """(set-up's qp, the solver after the row update, a fresh solver of the moved problem)."""
    method = request.param
    solver = df.FetiSolver(on_circle(hertz_mesh, 0.0, 0.0), rtol=RTOL, method=method)
    solver.solve()
    before = solver.qp
    kplus = {"n": 0}
    apply = {"tfeti": BlockSystem, "feti1": BlockSystem, "fetidp": CornerSystem}[method]
    original = apply.apply_kplus

    def counted(system, x, y):
        kplus["n"] += 1
        original(system, x, y)

    apply.apply_kplus = counted
    try:
        solver.update(on_circle(hertz_mesh, 0.3, 0.001))
    finally:
        apply.apply_kplus = original
    fresh = df.FetiSolver(on_circle(hertz_mesh, 0.3, 0.001), rtol=RTOL, method=method)
    yield method, before, solver, fresh, kplus["n"]
    fresh.destroy()
    solver.destroy()


def test_operators_equal_a_fresh_setup(updated):
    method, _, solver, fresh, _ = updated
    qp, new = solver.qp, fresh.qp
    comm = qp.system.comm
    assert qp.method == new.method == method
    B, Bf = local_csr(qp.primal.B), local_csr(new.primal.B)
    assert B.shape == Bf.shape
    assert rel(B.toarray(), Bf.toarray(), comm) <= 1e-13
    assert rel(qp.feti.d.array_r, new.feti.d.array_r, comm) <= 1e-12
    G, Gf = qp.feti.Gt_local.toarray(), new.feti.Gt_local.toarray()
    assert G.shape == Gf.shape
    assert rel(G, Gf, comm) <= 1e-13
    x = qp.b.duplicate()
    x.array[:] = global_random(x)
    y, yf = x.duplicate(), x.duplicate()
    qp.feti.F.mult(x, y)
    new.feti.F.mult(x, yf)
    assert rel(y.array_r, yf.array_r, comm) <= 1e-10
    assert rel(qp.b.array_r, new.b.array_r, comm) <= 1e-10
    for v in (x, y, yf):
        v.destroy()


def test_kept_what_depends_on_K_alone(updated):
    method, before, solver, _, kplus = updated
    qp = solver.qp
    if method in ("feti1", "fetidp"):  # K held on the Dirichlet dofs: the set-up's
        assert np.shares_memory(qp.steps[0].child.K.data, before.steps[0].child.K.data)
    if method == "fetidp":
        new, old = qp.steps[-1].algebra, before.steps[-1].algebra
        assert new is not old and new.B is not old.B  # B̃ is new ...
        for name in ("E", "K_rr", "K_rc", "Krr_plus", "S", "S_plus", "_psi"):  # ... K's kept
            assert getattr(new, name) is getattr(old, name), name
    else:
        assert qp.primal.Kplus is before.primal.Kplus
    assert qp.feti.R is before.feti.R  # the kernel of the same K
    # the load is the same: K⁺f is kept; K⁺ in ‖PFP‖'s estimate, and in b only where λ̂ ≠ 0
    lam_hat = qp.lam_hat.norm(PETSc.NormType.NORM_INFINITY)
    assert kplus == qp.proj.norm_mults + (lam_hat > 0)


def test_norm_estimate_of_the_new_operator(updated):
    _, _, solver, fresh, _ = updated
    qp = solver.qp
    top = estimate_norm(qp.A, qp.b, rtol=1e-13, max_it=500).value  # converged, random start
    assert top * (1 - 3e-4) <= qp.norm_A <= top * (1 + 1e-10)  # a Lanczos value: ≤ ‖A‖
    assert qp.norm_A == pytest.approx(fresh.qp.norm_A, rel=3e-4)
    assert qp.proj.norm_mults < fresh.qp.proj.norm_mults


def test_solution_equals_a_fresh_setup(updated):
    _, _, solver, fresh, _ = updated
    warm, cold = solver.solve(), fresh.solve()
    assert warm.report.converged and cold.report.converged
    assert ref.rel_max_diff(warm.nodal_values(), cold.nodal_values()) <= 1e-6
    scale = np.abs(cold.contact.force).max()
    assert np.abs(warm.contact.force - cold.contact.force).max() <= 1e-6 * scale
    assert warm.report.hessian_mults < cold.report.hessian_mults
