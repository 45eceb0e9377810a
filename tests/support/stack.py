"""What the environment that runs the tests has: its MPI launcher and its factor packages."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from dolfinx_feti import compat
from dolfinx_feti.factor import available_factors


def mpi_launcher(n: int) -> list[str]:
    """The command prefix that starts ``n`` ranks of a program with this environment's MPI.

    DOLFINx 0.11's wheel brings MPICH with its ``mpiexec`` beside the interpreter (the venv's
    bin/); Debian 12's DOLFINx 0.5.2 runs under Open MPI's ``mpirun`` (as root here, which Open
    MPI refuses without the flag; 2 ranks may exceed the cores it counts).
    """
    own = Path(sys.executable).parent / "mpiexec"  # not resolved: the venv's bin/
    if own.exists():
        return [str(own), "-n", str(n)]
    return ["mpirun", "-n", str(n), "--allow-run-as-root", "--oversubscribe"]


def factor_params(*names: str) -> list:
    """``factor`` values for parametrize; a package this PETSc lacks is skipped, and says so."""
    return [pytest.param(name, marks=pytest.mark.skipif(
        name not in available_factors(),
        reason=f"{name} is not in the PETSc of {compat.version_label()}")) for name in names]
