"""Exceptions with messages that name the problem, raised on every rank.

:func:`collective` is the one mechanism that keeps an error on one rank from hanging the others:
every phase that runs user code (a labeller, a Dirichlet value, a slip bound, a signed distance,
the forms) or that only some ranks perform (rank 0 reads the mesh, checks and writes the
outputs) runs inside ``with collective(comm, site):``. Each site has a name in :data:`SITES`;
:func:`inject_fault` makes a site fail on one rank, so that a test can check every site.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from mpi4py import MPI


class InputError(ValueError):
    """The problem as described cannot be solved: a missing tag, bad data, an ill-posed load."""


class SolveError(RuntimeError):
    """A phase of the solve failed (e.g. a singular subdomain matrix)."""


class NotConverged(SolveError):
    """The solver did not converge, with ``error_if_not_converged`` set (raised on every rank).

    Attributes:
        solution: The solution reached (its report says why it stopped).
    """

    def __init__(self, message: str, solution=None) -> None:
        super().__init__(message)
        self.solution = solution


#: The collective phases that run user code or rank-local I/O, by name (see :func:`collective`).
SITES = {
    "problem file": "reading the problem file (rank 0)",
    "options": "the solver options (read from keywords, argv and PETSc's database per rank)",
    "mesh": "reading or generating the mesh with gmsh (rank 0)",
    "output folder": "checking the output folder before the solve (rank 0)",
    "decomposition": "the decomposition (a ByFunction labeller, PT-Scotch on rank 0)",
    "constraints": "the constraint rows (Dirichlet value functions, obstacle distances)",
    "friction": "the slip bounds (Tresca bound functions)",
    "assembly": "the subdomain forms (the forms callback) and their assembly",
    "factorization": "the factorization of the subdomain matrices",
    "outputs": "writing the outputs (XDMF on all ranks, the other files on rank 0)",
}

_FAULTS: dict[str, int] = {}


@contextmanager
def inject_fault(site: str, rank: int) -> Iterator[None]:
    """Make the phase ``site`` raise on ``rank`` while the block runs (for tests).

    The fault is raised at the start of the phase, inside its guard, as user code would raise.
    """
    if site not in SITES:
        raise KeyError(f"unknown site {site!r}; the sites are {sorted(SITES)}")
    _FAULTS[site] = rank
    try:
        yield
    finally:
        _FAULTS.pop(site, None)


@contextmanager
def collective(comm: MPI.Comm, site: str = "") -> Iterator[None]:
    """Run a rank-local block; if it raises on any rank, raise on every rank.

    Without this, a rank that fails (a user callback that raises, a file that cannot be written
    on rank 0) would leave the others waiting forever in the next collective call. Every rank
    raises the same exception with the same message, that of the lowest failing rank, naming
    the site and the rank: an :class:`InputError` when that rank raised one (bad input), else a
    :class:`SolveError`. On the failing rank the original exception is chained (``from``).

    Args:
        comm: The ranks that run the block.
        site: The name of the phase (a key of :data:`SITES`; "" for none).
    """
    error = None
    try:
        if site and _FAULTS.get(site) == comm.rank:
            raise RuntimeError(f"fault injected at {site!r}")
        yield
    except Exception as e:  # noqa: BLE001 - re-raised below, on every rank
        error = e
    failures = comm.allgather(None if error is None else
                              (isinstance(error, InputError), _describe(error)))
    failed = [(r, f) for r, f in enumerate(failures) if f is not None]
    if not failed:
        return
    rank, (is_input, message) = failed[0]
    if comm.size == 1 and isinstance(error, InputError | SolveError):
        raise error  # serial: our own error as it was raised
    where = f"in {site}" if site else ""
    if comm.size > 1:
        where = f"{where} on rank {rank}" if where else f"raised on rank {rank}"
    cls = InputError if is_input else SolveError
    raise cls(f"{message} ({where})" if where else message) from error


def _describe(error: Exception) -> str:
    """The message of an error; its type too unless it is one of ours."""
    if isinstance(error, InputError | SolveError):
        return str(error)
    return f"{type(error).__name__}: {error}"
