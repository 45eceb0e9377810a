"""Reductions of small values over the ranks, for the solvers' inner loops.

mpi4py's lower-case ``comm.allreduce`` pickles its operands: about 20–30 µs for a three-entry
array, several times a product by F on a small subdomain, and a few of them run at every MPRGP
step. These functions reduce through buffers (``comm.Allreduce``) and skip the call on one rank,
where the value is its own reduction. On two ranks the sums are the same to the bit as the
pickled ones (a + b is commutative in floating point).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI


def sum_array(comm: MPI.Comm, a: np.ndarray) -> np.ndarray:
    """The entrywise sum of ``a`` over the ranks, as a new array of ``a``'s dtype."""
    a = np.ascontiguousarray(a)
    if comm.size == 1:
        return a.copy()
    out = np.empty_like(a)
    comm.Allreduce(a, out, op=MPI.SUM)
    return out


def _scalar(comm: MPI.Comm, value: float, op: MPI.Op) -> float:
    buf = np.array([value], dtype=np.float64)
    comm.Allreduce(MPI.IN_PLACE, buf, op=op)
    return float(buf[0])


def sum_scalar(comm: MPI.Comm, value: float) -> float:
    """``value`` summed over the ranks."""
    return float(value) if comm.size == 1 else _scalar(comm, value, MPI.SUM)


def max_scalar(comm: MPI.Comm, value: float) -> float:
    """The largest ``value`` over the ranks."""
    return float(value) if comm.size == 1 else _scalar(comm, value, MPI.MAX)


def min_scalar(comm: MPI.Comm, value: float) -> float:
    """The smallest ``value`` over the ranks."""
    return float(value) if comm.size == 1 else _scalar(comm, value, MPI.MIN)


def any_rank(comm: MPI.Comm, flag: bool) -> bool:
    """Whether ``flag`` holds on some rank."""
    return bool(flag) if comm.size == 1 else _scalar(comm, 1.0 if flag else 0.0, MPI.MAX) > 0.0


def count(comm: MPI.Comm, n: int) -> int:
    """``n`` summed over the ranks (a count: exact in a float below 2⁵³)."""
    return int(n) if comm.size == 1 else int(_scalar(comm, float(n), MPI.SUM))


__all__ = ["any_rank", "count", "max_scalar", "min_scalar", "sum_array", "sum_scalar"]
