"""The decomposition of a distributed mesh equals the serial one (run serially and under mpirun).

Every rank builds the same small global mesh, keeps some of its cells (contiguous blocks as
the scatter makes them, an uneven split, a rank without cells, a scattered subset) and runs
the distributed functions; their results must equal the serial functions' restricted to the
rank's cells, exactly.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from mpi4py import MPI
from test_decompose import _mesh_of

import dolfinx_feti as df
from dolfinx_feti.io import meshes
from dolfinx_feti.mesh import topology
from dolfinx_feti.mesh.decompose import (
    ByFunction,
    ByTags,
    Parts,
    _split_components,
    decompose,
    fixed_point_weights,
    rcb,
)
from dolfinx_feti.mesh.distributed_decompose import (
    _split,
    decompose_distributed,
    rcb_distributed,
    split_components_distributed,
)

COMM = MPI.COMM_WORLD
SPLITS = ["even", "uneven", "last_empty", "first_empty", "scattered"]


def _with_splits(cases: list) -> list:
    """The cases, each with one of the splits in turn (collectives are slow on a loaded machine:
    every case once, not under every split)."""
    return [(*(c if isinstance(c, tuple) else (c,)), SPLITS[i % len(SPLITS)])
            for i, c in enumerate(cases)]

# ------------------------------------------------------------------------------------------
# Splits of the items over the ranks, and meshes
# ------------------------------------------------------------------------------------------


def _mine(num: int, split: str, seed: int = 0) -> np.ndarray:
    """The ids this rank keeps of 0 … num − 1 (ascending)."""
    p, r = COMM.size, COMM.rank
    if split == "scattered":  # any subset, as after a migration to subdomain owners
        return np.flatnonzero(np.random.default_rng(seed).integers(0, p, num) == r)
    share = {"even": np.ones(p), "uneven": np.arange(p, 0, -1.0) ** 2,
             "last_empty": np.r_[np.ones(p - 1), 0.0] if p > 1 else np.ones(1),
             "first_empty": np.r_[0.0, np.ones(p - 1)] if p > 1 else np.ones(1)}[split]
    bounds = np.round(np.r_[0.0, np.cumsum(share)] / share.sum() * num).astype(np.int64)
    return np.arange(bounds[r], bounds[r + 1])


def _grid_points(shape: tuple[int, ...]) -> np.ndarray:
    """Integer grid points (many equal coordinates), x fastest."""
    axes = [np.arange(s, dtype=np.float64) for s in shape]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(shape))[:, ::-1]


def _structured(cell_type: str, n: tuple[int, ...], origin=(0.0, 0.0, 0.0), body=0):
    """(x, cells, cell_type) of a structured grid of n cells per axis on [origin, origin + n]."""
    gdim = len(n)
    x = _grid_points(tuple(k + 1 for k in reversed(n)))[:, :gdim] + np.asarray(origin[:gdim])
    stride = np.cumprod([1] + [k + 1 for k in n[:-1]])
    corner = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, gdim)
    bits = np.array([[(i >> a) & 1 for a in range(gdim)] for i in range(2 ** gdim)])
    boxes = ((corner[:, None, :] + bits[None]) * stride).sum(axis=2)  # tensor order, x fastest
    if cell_type in ("quadrilateral", "hexahedron"):
        return x, boxes
    if cell_type == "triangle":
        return x, boxes[:, [[0, 1, 3], [0, 3, 2]]].reshape(-1, 3)
    kuhn = [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]]
    return x, boxes[:, kuhn].reshape(-1, 4)


def _u_shape(cell_type: str, n: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """A U of an n × n grid without its upper middle third: bisections fall apart in pieces."""
    x, cells = _structured(cell_type, (n, n))
    mid = x[cells].mean(axis=1)
    hole = (mid[:, 0] > n / 3) & (mid[:, 0] < 2 * n / 3) & (mid[:, 1] > n / 3)
    kept = cells[~hole]
    used, kept = np.unique(kept, return_inverse=True)
    return x[used], kept.reshape(-1, cells.shape[1])


def _scrambled(mesh: df.MeshData, seed: int = 1) -> df.MeshData:
    """The same mesh with its cells in a random order (ties of coordinates meet random ids)."""
    order = np.random.default_rng(seed).permutation(mesh.cells.shape[0])
    return df.MeshData(x=mesh.x, cells=mesh.cells[order], cell_type=mesh.cell_type,
                       cell_body=mesh.cell_body[order], body_names=mesh.body_names,
                       facet_groups={}, node_tags=mesh.node_tags)


MESHES = {
    "triangles": lambda: _mesh_of([("plate", *_structured("triangle", (12, 8)))]),
    "quads_two_bodies": lambda: _mesh_of([
        ("a", *_structured("quadrilateral", (10, 6))),
        ("b", *_structured("quadrilateral", (5, 5), origin=(0.0, 6.0)))],
        cell_type="quadrilateral"),
    "tets": lambda: _scrambled(_mesh_of([("cube", *_structured("tetrahedron", (4, 3, 3)))],
                                        cell_type="tetrahedron")),
    "hexes_two_bodies": lambda: _mesh_of([
        ("lower", *_structured("hexahedron", (5, 4, 2))),
        ("upper", *_structured("hexahedron", (5, 4, 3), origin=(0.0, 0.0, 2.0)))],
        cell_type="hexahedron"),
    "u_shape": lambda: _mesh_of([("u", *_u_shape("triangle"))]),
}
GMSH_MESHES = {
    "gmsh_triangles": lambda: df.build_mesh(_rectangle, quads=False),
    "gmsh_quads": lambda: df.build_mesh(_rectangle, quads=True),
    "gmsh_blocks3d": lambda: df.build_mesh(meshes.blocks3d, n=3),
    "gmsh_hertz2d": lambda: df.build_mesh(meshes.hertz2d, h_contact=0.5, h_far=4.0),
}
_BUILT: dict[str, df.MeshData] = {}


def _rectangle(quads: bool):
    from element_models import rectangle

    return rectangle(quads=quads, h=0.3)


def _mesh(name: str) -> df.MeshData:
    if name not in _BUILT:
        _BUILT[name] = {**MESHES, **GMSH_MESHES}[name]()
    return _BUILT[name]


def _distributed(mesh: df.MeshData, how, split: str):
    """decompose_distributed on this rank's cells of ``split``: (ids, cell_sub, sub_body)."""
    ids = _mine(mesh.cells.shape[0], split, seed=mesh.cells.shape[0])
    cells = mesh.cells[ids]
    sub, sub_body = decompose_distributed(cells, mesh.x[cells], ids, mesh.cell_body[ids],
                                          mesh.cell_type, mesh.body_names, mesh.cells.shape[0],
                                          how, COMM)
    return ids, sub, sub_body


