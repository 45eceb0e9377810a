"""Connected components of a graph whose vertices and edges are spread over the ranks.

:func:`component_minima` gives every vertex the smallest value of its component without
gathering the graph anywhere: a forest of parent pointers, one per vertex on the rank that
owns the vertex, is merged by the hooking and shortcutting of Shiloach & Vishkin (1982) in the
form of Awerbuch & Shiloach (1987). A round:

1. star check: which trees are stars (every vertex a child of the root);
2. conditional star hooking: the root of a star that has an edge to a tree of smaller parent
   takes the smallest such parent as its parent (parents fall, so no cycle);
3. unconditional hooking of stagnant stars: a star that neither hooked nor was hooked onto in
   step 2 and still has an edge out hooks onto any neighbour's parent. Two stagnant stars are
   never adjacent (the larger would have hooked onto the smaller in step 2), so the trees
   hooked onto do not move in this step: no cycle;
4. shortcut: every vertex takes its grandparent as its parent.

A star with an edge out joins another tree in steps 2 or 3 of every round, and the other trees
halve their height in step 4, so O(log n) rounds suffice for n vertices (Awerbuch & Shiloach
1987 bound them by log_{3/2} n); ``tests/test_distributed_graph.py`` checks ≤ 2 log2 n + 4
rounds on chains and trees built against the hooking order. The search stops after the first
round in which no parent changed on any rank (one Allreduce of a flag per round): then every
tree is a star and no edge joins two trees, so the trees are the components. Every query about a
vertex (its parent, its star flag) is answered by its owner through :func:`.exchange.exchange`
and :func:`.exchange.answer`, so a rank holds O(its vertices + its edges) at any time.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from .exchange import answer, exchange


class _Vertices:
    """This rank's vertices ``offset … offset + n − 1`` and the owner of any global vertex."""

    def __init__(self, comm: MPI.Comm, n: int):
        self.comm = comm
        self.starts = np.concatenate([[0], np.cumsum(comm.allgather(int(n)))]).astype(np.int64)
        self.offset = int(self.starts[comm.rank])

    def owner(self, vertex: np.ndarray) -> np.ndarray:
        return np.searchsorted(self.starts, vertex, side="right") - 1

    def route(self, vertex: np.ndarray):
        """Ask the owners about ``vertex``.

        Returns:
            The rows of the asked vertices at this rank (as an owner), and the routing of the
            answers for :func:`.exchange.answer`.
        """
        (asked,), order, counts, rcounts = exchange(self.comm, self.owner(vertex), vertex)
        return asked - self.offset, (order, counts, rcounts)

    def read(self, table: np.ndarray, rows: np.ndarray, routing) -> np.ndarray:
        """``table`` (this rank's vertices) at the vertices of a :meth:`route`."""
        return answer(self.comm, table[rows], *routing)

    def send_min(self, target: np.ndarray, value: np.ndarray, fill: np.ndarray) -> np.ndarray:
        """``fill`` lowered, at every local vertex, to the smallest value sent to it."""
        (t, v), _, _, _ = exchange(self.comm, self.owner(target), target, value)
        out = fill.copy()
        np.minimum.at(out, t - self.offset, v)
        return out


def _smallest_per_target(target: np.ndarray, value: np.ndarray):
    """One (target, smallest value) per target (fewer rows to send)."""
    order = np.lexsort((value, target))
    target, value = target[order], value[order]
    head = np.r_[True, target[1:] != target[:-1]] if target.size else np.zeros(0, bool)
    return target[head], value[head]


def component_minima(comm: MPI.Comm, values: np.ndarray, edges: np.ndarray,
                     stats: dict | None = None) -> np.ndarray:
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

    Returns:
        For each local vertex, the smallest value of the vertices of its component.
    """
    values = np.asarray(values, dtype=np.int64)
    n = values.size
    at = _Vertices(comm, n)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    e = e[e[:, 0] != e[:, 1]]
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
    never = np.iinfo(np.int64).max
    rounds = 0
    while True:
        rounds += 1
        start = parent
        # 1. star check
        rows, routing = at.route(parent)
        grand = at.read(parent, rows, routing)
        deep = grand != parent
        star = ~deep
        star[at.send_min(grand[deep], np.zeros(int(deep.sum()), dtype=np.int64),
                         np.ones(n, dtype=np.int64)) == 0] = False
        star &= at.read(star, rows, routing)
        # 2. conditional star hooking: roots of stars onto smaller parents of neighbours
        pu, pv = parent[u], at.read(parent, far_rows, far_routing)[far_of]
        hook = star[u] & (pv < pu)
        target, value = _smallest_per_target(pu[hook], pv[hook])
        parent = at.send_min(target, value, parent)
        hooked = parent != start
        # 3. stagnant stars (not hooked, not hooked onto) hook onto any other tree
        onto = at.send_min(parent[hooked], np.zeros(int(hooked.sum()), dtype=np.int64),
                           np.ones(n, dtype=np.int64)) == 0
        stagnant = at.read(star & ~hooked & ~onto, rows, routing)  # of each vertex's root
        hook = stagnant[u] & (pv != pu)
        target, value = _smallest_per_target(pu[hook], pv[hook])
        lowest = at.send_min(target, value, np.full(n, never, dtype=np.int64))
        parent = np.where(lowest < never, lowest, parent)
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
    low = np.full(n, never, dtype=np.int64)
    np.minimum.at(low, t - at.offset, v)
    return answer(comm, low[t - at.offset], order, counts, rcounts)


__all__ = ["component_minima"]
