"""The command dolfinx-feti / python -m dolfinx_feti: every shipped problem file against the
Python API, the outputs (XDMF, JSON, NPZ, PNG), progress, -feti_ options, exit codes, and no
output when a solve fails. Runs serially and under mpirun -n 2 (main() on every rank)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import (
    COMM,
    FRICTION,
    HAS_FRICTION,
    PROBLEMS,
    ROOT,
    SHIPPED,
    api_problem,
    file_rtol,
    files_in,
    remove_shared,
    shared_dir,
    write_text,
)
from petsc4py import PETSc
from stack import mpi_launcher

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.cli import main, split_feti_options


@pytest.fixture
def outdir():
    d = shared_dir("feti-cli-")
    yield d
    remove_shared(d)


@pytest.fixture(scope="module")
def api_solutions():
    """The shipped problems solved through the Python API (once per module)."""
    return {}


def api_nodal(name: str, cache: dict) -> np.ndarray:
    if name not in cache:
        sol = df.solve(api_problem(name), rtol=file_rtol(name))
        assert sol.report.converged
        cache[name] = (sol.nodal_values(), sol.contact.force, sol.total_contact_force)
    return cache[name]


def rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max(initial=0.0) / max(np.abs(b).max(initial=0.0), 1e-300))


def xdmf_attributes(path) -> set[str]:
    root = ET.parse(path).getroot()
    return {a.get("Name") for a in root.iter("Attribute")}


# ------------------------------------------------------------------------------------------
# Shipped problem files
# ------------------------------------------------------------------------------------------


def test_a_problem_file_for_every_demo_and_mesh():
    names = {p.stem for p in PROBLEMS.glob("*.toml")}
    assert set(SHIPPED) <= names
    api_only = {"user_forms", "gmshio"}  # own UFL forms, a DOLFINx mesh: the Python API's
    for demo in (ROOT / "demos").glob("demo_*.py"):
        topic = demo.stem.removeprefix("demo_")
        if topic in api_only:
            continue
        assert any(n.startswith(topic) for n in names), f"no problem file for {demo.name}"
    text = "".join(p.read_text() for p in PROBLEMS.glob("*.toml"))
    for msh in (ROOT / "meshes").glob("*.msh"):
        assert f"../meshes/{msh.name}" in text, f"no problem file uses meshes/{msh.name}"


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_problem_matches_python_api(name, outdir, api_solutions, capsys):
    if name in FRICTION and not HAS_FRICTION:
        pytest.skip("friction is not available")
    code = main([str(PROBLEMS / f"{name}.toml"), "-o", str(outdir), "-q"])
    assert code == 0, capsys.readouterr().err
    data = np.load(outdir / f"{name}_nodal.npz")
    assert {"x", "u", "cells", "contact_node", "contact_force", "contact_pressure"} <= \
        set(data.files)
    u_api, force_api, total_api = api_nodal(name, api_solutions)
    assert data["u"].shape == u_api.shape
    assert rel_diff(data["u"], u_api) <= 1e-6
    assert rel_diff(data["contact_force"], force_api) <= 1e-5
    report = json.loads((outdir / f"{name}.json").read_text())
    assert report["converged"] and report["sizes"]["ranks"] == COMM.size
    assert np.allclose(report["extra"]["results"]["total_contact_force"], total_api,
                       rtol=1e-6, atol=1e-9)
    assert report["extra"]["options"]["rtol"] == file_rtol(name)
    assert report["extra"]["versions"]["dolfinx"] == compat.DOLFINX_VERSION
    assert {"petsc", "petsc4py", "numpy", "dolfinx_feti"} <= set(report["extra"]["versions"])
    assert report["extra"]["problem"]["nodes"] == data["x"].shape[0]
    assert not any(f.startswith(".") for f in files_in(outdir)), files_in(outdir)
    assert capsys.readouterr().out == ""  # -q


# An MPI process cannot start another MPI program (Open MPI's singleton start hangs inside an
# mpirun job): the subprocess tests run in the serial pass only.
MPIRUN = mpi_launcher(2)


@pytest.mark.serial
@pytest.mark.skipif(COMM.size > 1, reason="no MPI program inside an MPI job")
@pytest.mark.parametrize("launcher", [[], MPIRUN], ids=["serial", "mpirun-n2"])
def test_subprocess_python_m(launcher, outdir, api_solutions):
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    r = subprocess.run([*launcher, sys.executable, "-m", "dolfinx_feti", "problems/hertz2d.toml",
                        "-o", str(outdir), "-feti_rtol", "1e-8"], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"{2 if launcher else 1} rank(s)" in r.stdout
    assert "feti: iterations" in r.stdout and "converged" in r.stdout  # progress by default
    assert f"wrote {outdir / 'hertz2d.xdmf'}" in r.stdout
    data = np.load(outdir / "hertz2d_nodal.npz")
    assert rel_diff(data["u"], api_nodal("hertz2d", api_solutions)[0]) <= 1e-6
    assert set(files_in(outdir)) == {"hertz2d.xdmf", "hertz2d.h5", "hertz2d.json",
                                     "hertz2d_nodal.npz", "hertz2d_pressure.png"}
    png = (outdir / "hertz2d_pressure.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.serial
@pytest.mark.skipif(COMM.size > 1, reason="no MPI program inside an MPI job")
def test_console_script_installed():
    exe = Path(sys.executable).parent / "dolfinx-feti"  # this environment's (not resolved)
    if not exe.exists():
        pytest.skip("the console script is not installed (run scripts/setup.sh)")
    r = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "problem file" in r.stdout


# ------------------------------------------------------------------------------------------
# Outputs
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name, fields", [
    ("hertz2d", {"displacement", "von_mises", "subdomain", "contact_pressure"}),
    ("membranes_8", {"u", "subdomain", "contact_pressure"}),
])
def test_xdmf_reopens_with_the_named_fields(name, fields, outdir):
    assert main([str(PROBLEMS / f"{name}.toml"), "-o", str(outdir), "-q"]) == 0
    path = outdir / f"{name}.xdmf"
    assert xdmf_attributes(path) == fields
    text = path.read_text()
    assert f"{name}.h5:" in text and ".tmp" not in text
    msh = compat.read_xdmf_mesh(COMM, path)
    cells = COMM.allreduce(msh.topology.index_map(msh.topology.dim).size_local)
    mesh = api_problem(name).mesh
    assert cells == mesh.cells.shape[0]
    nodes = COMM.allreduce(msh.geometry.index_map().size_local)
    assert nodes == mesh.num_nodes


def test_von_mises_and_subdomains_in_the_solution(outdir):
    """The DG0 fields hold the values computed from the nodal solution."""
    from dolfinx_feti.results.postprocess import output_functions, von_mises

    problem = api_problem("blocks3d")
    sol = df.solve(problem, rtol=1e-8)
    sub, vm = output_functions(sol)
    assert (sub.name, vm.name) == ("subdomain", "von_mises")
    cells = compat.cell_input_indices(vm.function_space.mesh)
    expect = von_mises(problem.mesh, sol.nodal_values(), problem.forms.E, problem.forms.nu)
    n = cells.size
    dofs = compat.cell_dofs(vm.function_space).ravel()[:n]
    assert np.allclose(vm.x.array[dofs], expect[cells])
    assert np.array_equal(sub.x.array[dofs], sol.cell_subdomains()[cells].astype(float))
    # The upper block is nearly in a uniaxial-strain state: sigma_zz ~ -1, von Mises ~
    # (1 - 2 nu) / (1 - nu) = 0.571 at its top (where the rollers and the pressure dominate).
    upper = problem.mesh.cell_body == problem.mesh.body_names.index("upper")
    top = upper & (problem.mesh.x[problem.mesh.cells].mean(axis=1)[:, 2] > 0.85)
    assert np.all(np.abs(expect[top] - 0.4 / 0.7) < 0.1)


def test_pressure_plot_on_request(outdir):
    assert main([str(PROBLEMS / "blocks3d.toml"), "-o", str(outdir), "-q", "--plot"]) == 0
    assert (outdir / "blocks3d_pressure.png").read_bytes()[:4] == b"\x89PNG"
    assert main([str(PROBLEMS / "blocks3d.toml"), "-o", str(outdir / "b"), "-q"]) == 0
    assert "blocks3d_pressure.png" not in files_in(outdir / "b")


# ------------------------------------------------------------------------------------------
# Progress and options
# ------------------------------------------------------------------------------------------


def test_progress_levels(outdir, capsys):
    toml = str(PROBLEMS / "membranes_8.toml")
    assert main([toml, "-o", str(outdir)]) == 0
    out = capsys.readouterr().out
    if COMM.rank == 0:
        # the default method: one subdomain per membrane → FETI-1, the left one floats → SMALBE
        assert "feti: assembly" in out and "FETI-1 + smalbe" in out and "wrote" in out
        assert "||g^P||" not in out.split("FETI-1")[0]  # no iteration lines at verbose 1
    else:
        assert out == ""
    assert main([toml, "-o", str(outdir), "-v"]) == 0
    out = capsys.readouterr().out
    if COMM.rank == 0:
        assert "cg            ||g^P||" in out and "outer" in out
    assert main([toml, "-o", str(outdir), "-q"]) == 0
    assert capsys.readouterr().out == ""


def test_feti_options_reach_the_solver_and_do_not_leak(outdir):
    toml = str(PROBLEMS / "membranes_8.toml")
    assert main([toml, "-o", str(outdir), "-q", "-feti_rtol", "1e-5", "-feti_mprgp_gamma",
                 "2"]) == 0
    opts = json.loads((outdir / "membranes_8.json").read_text())["extra"]["options"]
    assert opts["rtol"] == 1e-5 and opts["mprgp_gamma"] == 2.0  # over the file's rtol 1e-8
    assert not PETSc.Options().hasName("feti_rtol")
    assert not PETSc.Options().hasName("feti_mprgp_gamma")
    assert df.SolverOptions.create().rtol == df.SolverOptions().rtol


def test_split_feti_options():
    own, feti = split_feti_options(["p.toml", "-feti_rtol", "1e-9", "-q", "-feti_smalbe_M",
                                    "-2", "-o", "d"])
    assert own == ["p.toml", "-q", "-o", "d"]
    assert feti == ["-feti_rtol", "1e-9", "-feti_smalbe_M", "-2"]


# ------------------------------------------------------------------------------------------
# Failures: exit codes and no output
# ------------------------------------------------------------------------------------------


def test_check_only_writes_nothing(outdir, capsys):
    assert main([str(PROBLEMS / "hertz2d.toml"), "-o", str(outdir / "o"), "--check"]) == 0
    assert files_in(outdir) == []
    if COMM.rank == 0:
        assert "valid" in capsys.readouterr().out


def test_not_converged_writes_only_the_report(outdir, capsys):
    code = main([str(PROBLEMS / "hertz2d.toml"), "-o", str(outdir), "-q", "-feti_max_it", "3"])
    assert code == 3
    assert files_in(outdir) == ["hertz2d.json"]
    report = json.loads((outdir / "hertz2d.json").read_text())
    assert report["converged"] is False
    if COMM.rank == 0:
        assert "did not converge" in capsys.readouterr().err


def test_failed_solve_writes_nothing(outdir, capsys):
    """A load the constraints cannot balance is found during the solve: exit 1, no file."""
    text = (PROBLEMS / "blocks3d.toml").read_text()
    text = text.replace('mesh = "../meshes/blocks3d.msh"',
                        f'mesh = "{(ROOT / "meshes" / "blocks3d.msh").as_posix()}"')
    text = text.replace('[[dirichlet]]\ngroup = "bottom"\n', "")  # the lower block floats
    toml = write_text(outdir / "floating.toml", text)
    code = main([str(toml), "-o", str(outdir / "out"), "-q"])
    assert code == 1
    assert files_in(outdir) == ["floating.toml"]
    if COMM.rank == 0:
        err = capsys.readouterr().err
        assert "floating.toml" in err and "cannot be balanced" in err


def test_interrupted_xdmf_write_leaves_no_file(outdir, monkeypatch, capsys):
    def broken(path, msh, functions):
        with open(path, "w") as f:
            f.write("<?xml")  # half a file, then the disk is full
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(compat, "write_xdmf", broken)
    code = main([str(PROBLEMS / "membranes_8.toml"), "-o", str(outdir), "-q"])
    assert code == 1
    assert files_in(outdir) == []
    if COMM.rank == 0:
        assert "No space left" in capsys.readouterr().err


def test_bad_command_line(capsys):
    assert main([]) == 2
    assert main([str(PROBLEMS / "hertz2d.toml"), "--no-such-flag"]) == 2
    assert main(["--help"]) == 0
    assert main(["--version"]) == 0
    if COMM.rank == 0:
        out = capsys.readouterr().out
        assert f"dolfinx {compat.DOLFINX_VERSION}" in out and "-feti_" in out