def _assert_serial(mesh: df.MeshData, how, split: str):
    ref = decompose(mesh, how, 1)
    ids, sub, sub_body = _distributed(mesh, how, split)
    np.testing.assert_array_equal(sub, ref.cell_sub[ids])
    assert sub.dtype == ref.cell_sub.dtype
    np.testing.assert_array_equal(sub_body, ref.sub_body)
    assert sub_body.dtype == ref.sub_body.dtype
    return ref


def _stripes(m: np.ndarray) -> np.ndarray:
    """Labels of alternating stripes: every label falls apart in several pieces."""
    return (np.floor(m[:, 0] / 2.0).astype(np.int64) % 2) * 7 - 3


# ------------------------------------------------------------------------------------------
# Recursive coordinate bisection
# ------------------------------------------------------------------------------------------


def _rcb_case(points: np.ndarray, n: int, weights, split: str, seed: int):
    """rcb_distributed of points whose ids are a permutation; compared with the serial rcb."""
    m = points.shape[0]
    perm = np.random.default_rng(seed).permutation(m)  # point i has id perm[i]
    by_id = np.empty_like(points)
    by_id[perm] = points
    w_by_id = None
    if weights is not None:
        w_by_id = np.empty_like(weights)
        w_by_id[perm] = weights
    ref = rcb(by_id, n, w_by_id)
    ids = _mine(m, split, seed)
    got = rcb_distributed(by_id[ids], ids, n, COMM, None if w_by_id is None else w_by_id[ids])
    np.testing.assert_array_equal(got, ref[ids])
    return ref


