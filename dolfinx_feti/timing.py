"""Wall-clock timing of the solve's phases."""

from __future__ import annotations

import time
from contextlib import contextmanager

from mpi4py import MPI


class Timer:
    """Accumulates the wall time of named phases; reports the maximum over ranks."""

    def __init__(self, on_end=None) -> None:
        """Start with no phase timed; ``on_end(name, seconds)`` is called as each phase ends."""
        self.phases: dict[str, float] = {}
        self._on_end = on_end

    @contextmanager
    def phase(self, name: str):
        """Time the enclosed block under ``name`` (times add up when a name repeats)."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            dt = time.perf_counter() - t0
            self.phases[name] = self.phases.get(name, 0.0) + dt
            if self._on_end is not None:
                self._on_end(name, dt)

    def reduced(self, comm: MPI.Comm) -> dict[str, float]:
        """Phase times, maximum over the ranks of ``comm`` (the slowest rank sets the pace)."""
        names = comm.bcast(list(self.phases), root=0)
        return {n: comm.allreduce(self.phases.get(n, 0.0), op=MPI.MAX) for n in names}
