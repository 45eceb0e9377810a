"""The command ``dolfinx-feti`` with a QP solver that never ends, to interrupt it in a test.

Run as ``python tests/support/endless_cli.py PROBLEM.toml [options]``: everything up to the QP
solver is the real command; the solver prints a line and then does collective work forever (an
allreduce every 10 ms, as an iterating solver does), so a test can send Ctrl-C at a known
point. Each rank also creates the file ``iterating.<rank>`` in the working folder: mpirun
forwards the ranks' output late under load, a file is there at once.
"""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the checkout, not an install

from mpi4py import MPI  # noqa: E402

import dolfinx_feti.solver  # noqa: E402, F401  (the module whose QP solve is patched)
from dolfinx_feti.cli import main  # noqa: E402


def endless(*args, **kwargs):
    Path(f"iterating.{MPI.COMM_WORLD.rank}").touch()
    # one write (print writes the text and the newline apart: mpirun may interleave ranks)
    sys.stdout.write(f"rank {MPI.COMM_WORLD.rank}: in the QP solver\n")
    sys.stdout.flush()
    while True:
        MPI.COMM_WORLD.allreduce(1)
        time.sleep(0.01)


sys.modules["dolfinx_feti.solver"].solve_qp = endless
sys.exit(main(sys.argv[1:]))
