"""Every demo (demos/demo_*.py) runs to the end serially and under mpirun -n 2, with the MPI
of the environment that runs the tests, and its report says the solve converged.

The demos start as separate programs (an MPI process cannot start another MPI program inside an
mpirun job), so these tests belong to the serial pass. Each demo writes into a scratch folder.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from mpi4py import MPI
from stack import mpi_launcher

#: Extra arguments that keep a demo short here (none needed today: each runs in seconds).
QUICK: dict[str, list[str]] = {}
#: Runs made by tests/problems/test_mortar_demos.py, which also checks their figures: not repeated
# here.
CHECKED_ELSEWHERE = {("demo_sphere_block3d.py", 1), ("demo_sphere_block3d.py", 2),
                     ("demo_disk_block2d.py", 1), ("demo_inclusions.py", 1)}


@pytest.mark.serial
@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="no MPI program inside an MPI job")
@pytest.mark.parametrize("ranks", [1, 2], ids=["serial", "mpirun-n2"])
def test_demo_runs(demo, ranks, root, tmp_path):
    if (demo, ranks) in CHECKED_ELSEWHERE:
        pytest.skip("run, and its figures checked, by tests/problems/test_mortar_demos.py")
    launcher = mpi_launcher(ranks) if ranks > 1 else []
    report = tmp_path / "report.json"
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    r = subprocess.run([*launcher, sys.executable, str(root / "demos" / demo),
                        "--out", str(tmp_path / "out"), "--json", str(report),
                        *QUICK.get(demo, [])],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, f"{demo} exited with {r.returncode}:\n{r.stderr[-4000:]}"
    data = json.loads(report.read_text())
    assert data["converged"], data.get("reason")
    assert data["sizes"]["ranks"] == ranks
    assert any((tmp_path / "out").iterdir()), "the demo wrote no output"
