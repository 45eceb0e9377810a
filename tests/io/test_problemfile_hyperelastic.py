"""Problem files with a hyperelastic model: ``[model] type = "neo-hookean" | "svk"``."""

from __future__ import annotations

import gmsh
import numpy as np
import pytest
from element_models import rectangle, stacked_blocks
from rubber_cases import rubber_cylinder, rubber_hemisphere
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


def write_block_mesh(folder, name: str = "block.msh", model=lambda: rectangle(h=0.3)) -> None:
    """A gmsh model of element_models as ``folder/name``: by default the unit block of
    ``rectangle``."""
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        model()
        gmsh.write(str(folder / name))
    finally:
        gmsh.finalize()


@pytest.mark.serial
@pytest.mark.parametrize("kind", ["neo-hookean", "svk"])
def test_hyperelastic_model_in_a_problem_file(tmp_path, kind):
    write_block_mesh(tmp_path)
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
    sol = df.solve(rubber_hemisphere(mesh, 0.1, parts=2), method="fetidp", rtol=1e-8)
    assert sol.report.converged
    u = sol.nodal_values()
    assert np.abs(data["u"] - u).max() <= 1e-8 * np.abs(u).max()
    assert sol.total_contact_force[2] > 0  # pressed onto the plane


@pytest.mark.serial
def test_hyperelastic_load_path_in_a_problem_file(tmp_path):
    """``[loading]`` on a neo-Hookean model: Newton at each factor on one set-up, through the
    command; every step equals the exact homogeneous state of its compression (the block on
    a frictionless plane, laterally free), and the history has a record per step."""
    import json

    from dolfinx_feti.cli import main
    from dolfinx_feti.drivers.scaled import scaled

    write_block_mesh(tmp_path)
    path = tmp_path / "block.toml"
    factors = (0.5, 1.0, 0.5)  # 15 %, 30 %, back to 15 %
    path.write_text(TEXT.format(kind="neo-hookean") + f"""
[loading]
factors = {list(factors)}

[solver]
rtol = 1e-12

[output]
nodal_values = "block_nodal.npz"
""")
    pf = problemfile.load(path)
    assert pf.loading == factors
    steps = [pf.problem_at(k) for k in range(len(factors))]
    assert all(type(p.forms) is df.NeoHookean for p in steps)
    assert [p.forms.load_factor for p in steps] == list(factors)
    assert [p.dirichlet[0].value for p in steps] == [(-0.15,), (-0.3,), (-0.15,)]
    # between two steps (a Newton cut-back) the loads are interpolated, not the last step's
    half = [pf.problem_at(t) for t in (0.5, 1.25)]
    assert [p.forms.load_factor for p in half] == [0.75, 0.875]
    assert np.allclose([p.dirichlet[0].value[0] for p in half], [-0.225, -0.2625], rtol=1e-14)
    for t in (-0.5, 2.5):
        with pytest.raises(df.InputError, match="outside"):
            pf.problem_at(t)
    sols = df.solve_path(pf.problem_at, range(len(factors)), rtol=1e-12, newton_rtol=1e-10)
    for sol, f in zip(sols, factors, strict=True):
        a, _ = neo_hookean_exact(0.3 * f)
        X, U = nodal(sol)
        assert np.abs(U - np.c_[(a - 1) * X[:, 0], -0.3 * f * X[:, 1]]).max() < 1e-9
    # the command (Newton's default rtol 1e-9): the last step's nodal values, a history
    # record per step
    assert main([str(path), "-o", str(tmp_path / "out"), "-q"]) == 0
    u = np.load(tmp_path / "out" / "block_nodal.npz")["u"]
    assert np.abs(u - sols[-1].nodal_values()).max() < 1e-8 * np.abs(u).max()
    history = json.loads((tmp_path / "out" / "block_history.json").read_text())
    assert len(history["steps"]) == len(factors)
    with pytest.raises(df.InputError, match="cannot be scaled"):
        scaled(df.ContactProblem(pf.problem.mesh, df.Poisson(source=1.0)), 2.0)


PAIR_TEXT = """mesh = "stack.msh"

[model]
type = "neo-hookean"
E = 10.0
nu = 0.3

[[dirichlet]]
group = "bottom"

[[dirichlet]]
group = "top"
value = [0.05, -0.05]

[[contact]]
type = "node_to_node"
slave = "upper_bottom"
master = "lower_top"
friction = { type = "coulomb", coefficient = 0.3 }
"""


@pytest.mark.serial
def test_node_to_node_friction_in_a_hyperelastic_problem_file(tmp_path):
    """Two neo-Hookean blocks with Coulomb friction on a node-to-node pair, from a file: the
    Python API's solution (friction on pairs under Newton)."""
    write_block_mesh(tmp_path, "stack.msh", stacked_blocks)
    path = tmp_path / "stack.toml"
    path.write_text(PAIR_TEXT)
    pf = problemfile.load(path)
    opts = {"rtol": 1e-12, "newton_rtol": 1e-10, "method": "fetidp"}
    sol = df.solve(pf.problem, **opts)
    api = df.ContactProblem(
        pf.problem.mesh, df.NeoHookean(10.0, 0.3),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", (0.05, -0.05))],
        contact=[df.NodeToNode("upper_bottom", "lower_top", friction=df.Coulomb(0.3))],
        decomposition=pf.problem.decomposition)
    ref = df.solve(api, **opts)
    assert sol.report.converged and ref.report.converged
    assert 0 < np.count_nonzero(sol.contact.state == 2) < sol.contact.state.size
    assert np.abs(sol.nodal_values() - ref.nodal_values()).max() < 1e-10
