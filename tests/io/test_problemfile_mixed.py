"""A problem file on bodies of several cell types: solved by the command as by the Python API
(serially and under mpirun -n 2), its outputs written; the options the mixed solve refuses
named by their keys."""

from __future__ import annotations

import json

import gmsh
import numpy as np
import pytest
from cli_helpers import COMM, files_in, remove_shared, shared_dir, write_text

import dolfinx_feti as df
from dolfinx_feti.cli import main
from dolfinx_feti.io import problemfile as pfile
from dolfinx_feti.io.meshes_occ import stacked_blocks

P, NU = 1.0, 0.3
E = {"lower": 1000.0, "upper": 500.0}  # a value per body: each mesh gets its own


@pytest.fixture(scope="module")
def folder():
    """A quadrilateral block under a triangle block, non-matching (rank 0 writes the .msh)."""
    d = shared_dir("feti-problemfile-mixed-")
    if COMM.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            stacked_blocks(2, 0.25, 0.4, recombine="lower")
            gmsh.write(str(d / "mixed.msh"))
        finally:
            gmsh.finalize()
    COMM.barrier()
    yield d
    remove_shared(d)


def _toml(folder, extra: str = "", contact: str = 'type = "mortar"') -> str:
    return f'''
mesh = "mixed.msh"
method = "tfeti"

[model]
type = "elasticity"
E = {{ lower = {E["lower"]}, upper = {E["upper"]} }}
nu = {NU}
tractions = {{ top = [0.0, {-P}] }}

[[dirichlet]]
group = "bottom"
components = [1]

[[dirichlet]]
group = "sym0"
components = [0]

[[contact]]
{contact}
slave = "upper_bottom"
master = "lower_top"

[decomposition]
type = "parts"
n = {{ lower = 2, upper = 1 }}

[solver]
rtol = 1e-12

[output]
nodal_values = "mixed.npz"
{extra}
'''


def _api_solution(msh):
    mesh = df.read_gmsh(str(msh))
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"top": [0.0, -P]}),
        dirichlet=[df.Dirichlet("bottom", 0.0, components=(1,)),
                   df.Dirichlet("sym0", 0.0, components=(0,))],
        contact=[df.Mortar("upper_bottom", "lower_top")],
        decomposition=df.Parts({"lower": 2, "upper": 1}))
    return df.solve(problem, method="tfeti", rtol=1e-12)


def _exact(x: np.ndarray, body: str) -> np.ndarray:
    """Uniform vertical stress -p in plane strain, the blocks of height 1 stacked, free sides."""
    e = E[body]
    uy = -(1 - NU**2) * P * (x[:, 1] / e if body == "lower" else
                              1 / E["lower"] + (x[:, 1] - 1) / e)
    return np.stack([NU * (1 + NU) * P / e * x[:, 0], uy], axis=1)


def test_mixed_problem_file_solved_by_the_command(folder):
    """The command on a .msh of a quadrilateral and a triangle body (E per body, parts per
    body): the per-mesh XDMF files, the nodal values and the report written; the displacement
    that of the Python API, itself the exact piecewise linear field."""
    toml = write_text(folder / "mixed.toml", _toml(folder))
    pf = pfile.load(toml)
    assert isinstance(pf.mesh, df.MixedMesh)
    assert pf.summary()["cell_types"] == ["quadrilateral", "triangle"]
    out = folder / "out"
    assert main([str(toml), "-o", str(out), "-q"]) == 0
    names = files_in(out)
    assert names == sorted(["mixed.json", "mixed.npz", "mixed_quadrilateral.xdmf",
                            "mixed_quadrilateral.h5", "mixed_triangle.xdmf",
                            "mixed_triangle.h5"]), names
    sol = _api_solution(folder / "mixed.msh")
    assert sol.report.converged
    assert sol.report.sizes["subdomains"] == 3
    for body in ("lower", "upper"):  # the patch test: exact on both meshes
        x, u = sol.displacement(body)
        ex = _exact(x, body)
        assert np.abs(u - ex).max() < 1e-10 * np.abs(ex).max()
    if COMM.rank == 0:
        saved = np.load(out / "mixed.npz")
        for k, mesh in enumerate(sol.meshes):
            t = mesh.cell_type
            u = sol.nodal_values(k)
            np.testing.assert_array_equal(saved[f"x_{t}"], mesh.x)
            assert np.abs(saved[f"u_{t}"] - u).max() <= 1e-10 * np.abs(u).max()
            assert np.abs(u).max() > 0
        report = json.loads((out / "mixed.json").read_text())
        assert report["converged"]
        res = report["extra"]["results"]
        assert [m["cell_type"] for m in res["meshes"]] == ["quadrilateral", "triangle"]
        # the contact force between the meshes carries the load p on the top (width 1)
        assert res["between_meshes"][0]["total_force"] == pytest.approx(P, rel=1e-8)
        assert report["extra"]["problem"]["cell_types"] == ["quadrilateral", "triangle"]
        for t in ("quadrilateral", "triangle"):  # each XDMF names its own .h5
            assert f"mixed_{t}.h5" in (out / f"mixed_{t}.xdmf").read_text()
    else:
        for k in range(len(sol.meshes)):
            sol.nodal_values(k)  # collective


@pytest.mark.parametrize("edit, key", [
    ({"extra": "", "contact": 'type = "node_to_node"'}, "contact[0]"),
    ({"extra": "", "contact": 'type = "mortar"\nfriction = { type = "tresca", bound = 1.0 }'},
     "contact[0].friction"),
    ({"extra": "pressure_plot = true"}, "output.pressure_plot"),
], ids=["node_to_node", "friction", "pressure_plot"])
def test_refused_parts_named(folder, edit, key):
    toml = write_text(folder / "refused.toml", _toml(folder, **edit))
    with pytest.raises(pfile.ProblemFileError) as info:
        pfile.load(toml)
    assert any(f.key == key and "cell types" in f.message for f in info.value.faults), \
        info.value.faults


@pytest.mark.parametrize("where", ["file", "command line"])
def test_refused_method_named(folder, where):
    """FETI-DP is refused by the key it was given with, before any solve."""
    text = _toml(folder)
    line = []
    if where == "file":
        text = text.replace('method = "tfeti"', 'method = "fetidp"')
    else:
        text = text.replace('method = "tfeti"\n', "")
        line = ["-feti_method", "fetidp"]
    toml = write_text(folder / "method.toml", text)
    with pytest.raises(pfile.ProblemFileError) as info:
        pfile.load(toml, command_line=line)
    key = "method" if where == "file" else "command line -feti_method"
    assert [f.key for f in info.value.faults] == [key]
    assert "'fetidp'" in info.value.faults[0].message
    out = folder / "method_out"
    assert main([str(toml), "-o", str(out), "-q", *line]) == 2
    assert files_in(out) == []


def test_plot_option_refused(folder, capsys):
    """--plot asks for a pressure plot, which bodies of several cell types do not have."""
    toml = write_text(folder / "plot.toml", _toml(folder))
    out = folder / "plot_out"
    assert main([str(toml), "-o", str(out), "-q", "--plot"]) == 2
    assert files_in(out) == []
    if COMM.rank == 0:
        assert "--plot: a pressure plot on bodies of several cell types" in \
            capsys.readouterr().err
