"""The decomposition of a distributed mesh, equal to the serial one on the whole mesh.

Each rank holds some cells of the mesh (their global vertex numbers and coordinates and their
global ids) and receives the global subdomain of each: exactly
``decompose(whole mesh, how, ...).cell_sub[cell_ids]``, whatever the number of ranks and the
split of the cells, and no rank ever holds an array of the size of the whole mesh.

- :func:`rcb_distributed`: the recursive coordinate bisection of :func:`.decompose.rcb`. All
  work items of one tree level are processed together: their bounding boxes by one reduction,
  then the cut of each by a distributed selection: the ranks propose sample points of the
  candidates left, the global counts (and weights) below the samples narrow the candidates
  down by a factor of about the number of samples per round, so a level takes a few
  collective rounds of small data, never a gather of the points.
- :func:`split_components_distributed`: the connected pieces of equal label of
  :func:`.decompose._split_components`: pieces of the local cells, linked through the facets
  that two ranks share (matched at the rank of a directory of facets), joined by the
  distributed connected components of the piece graph
  (:func:`.distributed_graph.component_minima`: O(log pieces) rounds of hooking and
  shortcutting, every rank holding only its own pieces and links); the pieces are numbered
  by their first cell through a directory of the cell ids.
- :func:`decompose_distributed`: the labels of ByTags / Parts / ByFunction, then the pieces.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from scipy.sparse.csgraph import connected_components

from ..errors import InputError, collective
from ..parallel.distributed_graph import component_minima
from ..parallel.exchange import Blocks, answer, exchange, exclusive_scan
from .auto_parts import BALANCE, Auto, auto_parts
from .connected_parts import merge_fragments_distributed, rank_facets
from .decompose import (
    ByFunction,
    ByTags,
    Parts,
    first_of_each,
    fixed_point_weights,
    midpoints_of,
    weight_target,
)
from .topology import cell_volumes, reference, row_keys

#: The number of sample points that all ranks together propose per selection round (bounds
#: the data of a round; each work item gets at most 64 per rank).
_SAMPLES_PER_ROUND = 2**15


@dataclass(frozen=True)
class BlockLabels:
    """This rank's labels of its cells, given (a block of a whole mesh).

    The labels of the whole mesh's decomposition that rank 0 ran (PT-Scotch's parts, a
    :class:`~.decompose.ByFunction` labeller's labels), cut with the blocks. The pieces of
    equal label are the subdomains, as for ``ByFunction``, without the midpoints a labeller
    would be called on.

    Attributes:
        label: One integer label per local cell.
    """

    label: np.ndarray


def rcb_distributed(points: np.ndarray, ids: np.ndarray, n: int, comm: MPI.Comm,
                    weights: np.ndarray | None = None) -> np.ndarray:
    """The parts of :func:`.decompose.rcb` of points spread over the ranks (collective).

    Args:
        points: This rank's points, (m_local, gdim).
        ids: Their global ids (unique over the ranks): the serial call sees all points
            ordered by id.
        n: The number of parts.
        comm: The ranks holding the points.
        weights: Non-negative weights of the points (``balance="volume"``), or None.

    Returns:
        The part of each local point: ``rcb(P, n, W)[position of ids in P]``, with P and W
        all ranks' points and weights in id order.
    """
    m = np.asarray(points).shape[0]
    return _rcb_forest(points, ids, np.zeros(m, dtype=np.int64), np.array([n]), comm, weights)


def _rcb_forest(points: np.ndarray, ids: np.ndarray, group: np.ndarray, parts: np.ndarray,
                comm: MPI.Comm, weights: np.ndarray | None = None) -> np.ndarray:
    """:func:`rcb_distributed` of several independent point sets at once.

    Point set g (the points with ``group == g``) is cut into ``parts[g]`` parts; the work
    items of all sets share the collective rounds.
    """
    x = np.ascontiguousarray(points, dtype=np.float64)
    m, gdim = x.shape
    ids = np.asarray(ids, dtype=np.int64)
    group = np.asarray(group, dtype=np.int64)
    parts = np.asarray(parts, dtype=np.int64)
    labels = np.zeros(m, dtype=np.int64)
    pos = np.lexsort((ids, group))  # the serial order: by id in each set
    x, gid, group = x[pos], ids[pos], group[pos]
    start = np.searchsorted(group, np.arange(parts.size + 1))
    size = np.diff(start).astype(np.int64)
    comm.Allreduce(MPI.IN_PLACE, size, op=MPI.SUM)
    q = total = None
    if weights is not None:
        w = np.asarray(weights, dtype=np.float64)[pos]
        wmax = np.full(parts.size, -np.inf)
        nz = start[:-1] < start[1:]
        wmax[nz] = np.maximum.reduceat(w, start[:-1][nz]) if m else wmax[nz]
        comm.Allreduce(MPI.IN_PLACE, wmax, op=MPI.MAX)
        q = fixed_point_weights(w, np.maximum(wmax, 0.0)[group], size[group])
        total = _segment_sums(q, start)
        comm.Allreduce(MPI.IN_PLACE, total, op=MPI.SUM)
    items = _Items(k=parts, first=np.zeros(parts.size, dtype=np.int64), size=size,
                   total=np.zeros(parts.size, dtype=np.int64) if total is None else total,
                   chain=np.full((parts.size, gdim), -1, dtype=np.int64))
    state = (x, gid, pos, q, start)
    state, items = _retire(state, items, labels)
    while items.k.size:
        state, items = _bisect_level(state, items, comm, q is not None)
        state, items = _retire(state, items, labels)
    return labels


class _Items:
    """The work items of one tree level (the same on every rank).

    Attributes:
        k: Parts to make of each item.
        first: Its first part.
        size: Its number of points (all ranks).
        total: Its total fixed-point weight (all ranks; zeros unweighted).
        chain: The axes of the levels above, the latest first, each once (-1 after them):
            the points of an item are ordered by their coordinates along these axes, then
            by id.
    """

    def __init__(self, k, first, size, total, chain):
        self.k, self.first, self.size, self.total, self.chain = k, first, size, total, chain

    def take(self, keep: np.ndarray) -> _Items:
        return _Items(self.k[keep], self.first[keep], self.size[keep], self.total[keep],
                      self.chain[keep])


def _segment_sums(values: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Exact int64 sums of ``values[start[i]:start[i + 1]]``."""
    cs = np.concatenate([[0], np.cumsum(values, dtype=np.int64)])
    return cs[start[1:]] - cs[start[:-1]]


