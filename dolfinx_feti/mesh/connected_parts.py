"""Connected parts close to the number asked for: the fragments a cut leaves merged away.

A cut of a body into n parts (recursive coordinate bisection, or a graph partitioner) can
leave a part in several pieces that do not share a facet — on a mesh graded toward a contact,
or a body that is not convex. Each piece is a subdomain of its own (a subdomain must be
connected), so ``Parts(8)`` could give 82 subdomains, most of them a handful of cells, each
with its own rigid motions and factorization. Here the pieces are joined back into n parts:

- the *main* pieces: the largest piece of each part (ties: the first), and any other piece of
  at least half the body's mean part size (a body that falls apart in big pieces keeps them);
- every other piece (a *fragment*) is merged into the neighbouring piece of the same body with
  which it shares the most facets (ties: the first piece); a chain of fragments ends at a
  main piece, or — where fragments only touch each other — forms a subdomain of its own;
- the groups are numbered in the order of their first cell, as pieces are.

Every merge joins pieces that share a facet, so the subdomains stay connected. The rule reads
only integers (cell counts, shared-facet counts, piece numbers), so the piece graph built
from the whole mesh (:func:`merge_fragments`) and from a mesh spread over the ranks
(:func:`merge_fragments_distributed`) give the same subdomains, bit for bit. The piece graph
has one vertex per piece (subdomains, not cells): every rank holds it whole.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from scipy.sparse.csgraph import connected_components

from ..parallel.exchange import Blocks, exchange
from .topology import cell_facets, facet_index, facet_neighbours, reference, row_keys

#: A piece other than its part's largest is kept when it holds at least this fraction of the
#: body's mean part size (cells).
KEEP_FRACTION = 0.5


def merge_plan(size: np.ndarray, label: np.ndarray, body: np.ndarray,
               edges: np.ndarray) -> np.ndarray:
    """The subdomain of every piece after the fragments are merged (pure, on every rank).

    Args:
        size: Cells of each piece, (P,).
        label: The part each piece came from, (P,) (pieces of one part share it).
        body: The body of each piece, (P,).
        edges: ``(a, b, facets)`` rows, a < b: pieces a and b share that many facets; each
            pair once.

    Returns:
        The new subdomain of each piece, numbered in the order of the pieces' numbers.
    """
    npiece = size.size
    if npiece == 0:
        return np.zeros(0, dtype=np.int64)
    # the main pieces: the largest of each part (the first of equal ones), and the big ones
    order = np.lexsort((np.arange(npiece), -size, label))
    first_of_part = np.r_[True, label[order][1:] != label[order][:-1]]
    main = np.zeros(npiece, dtype=bool)
    main[order[first_of_part]] = True
    body_cells = np.bincount(body, weights=size)
    _, part_body = np.unique(np.column_stack([label, body]), axis=0, return_index=True)
    parts_of_body = np.bincount(body[part_body], minlength=body_cells.size)
    mean = body_cells / np.maximum(parts_of_body, 1)
    main |= size >= KEEP_FRACTION * mean[body]
    # each fragment points to its neighbour of the same body across the most facets
    a, b, count = (np.asarray(edges, dtype=np.int64).reshape(-1, 3).T)
    same = body[a] == body[b]
    src = np.r_[a[same], b[same]]
    dst = np.r_[b[same], a[same]]
    cnt = np.r_[count[same], count[same]]
    target = np.arange(npiece)
    frag = ~main[src]
    src, dst, cnt = src[frag], dst[frag], cnt[frag]
    best = np.lexsort((dst, -cnt, src))  # per source: most facets first, then the first piece
    head = np.r_[True, src[best][1:] != src[best][:-1]] if best.size else np.zeros(0, bool)
    target[src[best][head]] = dst[best][head]
    # the groups: components of the pointer graph (each holds at most one main piece)
    graph = sp.coo_matrix((np.ones(npiece), (np.arange(npiece), target)),
                          shape=(npiece, npiece))
    _, group = connected_components(graph, directed=False)
    first = np.full(group.max() + 1, npiece)
    np.minimum.at(first, group, np.arange(npiece))
    rank = np.empty_like(first)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    return rank[group]


def rank_facets(cells: np.ndarray, cell_type: str | None, nv: int,
                whole: np.ndarray | None = None, cell_ids: np.ndarray | None = None,
                alone: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The facets of a rank's cells: the local pairs, the single ones and their vertices.

    Args:
        cells: The rank's cells in global vertex numbers.
        cell_type: The cells' type (None: simplices).
        nv: A bound of the vertex numbers.
        whole: The whole mesh's cells, when this rank holds them (a mesh read whole): the
            facets are then taken
            in the order of the whole mesh's facet index (:func:`.topology.facet_index`,
            which the mesh checks leave cached) instead of being sorted again. The order is
            the same: the whole mesh's sorted facets restricted to the rank's cells are
            those cells' facets sorted stably, the cells being numbered in the same order.
        cell_ids: With ``whole``, the rank's cells among them (ascending).
        alone: The rank is the only one (no facet is shared with another rank): the single
            facets and their vertices are not needed (returned empty).

    Returns:
        ``(pairs, single, outer)``: the pairs of local cells sharing a facet (as
        :func:`.topology.facet_neighbours`), whether each facet (row ``cell * nf + j``) has
        no second local cell (the other cell, if any, is on another rank), and the sorted
        vertices of those single facets, in the order of their rows.
    """
    nc = cells.shape[0]
    ref = reference(cells, cell_type)
    nf = len(ref.facets)
    if whole is None:
        keys = row_keys(cell_facets(cells, cell_type).reshape(nc * nf, len(ref.facets[0])), nv)
        order = np.argsort(keys, kind="stable")
        keys = keys[order]
    else:
        keys, order, _ = facet_index(whole, cell_type)
        if nc < whole.shape[0]:  # the rank's facets, renumbered by its cells
            local = np.full(whole.shape[0], -1, dtype=np.int64)
            local[cell_ids] = np.arange(nc)
            at = local[order // nf]
            keep = at >= 0
            keys, order = keys[keep], at[keep] * nf + order[keep] % nf
    same = keys[1:] == keys[:-1]
    pairs = np.stack([order[:-1][same] // nf, order[1:][same] // nf], axis=1)
    if alone:
        return pairs, np.zeros(nc * nf, dtype=bool), np.zeros((0, len(ref.facets[0])), np.int64)
    single = np.ones(nc * nf, dtype=bool)
    single[order[:-1][same]] = single[order[1:][same]] = False
    f = np.flatnonzero(single)
    outer = np.sort(cells[(f // nf)[:, None], np.array(ref.facets)[f % nf]], axis=1)
    return pairs, single, outer


def _pair_counts(a: np.ndarray, b: np.ndarray, npiece: int) -> np.ndarray:
    """``(a, b, count)`` rows of the distinct unordered pairs a ≠ b, a < b."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keep = lo != hi
    keys, count = np.unique(lo[keep].astype(np.int64) * npiece + hi[keep], return_counts=True)
    return np.column_stack([keys // npiece, keys % npiece, count]).astype(np.int64)


def merge_fragments(cells: np.ndarray, cell_sub: np.ndarray, label: np.ndarray,
                    cell_body: np.ndarray, cell_type: str | None) -> np.ndarray:
    """The subdomains of the whole mesh's pieces ``cell_sub`` with the fragments merged.

    Args:
        cells: The cells (vertex numbers).
        cell_sub: The piece of each cell (connected pieces of equal label, numbered by their
            first cell).
        label: The part of each cell (the cut's label).
        cell_body: The body of each cell.
        cell_type: The cells' type.
    """
    npiece = int(cell_sub.max()) + 1 if cell_sub.size else 0
    first = np.full(npiece, cell_sub.size)
    np.minimum.at(first, cell_sub, np.arange(cell_sub.size))
    pairs = facet_neighbours(cells, cell_type)
    edges = _pair_counts(cell_sub[pairs[:, 0]], cell_sub[pairs[:, 1]], max(npiece, 1))
    plan = merge_plan(np.bincount(cell_sub, minlength=npiece), label[first],
                      cell_body[first].astype(np.int64), edges)
    return plan[cell_sub].astype(cell_sub.dtype)


def merge_fragments_distributed(cells: np.ndarray, cell_ids: np.ndarray, cell_sub: np.ndarray,
                                label: np.ndarray, cell_body: np.ndarray,
                                cell_type: str | None, comm: MPI.Comm,
                                whole: np.ndarray | None = None) -> np.ndarray:
    """:func:`merge_fragments` on a mesh spread over the ranks (collective).

    Args:
        cells: This rank's cells in global vertex numbers.
        cell_ids: Their global ids.
        cell_sub: Their global pieces (:func:`.distributed_decompose.split_components_distributed`).
        label: Their parts (non-negative).
        cell_body: Their bodies.
        cell_type: The cells' type.
        comm: The ranks holding the cells.
        whole: The whole mesh's cells, if this rank holds them (:func:`rank_facets`).

    Returns:
        The subdomain of each local cell: ``merge_fragments(all …)[cell_ids]``.
    """
    cells = np.asarray(cells, dtype=np.int64)
    ids = np.asarray(cell_ids, dtype=np.int64)
    sub = np.asarray(cell_sub, dtype=np.int64)
    nc = cells.shape[0]
    head = np.array([sub.max() + 1 if nc else 0, cells.max() + 1 if cells.size else 0],
                    dtype=np.int64)
    comm.Allreduce(MPI.IN_PLACE, head, op=MPI.MAX)
    npiece, nv = int(head[0]), int(head[1])
    size = np.bincount(sub, minlength=npiece).astype(np.int64)
    comm.Allreduce(MPI.IN_PLACE, size, op=MPI.SUM)
    # each piece's label and body: those of its first cell (the smallest id)
    first = np.full(npiece, np.iinfo(np.int64).max)
    np.minimum.at(first, sub, ids)
    comm.Allreduce(MPI.IN_PLACE, first, op=MPI.MIN)
    at_first = ids == first[sub]
    piece_label = np.full(npiece, -1, dtype=np.int64)
    piece_body = np.full(npiece, -1, dtype=np.int64)
    piece_label[sub[at_first]] = np.asarray(label, dtype=np.int64)[at_first]
    piece_body[sub[at_first]] = np.asarray(cell_body, dtype=np.int64)[at_first]
    comm.Allreduce(MPI.IN_PLACE, piece_label, op=MPI.MAX)
    comm.Allreduce(MPI.IN_PLACE, piece_body, op=MPI.MAX)
    # the facets between pieces: within this rank, and across ranks met at a directory rank
    pairs, single, outer = rank_facets(cells, cell_type, nv, whole, ids, comm.size == 1)
    nf, nvf = len(reference(cells, cell_type).facets), outer.shape[1]
    local = _pair_counts(sub[pairs[:, 0]], sub[pairs[:, 1]], max(npiece, 1))
    remote = np.zeros((0, 3), dtype=np.int64)
    if comm.size > 1:  # one rank holds both cells of each of its facets
        home = Blocks(nv, comm.size).home(outer.sum(axis=1) % max(nv, 1))
        (got,), _, _, _ = exchange(comm, home,
                                   np.column_stack([outer, sub[np.flatnonzero(single) // nf]]))
        gkeys = row_keys(got[:, :nvf], nv)
        gorder = np.argsort(gkeys, kind="stable")
        gsame = gkeys[gorder][1:] == gkeys[gorder][:-1]
        remote = _pair_counts(got[gorder[:-1][gsame], nvf], got[gorder[1:][gsame], nvf],
                              max(npiece, 1))
    every = np.concatenate(comm.allgather(np.concatenate([local, remote])))
    keys, inv = np.unique(every[:, 0] * max(npiece, 1) + every[:, 1], return_inverse=True)
    counts = np.bincount(inv.ravel(), weights=every[:, 2]).astype(np.int64)
    edges = np.column_stack([keys // max(npiece, 1), keys % max(npiece, 1), counts])
    plan = merge_plan(size, piece_label, piece_body, edges)
    return plan[sub].astype(np.asarray(cell_sub).dtype)


__all__ = ["KEEP_FRACTION", "merge_fragments", "merge_fragments_distributed", "merge_plan",
           "rank_facets"]
