"""bench/time_against_error.py on its smallest case (2D Hertz H1, mortar, serial) — issue 24.

The script writes its table, JSON and plot; its SNES VI reference satisfies the KKT conditions
of the undecomposed problem, a tight FETI solve (rtol 1e-10) agrees with it (so both solve the
same discrete problem), and each method at rtol 1e-6 is within 1e-5 of it in u and in the nodal
contact forces (issue 24's accuracy goal).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from mpi4py import MPI

GOAL = 1e-5
#: The KKT test's violation_force residual (drivers/kkt_stop.py) holds the nodal contact
#: forces of FETI-1 and FETI-DP here: without it they stopped at 2.4e-5 on this mesh (the
#: oscillation of the forces next to the symmetry axis, docs/benchmarks.md § 26).


@pytest.fixture(scope="module")
def h1_run(tmp_path_factory, root):
    out = tmp_path_factory.mktemp("tae") / "tae"
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, str(root / "bench" / "time_against_error.py"),
                        "--cases", "H1", "--rtols", "1e-6,1e-10", "--repeat", "1",
                        "--out", str(out)], cwd=root, env=env, capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr[-4000:]
    return out


def _rows(out, config, rtol):
    data = json.loads(out.with_suffix(".json").read_text())
    (res,) = data["results"]
    return res, [r for r in res["rows"] if r["config"] == config and r["rtol"] == rtol]


pytestmark = [pytest.mark.serial,
              pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="no MPI program in an MPI job")]


def test_outputs_and_reference(h1_run):
    for suffix in (".md", ".json", ".png"):
        assert h1_run.with_suffix(suffix).stat().st_size > 0, suffix
    res, _ = _rows(h1_run, "snes", 1e-6)
    assert res["case"] == "H1" and res["ndofs"] > 20000
    assert max(res["ref_kkt"].values()) < 1e-10
    assert set(res["floors"]) == {"mumps", "gamg"}
    assert "| H1 |" in h1_run.with_suffix(".md").read_text()
    # an independent check of the reference: a tight FETI solve of the same problem
    _, (tight,) = _rows(h1_run, "tfeti", 1e-10)
    assert tight["err_u"] < 1e-9 and tight["err_f"] < 1e-8, tight


@pytest.mark.parametrize("config", ["tfeti", "feti1", "fetidp", "auto", "snes"])
def test_error_at_rtol_1e6(h1_run, config):
    _, (row,) = _rows(h1_run, config, 1e-6)
    assert row["err_u"] <= GOAL and row["err_f"] <= GOAL, row