def _retire(state, items: _Items, labels: np.ndarray):
    """Label the points of the finished items (one part or no point) and drop them."""
    x, gid, pos, q, start = state
    done = (items.k == 1) | (items.size == 0)
    count = np.diff(start)
    item = np.repeat(np.arange(items.k.size), count)
    gone = done[item]
    labels[pos[gone]] = items.first[item[gone]]
    keep = ~gone
    q = None if q is None else q[keep]
    start = np.concatenate([[0], np.cumsum(count[~done])])
    return (x[keep], gid[keep], pos[keep], q, start), items.take(~done)


def _ordered(v: np.ndarray) -> np.ndarray:
    """int64 numbers in the order of the float64 values (-0.0 and 0.0 are equal)."""
    b = np.ascontiguousarray(v, dtype=np.float64).view(np.int64)
    magnitude = b & np.int64(0x7FFFFFFFFFFFFFFF)
    return np.where(b < 0, -magnitude, magnitude)


def _keys(x: np.ndarray, gid: np.ndarray, chain: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The sort keys of points ``rows`` in items of axes ``chain`` (one row each), (r, gdim + 1).

    Compared lexicographically they order the points of an item as the serial stable sorts
    do; the axes after the chain are zeros.
    """
    coord = x[rows[:, None], np.maximum(chain, 0)]
    return np.column_stack([np.where(chain >= 0, _ordered(coord), 0), gid[rows]])


def _lex_le(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise ``a <= b`` in lexicographic order."""
    differ = a != b
    col = np.argmax(differ, axis=1)
    r = np.arange(a.shape[0])
    return ~differ.any(axis=1) | (a[r, col] < b[r, col])


def _count_le(x, gid, chain, lo, hi, keys) -> np.ndarray:
    """For each query, the position in ``[lo, hi)`` (sorted rows) after the rows ≤ its key."""
    lo, hi = lo.copy(), hi.copy()
    while True:  # binary search, about log2(points) rounds
        a = np.flatnonzero(lo < hi)
        if a.size == 0:
            return lo
        mid = (lo[a] + hi[a]) // 2
        le = _lex_le(_keys(x, gid, chain[a], mid), keys[a])
        lo[a] = np.where(le, mid + 1, lo[a])
        hi[a] = np.where(le, hi[a], mid)


def _bisect_level(state, items: _Items, comm: MPI.Comm, weighted: bool):
    """Cut every item of a level in two as the serial rcb does; returns the next level."""
    x, gid, pos, q, start = state
    m, gdim = x.shape
    item = np.repeat(np.arange(items.k.size), np.diff(start))
    chain = _longest_sides(x, start, items.chain, comm)
    # the serial stable sort along the axis, inside each item (already in the order above)
    perm = np.lexsort((x[np.arange(m), chain[item, 0]], item))
    x, gid, pos = x[perm], gid[perm], pos[perm]
    q = np.zeros(m, dtype=np.int64) if q is None else q[perm]
    cut = _Cut(items, weighted, start)
    _select(cut, x, gid, q, chain, start, comm)
    k1 = items.k // 2
    # the children, left then right of each item: their points are contiguous
    children = _Items(k=np.column_stack([k1, items.k - k1]).ravel(),
                      first=np.column_stack([items.first, items.first + k1]).ravel(),
                      size=np.column_stack([cut.c_hi, items.size - cut.c_hi]).ravel(),
                      total=np.column_stack([cut.w_hi, items.total - cut.w_hi]).ravel(),
                      chain=np.repeat(chain, 2, axis=0))
    bounds = np.concatenate([np.column_stack([start[:-1], cut.p_hi]).ravel(), [m]])
    return (x, gid, pos, q if weighted else None, bounds), children


def _longest_sides(x: np.ndarray, start: np.ndarray, chain: np.ndarray, comm: MPI.Comm
                   ) -> np.ndarray:
    """The items' axis chains with their longest side first (one reduction of their boxes)."""
    ni, gdim = chain.shape
    box = np.full((ni, 2 * gdim), np.inf)  # min, then -max
    nz = np.diff(start) > 0
    if x.shape[0]:
        box[nz, :gdim] = np.minimum.reduceat(x, start[:-1][nz], axis=0)
        box[nz, gdim:] = -np.maximum.reduceat(x, start[:-1][nz], axis=0)
    comm.Allreduce(MPI.IN_PLACE, box, op=MPI.MIN)
    axis = np.argmax(-box[:, gdim:] - box[:, :gdim], axis=1)  # the first of equal sides
    rest = np.where(chain == axis[:, None], -1, chain)
    rest = np.take_along_axis(rest, np.argsort(rest < 0, axis=1, kind="stable"), axis=1)
    return np.column_stack([axis, rest[:, :gdim - 1]])


class _Cut:
    """The cut of each item and the search for it.

    The cut of an item is after the first point y (in key order) with
    ``(W(<= y) >= target and C(<= y) >= lower) or C(<= y) >= upper``, C and W the count and
    weight of the item's points up to y: the serial rule (the cell-count cut, or the
    weighted one with its clamp). The search keeps y in ``(lo, hi]``: their global counts
    ``c_lo``, ``c_hi``, the weight ``w_hi`` up to hi, and this rank's positions after them,
    ``p_lo``, ``p_hi``.
    """

    def __init__(self, items: _Items, weighted: bool, start: np.ndarray):
        k, size, total = items.k, items.size, items.total
        k1 = k // 2
        if not weighted:  # Python's round of a true division, as the serial code
            cut = np.array([int(round(int(s) * int(a) / int(b)))
                            for s, a, b in zip(size, k1, k, strict=True)], dtype=np.int64)
            fixed = np.ones(k.size, dtype=bool)
        else:  # with fewer points than parts the serial clamp (and slice) decide alone
            upper = size - (k - k1)
            cut = np.where(upper >= 0, upper, np.maximum(size + upper, 0))
            fixed = size < k
        self.target = np.where(fixed, 0, weight_target(total, k1, k) if weighted else 0)
        self.lower = np.where(fixed, cut, k1)
        self.upper = np.where(fixed, cut, size - (k - k1))
        self.c_lo = np.zeros(k.size, dtype=np.int64)
        self.c_hi, self.w_hi = size.copy(), total.copy()
        self.p_lo, self.p_hi = start[:-1].copy(), start[1:].copy()
        self.done = fixed & ((cut == 0) | (cut == size))
        empty = self.done & (cut == 0)
        self.c_hi[empty], self.w_hi[empty], self.p_hi[empty] = 0, 0, self.p_lo[empty]

    def holds(self, j: np.ndarray, c: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Whether the cut rule holds at count c and weight w of items j (rows)."""
        return ((w >= self.target[j, None]) & (c >= self.lower[j, None])) | \
            (c >= self.upper[j, None])


def _select(cut: _Cut, x, gid, q, chain, start, comm: MPI.Comm) -> None:
    """Narrow every item's ``(lo, hi]`` down to its cut: rounds of two collectives.

    Each rank proposes up to ``nq`` of its candidates per item, evenly spaced in key order
    (all of them when it has no more); the global counts and weights up to every proposal
    give the new ``(lo, hi]`` between two consecutive proposals, which holds at most about
    1/(nq + 1) of the candidates (plus one per rank).
    """
    gdim = x.shape[1]
    cw = np.concatenate([[0], np.cumsum(q)])  # weights up to each local position
    while not cut.done.all():
        j = np.flatnonzero(~cut.done)
        nq = max(1, min(64, _SAMPLES_PER_ROUND // (j.size * comm.size)))
        local = (cut.p_hi[j] - cut.p_lo[j])[:, None]
        t = np.arange(nq)
        few = local <= nq
        rows = cut.p_lo[j, None] + np.where(few, t, (t + 1) * local // (nq + 1))
        valid = ~few | (t < local)
        prop = np.zeros((j.size, nq, gdim + 3), dtype=np.int64)  # valid, key, weight
        prop[valid, 0] = 1
        prop[valid, 1:gdim + 2] = _keys(x, gid, chain[np.broadcast_to(j[:, None], rows.shape)
                                                        [valid]], rows[valid])
        prop[valid, gdim + 2] = q[rows[valid]]
        every = np.empty((comm.size,) + prop.shape, dtype=np.int64)
        comm.Allgather(prop, every)
        every = every.transpose(1, 0, 2, 3).reshape(-1, gdim + 3)
        qi = np.repeat(j, comm.size * nq)
        at = _count_le(x, gid, chain[qi], cut.p_lo[qi], cut.p_hi[qi], every[:, 1:gdim + 2])
        sums = np.stack([at - start[qi], cw[at] - cw[start[qi]]]).reshape(2, j.size, -1)
        comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        c, w = sums
        every = every.reshape(j.size, -1, gdim + 3)
        ok = every[:, :, 0] == 1
        holds = ok & cut.holds(j, c, w)
        # the point y itself if the rule fails at the point before it
        found = (holds & ~cut.holds(j, c - 1, w - every[:, :, gdim + 2])).any(axis=1)
        at = at.reshape(j.size, -1)
        r = np.arange(j.size)
        below = np.where(ok & ~holds, c, -1)
        b = np.argmax(below, axis=1)
        move = below[r, b] > cut.c_lo[j]
        cut.c_lo[j[move]], cut.p_lo[j[move]] = c[r, b][move], at[r, b][move]
        above = np.where(holds, c, np.iinfo(np.int64).max)
        a = np.argmin(above, axis=1)
        move = above[r, a] < cut.c_hi[j]
        cut.c_hi[j[move]], cut.w_hi[j[move]] = c[r, a][move], w[r, a][move]
        cut.p_hi[j[move]] = at[r, a][move]
        cut.done[j] = found | (cut.c_hi[j] - cut.c_lo[j] == 1)


def split_components_distributed(cells: np.ndarray, cell_ids: np.ndarray, label: np.ndarray,
                                 cell_type: str | None, comm: MPI.Comm) -> np.ndarray:
    """The connected pieces of equal label of :func:`.decompose._split_components` (collective).

    Args:
        cells: This rank's cells in global vertex numbers, (C_local, vertices per cell).
        cell_ids: Their global ids (the cells of all ranks are the mesh's cells 0 … C − 1).
        label: Their labels.
        cell_type: The cells' type (None: simplices).
        comm: The ranks holding the cells.

    Returns:
        The piece of each local cell: ``_split_components(all cells, all labels)[cell_ids]``,
        pieces numbered in the order of their first (smallest id) cell. Cells are connected
        through a facet of exactly two cells (the mesh checks reject facets of more).
    """
    return _split(cells, cell_ids, label, cell_type, comm)[0]


def _split(cells, cell_ids, label, cell_type, comm, num_cells=None, stats=None, whole=None):
    """:func:`split_components_distributed`, and the first cell of each local cell's piece.

    ``stats``, if given, receives the rounds of the search across ranks
    (:func:`.distributed_graph.component_minima`); ``whole``: the whole mesh's cells if this
    rank holds them (:func:`.connected_parts.rank_facets`).
    """
    cells = np.asarray(cells, dtype=np.int64)
    ids = np.asarray(cell_ids, dtype=np.int64)
    label = np.asarray(label).astype(np.int64)
    nc = cells.shape[0]
    bound = np.array([cells.max() + 1 if cells.size else 0, ids.max() + 1 if nc else 0],
                     dtype=np.int64)
    comm.Allreduce(MPI.IN_PLACE, bound, op=MPI.MAX)
    nv, num = int(bound[0]), int(bound[1] if num_cells is None else num_cells)
    piece, first, edges = _pieces_and_links(cells, ids, label, cell_type, nv, comm, whole)
    # the pieces joined across ranks: each takes the smallest first cell of its component
    first = component_minima(comm, first, edges, stats)
    # number the pieces by their first cell: a directory of the cell ids
    firsts = np.unique(first)
    (asked,), order, counts, rcounts = exchange(comm, Blocks(num, comm.size).home(firsts),
                                                firsts)
    mine = np.unique(asked)
    number = exclusive_scan(comm, mine.size) + np.searchsorted(mine, asked)
    number = answer(comm, number, order, counts, rcounts)
    sub = number[np.searchsorted(firsts, first)]
    return sub[piece].astype(np.int32), first[piece]


def _pieces_and_links(cells, ids, label, cell_type, nv, comm, whole=None):
    """The pieces of equal label of this rank's cells and the links between pieces of ranks.

    Returns:
        ``(piece, first, edges)``: the local piece of each cell, the first (smallest id) cell
        of each piece, and pairs of pieces (numbered globally, rank by rank) that two cells of
        equal label on two ranks join through a facet. Only the rank that keeps a facet in
        the facet directory holds its link.
    """
    nc = cells.shape[0]
    # the pieces of the local cells (facet pairs as in topology.facet_neighbours)
    pairs, single, outer = rank_facets(cells, cell_type, nv, whole, ids, comm.size == 1)
    nf, nvf = len(reference(cells, cell_type).facets), outer.shape[1]
    pairs = pairs[label[pairs[:, 0]] == label[pairs[:, 1]]]
    graph = sp.coo_matrix((np.ones(pairs.shape[0]), (pairs[:, 0], pairs[:, 1])), shape=(nc, nc))
    npiece, piece = connected_components(graph, directed=False) if nc else (0, np.zeros(0, int))
    if nc and np.all(ids[1:] > ids[:-1]):  # cells in id order (blocks are): the first is the least
        first = ids[first_of_each(piece, npiece)]
    else:
        first = np.full(npiece, np.iinfo(np.int64).max)
        np.minimum.at(first, piece, ids)
    offset = exclusive_scan(comm, npiece)
    if comm.size == 1:  # both cells of every facet are here
        return piece, first, np.zeros((0, 2), dtype=np.int64)
    # facets of one local cell: the other cell, if any, is on another rank; meet at the rank
    # that keeps the sum of their vertices modulo nv in a directory (their smallest vertex
    # would send most facets to the first ranks: the least of a few numbers is small)
    c = np.flatnonzero(single) // nf
    rows = np.column_stack([outer, label[c], ids[c], offset + piece[c]])
    home = Blocks(nv, comm.size).home(outer.sum(axis=1) % max(nv, 1))
    (got,), _, _, _ = exchange(comm, home, rows)
    _, inv = np.unique(row_keys(got[:, :nvf], nv), return_inverse=True)
    got = got[np.lexsort((got[:, nvf + 1], inv.ravel()))]
    inv = np.sort(inv.ravel())
    link = (inv[1:] == inv[:-1]) & (got[1:, nvf] == got[:-1, nvf])
    edges = np.column_stack([got[:-1, nvf + 2][link], got[1:, nvf + 2][link]])
    return piece, first, edges


def decompose_distributed(cells: np.ndarray, cell_x: np.ndarray, cell_ids: np.ndarray,
                          cell_body: np.ndarray, cell_type: str, body_names: tuple[str, ...],
                          num_cells: int, how, comm: MPI.Comm, whole: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray]:
    """The subdomains of :func:`.decompose.decompose` on a distributed mesh (collective).

    Args:
        cells: This rank's cells in global vertex numbers, (C_local, vertices per cell).
        cell_x: Their vertices' coordinates, (C_local, vertices per cell, gdim).
        cell_ids: Their global ids (all ranks' cells are the mesh's ``num_cells`` cells).
        cell_body: Their bodies (indices into ``body_names``).
        cell_type: The cells' type.
        body_names: The bodies of the mesh.
        num_cells: The number of cells of the whole mesh.
        how: :class:`~.decompose.ByTags`, :class:`~.decompose.Parts` (method "rcb") or
            :class:`~.decompose.ByFunction` (called on every rank with its cells' midpoints).
        comm: The ranks holding the cells.
        whole: The whole mesh's cells, if this rank holds them (a mesh read whole): the
            pieces then start from its cached facet index
            (:func:`.connected_parts.rank_facets`).

    Returns:
        ``(cell_sub, sub_body)``: the subdomain of each local cell and the body of every
        subdomain, those of the serial ``decompose`` on the whole mesh.

    Raises:
        InputError: On every rank, as the serial decomposition would: more parts than cells
            in a body, unknown bodies, a labeller that fails or returns bad labels; and for
            ``method="ptscotch"``, which needs the whole mesh on one rank.
    """
    cell_x = np.ascontiguousarray(cell_x, dtype=np.float64)  # the layout of x[cells]
    cell_body = np.asarray(cell_body)
    nc, nvc, gdim = cell_x.shape
    if isinstance(how, Auto):  # Parts by the cells of each body over all ranks
        count = np.bincount(cell_body, minlength=len(body_names)).astype(np.int64)
        comm.Allreduce(MPI.IN_PLACE, count, op=MPI.SUM)
        how = Parts(auto_parts(how, count, body_names, cell_type, comm.size), balance=BALANCE)
    if isinstance(how, ByTags):
        label = cell_body.astype(np.int64)
    elif isinstance(how, Parts):
        size = np.bincount(cell_body, minlength=len(body_names)).astype(np.int64)
        comm.Allreduce(MPI.IN_PLACE, size, op=MPI.SUM)
        parts = []
        for b, name in enumerate(body_names):  # the checks of the serial code, in its order
            n = how.n.get(name, 1) if isinstance(how.n, Mapping) else how.n
            if n > size[b]:
                raise InputError(f"Parts: {n} parts for body {name!r}, which has only "
                                 f"{size[b]} cells")
            if how.balance == "volume" and how.method != "rcb":
                raise InputError("Parts: balance='volume' needs method='rcb'")
            if how.method == "ptscotch":
                raise InputError("Parts: method='ptscotch' partitions the whole mesh on one rank "
                                 "and cannot run on a distributed mesh: use method='rcb', or a "
                                 "mesh read whole (read_gmsh(..., replicate=True or False))")
            if how.method != "rcb":
                raise InputError(f"Parts: unknown method {how.method!r}; use 'rcb' or 'ptscotch'")
            parts.append(int(n))
        if isinstance(how.n, Mapping):
            unknown = set(how.n) - set(body_names)
            if unknown:
                raise InputError(f"Parts: unknown bodies {sorted(unknown)}; the bodies are "
                                 f"{list(body_names)}")
        weights = None
        if how.balance == "volume":
            local = np.arange(nc * nvc).reshape(nc, nvc)
            weights = np.abs(cell_volumes(cell_x.reshape(-1, gdim), local, cell_type))
        part = _rcb_forest(_midpoints(cell_x), cell_ids, cell_body, np.array(parts), comm, weights)
        label = cell_body.astype(np.int64) * (1 << 32) + part
    elif isinstance(how, BlockLabels):
        label = how.label
    elif isinstance(how, ByFunction):
        label = np.zeros(0, dtype=np.int64)
        with collective(comm, "decomposition"):
            if nc:  # a rank without cells does not call the labeller
                label = labels_of(how, _midpoints(cell_x))
    else:
        raise InputError(f"unknown decomposition {how!r}: use Auto(), ByTags(), Parts(n) or "
                         "ByFunction(fn)")
    cell_sub, first = _split(cells, cell_ids, label, cell_type, comm, num_cells, whole=whole)
    if isinstance(how, Parts) and how.merge:  # first: each cell's group's first cell is a first
        cell_sub = merge_fragments_distributed(cells, cell_ids, cell_sub, label, cell_body,
                                               cell_type, comm, whole)
    nsub = np.array([cell_sub.max() + 1 if nc else 0], dtype=np.int64)
    comm.Allreduce(MPI.IN_PLACE, nsub, op=MPI.MAX)
    sub_body = np.full(int(nsub[0]), -1, dtype=np.int64)
    is_first = np.asarray(cell_ids) == first
    sub_body[cell_sub[is_first]] = cell_body[is_first]
    comm.Allreduce(MPI.IN_PLACE, sub_body, op=MPI.MAX)
    return cell_sub, sub_body.astype(cell_body.dtype)


def _midpoints(cell_x: np.ndarray) -> np.ndarray:
    """The mean of each cell's vertices, bit for bit ``cell_x.mean(axis=1)``."""
    nc, nvc, gdim = cell_x.shape
    return midpoints_of(cell_x.reshape(-1, gdim), np.arange(nc * nvc).reshape(nc, nvc))


def labels_of(how: ByFunction, midpoints: np.ndarray) -> np.ndarray:
    """The user's labels of the midpoints, checked as the serial decomposition checks them."""
    try:
        label = np.asarray(how.fn(midpoints))
    except Exception as e:  # the user's labeller: say which function failed
        raise InputError(f"ByFunction.fn(midpoints) raised {type(e).__name__}: {e}") from e
    if label.shape != (midpoints.shape[0],) or not np.issubdtype(label.dtype, np.integer):
        raise InputError("ByFunction: the function must return one integer label per cell "
                         f"(shape ({midpoints.shape[0]},)), got {label.dtype} {label.shape}")
    return label


__all__ = ["BlockLabels", "decompose_distributed", "labels_of", "rcb_distributed",
           "split_components_distributed"]
