"""Dof points and the point → subdomain directory of a mesh whose cells are spread over ranks.

Each rank holds some cells in global vertex numbers (a block after the scatter of
the mesh, any subset after :func:`migrate`). The functions here give exactly what the serial
code gives on the whole mesh (:func:`.dofpoints.dof_points`, :class:`.decompose.Decomposition`),
restricted to the rank's cells, without any rank holding an array of the size of the mesh:

- :func:`number_points`: the global dof points of the local cells. For degree 2 the points of
  the edges, faces and interiors are numbered, per dimension, in the order of their keys
  (:func:`.topology.row_keys`: int64 keys, or byte strings compared bytewise). A sample sort
  routes each key to the rank whose key range holds it (splitters compared with NumPy's own
  ordering of the keys, so both kinds of key sort as in the serial ``np.unique``); that rank
  numbers its distinct keys, and the ranks' key ranges follow one another, so the number of a
  key is an offset (the keys of the ranks before) plus its rank in the local range.
- :func:`point_coordinates`: the coordinates of the local points (vertices, entity midpoints).
- :func:`point_subdomains`: for each local point, every subdomain that holds it (on any rank),
  and the number of points of every subdomain, through a
  :class:`~dolfinx_feti.parallel.exchange.Blocks`
  directory of the points: the (subdomain, point) pairs go to the point's home rank, which
  sends each rank that sent a pair the point's whole sorted list.
- :func:`owners` and :func:`migrate`: the serial assignment of subdomains to ranks, and the
  move of the cells (with any per-cell arrays) to the ranks that own their subdomains.

Every function is collective: each rank calls it once, with its own cells (possibly none).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from ..errors import InputError, collective
from ..parallel.exchange import Blocks, answer, exchange
from .decompose import assign_ranks
from .dofpoints import degree2_entities
from .topology import REFERENCE, row_keys

#: Samples each rank contributes per rank of the communicator to choose the sort's splitters
#: (more samples: key ranges of more even size).
OVERSAMPLING = 16


def number_points(cells: np.ndarray, cell_type: str, degree: int, num_vertices: int,
                  comm: MPI.Comm) -> tuple[np.ndarray, int, dict[int, int]]:
    """The global dof points of the local cells, numbered as :func:`.dofpoints.dof_points`.

    Args:
        cells: (C_local, nvc) the local cells in global vertex numbers.
        cell_type: The cells' type.
        degree: The Lagrange degree, 1 or 2.
        num_vertices: The number of vertices of the whole mesh.
        comm: The ranks that hold the mesh's cells.

    Returns:
        ``(cell_points, num_points, first)``: the points of each local cell (C_local, k) in
        the serial layout (its vertices, then its edges, faces and interior in the reference
        order), the number of points of the whole mesh, and dim → the number of the first
        point of that dimension (the serial ``entities[dim][1]``; empty for degree 1).

    Raises:
        InputError: On every rank, if a rank's cells or the degree are invalid.
    """
    cells = np.asarray(cells)
    with collective(comm):
        _check_cells(cells, cell_type, num_vertices)
        if degree not in (1, 2):
            raise InputError(f"Lagrange degree {degree}: only 1 and 2 are supported")
    cells = cells.astype(np.int64, copy=False)
    N = int(num_vertices)
    if degree == 1:
        return cells, N, {}
    C = cells.shape[0]
    entities = degree2_entities(cell_type)
    local, inverse = [], []
    for _, vertex_lists in entities:
        v = cells.T[np.array(vertex_lists)]  # (ne, nve, C): entity by entity (longer sorted runs)
        keys, _, inv = unique_sorted(row_keys(v.transpose(0, 2, 1).reshape(-1, v.shape[1]), N))
        local.append(keys)
        inverse.append(inv.reshape(v.shape[0], C).T)
    numbers, totals = _rank_in_union(local, comm)
    parts, first, offset = [cells], {}, N
    for (dim, _), number, inv, total in zip(entities, numbers, inverse, totals, strict=True):
        parts.append(offset + number[inv])
        first[dim] = offset
        offset += total
    return np.concatenate(parts, axis=1), offset, first


def point_coordinates(cell_points: np.ndarray, cells: np.ndarray, cell_x: np.ndarray,
                      cell_type: str, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """The coordinates of the local points: vertices, and the midpoints of the entities.

    The serial points' coordinates on a first-order mesh, bit for bit: a midpoint is the mean
    of its entity's vertices taken in the order of their global numbers, whichever cell
    supplies it.

    Args:
        cell_points: (C_local, k) the local cells' points (:func:`number_points`).
        cells: (C_local, nvc) the local cells in global vertex numbers.
        cell_x: (C_local, nvc, gdim) the coordinates of their vertices.
        cell_type: The cells' type.
        degree: The Lagrange degree, 1 or 2.

    Returns:
        ``(points, x)``: the sorted distinct points of the local cells and their coordinates.
    """
    cells = np.asarray(cells, dtype=np.int64)
    cell_x = np.asarray(cell_x, dtype=float)
    cell_points = np.asarray(cell_points, dtype=np.int64)
    C, nvc = cells.shape
    # the points of one dimension fill a range of numbers after those of the dimension before:
    # one (smaller) sort per dimension, of the columns one after the other (longer sorted runs)
    groups = [(nvc, None)] + [(len(local), np.array(local)) for _, local in
                              (degree2_entities(cell_type) if degree == 2 else ())]
    points, xs, start = [], [], 0
    for width, local in groups:
        values, first, _ = unique_sorted(cell_points[:, start:start + width].T.ravel(), False)
        cell, slot = first % max(C, 1), first // max(C, 1)  # one cell holding each point
        if local is None:
            xs.append(cell_x[cell, slot])
        else:
            at = local[slot]  # (n, nve): the local vertices of each entity
            c = cell[:, None]
            at = np.take_along_axis(at, np.argsort(cells[c, at], axis=1), axis=1)  # by number
            xs.append(cell_x[c, at].mean(axis=1))
        points.append(values)
        start += width
    return np.concatenate(points), np.concatenate(xs)


def point_subdomains(cell_points: np.ndarray, cell_sub: np.ndarray, num_points: int, nsub: int,
                     comm: MPI.Comm) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The subdomains of each local point, over all ranks, and the size of every subdomain.

    Args:
        cell_points: (C_local, k) the global points of the local cells.
        cell_sub: (C_local,) the subdomain of each local cell.
        num_points: The number of points of the whole mesh.
        nsub: The number of subdomains.
        comm: The ranks that hold the mesh's cells.

    Returns:
        ``(points, ptr, subs, sub_size)``: the sorted distinct points of the local cells; the
        sorted subdomains holding ``points[i]`` are ``subs[ptr[i]:ptr[i + 1]]`` (the serial
        ``Decomposition.node_subdomains()`` of those points); and the number of points of
        each subdomain (nsub,), the same on every rank (the serial ``diff(sub_ptr)``).

    Raises:
        InputError: On every rank, if a rank's points or subdomains are out of range.
    """
    directory = SubdomainDirectory(cell_points, cell_sub, num_points, nsub, comm)
    points = _distinct(np.asarray(cell_points, dtype=np.int64).ravel())
    ptr, subs = directory.ask(points)
    return points, ptr, subs, directory.sub_size


