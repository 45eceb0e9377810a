"""The whole solve with the sparse coarse problem (forced by DENSE_MAX = 0) against the dense one:
the same solution to solver tolerance, the same rank of G and the same warnings, including a
body with rigid motions that no row sees (a singular G Gᵀ, and in the recovery G_A G_Aᵀ)."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

import dolfinx_feti as df
import dolfinx_feti.qp.equality as equality

RTOL = 1e-10


def blocks(variant: str) -> df.ContactProblem:
    mesh = df.read_gmsh("meshes/blocks3d.msh")
    extra = [df.Dirichlet("sides_upper", components=[0, 1])] if variant == "constrained" else []
    return df.ContactProblem(
        mesh, df.Elasticity(1000.0, 0.3, tractions={"top": (0.0, 0.0, -1.0)}),
        dirichlet=[df.Dirichlet("bottom"), *extra],
        contact=[df.NodeToNode("contact_upper", "contact_lower")], decomposition=df.Parts(2))


def membranes() -> df.ContactProblem:
    mesh = df.read_gmsh("meshes/membranes_8.msh")
    return df.ContactProblem(
        mesh, df.Poisson(source=ref.membrane_source), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")],
        decomposition=df.ByFunction(
            lambda m: (np.floor(m[:, 0] / 0.25) + 8 * np.floor(m[:, 1] / 0.25)).astype(int)))


CASES = {"membranes": membranes, "blocks free": lambda: blocks("free"),
         "blocks constrained": lambda: blocks("constrained")}


@pytest.mark.parametrize("case", sorted(CASES))
def test_sparse_coarse_solve_equals_dense(case, monkeypatch):
    problem = CASES[case]()
    dense = df.solve(problem, rtol=RTOL)
    monkeypatch.setattr(equality, "DENSE_MAX", 0)
    sparse = df.solve(problem, rtol=RTOL)
    for s in (dense, sparse):
        assert s.report.converged, s.report.summary()
    assert sparse.report.sizes["coarse_rank"] == dense.report.sizes["coarse_rank"]
    assert sparse.report.warnings == dense.report.warnings
    u_d, u_s = dense.nodal_values(), sparse.nodal_values()
    assert np.abs(u_s - u_d).max() <= 1e-8 * np.abs(u_d).max()
    assert ref.rel_max_diff(sparse.contact.force, dense.contact.force) <= 1e-8
    if case == "blocks free":  # three in-plane motions of the upper block: rank 12 − 3
        assert dense.report.sizes["coarse_rank"] == dense.report.sizes["coarse"] - 3
