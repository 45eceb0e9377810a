"""Problem files with a hyperelastic model: ``[model] type = "neo-hookean" | "svk"``."""

from __future__ import annotations

import gmsh
import numpy as np
import pytest
from element_models import rectangle
from test_newton import neo_hookean_exact, nodal

import dolfinx_feti as df
from dolfinx_feti.io import problemfile

TEXT = """mesh = "block.msh"

[model]
type = "{kind}"
E = 10.0
nu = 0.3

[[dirichlet]]
group = "top"
value = [-0.3]
components = [1]

[[dirichlet]]
group = "left"
components = [0]

[[contact]]
type = "obstacle"
group = "bottom"
plane = {{ point = [0.0, 0.0], normal = [0.0, 1.0] }}
"""


@pytest.mark.serial
@pytest.mark.parametrize("kind", ["neo-hookean", "svk"])
def test_hyperelastic_model_in_a_problem_file(tmp_path, kind):
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        rectangle(h=0.3)
        gmsh.write(str(tmp_path / "block.msh"))
    finally:
        gmsh.finalize()
    path = tmp_path / "block.toml"
    path.write_text(TEXT.format(kind=kind))
    pf = problemfile.load(path)
    material = pf.problem.forms
    assert isinstance(material, df.NeoHookean if kind == "neo-hookean"
                      else df.SaintVenantKirchhoff)
    if kind == "neo-hookean":
        sol = df.solve(pf.problem, rtol=1e-12, newton_rtol=1e-10)
        assert sol.report.converged
        a, _ = neo_hookean_exact(0.3)
        X, U = nodal(sol)
        assert np.abs(U - np.c_[(a - 1) * X[:, 0], -0.3 * X[:, 1]]).max() < 1e-9
