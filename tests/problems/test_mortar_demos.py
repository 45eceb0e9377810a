"""The mortar demos run as a user runs them, and their figures hold.

Each demo runs once in a subprocess (serially; the sphere also under ``mpirun -n 2``; these
runs stand for those of tests/problems/test_demos.py, which skips them) and
writes its report with the comparison it prints; the assertions are on those figures, with
bounds from what the demos measure at their default sizes (the demo texts give the numbers):

- demo_sphere_block3d (h = 0.1 / 0.17): contact radius within one element of Hertz's, the
  Hertz profile fitted to the nodal pressures within 1 % (radius) and 3.5 % (peak: the
  bodies are finite, +2.3 % here), total contact force = the discrete load;
- demo_disk_block2d (h = 0.2, 0.1, 0.05): the peak-pressure error falls with h and is below
  3 % on the finest mesh, the half-width within one block element on every mesh;
- demo_inclusions: the tied model deviates from the fragmented (conforming) one of the same
  element size by less than the conforming model's own discretization error (its change
  from h to h/2).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from stack import mpi_launcher

import dolfinx_feti as df
from dolfinx_feti.io import meshes_occ

ROOT = Path(__file__).resolve().parents[2]

# An MPI process cannot start another MPI program: the demos run in the serial pass only.
subprocess_test = pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                     reason="no MPI program inside an MPI job")


def run_demo(name: str, folder: Path, *args: str, launcher: list[str] | None = None) -> dict:
    """Run demos/demo_<name>.py; its JSON report, with its stdout and output folder."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    report = folder / f"{name}.json"
    r = subprocess.run([*(launcher or []), sys.executable, str(ROOT / "demos" / f"demo_{name}.py"),
                        "--out", str(folder), "--json", str(report), *args], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    data = json.loads(report.read_text())
    data["stdout"], data["folder"] = r.stdout, folder
    return data


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    return run_demo("sphere_block3d", tmp_path_factory.mktemp("sphere"))


@pytest.mark.serial
@subprocess_test
def test_sphere_on_block_against_hertz(sphere, tmp_path_factory):
    assert sphere["converged"] and not sphere["warnings"], sphere["warnings"]
    h = sphere["extra"]["hertz"]
    assert h["force_error"] < 1e-7  # measured 2.7e-9 (solver tolerance 1e-8)
    assert abs(h["a_h"] - h["a"]) < h["h_sphere"]  # measured -0.031: within one element
    assert abs(h["a_fit"] / h["a"] - 1) < 0.01  # measured +0.09 %
    assert 0 < h["p0_fit"] / h["p0"] - 1 < 0.035  # measured +2.34 %
    search = sphere["extra"]["mortar"][0]
    assert search["uncoupled_slave_nodes"] > 0  # whole candidate surfaces: most out of reach
    assert search["rim_rows"] == 0 and search["active_rows"] > 0
    assert "Hertz profile fitted" in sphere["stdout"]
    assert (sphere["folder"] / "sphere_block3d.xdmf").exists()
    assert (sphere["folder"] / "sphere_block3d_pressure.png").read_bytes()[:4] == b"\x89PNG"


#: The solver tolerance of the rank-count comparison. At the demo's default (1e-8) two runs
#: stop at different points inside the tolerance (their reductions round differently), and
#: the peak nodal pressure, a single multiplier, is the most sensitive figure: measured 1.9e-6
#: apart between 1 and 2 ranks (the 1-rank value 2.0e-6 and the 2-rank one 1.8e-7 from the
#: solution at 1e-10; the preconditioner Z is the same on both); at 1e-10, 3.8e-9 apart. The
#: spread was large because the mortar group of B Δ Bᵀ (579 rows) exceeded the stiffness
#: scaling's MERGE_MAX (256 then) and was split: inverted whole, as with the cap of 2 048 now,
#: the runs agree to 1.8e-9 at 1e-8 (docs/robustness.md, finding 14).
COMPARE_RTOL = "1e-10"


@pytest.mark.serial
@subprocess_test
def test_sphere_on_block_under_mpirun_gives_the_serial_figures(tmp_path_factory):
    ser = run_demo("sphere_block3d", tmp_path_factory.mktemp("sphere_serial"),
                   "--rtol", COMPARE_RTOL)
    par = run_demo("sphere_block3d", tmp_path_factory.mktemp("sphere_mpi"),
                   "--rtol", COMPARE_RTOL, launcher=mpi_launcher(2))
    assert ser["sizes"]["ranks"] == 1 and ser["converged"] and not ser["warnings"]
    assert par["sizes"]["ranks"] == 2 and par["converged"] and not par["warnings"]
    s, p = ser["extra"]["hertz"], par["extra"]["hertz"]
    assert p["a_h"] == s["a_h"] and p["nodes"] == s["nodes"]  # the same active set
    for key in ("p0_fit", "a_fit", "peak", "contact_force"):
        assert p[key] == pytest.approx(s[key], rel=1e-6), key


@pytest.mark.serial
@subprocess_test
def test_disk_on_block_converges_to_hertz(tmp_path):
    r = run_demo("disk_block2d", tmp_path)
    assert r["converged"] and not r["warnings"], r["warnings"]
    conv = r["extra"]["hertz_convergence"]
    rows = conv["meshes"]
    assert [m["h_disk"] for m in rows] == [0.2, 0.1, 0.05]
    peak = [m["peak_error"] for m in rows]
    assert peak[0] > peak[1] > peak[2] > 0, peak  # measured +5.90, +4.19, +2.28 %
    assert peak[2] < 0.03
    for m in rows:
        assert abs(m["a_h_error"]) < m["h_block"], m  # within one (block) element
        assert m["force_error"] < 1e-7
    finest = rows[-1]
    assert abs(finest["p0_fit"] / conv["p0"] - 1) < 0.01  # measured +0.67 %
    assert abs(finest["a_fit"] / conv["a"] - 1) < 0.01  # measured -0.36 %
    assert (tmp_path / "disk_block2d_pressure.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.serial
@subprocess_test
def test_inclusions_tie_agrees_with_the_conforming_mesh(tmp_path):
    r = run_demo("inclusions", tmp_path)
    assert r["converged"] and not r["warnings"], r["warnings"]
    inc = r["extra"]["inclusions"]
    assert inc["force_error"] < 1e-7
    tie, contact = r["extra"]["mortar"]
    assert tie["type"] == "tie" and tie["uncoupled_slave_nodes"] == 0 and tie["rows"] > 0
    assert contact["type"] == "mortar" and 0 < contact["active_rows"] < contact["rows"]
    dev, err = inc["deviation_tied"], inc["discretization_error"]
    # measured: displacement 6.0e-4 vs 3.4e-3, energy 1.4e-6 vs 3.5e-3, peak pressure 1.5e-5
    # vs 1.7e-2, end of the contact zone 0 vs 0.25 elements
    for key in ("displacement", "energy", "peak_pressure"):
        assert dev[key] < err[key], (key, dev[key], err[key])
    assert dev["contact_end"] <= 1.0  # within one element
    assert err["displacement"] > 0 and err["energy"] > 0  # the references differ, as they must
    assert (tmp_path / "inclusions.xdmf").exists()


# -- the model generator ---------------------------------------------------------------------

def test_slab_with_inclusions_meshes_the_inclusions_on_their_own():
    mesh = df.build_mesh(meshes_occ.slab_with_inclusions, comm=MPI.COMM_SELF)
    assert mesh.body_names == ("matrix", "inclusions", "foundation")
    holes, inc = np.unique(mesh.facets("holes")), np.unique(mesh.facets("inclusion_surface"))
    assert np.intersect1d(holes, inc).size == 0  # not fragmented: no node in common
    assert inc.size > holes.size  # the inclusions are finer (0.03 against 0.05)
    centres = np.array([[0.4, 0.3], [1.0, 0.3], [1.6, 0.3]])
    for nodes in (holes, inc):  # both on the circles of radius 0.18
        d = np.linalg.norm(mesh.x[nodes][:, None] - centres[None], axis=2).min(axis=1)
        assert np.allclose(d, 0.18, atol=1e-9)
    # the contact surfaces do not match either
    assert np.intersect1d(mesh.facets("slab_bottom"), mesh.facets("foundation_top")).size == 0
    load = mesh.x[np.unique(mesh.facets("load"))]
    assert np.allclose(load[:, 1], 0.6) and load[:, 0].min() == 0 and load[:, 0].max() == 0.8


def test_slab_with_inclusions_conforming_shares_the_nodes():
    mesh = df.build_mesh(meshes_occ.slab_with_inclusions, conforming=True, comm=MPI.COMM_SELF)
    assert "holes" not in mesh.facet_groups and "inclusion_surface" not in mesh.facet_groups
    body = {n: mesh.body_names.index(n) for n in ("matrix", "inclusions")}
    in_matrix = np.unique(mesh.cells[mesh.cell_body == body["matrix"]])
    in_inclusions = np.unique(mesh.cells[mesh.cell_body == body["inclusions"]])
    shared = np.intersect1d(in_matrix, in_inclusions)
    assert shared.size > 0  # the interface nodes, glued by the ordinary gluing
    centres = np.array([[0.4, 0.3], [1.0, 0.3], [1.6, 0.3]])
    d = np.linalg.norm(mesh.x[shared][:, None] - centres[None], axis=2).min(axis=1)
    assert np.allclose(d, 0.18, atol=1e-9)


@pytest.mark.parametrize("kwargs", [{"h_matrix": 0.0}, {"load_length": 2.5},
                                    {"inclusions": ((0.1, 0.3, 0.18),)}])
def test_slab_with_inclusions_refuses_bad_input(kwargs):
    import gmsh

    gmsh.initialize()
    try:
        with pytest.raises(ValueError, match="slab_with_inclusions"):
            meshes_occ.slab_with_inclusions(**kwargs)
    finally:
        gmsh.finalize()
