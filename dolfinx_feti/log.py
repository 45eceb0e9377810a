"""Progress output on rank 0: one line per phase and an iteration monitor, PETSc-style.

Quiet by default (``verbose=0``); ``verbose=1`` prints the phases, ``verbose=2`` also the
iterations (``-feti_verbose 2`` on the command line). Lines go through the ``dolfinx_feti``
logger, so an application can redirect or silence them with the ``logging`` module.
"""

from __future__ import annotations

import logging
import sys

from mpi4py import MPI

logger = logging.getLogger("dolfinx_feti")


class Progress:
    """Prints on rank 0 of ``comm`` according to ``verbose``."""

    def __init__(self, comm: MPI.Comm, verbose: int) -> None:
        """Attach a stdout handler to the package logger if it has none and output is asked."""
        self.enabled = verbose > 0 and comm.rank == 0
        self.monitoring = verbose > 1 and comm.rank == 0
        if self.enabled and not logger.handlers:
            handler = logging.StreamHandler(sys.stdout)
            handler.setFormatter(logging.Formatter("%(message)s"))
            logger.addHandler(handler)
            logger.setLevel(logging.INFO)
            logger.propagate = False

    def phase(self, name: str, seconds: float) -> None:
        """One line when a phase ends."""
        if self.enabled:
            logger.info("feti: %-15s %8.3f s", name, seconds)

    def info(self, message: str) -> None:
        """A free-form line."""
        if self.enabled:
            logger.info("feti: %s", message)

    def inner(self, it: int, gP: float, kind: str) -> None:
        """Monitor of CG/MPRGP iterations (``monitor(it, norm, kind)``)."""
        if self.monitoring:
            logger.info("  %5d %-13s ||g^P|| %.3e", it, kind, gP)

    def outer(self, k: int, record: dict) -> None:
        """Monitor of SMALBE outer iterations (``monitor(k, record)``)."""
        if self.monitoring:
            logger.info("  outer %3d: inner %4d  ||g^P|| %.3e  ||Gx|| %.3e  M %.3e", k,
                        record.get("inner_iterations", 0), record.get("gP", float("nan")),
                        record.get("Dx", float("nan")), record.get("M", float("nan")))