@pytest.mark.parametrize(("n", "weighted", "split"),
                         _with_splits([(n, w) for n in (1, 2, 3, 7, 16) for w in (False, True)]))
def test_rcb_random_points(n, weighted, split):
    rng = np.random.default_rng(n)
    for gdim, m in ((2, 700), (3, 500)):
        pts = rng.random((m, gdim)) * [3.0, 1.0, 2.0][:gdim]
        w = rng.random(m) ** 3 if weighted else None
        ref = _rcb_case(pts, n, w, split, seed=m + n)
        assert np.unique(ref).size == n


@pytest.mark.parametrize(("n", "weighted", "split"),
                         _with_splits([(n, w) for n in (2, 3, 7, 16) for w in (False, True)]))
def test_rcb_grids_with_ties(n, weighted, split):
    """Integer grids: whole rows of equal coordinates, cut by the order of the levels above."""
    for shape in ((9, 31), (6, 5, 7), (4, 4, 4)):
        pts = _grid_points(shape)
        # equal weights: the weighted cut also meets exact ties of the prefix sums
        w = np.where(pts[:, 0] < 2, 0.1, 0.3) if weighted else None
        _rcb_case(pts, n, w, split, seed=n)
        _rcb_case(pts[::-1].copy(), n, w, split, seed=n + 1)


@pytest.mark.parametrize("weighted", [False, True])
def test_rcb_fewer_points_than_parts(weighted):
    rng = np.random.default_rng(3)
    for m in (0, 1, 2, 5, 11):
        pts = np.round(rng.random((m, 2)) * 2)
        _rcb_case(pts, 16, rng.random(m) if weighted else None, "scattered", seed=m)


def test_rcb_zero_and_negative_zero_coordinates_tie():
    pts = np.array([[0.0, 1.0], [-0.0, 0.0], [0.0, 2.0], [-0.0, 3.0], [1.0, 0.5]] * 5)
    _rcb_case(pts, 4, None, "even", seed=0)


def test_rcb_collective_rounds_grow_with_levels_not_parts():
    """The collective calls of a level do not grow with its number of work items."""

    class Counting:
        def __init__(self, comm):
            self.comm, self.calls = comm, 0

        def __getattr__(self, name):
            attr = getattr(self.comm, name)
            if name[0].isupper() or name in ("allgather", "gather", "exscan"):
                self.calls += 1
            return attr

    pts = np.random.default_rng(0).random((4000, 2))
    ids = _mine(4000, "even")
    calls = {}
    for n in (2, 64):
        comm = Counting(COMM)
        rcb_distributed(pts[ids], ids, n, comm)
        calls[n] = comm.calls
    levels = 6  # log2(64)
    # a level: one reduction of the boxes and at most 4 rounds of 2 calls on 4000 points
    assert calls[64] <= 1 + levels * (1 + 2 * 4)
    assert calls[64] <= levels * calls[2]


def test_weighted_rcb_cut_is_the_exact_one():
    """The serial weighted cut is where the exact (rational) prefix sum of the weights reaches
    the exact target; a floating cumsum misses it at ties (here ten weights of 0.1)."""
    rng = np.random.default_rng(5)

    def exact(points, n, weights):
        labels = np.zeros(points.shape[0], dtype=np.int64)
        work = [(np.arange(points.shape[0]), n, 0)]
        while work:
            idx, k, first = work.pop()
            if k == 1 or idx.size == 0:
                labels[idx] = first
                continue
            p = points[idx]
            order = idx[np.argsort(p[:, np.argmax(np.ptp(p, axis=0))], kind="stable")]
            k1 = k // 2
            cw = np.cumsum([Fraction(float(w)) for w in weights[order]])
            cut = int(np.searchsorted(cw >= cw[-1] * k1 / k, True)) + 1
            cut = min(max(cut, k1), idx.size - (k - k1))
            work += [(order[:cut], k1, first), (order[cut:], k - k1, first + k1)]
        return labels

    for m, n in ((10, 2), (60, 3), (200, 7)):
        pts = rng.random((m, 2))
        for w in (np.full(m, 0.1), rng.random(m), np.round(rng.random(m) * 4) / 10):
            np.testing.assert_array_equal(rcb(pts, n, w), exact(pts, n, w))
    # the float cumsum of ten times 0.1 stays below half of its total at the fifth point
    line = np.column_stack([np.arange(10.0), np.zeros(10)])
    assert np.bincount(rcb(line, 2, np.full(10, 0.1))).tolist() == [5, 5]