class SubdomainDirectory:
    """The sorted subdomains of every point, kept by the points' home ranks (collective).

    Built once from the ranks' cells, it answers for any points afterwards: the set of
    (point, subdomain) pairs does not change when the cells move (:func:`migrate`), so the
    directory built before the move answers the ranks' points after it.

    Attributes:
        sub_size: The number of points of each subdomain (nsub,), the same on every rank (the
            serial ``diff(sub_ptr)``).
    """

    def __init__(self, cell_points: np.ndarray, cell_sub: np.ndarray, num_points: int,
                 nsub: int, comm: MPI.Comm) -> None:
        """Send the distinct (point, subdomain) pairs of the local cells to the points' homes.

        Args: as :func:`point_subdomains`.

        Raises:
            InputError: On every rank, if a rank's points or subdomains are out of range.
        """
        cell_points, cell_sub = np.asarray(cell_points), np.asarray(cell_sub)
        with collective(comm):
            _check_numbers(cell_points, num_points, "cell_points", 2)
            _check_numbers(cell_sub, nsub, "cell_sub", 1)
            if cell_sub.shape[0] != cell_points.shape[0]:
                raise InputError(f"cell_sub has {cell_sub.shape[0]} entries for "
                                 f"{cell_points.shape[0]} cells")
            if int(nsub) * int(num_points) >= 2**63:
                raise InputError(f"{nsub} subdomains × {num_points} points: (subdomain, point) "
                                 "pairs beyond 64-bit keys")
        nsub = int(nsub)
        self.comm = comm
        self.blocks = Blocks(num_points, comm.size)
        # The distinct (point, subdomain) pairs of the local cells, to the points' home ranks.
        key = _distinct(cell_points.astype(np.int64).T.ravel() * nsub  # column by column: runs
                        + np.tile(cell_sub.astype(np.int64), cell_points.shape[1]))
        (got,), _, _, _ = exchange(comm, self.blocks.home(key // nsub), key)
        # Home: each point's sorted subdomains (pairs sent by several ranks counted once).
        key = got if comm.size == 1 else _distinct(got)  # one rank sent it distinct and sorted
        point, self._sub = key // nsub, key % nsub
        self.sub_size = np.bincount(self._sub, minlength=nsub).astype(np.int64)
        comm.Allreduce(MPI.IN_PLACE, self.sub_size, op=MPI.SUM)
        self._held, self._start = _starts(point)
        self._count = np.diff(np.append(self._start, point.size))

    def ask(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sorted subdomains of each of this rank's sorted distinct points (collective).

        Returns:
            ``(ptr, subs)``: the subdomains of ``points[i]`` are ``subs[ptr[i]:ptr[i + 1]]``.
        """
        comm, size = self.comm, self.comm.size
        points = np.asarray(points, dtype=np.int64)
        (asked,), _, _, rcounts = exchange(comm, self.blocks.home(points), points)
        sender = np.repeat(np.arange(size, dtype=np.int64), rcounts)
        at = np.minimum(np.searchsorted(self._held, asked), self._held.size - 1)
        # a point of no cell gets no list (the check below then fails on its rank)
        n = np.where(self._held[at] == asked, self._count[at], 0) if self._held.size else \
            np.zeros(asked.size, dtype=np.int64)
        # Each sender's points arrive in its (ascending) order and go back in it, whole lists
        # by point, then subdomain; the homes' blocks ascend with their ranks: the rows arrive
        # sorted.
        rows = index_ranges(self._start[at], n) if self._held.size else np.zeros(0, np.int64)
        (back,), _, _, _ = exchange(comm, np.repeat(sender, n),
                                    np.column_stack([np.repeat(asked, n), self._sub[rows]]))
        held, start = _starts(back[:, 0])
        if not np.array_equal(held, points):
            raise AssertionError("the subdomain directory has no list for some points")
        ptr = np.append(start, back.shape[0]).astype(np.int64)
        return ptr, back[:, 1]


def owners(sub_size: np.ndarray, comm_size: int) -> np.ndarray:
    """The rank owning each subdomain: the serial assignment (``Decomposition.sub_rank``).

    Contiguous blocks of subdomains of balanced point counts; ``owners(...)[cell_sub]`` is
    the rank each cell moves to (:func:`migrate`).
    """
    return assign_ranks(np.asarray(sub_size, dtype=np.int64), int(comm_size))


def migrate(dest: np.ndarray, *arrays: np.ndarray, comm: MPI.Comm,
            key: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """Move each local cell's rows of the per-cell arrays to rank ``dest`` of the cell.

    Args:
        dest: (C_local,) the rank each cell goes to (``owners(...)[cell_sub]``).
        *arrays: Per-cell arrays (cells, cell_x, cell_body, cell_ids, cell_sub, cell_points,
            …), each with C_local rows.
        comm: The ranks that hold the mesh's cells.
        key: (C_local,) the global cell ids, to sort the received cells by. Without it the
            cells come by sending rank, each rank's in its order: the order of the global ids
            when every rank holds ascending ids after those of the rank before (the blocks of
            the mesh's scatter), not after a migration.

    Returns:
        The arrays of the cells this rank receives, in the order of ``arrays``.

    Raises:
        InputError: On every rank, if a rank's destinations or arrays are invalid.
    """
    dest = np.asarray(dest)
    arrays = tuple(np.asarray(a) for a in arrays)
    extra = () if key is None else (np.asarray(key),)
    with collective(comm):
        _check_numbers(dest, comm.size, "dest", 1)
        named = [(f"array {i}", a) for i, a in enumerate(arrays)] + [("key", a) for a in extra]
        for name, a in named:
            if a.ndim == 0 or a.shape[0] != dest.shape[0]:
                raise InputError(f"migrate: {name} has shape {a.shape}, not {dest.shape[0]} "
                                 "rows (one per cell)")
    received, _, _, _ = exchange(comm, dest, *arrays, *extra)
    if key is None:
        return tuple(received)
    if np.all(received[-1][1:] > received[-1][:-1]):  # e.g. no cell moved: no copies
        return tuple(received[:-1])
    order = np.argsort(received[-1], kind="stable")
    return tuple(a[order] for a in received[:-1])


# ------------------------------------------------------------------------------------------------
# The sample sort
# ------------------------------------------------------------------------------------------------


def _rank_in_union(key_sets: list[np.ndarray], comm: MPI.Comm
                   ) -> tuple[list[np.ndarray], list[int]]:
    """Position of each local key in the sorted union of the keys of all ranks (collective).

    Args:
        key_sets: Arrays of sorted distinct keys (int64 or void; the same dtype on every rank
            for each array).
        comm: The ranks.

    Returns:
        For each array, the position of each of its keys in the union of that array over all
        ranks, and the size of each union.
    """
    size = comm.size
    samples = [keys[(np.arange(m) * 2 + 1) * keys.size // (2 * m)]
               for keys in key_sets for m in [min(keys.size, OVERSAMPLING * size)]]
    gathered = comm.allgather(samples)
    received, routes, distinct = [], [], []
    for i, keys in enumerate(key_sets):
        pool = np.sort(np.concatenate([g[i] for g in gathered]))
        if pool.size:
            splitters = pool[np.arange(1, size) * pool.size // size]
            dest = np.searchsorted(splitters, keys, side="right")
        else:
            dest = np.zeros(keys.size, dtype=np.int64)
        (rows,), order, counts, rcounts = exchange(comm, dest, _as_rows(keys))
        mine, _, inv = unique_sorted(_from_rows(rows, keys.dtype))
        received.append(inv)
        routes.append((order, counts, rcounts))
        distinct.append(mine.size)
    every = np.array(comm.allgather(distinct), dtype=np.int64).reshape(size, len(key_sets))
    offsets = np.cumsum(every, axis=0) - every
    numbers = [answer(comm, offsets[comm.rank, i] + inv, *route)
               for i, (inv, route) in enumerate(zip(received, routes, strict=True))]
    return numbers, [int(t) for t in every.sum(axis=0)]


def _as_rows(keys: np.ndarray) -> np.ndarray:
    """Keys as rows of int64 (what MPI sends): one column for int64 keys, w for void keys."""
    if keys.dtype.kind != "V":
        return keys.astype(np.int64, copy=False)[:, None]
    return np.ascontiguousarray(keys).view(np.int64).reshape(keys.size, keys.dtype.itemsize // 8)


def _from_rows(rows: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """The keys of :func:`_as_rows` back."""
    if dtype.kind != "V":
        return rows[:, 0].astype(dtype, copy=False)
    return np.ascontiguousarray(rows).view(dtype).reshape(-1)


# ------------------------------------------------------------------------------------------------
# Helpers
# ------------------------------------------------------------------------------------------------


def unique_sorted(a: np.ndarray, inverse: bool = True
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``np.unique(a, return_index=True, return_inverse=inverse)`` (any index of each value).

    By a stable sort: NumPy's timsort merges the sorted runs that the exchanges deliver (each
    sender's keys in order) in near-linear time, several times faster than a quicksort.
    """
    order = np.argsort(a, kind="stable")
    values, start = _starts(a[order])
    if not inverse:
        return values, order[start], None
    where = np.empty(a.size, dtype=np.int64)
    where[order] = np.repeat(np.arange(start.size), np.diff(np.append(start, a.size)))
    return values, order[start], where


def _distinct(a: np.ndarray) -> np.ndarray:
    """The sorted distinct values of ``a`` (a stable sort, as in :func:`unique_sorted`)."""
    return _starts(np.sort(a, kind="stable"))[0]


def _starts(sorted_values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct values of a sorted array and the index where each begins."""
    new = np.ones(sorted_values.size, dtype=bool)
    new[1:] = sorted_values[1:] != sorted_values[:-1]
    start = np.flatnonzero(new)
    return sorted_values[start], start


def index_ranges(start: np.ndarray, length: np.ndarray) -> np.ndarray:
    """The concatenated index ranges ``start[i]:start[i] + length[i]``."""
    total = int(length.sum())
    shift = np.repeat(start - (np.cumsum(length) - length), length)
    return shift + np.arange(total, dtype=np.int64)


def _check_cells(cells: np.ndarray, cell_type: str, num_vertices: int) -> None:
    if cell_type not in REFERENCE:
        raise InputError(f"unknown cell type {cell_type!r}; the types are {sorted(REFERENCE)}")
    nvc = REFERENCE[cell_type].num_vertices
    if cells.ndim != 2 or cells.shape[1] != nvc:
        raise InputError(f"{cell_type} cells need {nvc} vertices each: cells of shape "
                         f"{cells.shape}")
    _check_numbers(cells, num_vertices, "cells", 2)


def _check_numbers(a: np.ndarray, bound: int, name: str, ndim: int) -> None:
    """``a`` is an integer array of ``ndim`` dimensions with entries in [0, bound)."""
    if a.ndim != ndim or (a.size and not np.issubdtype(a.dtype, np.integer)):
        raise InputError(f"{name} must be a {ndim}-d integer array, got {a.dtype} {a.shape}")
    if a.size and (a.min() < 0 or a.max() >= bound):
        raise InputError(f"{name} has entries outside [0, {bound}): {a.min()} … {a.max()}")


__all__ = ["SubdomainDirectory", "migrate", "number_points", "owners", "point_coordinates",
           "point_subdomains"]
