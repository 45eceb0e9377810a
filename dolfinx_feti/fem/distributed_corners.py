"""FETI-DP's corners and floating motions on a distributed mesh, without the whole mesh.

The counterpart of :mod:`.corners` (the specification: the same corners, numbered the same,
and the same span of floating motions) for the shares of a mesh read with ``distribute=True``
(:func:`~dolfinx_feti.setup.share_distributed.share_from_parts`). Each rank holds whole subdomains,
their dof points and every point's list of subdomains (the node directory). From there:

1. Outer boundary: a facet of the rank's cells (with a vertex on an interface) that no other
   local cell has is sent to a home rank (by the sum of its vertices); a facet only one rank
   sent is on the outer boundary (its vertices are marked, as the serial code marks the
   vertices of ``boundary_facets``), a facet sent twice joins two subdomains of two ranks.
2. Globs: every rank sends its interface points with their subdomain lists to a home rank (by
   the sum of the subdomains), which ORs the boundary marks of a point's copies and counts the
   points of every glob exactly as :func:`.corners.primal_globs` does serially.
3. Rigid joining of the subdomains sharing a facet: the owner of s evaluates every pair (s, t)
   with the corners of step 2. Adding corners only adds rows to a pair's rigid-motion rows, so
   a pair that is rigid then is rigid after the serial loop's additions too (the residual
   assumption: the relative eigenvalue threshold :data:`.corners.RANK_RTOL`, scaled by the
   trace that the added rows also raise, does not turn a rigid pair non-rigid). Only the pairs
   that are not rigid are gathered on rank 0 — their shared points' numbers, coordinates and
   flags — which replays the serial greedy loop over them in the serial order and broadcasts
   the points it adds.
4. The corner unknowns are numbered by (global point, component) through a directory of the
   points (an exclusive scan over its home ranks).
5. Components (subdomains joined through facets) from the gathered pairs of subdomains (one row
   per adjacent pair); per component the bounding box (exact, by MIN / MAX reductions) and the
   Gram matrix of the rigid-motion rows of its fixed dofs, each point counted once (by the rank
   holding its smallest subdomain of the component), reduced on rank 0 whose null-space bases
   every rank uses. The basis may differ from the serial one by round-off (the Gram matrix is
   summed in another order): the span is the same.

Global or gathered: per-subdomain flags and component numbers, the adjacent subdomain pairs,
the non-rigid pairs' points (rank 0), the added points and the Gram matrices (every rank).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from ..errors import collective
from ..mesh.distributed_points import index_ranges
from ..mesh.topology import REFERENCE, cell_facets, row_keys
from ..parallel.exchange import Blocks, answer, exchange, exclusive_scan
from .corners import (
    body_label,
    box_scale,
    components_of_pairs,
    free_of_gram,
    glob_keys,
    held_alone,
    join_pair,
    joined_rigidly,
    motions_at,
    primal_globs,
    scaled_motions,
)
from .rigid import rigid_motions


def fetidp_share(share, bs: int, body_names, comm: MPI.Comm, *, edges: bool,
                 auto: bool = False) -> tuple[str, dict | None]:
    """FETI-DP's data of this rank's dofs, as :func:`.dual._fetidp_parts` hands it (collective).

    Args:
        share: This rank's :class:`~dolfinx_feti.setup.share.RankShare` with its node directory.
        bs: Components per point.
        body_names: The names of the bodies.
        comm: The ranks.
        edges: Also the edges primal (:func:`.corners.choose_corners`).
        auto: Choose by the rule of :func:`.dual.choose_method` (the caller has settled that
            there are gluing rows): ``"tfeti"`` (and no data) if a primal component floats.

    Returns:
        ``(method, extra)``: ``"fetidp"`` and the dict ``{"corners", "count", "modes",
        "bodies", "info"}`` of :class:`~dolfinx_feti.feti.corners.EliminateCorners`, or
        ``("tfeti", None)``.
    """
    dec = share.dec
    pairs, outer = _facet_pairs_and_boundary(share, comm)
    comp = components_of_pairs(pairs, dec.num_subdomains)
    modes, bodies = _floating_motions(share, comp, bs, body_names, comm)
    if auto and bodies:
        return "tfeti", None
    corner, vertices = _globs(share, outer, edges, comm)
    _join_pairs(share, pairs, corner, bs, comm)
    index, count, nodes = _numbered(share, corner, comm)
    info = {"corner_nodes": nodes, "vertices": vertices, "corner_dofs": count}
    return "fetidp", {"corners": index[dec.pair_node].ravel(), "count": count, "modes": modes,
                      "bodies": bodies, "info": info}


def _pair_subs(dec) -> np.ndarray:
    """The subdomain of each local (subdomain, point) pair."""
    return np.repeat(dec.subs, np.diff(dec.pair_ptr))


def _facet_pairs_and_boundary(share, comm: MPI.Comm) -> tuple[np.ndarray, np.ndarray]:
    """The pairs of subdomains that share a facet, and the points on the outer boundary.

    Returns:
        The pairs (s < t), sorted (every rank), and the mask of the local points that are
        vertices of a facet of the outer boundary (step 1 of the module docstring).
    """
    mesh, pids = share.mesh, share.point_ids
    cells, ct = mesh.cells, mesh.cell_type
    nf, nvf = len(REFERENCE[ct].facets), len(REFERENCE[ct].facets[0])
    # only facets with a vertex on an interface matter (the pairs share all their vertices, the
    # boundary marks count at interface points only); a facet and its twin are kept alike
    inter = np.diff(share.directory.ptr)[:mesh.x.shape[0]] >= 2
    near = np.flatnonzero(inter[cells].any(axis=1))
    facets = cell_facets(cells[near], ct).reshape(near.size * nf, nvf)
    keep = np.flatnonzero(inter[facets].any(axis=1))
    facets, facet_cell = facets[keep], near[keep // nf]
    keys = row_keys(facets, mesh.x.shape[0])
    order = np.argsort(keys, kind="stable")
    same = keys[order][1:] == keys[order][:-1]
    sub = share.dec.cell_sub
    local = np.sort(np.stack([sub[facet_cell[order[:-1][same]]],
                              sub[facet_cell[order[1:][same]]]], axis=1), axis=1)
    single = np.ones(keep.size, dtype=bool)
    single[order[:-1][same]] = single[order[1:][same]] = False
    f = np.flatnonzero(single)
    global_f = np.sort(pids[facets[f]], axis=1)  # vertices come first among the points
    # the twins meet at the home of their vertices' sum modulo N, as in distributed_decompose
    home = Blocks(share.num_points, comm.size).home(global_f.sum(axis=1) % share.num_points)
    (got, got_sub), order, counts, rcounts = exchange(
        comm, home, global_f, sub[facet_cell[f]].astype(np.int64))
    _, inverse, count = np.unique(row_keys(got, share.num_points), return_inverse=True,
                                  return_counts=True)
    inverse = inverse.ravel()
    is_outer = count[inverse] == 1
    by = np.argsort(inverse, kind="stable")  # the two copies of a shared facet side by side
    twice = np.flatnonzero(inverse[by][1:] == inverse[by][:-1])
    cross = np.sort(np.stack([got_sub[by][twice], got_sub[by][twice + 1]], axis=1), axis=1)
    outer_f = answer(comm, is_outer, order, counts, rcounts)
    outer = np.zeros(pids.size, dtype=bool)
    outer[facets[f[outer_f]].ravel()] = True
    mine = np.concatenate([local, cross]).astype(np.int64)
    mine = np.unique(mine[mine[:, 0] != mine[:, 1]], axis=0)
    pairs = np.concatenate(comm.allgather(mine)).reshape(-1, 2)
    return np.unique(pairs, axis=0), outer


def _globs(share, outer: np.ndarray, edges: bool, comm: MPI.Comm) -> tuple[np.ndarray, int]:
    """The primal mask of the local points before the pairs are joined (step 2).

    Returns:
        The mask and the number of primal points of the whole mesh.
    """
    d, pids = share.directory, share.point_ids
    mult = np.diff(d.ptr)
    width = comm.allreduce(int(mult.max(initial=0)), op=MPI.MAX)
    inter = np.flatnonzero(mult >= 2)
    key = glob_keys(d.ptr, d.subs, inter, outer[inter], width)
    nsub = share.dec.num_subdomains  # a glob's home: its subdomains' sum modulo their number
    home = Blocks(nsub, comm.size).home(np.where(key[:, :-1] >= 0, key[:, :-1], 0).sum(axis=1)
                                        % nsub)
    (got_pid, got_key), order, counts, rcounts = exchange(comm, home, pids[inter], key)
    points, first, inverse = np.unique(got_pid, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    flag = np.zeros(points.size, dtype=np.int64)
    np.maximum.at(flag, inverse, got_key[:, -1])  # on the boundary if any copy says so
    keys = got_key[first]
    keys[:, -1] = flag
    primal = primal_globs(keys, edges) if points.size else np.zeros(0, dtype=bool)
    corner = np.zeros(pids.size, dtype=bool)
    corner[inter] = answer(comm, primal[inverse], order, counts, rcounts)
    return corner, comm.allreduce(int(primal.sum()), op=MPI.SUM)


def _join_pairs(share, pairs: np.ndarray, corner: np.ndarray, bs: int, comm: MPI.Comm) -> None:
    """Add to ``corner`` the points the serial loop adds to join every pair rigidly (step 3)."""
    dec, d, x, pids = share.dec, share.directory, share.points.x, share.point_ids
    held_mine = np.zeros(dec.subs.size, dtype=bool)
    loose = []
    with collective(comm, "constraints"):  # rank-local work: a failure must reach every rank
        held_mine[:] = [held_alone(x[dec.nodes(s)], d.fixed[dec.nodes(s)], bs)
                        for s in dec.subs]
    held = np.zeros(dec.num_subdomains, dtype=bool)
    for subs, h in comm.allgather((dec.subs, held_mine)):
        held[subs] = h
    # the local points of every subdomain, by subdomain then point
    e_point = np.repeat(np.arange(pids.size), np.diff(d.ptr))
    e_order = np.argsort(d.subs, kind="stable")  # the points ascend already
    e_sub, e_point = d.subs[e_order], e_point[e_order]
    with collective(comm, "constraints"):
        for s, t in pairs[dec.sub_rank[pairs[:, 0]] == comm.rank]:
            if held[s] and held[t]:
                continue
            lo, hi = np.searchsorted(e_sub, [t, t + 1])
            both = np.intersect1d(dec.nodes(int(s)), e_point[lo:hi], assume_unique=True)
            # the serial loop may add points to a pair not rigid now: rank 0 replays it
            if not joined_rigidly(scaled_motions(x[both], bs), corner[both], d.fixed[both]):
                loose.append((int(s), int(t), pids[both], x[both], corner[both],
                              d.fixed[both]))
    gathered = comm.gather(loose, root=0)
    added = None
    with collective(comm, "constraints"):
        if comm.rank == 0:
            added = _replay(sorted(p for g in gathered for p in g), bs)
    added = comm.bcast(added, root=0)
    corner[np.isin(pids, added)] = True


def _replay(loose: list, bs: int) -> np.ndarray:
    """Rank 0: the serial greedy loop over the pairs not rigid with the first corners."""
    if not loose:
        return np.zeros(0, dtype=np.int64)
    ids = np.concatenate([p[2] for p in loose])
    points, first = np.unique(ids, return_index=True)
    state = np.concatenate([p[4] for p in loose])[first]
    added = []
    for _, _, pid, x, _, fixed in loose:
        at = np.searchsorted(points, pid)
        new = join_pair(scaled_motions(x, bs), state[at], fixed)
        state[at[new]] = True
        added.append(pid[new])
    return np.unique(np.concatenate(added))


def _numbered(share, corner: np.ndarray, comm: MPI.Comm) -> tuple[np.ndarray, int, int]:
    """The corner unknowns of the local points (step 4).

    Returns:
        The corner unknown of each local (point, component) (−1: none), the number of corner
        unknowns and of corner points of the whole mesh.
    """
    pids, fixed = share.point_ids, share.directory.fixed
    unknown = corner[:, None] & ~fixed
    at = np.flatnonzero(corner)
    (got, got_n), order, counts, rcounts = exchange(
        comm, Blocks(share.num_points, comm.size).home(pids[at]), pids[at],
        unknown[at].sum(axis=1))
    points, first, inverse = np.unique(got, return_index=True, return_inverse=True)
    n = got_n[first]
    start = exclusive_scan(comm, int(n.sum())) + np.cumsum(n) - n
    offset = answer(comm, start[inverse.ravel()], order, counts, rcounts)
    index = np.full(fixed.shape, -1, dtype=np.int64)
    within = np.cumsum(unknown[at], axis=1) - 1
    index[at] = np.where(unknown[at], offset[:, None] + within, -1)
    total = comm.allreduce(np.array([n.sum(), points.size], dtype=np.int64), op=MPI.SUM)
    return index, int(total[0]), int(total[1])


def _floating_motions(share, comp: np.ndarray, bs: int, body_names, comm: MPI.Comm
                      ) -> tuple[np.ndarray, list[str]]:
    """The free rigid motions of the floating components at the local dofs (step 5)."""
    dec, d, x = share.dec, share.directory, share.points.x
    ncomp, gdim = int(comp.max(initial=-1)) + 1, x.shape[1]
    pair_sub = _pair_subs(dec)
    pc = comp[pair_sub]
    lo = np.full((ncomp, gdim), np.inf)
    hi = np.full((ncomp, gdim), -np.inf)
    by = np.argsort(pc, kind="stable")
    here, at = np.unique(pc[by], return_index=True)
    if here.size:  # the box of each component's local points
        lo[here] = np.minimum.reduceat(x[dec.pair_node[by]], at)
        hi[here] = np.maximum.reduceat(x[dec.pair_node[by]], at)
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    boxes = [box_scale(lo[c], hi[c]) for c in range(ncomp)]
    centre = np.array([b[0] for b in boxes]).reshape(ncomp, gdim)
    scale = np.array([b[1] for b in boxes])
    # each fixed (point, component) once: at the pair of its smallest subdomain in the component
    sel = np.flatnonzero(d.fixed[dec.pair_node].any(axis=1))
    p, c = dec.pair_node[sel], pc[sel]
    n_subs = np.diff(d.ptr)[p]
    e_pair = np.repeat(np.arange(sel.size), n_subs)
    e_sub = d.subs[index_ranges(d.ptr[p], n_subs)]
    hit = np.flatnonzero(comp[e_sub] == c[e_pair])  # the subdomains of a point ascend
    _, first = np.unique(e_pair[hit], return_index=True)  # every pair's own one is a hit
    counted = e_sub[hit[first]] == pair_sub[sel]
    sel, p, c = sel[counted], p[counted], c[counted]
    xc = (x[p] - centre[c]) / scale[c][:, None]  # as rigid_motions scales them
    k = rigid_motions(np.zeros((1, gdim)), bs).shape[1]
    Y = rigid_motions(xc, bs, np.zeros(gdim), 1.0).reshape(sel.size, bs, k)
    f = d.fixed[p]
    rows, row_comp = Y[f], np.broadcast_to(c[:, None], f.shape)[f]
    gram = np.zeros((ncomp, k, k))
    np.add.at(gram, row_comp, rows[:, :, None] * rows[:, None, :])
    nrows = np.bincount(row_comp, minlength=ncomp).astype(np.float64)
    total = np.zeros_like(gram) if comm.rank == 0 else None
    ntotal = np.zeros_like(nrows) if comm.rank == 0 else None
    comm.Reduce(gram, total, op=MPI.SUM, root=0)
    comm.Reduce(nrows, ntotal, op=MPI.SUM, root=0)
    free = None
    with collective(comm, "constraints"):
        if comm.rank == 0:
            free = [free_of_gram(total[i], int(ntotal[i])) for i in range(ncomp)]
    free = comm.bcast(free, root=0)
    node = np.repeat(dec.pair_node, bs)
    dof_comp = np.tile(np.arange(bs), dec.pair_node.size)
    dof_c = np.repeat(pc, bs)
    width = np.array([f.shape[1] for f in free], dtype=np.int64)
    start = np.cumsum(width) - width
    Z = np.zeros((node.size, int(width.sum())))
    by = np.argsort(dof_c, kind="stable")
    bounds = np.searchsorted(dof_c[by], np.arange(ncomp + 1))
    for i in np.unique(pc[width[pc] > 0]):  # the floating components with local dofs
        mine = by[bounds[i]:bounds[i + 1]]
        Z[mine, start[i]:start[i] + width[i]] = motions_at(
            x[node[mine]], dof_comp[mine], bs, centre[i], scale[i], free[i])
    bodies = [body_label(body_names, dec.sub_body[comp == i])
              for i in np.flatnonzero(width) for _ in range(width[i])]
    Z[d.fixed[node, dof_comp]] = 0.0
    return Z, bodies


__all__ = ["fetidp_share"]