def test_fixed_point_weights_keep_sums_exact():
    w = np.random.default_rng(0).random(1000)
    q = fixed_point_weights(w, w.max(), w.size)
    assert q.dtype == np.int64 and q.max() < 2**62 // 1024
    np.testing.assert_allclose(q / q.max(), w / w.max(), rtol=1e-12)


# ------------------------------------------------------------------------------------------
# Connected pieces of equal label
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("name", "split"), _with_splits(sorted(MESHES)))
def test_split_components(name, split):
    mesh = _mesh(name)
    nc = mesh.cells.shape[0]
    for nlabels in (1, 2, 5):
        label = np.random.default_rng(nlabels).integers(0, nlabels, nc)
        ref = _split_components(mesh.cells, label, mesh.cell_type)
        ids = _mine(nc, split, seed=nlabels)
        got = split_components_distributed(mesh.cells[ids], ids, label[ids], mesh.cell_type,
                                           COMM)
        np.testing.assert_array_equal(got, ref[ids])


@pytest.mark.parametrize("name", ["tets", "hexes_two_bodies"])
def test_split_components_with_large_vertex_numbers(name):
    """Vertex numbers too large for int64 facet keys (the keys are then the rows' bytes)."""
    mesh = _mesh(name)
    cells = mesh.cells * 1_000_003 + 7
    assert topology.row_keys(cells[:1, :4], int(cells.max()) + 1).dtype.kind == "V"
    label = np.random.default_rng(0).integers(0, 3, cells.shape[0])
    ref = _split_components(mesh.cells, label, mesh.cell_type)
    np.testing.assert_array_equal(_split_components(cells, label, mesh.cell_type), ref)
    ids = _mine(cells.shape[0], "uneven")
    got = split_components_distributed(cells[ids], ids, label[ids], mesh.cell_type, COMM)
    np.testing.assert_array_equal(got, ref[ids])


@pytest.mark.parametrize("cell_type", ["quadrilateral", "triangle"])
def test_split_components_chain_across_ranks(cell_type):
    """A strip of cells dealt to the ranks round-robin: no two neighbours on one rank, so the
    pieces of a label form a chain that alternates between the ranks (one piece per cell).
    Joined exactly as the serial pieces, in O(log(pieces)) rounds, not O(chain)."""
    n = 3000
    x, cells = _structured(cell_type, (n, 1))
    # vertices numbered at random: the facet directory's ranks see scattered links of the
    # chain, not runs of it that they could join alone
    cells = np.random.default_rng(0).permutation(x.shape[0])[cells]
    nc = cells.shape[0]
    mid = np.arange(nc) // (nc // n)  # cells along the strip, one or two per square
    for label in (np.zeros(nc, dtype=np.int64),  # one piece of the whole strip
                  (mid > n / 3).astype(np.int64) + (mid > 0.9 * n)):  # three pieces
        ref = _split_components(cells, label, cell_type)
        ids = np.flatnonzero(np.arange(nc) % COMM.size == COMM.rank)
        stats: dict = {}
        sub, first = _split(cells[ids], ids, label[ids], cell_type, COMM, stats=stats)
        np.testing.assert_array_equal(sub, ref[ids])
        lowest = np.full(ref.max() + 1, nc)
        np.minimum.at(lowest, ref, np.arange(nc))
        np.testing.assert_array_equal(first, lowest[ref[ids]])
        assert stats["rounds"] <= 2 * np.log2(nc) + 4
        if COMM.size > 1:  # the chain's links were spread: it took the hooking rounds
            assert stats["rounds"] > 3


# ------------------------------------------------------------------------------------------
# The decomposition
# ------------------------------------------------------------------------------------------

HOWS = {
    "tags": ByTags(),
    "parts3": Parts(3),
    "parts7": Parts(7),
    "parts16": Parts(16),
    "volume3": Parts(3, balance="volume"),
    "volume7": Parts(7, balance="volume"),
    "pieces7": Parts(7, merge=False),
    "stripes": ByFunction(_stripes),
}


