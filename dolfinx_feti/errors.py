"""Exceptions with messages that name the problem, raised on every rank."""

from contextlib import contextmanager

from mpi4py import MPI


class InputError(ValueError):
    """The problem as described cannot be solved: a missing tag, bad data, an ill-posed load."""


class SolveError(RuntimeError):
    """A phase of the solve failed (e.g. a singular subdomain matrix)."""


@contextmanager
def collective(comm: MPI.Comm):
    """Run a rank-local block; if it raises on any rank, raise on every rank.

    Without this, a rank that fails while assembling or factoring its subdomains would leave
    the others waiting forever in the next collective call. The error of the lowest failing
    rank is raised everywhere, with its type when it is one of ours.
    """
    error = None
    try:
        yield
    except Exception as e:  # noqa: BLE001 - re-raised below, on every rank
        error = e
    failures = comm.allgather(None if error is None else (type(error).__name__, str(error)))
    failed = [(r, f) for r, f in enumerate(failures) if f is not None]
    if not failed:
        return
    if error is not None:
        raise error
    rank, (kind, message) = failed[0]
    cls = {"InputError": InputError}.get(kind, SolveError)
    raise cls(f"{message} (raised on rank {rank})")
