"""Friction on mortar rows (non-matching meshes) against an independent monolithic solve.

The reference (tests/support/friction_reference.py) assembles the undecomposed problem, builds the
normal and tangential rows itself from the mortar weights (with its own tangent basis) and
solves the dual cone QP by a semismooth Newton method; only the weights w_jk come from the
library's mortar integrals, which tests/constraints/test_mortar.py checks on their own.
"""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref
import scipy.sparse as sp
from friction_reference import FrictionReference
from test_friction import compare
from test_mortar import occ_mesh

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar import mortar_coupling
from dolfinx_feti.io.meshes_occ import stacked_blocks

E, NU = 21.19, 0.277
RTOL = 1e-10
SIZES = {2: (0.1, 0.17), 3: (0.25, 0.42)}


def shift(dim):
    return (0.02, -0.02) if dim == 2 else (0.02, 0.01, -0.02)


def problem(mesh, dim, friction):
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=shift(dim))],
        contact=[df.Mortar("upper_bottom", "lower_top", friction=friction)],
        decomposition=df.Parts(2))


@pytest.fixture(scope="module", params=[2, 3])
def case(request):
    dim = request.param
    mesh = occ_mesh(stacked_blocks, dim, *SIZES[dim])
    c = mortar_coupling(mesh.x, mesh.cells, mesh.facets("upper_bottom"),
                        mesh.facets("lower_top"))
    assert np.all(c.coupled)
    W = sp.diags(1.0 / np.asarray(c.M.sum(axis=1)).ravel()) @ c.M
    normal = (0.0, 1.0) if dim == 2 else (0.0, 0.0, 1.0)
    r = FrictionReference(mesh, ref.elasticity_forms(E, NU),
                          dirichlet=[("bottom", (0.0,) * dim), ("top", shift(dim))],
                          slave="upper_bottom", normal=normal, weights=W)
    return dim, mesh, r


def test_tresca_on_mortar_rows(case):
    dim, mesh, r = case
    g = 0.045  # bonded, the tangential tractions range from 0.01 to 0.05: partial slip
    sol = df.solve(problem(mesh, dim, df.Tresca(g)), rtol=RTOL)
    assert sol.report.converged, sol.report.summary()
    rs = r.solve_tresca(g)
    compare(sol, rs)
    state = sol.contact.state
    assert np.any(state == df.ContactData.STICK) and np.any(state == df.ContactData.SLIP)


def test_coulomb_on_mortar_rows(case):
    dim, mesh, r = case
    F = 0.3
    sol = df.solve(problem(mesh, dim, df.Coulomb(F, rtol=1e-10)), rtol=RTOL)
    assert sol.report.converged, sol.report.summary()
    assert sol.report.extra["friction"]["fixed_point_converged"]
    compare(sol, r.solve_coulomb(F))
