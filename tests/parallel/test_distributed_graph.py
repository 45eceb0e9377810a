"""Connected components of a distributed graph (run serially and under mpirun).

Every rank builds the same global graph, keeps a block of its vertices (some ranks without
any) and a share of its edges (any edge on any rank, some twice, some reversed, loops), and
``component_minima`` must give every local vertex the smallest value of its component, as
scipy's ``connected_components`` of the whole graph says, in O(log n) rounds.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from mpi4py import MPI
from scipy.sparse.csgraph import connected_components

from dolfinx_feti.parallel.distributed_graph import component_minima

COMM = MPI.COMM_WORLD


def _reference(n: int, edges: np.ndarray, values: np.ndarray) -> np.ndarray:
    g = sp.coo_matrix((np.ones(edges.shape[0]), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, comp = connected_components(g, directed=False)
    low = np.full(n, np.iinfo(np.int64).max)
    np.minimum.at(low, comp, values)
    return low[comp]


def _block(n: int, layout: str) -> slice:
    """This rank's vertices: contiguous blocks, even or with the first or last rank empty."""
    p, r = COMM.size, COMM.rank
    share = {"even": np.ones(p),
             "first_empty": np.r_[0.0, np.ones(p - 1)] if p > 1 else np.ones(1),
             "last_empty": np.r_[np.ones(p - 1), 0.0] if p > 1 else np.ones(1)}[layout]
    bounds = np.round(np.r_[0.0, np.cumsum(share)] / share.sum() * n).astype(np.int64)
    return slice(bounds[r], bounds[r + 1])


def _check(n: int, edges: np.ndarray, values: np.ndarray, layout: str = "even",
           seed: int = 0, join_held: bool = True) -> int:
    """component_minima on this rank's block against the reference; returns the rounds."""
    rng = np.random.default_rng(seed)
    # the edges dealt to random ranks, some twice and some reversed, plus a few loops
    held = edges[rng.integers(0, COMM.size, edges.shape[0]) == COMM.rank]
    flip = rng.random(held.shape[0]) < 0.5
    held = np.where(flip[:, None], held[:, ::-1], held)
    loops = np.repeat(rng.integers(0, max(n, 1), 3), 2).reshape(3, 2) if n else held[:0]
    held = np.concatenate([held, held[::3], loops])
    mine = _block(n, layout)
    stats: dict = {}
    got = component_minima(COMM, values[mine], held, stats, join_held)
    np.testing.assert_array_equal(got, _reference(n, edges, values)[mine])
    assert COMM.allgather(stats["rounds"]) == [stats["rounds"]] * COMM.size
    return stats["rounds"]


def _chain(order: np.ndarray) -> np.ndarray:
    return np.column_stack([order[:-1], order[1:]])


def _chains(n: int, rng) -> dict[str, np.ndarray]:
    """Paths through all n vertices in orders that make long chains of hooks."""
    k = np.arange(n)
    alternate = np.r_[k[::2], k[1::2]]  # neighbours in the path are far apart in number
    return {"ascending": k, "descending": k[::-1], "alternate": alternate,
            "alternate_inverse": np.argsort(alternate), "random": rng.permutation(n)}


@pytest.mark.parametrize("layout", ["even", "first_empty", "last_empty"])
def test_chains_exact_and_logarithmic(layout):
    """A path of n vertices: the slowest case of label propagation (n rounds); the hooking
    and shortcutting need O(log n). Without the join of the held edges (the rounds of the
    graph as given, also on one rank), and with it."""
    rng = np.random.default_rng(1)
    n = 1 << 13
    for name, order in _chains(n, rng).items():
        values = rng.permutation(n).astype(np.int64) * 5 - 7
        rounds = _check(n, _chain(order), values, layout, seed=len(name), join_held=False)
        assert 0.5 * np.log2(n) < rounds <= 2 * np.log2(n) + 4, (name, rounds)
        assert _check(n, _chain(order), values, layout, seed=len(name)) <= 2 * np.log2(n) + 4


def test_several_chains_and_isolated_vertices():
    """Components of every size, lone vertices among them, values of any sign."""
    rng = np.random.default_rng(2)
    n = 3000
    perm = rng.permutation(n)
    cuts = np.sort(rng.choice(np.arange(1, n), 40, replace=False))
    edges = np.concatenate([_chain(c) for c in np.split(perm, cuts) if c.size > 1])
    values = rng.integers(-10**12, 10**12, n)
    _check(n, edges, values, "last_empty", seed=3)


@pytest.mark.parametrize("kind", ["random", "binary_tree", "recursive_tree", "grid", "star"])
def test_graphs(kind):
    rng = np.random.default_rng(4)
    n = 2000
    k = np.arange(1, n)
    edges = {"random": rng.integers(0, n, (n, 2)),  # many small components and one large
             "binary_tree": np.column_stack([k, (k - 1) // 2]),
             "recursive_tree": np.column_stack([k, rng.integers(0, k)]),
             "grid": np.r_[np.column_stack([np.arange(n - 1), np.arange(1, n)])[k % 40 != 0],
                           np.column_stack([np.arange(n - 40), np.arange(40, n)])],
             "star": np.column_stack([k, np.zeros(n - 1, dtype=np.int64)])}[kind]
    perm = rng.permutation(n)  # numbers unrelated to the structure
    values = rng.permutation(n).astype(np.int64)
    rounds = _check(n, perm[edges], values, "first_empty", seed=5, join_held=False)
    assert rounds <= 2 * np.log2(n) + 4
    _check(n, perm[edges], values, "first_empty", seed=5)


def test_no_edges_and_no_vertices():
    """No edge: every vertex its own component, in one round; no vertex at all: no error."""
    values = np.arange(10, dtype=np.int64)[::-1].copy()
    assert _check(10, np.zeros((0, 2), dtype=np.int64), values) == 1
    assert _check(0, np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)) == 1
