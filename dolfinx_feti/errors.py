"""Exceptions with messages that name the problem."""


class InputError(ValueError):
    """The problem as described cannot be solved: a missing tag, bad data, an ill-posed load."""


class SolveError(RuntimeError):
    """A phase of the solve failed (e.g. a singular subdomain matrix)."""
