"""The pressure plot's first import of matplotlib keeps no Solution alive in a reference cycle.

matplotlib's first import leaves cyclic garbage whose frames reach their caller's frame; made
from the command's output step, that frame held the Solutions, so their PETSc objects waited
for the cyclic collector (tests/feti/test_reference_cycles.py says why that matters). Only a
fresh interpreter imports matplotlib for the first time: the command runs in a subprocess.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest
from cli_helpers import PROBLEMS, ROOT

SCRIPT = textwrap.dedent("""
    import gc, sys
    from dolfinx_feti.cli import main  # first: it loads MPI before PETSc (0.11's wheels)
    from petsc4py import PETSc
    assert "matplotlib" not in sys.modules
    gc.collect()
    gc.disable()
    gc.set_debug(gc.DEBUG_SAVEALL)
    status = main([sys.argv[1], "-o", sys.argv[2], "-q", "--plot"])
    gc.collect()
    left = sorted({type(o).__name__ for o in gc.garbage if isinstance(o, PETSc.Object)})
    print("status", status, "matplotlib" in sys.modules, "left", ",".join(left) or "-")
""")


@pytest.mark.serial
def test_first_plot_leaves_no_petsc_object_in_a_cycle(tmp_path):
    run = subprocess.run([sys.executable, "-c", SCRIPT, str(PROBLEMS / "blocks3d.toml"),
                          str(tmp_path)], capture_output=True, text=True, cwd=ROOT,
                         timeout=600)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["status", "0", "True", "left", "-"], run.stdout
    assert (tmp_path / "blocks3d_pressure.png").stat().st_size > 0