@pytest.mark.parametrize(("name", "how", "split"),
                         _with_splits([(m, h) for m in sorted(MESHES) for h in sorted(HOWS)]))
def test_decompose_distributed_is_the_serial_one(name, how, split):
    mesh = _mesh(name)
    _assert_serial(mesh, HOWS[how], split)


def test_cases_exercise_pieces():
    """The U-shape falls apart under rcb and the stripes under ByFunction (more subdomains than
    labels), so that the tests above join pieces across ranks."""
    assert decompose(_mesh("u_shape"), Parts(3, merge=False), 1).num_subdomains > 3
    assert decompose(_mesh("u_shape"), Parts(3), 1).num_subdomains == 3
    assert decompose(_mesh("triangles"), ByFunction(_stripes), 1).num_subdomains > 2
    assert decompose(_mesh("quads_two_bodies"), Parts({"a": 3, "b": 2}), 1).num_subdomains == 5


@pytest.mark.parametrize("split", ["even", "last_empty", "scattered"])
def test_parts_per_body(split):
    _assert_serial(_mesh("hexes_two_bodies"), Parts({"upper": 5}), split)
    _assert_serial(_mesh("quads_two_bodies"), Parts({"a": 4, "b": 3}, balance="volume"), split)


@pytest.mark.parametrize(("name", "split"), _with_splits(sorted(GMSH_MESHES)))
def test_gmsh_meshes(name, split):
    mesh = _mesh(name)
    for how in (ByTags(), Parts(5), Parts(6, balance="volume"),
                ByFunction(lambda m: (np.floor(m[:, 0] * 1.3) % 3).astype(np.int64))):
        _assert_serial(mesh, how, split)


# ------------------------------------------------------------------------------------------
# Bad input: the serial errors, on every rank
# ------------------------------------------------------------------------------------------


def test_too_many_parts():
    mesh = _mesh("quads_two_bodies")
    with pytest.raises(df.InputError, match="26 parts for body 'b', which has only 25 cells"):
        _distributed(mesh, Parts({"b": 26}), "last_empty")


def test_unknown_bodies():
    with pytest.raises(df.InputError, match=r"unknown bodies \['c'\]"):
        _distributed(_mesh("quads_two_bodies"), Parts({"a": 2, "c": 2}), "even")


def test_ptscotch_needs_the_whole_mesh():
    with pytest.raises(df.InputError, match="ptscotch.*whole mesh on one rank"):
        _distributed(_mesh("triangles"), Parts(2, method="ptscotch"), "even")
    with pytest.raises(df.InputError, match="balance='volume' needs method='rcb'"):
        _distributed(_mesh("triangles"), Parts(2, method="ptscotch", balance="volume"), "even")


def test_unknown_decomposition():
    with pytest.raises(df.InputError, match="unknown decomposition"):
        _distributed(_mesh("triangles"), "grid", "even")


def test_labeller_failing_on_some_cells_fails_everywhere():
    """The labeller raises only for the cells at x > 10, which one rank holds."""

    def fn(m):
        if np.any(m[:, 0] > 10):
            raise ValueError("no labels beyond x = 10")
        return np.zeros(m.shape[0], dtype=np.int64)

    with pytest.raises(df.InputError, match="ByFunction.fn.*raised ValueError: no labels"):
        _distributed(_mesh("triangles"), ByFunction(fn), "even")
    with pytest.raises(df.InputError, match="one integer label per cell"):
        _distributed(_mesh("triangles"), ByFunction(lambda m: m[:, 0]), "uneven")


def test_volume_weights_are_the_serial_cell_volumes():
    """The weights of balance='volume' on local cells are those of the whole mesh's cells."""
    mesh = _mesh("tets")
    ids = _mine(mesh.cells.shape[0], "scattered")
    local = np.arange(ids.size * 4).reshape(-1, 4)
    np.testing.assert_array_equal(
        topology.cell_volumes(mesh.x[mesh.cells[ids]].reshape(-1, 3), local, "tetrahedron"),
        topology.cell_volumes(mesh.x, mesh.cells, "tetrahedron")[ids])
