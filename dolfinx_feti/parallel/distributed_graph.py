"""Connected components of a graph whose vertices and edges are spread over the ranks.

:func:`component_minima` gives every vertex the smallest value of its component without
gathering the graph anywhere: a forest of parent pointers, one per vertex on the rank that
owns the vertex, is merged by the star hooking and shortcutting of Shiloach & Vishkin (1982)
and Awerbuch & Shiloach (1987). The edges a rank holds are first replaced by stars of their
components there (scipy, no communication: what one rank sees whole costs no round). A round:

1. star check: which trees are stars (every vertex a child of the root);
2. conditional star hooking: the root of a star that has an edge to a tree of smaller parent
   takes the smallest such parent as its parent (parents fall, so no cycle);
3. hooking of stagnant stars: a star that neither hooked nor was hooked onto in step 2 and
   has an edge out hooks onto a neighbour's parent. Two stagnant stars are never adjacent
   (the larger would have hooked onto the smaller in step 2), so the trees hooked onto do not
   move in this step: no cycle;
4. shortcut: every vertex takes its grandparent as its parent.

Every star with an edge out joins another tree in step 2 or 3, and shortcutting halves the
height of the other trees, which is what the analysis of these authors turns into O(log n)
rounds for n vertices; ``tests/parallel/test_distributed_graph.py`` checks ≤ 2 log2 n + 4 rounds on
paths numbered against the hooking order (where propagating labels would take n rounds) and on
trees (on paths it takes about log2 n + 1 rounds). The search stops after the first round in which
no parent changed on any rank (an Allreduce of a flag): then every tree is a star and no edge
joins two trees, so the trees are the components. Every question about a vertex (its parent,
its star flag) is answered by its owner through :func:`.exchange.exchange` and
:func:`.exchange.answer`, so a rank holds O(its vertices + its edges) at any time.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from scipy.sparse.csgraph import connected_components

from .exchange import RankNumbering, answer, exchange


class _Vertices(RankNumbering):
    """This rank's vertices ``offset … offset + n − 1``, and messages to any vertex."""

    def lowest(self, target: np.ndarray, value: np.ndarray):
        """Send values to vertices: the local vertices that received any and their smallest."""
        (got,), _, _, _ = exchange(self.comm, self.owner(target), np.column_stack([target, value]))
        t, v = _smallest_per_target(got[:, 0], got[:, 1])
        return t - self.offset, v

    def marked(self, target: np.ndarray) -> np.ndarray:
        """Whether any rank named each local vertex in ``target``."""
        (t,), _, _, _ = exchange(self.comm, self.owner(target), target)
        out = np.zeros(self.starts[self.comm.rank + 1] - self.offset, dtype=bool)
        out[t - self.offset] = True
        return out


def _smallest_per_target(target: np.ndarray, value: np.ndarray):
    """One (target, smallest value) per target (fewer rows to send)."""
    order = np.lexsort((value, target))
    target, value = target[order], value[order]
    head = np.r_[True, target[1:] != target[:-1]] if target.size else np.zeros(0, bool)
    return target[head], value[head]


def _stars(edges: np.ndarray) -> np.ndarray:
    """Edges of the same connectivity: each component of ``edges`` a star around its vertex.

    The smallest vertex is the centre; the hooking then starts from trees of the components
    that this rank sees whole, and has fewer edges to read.
    """
    if edges.size == 0:
        return edges
    vertex, end = np.unique(edges, return_inverse=True)
    end = end.reshape(edges.shape)
    m = vertex.size
    graph = sp.coo_matrix((np.ones(end.shape[0]), (end[:, 0], end[:, 1])), shape=(m, m))
    _, comp = connected_components(graph, directed=False)
    _, lowest = np.unique(comp, return_index=True)  # vertices ascending: the first is the least
    centre = vertex[lowest[comp]]
    return np.column_stack([vertex, centre])[vertex != centre]


def component_minima(comm: MPI.Comm, values: np.ndarray, edges: np.ndarray,
                     stats: dict | None = None, join_held: bool = True) -> np.ndarray:
    """The smallest value over the connected component of every local vertex (collective).

    Args:
        comm: The ranks.
        values: The values of this rank's vertices (int64). The vertices of all ranks are
            numbered globally, rank by rank: this rank's are ``offset … offset + n − 1``
            with ``offset`` the number of vertices of the ranks before it.
        edges: Undirected edges held on this rank, (k, 2) global vertex numbers; any rank may
            hold any edge, and an edge may be held several times.
        stats: If given, ``stats["rounds"]`` receives the number of hooking rounds (the same
            on every rank).
        join_held: Whether the edges held on this rank are first replaced by stars of their
            components (by scipy, no communication). False only to test the rounds on the
            graph as given.

    Returns:
        For each local vertex, the smallest value of the vertices of its component.
    """
    values = np.asarray(values, dtype=np.int64)
    n = values.size
    at = _Vertices(comm, n)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    e = _stars(e) if join_held else e[e[:, 0] != e[:, 1]]
    # every edge in both directions, at the owner of its first end, once
    both = np.concatenate([e, e[:, ::-1]])
    (got,), _, _, _ = exchange(comm, at.owner(both[:, 0]), both)
    got = got[np.lexsort((got[:, 1], got[:, 0]))]
    keep = np.r_[True, (got[1:] != got[:-1]).any(axis=1)] if got.size else np.zeros(0, bool)
    u, v = got[keep, 0] - at.offset, got[keep, 1]
    # the far ends do not move: their parents are read through one routing every round
    far, far_of = np.unique(v, return_inverse=True)
    far_rows, far_routing = at.route(far)
    far_of = far_of.ravel()
    parent = at.offset + np.arange(n, dtype=np.int64)
    rounds = 0
    while True:
        rounds += 1
        start = parent
        # 1. star check
        rows, routing = at.route(parent)
        grand = at.read(parent, rows, routing)
        deep = grand != parent
        star = ~deep & ~at.marked(grand[deep])
        star &= at.read(star, rows, routing)
        # 2. conditional star hooking: roots of stars onto smaller parents of neighbours
        pu, pv = parent[u], at.read(parent, far_rows, far_routing)[far_of]
        hook = star[u] & (pv < pu)
        root, low = at.lowest(*_smallest_per_target(pu[hook], pv[hook]))
        parent = parent.copy()
        parent[root] = low
        hooked = parent != start
        # 3. stagnant stars (not hooked, not hooked onto) hook onto any other tree
        onto = at.marked(parent[hooked])
        stagnant = at.read(star & ~hooked & ~onto, rows, routing)  # of each vertex's root
        hook = stagnant[u] & (pv != pu)
        root, low = at.lowest(*_smallest_per_target(pu[hook], pv[hook]))
        parent[root] = low
        # 4. shortcut
        rows, routing = at.route(parent)
        parent = at.read(parent, rows, routing)
        changed = np.array([int((parent != start).any())], dtype=np.int64)
        comm.Allreduce(MPI.IN_PLACE, changed, op=MPI.MAX)
        if not changed[0]:
            break
    if stats is not None:
        stats["rounds"] = rounds
    # every tree is a star: the minimum at the root, read back by its vertices
    (t, v), order, counts, rcounts = exchange(comm, at.owner(parent), parent, values)
    root, low = _smallest_per_target(t, v)
    return answer(comm, low[np.searchsorted(root, t)], order, counts, rcounts)


__all__ = ["component_minima"]
