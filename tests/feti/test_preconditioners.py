"""FETI preconditioners and QP variants: the same solution, and the expected effect on counts."""

from __future__ import annotations

import numpy as np
import pytest
from membranes import b1_grid, b1_source

import dolfinx_feti as df


@pytest.fixture(scope="module")
def b1(root):
    return b1_grid(root)


@pytest.fixture(scope="module")
def hertz(root):
    mesh = df.read_gmsh(root / "meshes/hertz2d.msh")
    return df.ContactProblem(
        mesh, df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -10.0 / 16)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.NodeToNode("disk_contact", "block_contact")], decomposition=df.Parts(2))


@pytest.fixture(scope="module")
def hertz_reference(hertz):
    return df.solve(hertz, rtol=1e-10)


VARIANTS = [
    {"preconditioner": "lumped"},
    {"preconditioner": "dirichlet"},
    {"mprgp_alpha": "bb"},
    {"mprgp_expansion": "optimal"},
    {"mprgp_expansion": "projcg"},
    {"preconditioner": "dirichlet", "mprgp_alpha": "bb"},
    {"preconditioner": "lumped", "preconditioner_scaling": "stiffness"},
    {"preconditioner": "dirichlet", "preconditioner_scaling": "stiffness"},
    {"smalbe_acceleration": "none"},
]


@pytest.mark.parametrize("variant", VARIANTS, ids=lambda v: "-".join(map(str, v.values())))
def test_variants_give_the_same_contact_solution(hertz, hertz_reference, variant):
    sol = df.solve(hertz, rtol=1e-10, **variant)
    assert sol.report.converged
    u, ref = sol.nodal_values(), hertz_reference.nodal_values()
    assert np.abs(u - ref).max() <= 1e-7 * np.abs(ref).max()
    assert abs(sol.total_contact_force[1] - 5.0) <= 1e-8 * 5.0
    if "preconditioner" in variant:
        assert sol.report.counts["precond"] > 0


def test_dirichlet_preconditioner_saves_f_multiplications(hertz):
    plain = df.solve(hertz, rtol=1e-8, preconditioner="none").report
    lumped = df.solve(hertz, rtol=1e-8, preconditioner="lumped",
                      preconditioner_scaling="multiplicity").report
    dirichlet = df.solve(hertz, rtol=1e-8, preconditioner="dirichlet",
                         preconditioner_scaling="multiplicity").report
    assert dirichlet.hessian_mults < lumped.hessian_mults < plain.hessian_mults
    assert "precond" not in plain.counts and lumped.counts["precond"] > 0


def test_redundant_rows_fall_back_to_multiplicity_scaling(root):
    """B diag(K)⁻¹ Bᵀ is singular with redundant gluing rows: the stiffness-scaled default
    says so and uses multiplicity scaling; the solve is the same."""
    mesh = df.read_gmsh(root / "meshes/membranes_8.msh")
    prob = df.ContactProblem(
        mesh, df.Poisson(source=b1_source), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")],
        decomposition=df.ByFunction(lambda m: (np.floor(m[:, 0] / 0.5)
                                               + 4 * np.floor(m[:, 1] / 0.5)).astype(np.int64)),
        gluing="redundant")
    sol = df.solve(prob, rtol=1e-10)
    assert sol.report.converged
    assert any("multiplicity scaling instead" in w for w in sol.report.warnings)
    ref = df.solve(prob, rtol=1e-10, preconditioner="none")
    assert not any("scaling" in w for w in ref.report.warnings)
    assert abs(sol.energy - ref.energy) <= 1e-9 * abs(ref.energy)


@pytest.mark.parametrize("preconditioner", ["none", "lumped", "dirichlet"])
@pytest.mark.parametrize("scaling", ["multiplicity", "stiffness"])
def test_preconditioned_b1_is_exact(b1, preconditioner, scaling):
    sol = df.solve(b1, rtol=1e-10, preconditioner=preconditioner, preconditioner_scaling=scaling)
    assert sol.report.converged
    assert abs(sol.contact.force.sum() - 0.25) < 1e-8
    assert abs(sol.energy - (-0.26012652)) <= 1e-6 * 0.26012652


def test_preconditioned_projected_cg_on_a_glued_problem(root):
    """No contact: PCG with the projected Dirichlet preconditioner; prescribed u = x on x = 0."""
    mesh = df.read_gmsh(root / "meshes/membranes_16.msh")
    grid = df.ByFunction(lambda m: (np.floor(m[:, 0] / 0.25)
                                    + 100 * np.floor(m[:, 1] / 0.25)).astype(np.int64))
    left_only = df.Poisson(source=-1.0, k={"left": 1.0, "right": 1.0})
    prob = df.ContactProblem(mesh, left_only, decomposition=grid,
                             dirichlet=[df.Dirichlet("dirichlet"), df.Dirichlet("contact_right")])
    plain = df.solve(prob, rtol=1e-10)
    pre = df.solve(prob, rtol=1e-10, preconditioner="dirichlet")
    assert plain.report.solver == pre.report.solver == "cg"
    assert pre.report.iterations < plain.report.iterations
    ref = plain.nodal_values()
    assert np.abs(pre.nodal_values() - ref).max() <= 1e-8 * np.abs(ref).max()


@pytest.mark.parametrize("rho", [1.0, 1e3, 1e5])
def test_dual_penalty_violates_the_equality_by_order_one_over_rho(b1, rho):
    """FETI-NCG_ρ: ||Gλ − e|| falls like 1/ρ (the seed's dual penalty table).

    Under the dual test: the KKT test (the default) raises ρ until the balance holds."""
    sol = df.solve(b1, rtol=1e-10, qp="penalty", penalty_rho=rho, stop_test="dual")
    assert sol.report.solver == "mprgp (dual penalty)"
    assert sol.report.converged
    exact = df.solve(b1, rtol=1e-10)
    assert sol.report.G_lambda < 0.1 / rho  # measured: 3.2e-2, 5.6e-5, 5.6e-7 (n = 16)
    if rho >= 1e5:
        assert abs(sol.energy - exact.energy) <= 1e-4 * abs(exact.energy)
