"""Point-to-point exchanges of array rows between ranks, and directories of global numbers.

The distributed set-up never gathers an array of the size of the whole mesh: a rank that needs
something about a global number (a vertex, a dof point, a facet key) sends the question to the
rank that keeps that number in a :class:`Blocks` directory, which answers in the layout of the
question (:func:`exchange`, then :func:`answer`).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from ..errors import SolveError


def exchange(comm: MPI.Comm, dest: np.ndarray, *arrays: np.ndarray):
    """Send row i of each array to rank ``dest[i]`` (collective).

    Returns:
        The received arrays (rows from rank 0 first, then rank 1, …; each sender's rows in
        their order), and the send order and the send and receive counts (to :func:`answer`).
    """
    dest = np.asarray(dest, dtype=np.int64)
    if comm.size == 1 and not np.any(dest):  # every row to this rank, in its order: copies
        counts = np.array([dest.size], dtype=np.int64)
        return ([np.array(a, dtype=np.asarray(a).dtype.newbyteorder("=")) for a in arrays],
                np.arange(dest.size), counts, counts.copy())
    order = np.argsort(dest, kind="stable")
    counts = np.bincount(dest, minlength=comm.size).astype(np.int64)
    rcounts = np.empty_like(counts)
    comm.Alltoall(counts, rcounts)
    out = []
    for a in arrays:
        a = np.asarray(a)
        # MPI knows native types only ('<d' from gmsh's arrays is not 'd' to it)
        a = np.ascontiguousarray(a[order], dtype=a.dtype.newbyteorder("="))
        width = int(np.prod(a.shape[1:], dtype=np.int64))
        recv = np.empty((int(rcounts.sum()),) + a.shape[1:], dtype=a.dtype)
        comm.Alltoallv([a, counts * width], [recv, rcounts * width])
        out.append(recv)
    return out, order, counts, rcounts


def answer(comm: MPI.Comm, values: np.ndarray, order: np.ndarray, counts: np.ndarray,
           rcounts: np.ndarray) -> np.ndarray:
    """Return to each sender of :func:`exchange` the rows ``values`` answering its rows."""
    values = np.ascontiguousarray(values)
    width = int(np.prod(values.shape[1:], dtype=np.int64))
    back = np.empty((int(counts.sum()),) + values.shape[1:], dtype=values.dtype)
    comm.Alltoallv([values, rcounts * width], [back, counts * width])
    out = np.empty_like(back)
    out[order] = back
    return out


class Blocks:
    """A directory of the numbers 0 … n − 1: rank r keeps the block ``lo[r]:lo[r + 1]``.

    The blocks are of nearly equal size and depend only on n and the number of ranks.
    """

    def __init__(self, n: int, size: int):
        self.n = int(n)
        self.lo = np.arange(size + 1, dtype=np.int64) * self.n // size

    def home(self, index: np.ndarray) -> np.ndarray:
        """The rank that keeps each number."""
        return np.searchsorted(self.lo, np.asarray(index, dtype=np.int64), side="right") - 1

    def local(self, rank: int) -> slice:
        """The numbers rank ``rank`` keeps."""
        return slice(int(self.lo[rank]), int(self.lo[rank + 1]))


class RankNumbering:
    """Items numbered globally rank by rank: this rank's are ``offset … offset + n − 1``.

    The directory of a numbering the ranks made themselves (pieces, vertices of a graph, the
    cells of blocks laid end to end): the owner of a number is the rank that numbered it, and
    :meth:`route` and :meth:`read` ask it about any numbers.
    """

    def __init__(self, comm: MPI.Comm, n: int):
        self.comm = comm
        self.starts = np.concatenate([[0], np.cumsum(comm.allgather(int(n)))]).astype(np.int64)
        self.offset = int(self.starts[comm.rank])

    def owner(self, number: np.ndarray) -> np.ndarray:
        """The rank that numbered each number."""
        return np.searchsorted(self.starts, number, side="right") - 1

    def route(self, number: np.ndarray):
        """Ask the owners about ``number`` (collective).

        Returns:
            The local rows (0 … n − 1) of the numbers asked of this rank, and the routing of
            the answers for :meth:`read`.
        """
        (asked,), order, counts, rcounts = exchange(self.comm, self.owner(number),
                                                    np.asarray(number, dtype=np.int64))
        return asked - self.offset, (order, counts, rcounts)

    def read(self, table: np.ndarray, rows: np.ndarray, routing) -> np.ndarray:
        """``table`` (one row per local item) at the numbers of a :meth:`route` (collective)."""
        return answer(self.comm, table[rows], *routing)


def hand_out(comm: MPI.Comm, make, what: str) -> object:
    """Rank 0 makes the pieces one at a time and sends each to its rank; returns this rank's.

    One piece at a time keeps rank 0's memory at the whole data plus two pieces (a scatter
    would hold every piece and its pickle at once). A failure while making a piece is sent in
    place of the pieces not yet sent, and every rank then raises it: none is left waiting.

    Args:
        comm: The ranks.
        make: ``make(rank)`` → the piece of that rank (called on rank 0 only).
        what: What is handed out, for the error message.
    """
    piece = failure = None
    if comm.rank == 0:
        for r in [*range(1, comm.size), 0]:
            msg = failure
            if failure is None:
                try:
                    msg = make(r)
                except Exception as e:  # every rank must hear of it
                    failure = msg = SolveError(f"{what} failed on rank 0 "
                                               f"({type(e).__name__}: {e})")
            if r == 0:
                piece = msg
            else:
                comm.send(msg, dest=r, tag=_TAG)
            del msg
    else:
        piece = comm.recv(source=0, tag=_TAG)
    failure = comm.bcast(failure, root=0)
    if failure is not None:
        raise failure
    return piece


#: The MPI tag of the pieces :func:`hand_out` sends.
_TAG = 7214


def exclusive_scan(comm: MPI.Comm, count: int) -> int:
    """The sum of ``count`` over the ranks before this one (0 on rank 0)."""
    start = comm.exscan(int(count))
    return 0 if comm.rank == 0 or start is None else int(start)


__all__ = ["Blocks", "RankNumbering", "answer", "exchange", "exclusive_scan", "hand_out"]
