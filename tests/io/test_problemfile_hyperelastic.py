"""Problem files with a hyperelastic model: ``[model] type = "neo-hookean" | "svk"``."""

from __future__ import annotations

import gmsh
import numpy as np
import pytest
from element_models import rectangle
from rubber_cases import rubber_cylinder
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


@pytest.mark.serial
def test_shipped_rubber_cylinder_matches_the_python_api(root, tmp_path):
    """problems/rubber_cylinder.toml through the command equals the same problem in Python."""
    from dolfinx_feti.cli import main

    assert main([str(root / "problems/rubber_cylinder.toml"), "-o", str(tmp_path), "-q"]) == 0
    data = np.load(tmp_path / "rubber_cylinder_nodal.npz")
    problem = rubber_cylinder(root)
    sol = df.solve(problem, method="fetidp", rtol=1e-8)
    assert sol.report.converged
    u = sol.nodal_values()
    assert np.abs(data["u"] - u).max() <= 1e-8 * np.abs(u).max()
    assert np.abs(u[:, 1]).max() > 0.09  # the centre line moved down by 0.1


@pytest.mark.serial
def test_shipped_rubber_hemisphere_matches_the_python_api(root, tmp_path):
    """problems/rubber_hemisphere.toml (a mesh generator of io.meshes_rubber) equals Python."""
    from dolfinx_feti.cli import main
    from dolfinx_feti.io.meshes_rubber import quarter_hemisphere

    assert main([str(root / "problems/rubber_hemisphere.toml"), "-o", str(tmp_path), "-q"]) == 0
    data = np.load(tmp_path / "rubber_hemisphere_nodal.npz")
    mesh = df.build_mesh(quarter_hemisphere, h_contact=0.1, h_far=0.3)
    problem = df.ContactProblem(
        mesh, df.NeoHookean(1.0, 0.3),
        dirichlet=[df.Dirichlet("top", -0.1, components=[2]),
                   df.Dirichlet("x0", 0.0, components=[0]),
                   df.Dirichlet("y0", 0.0, components=[1])],
        contact=[df.RigidObstacle("sphere", df.Plane((0.0, 0.0, -1.0), (0.0, 0.0, 1.0)))],
        decomposition=df.Parts(2))
    sol = df.solve(problem, method="fetidp", rtol=1e-8)
    assert sol.report.converged
    u = sol.nodal_values()
    assert np.abs(data["u"] - u).max() <= 1e-8 * np.abs(u).max()
    assert sol.total_contact_force[2] > 0  # pressed onto the plane
