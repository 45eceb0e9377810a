"""A rank's own rows of B from distributed data: the Dirichlet mask, gluing and Dirichlet rows.

The serial set-up (:func:`~.build.build_rows`) builds every row from the global node →
subdomains map and hands each rank the rows whose smallest subdomain it owns
(:func:`~dolfinx_feti.setup.share.row_ranges`). Here a rank builds those rows itself, from what it
holds of the distributed mesh: the sorted global dof points of its cells, each with the sorted
list of ALL subdomains that hold it, and the owner rank of every subdomain. The rows are the
serial ones, in the serial order, with the same entries in the same order.

Why this needs little communication: every subdomain holding a point is owned by a rank that
holds the point with its whole subdomain list, so each rank can build all gluing and Dirichlet
rows of its points and keep the ones it owns. Only the Dirichlet mask needs an exchange: a
point on a Dirichlet facet may be held by a rank whose cells do not hold that facet (a
subdomain touching the boundary at a vertex or an edge only). Points that only one rank holds
have all their cells, and so all their facets, on that rank; the others are settled in a
:class:`~dolfinx_feti.parallel.exchange.Blocks` directory of the points.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from mpi4py import MPI

from ..errors import InputError, collective
from ..parallel.exchange import Blocks, answer, exchange, exclusive_scan
from ..problem.conditions import Dirichlet
from .dirichlet import condition_values, dirichlet_rows
from .gluing import gluing_rows
from .rows import Rows


class ConditionPoints(NamedTuple):
    """A Dirichlet condition as one rank sees it.

    Attributes:
        condition: The condition.
        points: The global dof points on the condition's facets that are facets of this rank's
            cells (any order; repeats allowed).
        x: Their coordinates (n, gdim).
    """

    condition: Dirichlet
    points: np.ndarray
    x: np.ndarray


def shared_points(ptr: np.ndarray, subs: np.ndarray, sub_rank: np.ndarray,
                  rank: int) -> np.ndarray:
    """Mask of the points that a rank other than ``rank`` holds too.

    When each rank holds the cells of the subdomains it owns: the points of a subdomain that
    another rank owns.

    Args:
        ptr: Point → all subdomains holding it (CSR pointer) ...
        subs: ... and the subdomains.
        sub_rank: Owner of every subdomain.
        rank: This rank.
    """
    other = np.r_[0, np.cumsum(sub_rank[subs] != rank)]
    return other[ptr[1:]] > other[ptr[:-1]]


def dirichlet_mask_distributed(points: np.ndarray, conditions: list[ConditionPoints], bs: int,
                               num_points: int, comm: MPI.Comm,
                               shared: np.ndarray | None = None
                               ) -> tuple[np.ndarray, np.ndarray]:
    """The Dirichlet mask and values of this rank's points (collective).

    Equal to the serial ``dirichlet_mask(problem, mesh)`` at ``points``: every point on a
    condition's facets is fixed in the condition's components, with the value at its position,
    and a later condition wins per component. A value function is evaluated by each rank on
    the points of its own facets of the condition.

    Args:
        points: The sorted global dof points of this rank's cells.
        conditions: The Dirichlet conditions of the problem, in order, as this rank sees them.
        bs: Components per point.
        num_points: Number of dof points of the whole mesh.
        comm: The ranks.
        shared: Mask of the ``points`` that other ranks hold too (:func:`shared_points`); the
            others are settled here without exchange, since all their cells are on this rank.
            Default: all.

    Returns:
        ``fixed`` (n, bs) bool and ``values`` (n, bs) (0 where not fixed).

    Raises:
        InputError: On every rank, naming the condition (as the serial code does) when a rank's
            values are bad: a wrong number of values, a value function that fails or returns
            another shape, a value that is not finite.
    """
    points = np.asarray(points, dtype=np.int64)
    n = points.size
    fixed = np.zeros((n, bs), dtype=bool)
    values = np.zeros((n, bs))
    records = []  # (local point, condition, values with NaN where the condition is silent)
    with collective(comm, "constraints"):
        for i, (bc, pts, x) in enumerate(conditions):
            pts, first = np.unique(np.asarray(pts, dtype=np.int64), return_index=True)
            if pts.size == 0:  # like the serial code, which calls a value function on
                continue  # the group's points only
            comps, v = condition_values(bc, np.asarray(x, dtype=float)[first], bs)
            local = np.searchsorted(points, pts)
            if np.any(local >= n) or np.any(points[np.minimum(local, n - 1)] != pts):
                raise ValueError(f"Dirichlet on {bc.group!r}: facet points that are not "
                                 "points of this rank's cells")
            fixed[local[:, None], comps] = True
            values[local[:, None], comps] = v
            full = np.full((pts.size, bs), np.nan)
            full[:, comps] = v
            records.append((local, np.full(pts.size, i), full))
    shared = np.ones(n, dtype=bool) if shared is None else np.asarray(shared, dtype=bool)
    local, cond, vals = (np.concatenate(a) for a in zip(*records, strict=True)) if records \
        else (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros((0, bs)))
    send = shared[local]
    settled = settle_conditions(comm, np.c_[points[local[send]], cond[send]], vals[send], bs,
                                num_points, points[shared])
    fixed[shared] = ~np.isnan(settled)
    values[shared] = np.nan_to_num(settled, nan=0.0)
    return fixed, values


def settle_conditions(comm: MPI.Comm, point_cond: np.ndarray, vals: np.ndarray, bs: int,
                      num_points: int, query: np.ndarray) -> np.ndarray:
    """Combine the ranks' condition values per point in a directory; the values at ``query``.

    Args:
        comm: The ranks.
        point_cond: (m, 2) global point and condition index of each record ...
        vals: ... and its values (m, bs), NaN in the components the condition leaves free.
        bs: Components per point.
        num_points: Number of dof points of the whole mesh.
        query: The global points whose combined values this rank needs.

    Returns:
        (len(query), bs): the value of the last condition fixing each component, NaN if none.
    """
    blocks = Blocks(num_points, comm.size)
    (got, got_vals), *_ = exchange(comm, blocks.home(point_cond[:, 0]), point_cond, vals)
    lo = blocks.lo[comm.rank]
    keep = np.full((blocks.local(comm.rank).stop - lo, bs), np.nan)
    order = np.lexsort((got[:, 1], got[:, 0]))
    for c in range(bs):  # the last record (latest condition) fixing c at each point wins
        rec = order[~np.isnan(got_vals[order, c])]
        pts = got[rec, 0]
        last = np.ones(pts.size, dtype=bool)
        last[:-1] = pts[1:] != pts[:-1]
        keep[pts[last] - lo, c] = got_vals[rec[last], c]
    (asked,), order, counts, rcounts = exchange(comm, blocks.home(query), query)
    return answer(comm, keep[asked - lo], order, counts, rcounts)


def own_rows(points: np.ndarray, ptr: np.ndarray, subs: np.ndarray, fixed: np.ndarray,
             values: np.ndarray, bs: int, gdim: int, scheme: str, sub_rank: np.ndarray,
             comm: MPI.Comm, extra: Rows | None = None) -> tuple[Rows, int, int]:
    """This rank's rows of B, as the serial set-up orders and shares them (collective).

    The rows whose smallest subdomain this rank owns, among the gluing and Dirichlet rows of
    its points and the rows of ``extra``, in the order of the serial
    :func:`~.build.build_rows` (a stable sort by smallest subdomain of the blocks gluing,
    Dirichlet, then ``extra``), numbered from 0: equal, field by field, to the serial rows
    ``row_slice(build_rows(problem, dec), start, start + own.size)``.

    Args:
        points: The sorted global dof points of the cells of the subdomains this rank owns.
        ptr: Point → all subdomains holding it (CSR pointer) ...
        subs: ... and the subdomains (global numbers, sorted per point).
        fixed: The Dirichlet mask (n, bs) of the points ...
        values: ... and the values (:func:`dirichlet_mask_distributed`).
        bs: Components per point.
        gdim: Geometric dimension.
        scheme: The gluing scheme ("orthonormal", "redundant" or "nonredundant").
        sub_rank: Owner of every subdomain.
        comm: The ranks.
        extra: The rows the serial code adds after gluing and Dirichlet (ties, contact,
            friction), in its order, the same on every rank; None for none.

    Returns:
        The rows (global dof points in ``e_node``, ``node`` and ``partner``), the global index
        of the first of them, and the number of rows of the whole problem.

    Raises:
        InputError: On every rank, when a row's right-hand side or coefficient is not finite.
    """
    # only the points in two subdomains or more, or fixed, have rows: the interfaces and the
    # Dirichlet boundary, a small part of the points
    mult = np.diff(ptr)
    has_rows = mult >= 2
    for c in range(bs):  # not np.any(fixed, axis=1): ten times slower on (n, 2) masks
        has_rows |= fixed[:, c]
    sel = np.flatnonzero(has_rows)
    count = mult[sel]
    sel_ptr = np.r_[0, np.cumsum(count)].astype(np.int64)
    sel_subs = subs[np.repeat(ptr[sel] - sel_ptr[:-1], count) + np.arange(sel_ptr[-1])]
    sel_points = np.asarray(points, dtype=np.int64)[sel]
    blocks = []
    for block in (gluing_rows(sel_ptr, sel_subs, fixed[sel], bs, gdim, scheme),
                  dirichlet_rows(sel_ptr, sel_subs, fixed[sel], values[sel], bs, gdim)):
        block.e_node = sel_points[block.e_node]
        block.node = sel_points[block.node]
        blocks.append(block)
    blocks.append(Rows.empty(gdim) if extra is None else extra)
    rows = Rows.concatenate(blocks)
    first = rows.min_subdomain()
    mine = np.flatnonzero(np.asarray(sub_rank)[first] == comm.rank)
    rows = rows.permuted(mine[np.argsort(first[mine], kind="stable")])
    with collective(comm, "constraints"):
        if not np.all(np.isfinite(rows.rhs)) or not np.all(np.isfinite(rows.e_coef)):
            raise InputError("non-finite constraint data (a Dirichlet value, a gap or an "
                             "obstacle distance is NaN or Inf)")
    return rows, exclusive_scan(comm, rows.size), comm.allreduce(rows.size)


__all__ = ["ConditionPoints", "dirichlet_mask_distributed", "own_rows", "settle_conditions",
           "shared_points"]
