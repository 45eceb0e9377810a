"""Unit tests of mesh.decompose and mesh.topology on hand-made NumPy meshes (no gmsh, no MPI)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.mesh import topology
from dolfinx_feti.mesh.decompose import ByFunction, ByTags, Parts, assign_ranks, decompose, rcb

# ------------------------------------------------------------------------------------------
# Small meshes built here
# ------------------------------------------------------------------------------------------


def _grid(nx: int, ny: int, x0: float = 0.0, y0: float = 0.0, lx: float = 1.0,
          ly: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and triangles of an nx × ny grid of squares, each cut along one diagonal."""
    xs = np.linspace(x0, x0 + lx, nx + 1)
    ys = np.linspace(y0, y0 + ly, ny + 1)
    X, Y = np.meshgrid(xs, ys)  # row j = y index
    x = np.column_stack([X.ravel(), Y.ravel()])

    def node(i, j):
        return j * (nx + 1) + i

    tris = []
    for j in range(ny):
        for i in range(nx):
            a, b, c, d = node(i, j), node(i + 1, j), node(i + 1, j + 1), node(i, j + 1)
            tris += [(a, b, c), (a, c, d)]
    return x, np.array(tris, dtype=np.int64)


def _mesh_of(parts: list[tuple[str, np.ndarray, np.ndarray]],
             facet_groups: dict | None = None, cell_type: str = "triangle") -> df.MeshData:
    """MeshData of several bodies ``(name, x, cells)``; each body keeps its own nodes."""
    xs, cells, body = [], [], []
    offset = 0
    for b, (_, x, c) in enumerate(parts):
        xs.append(x)
        cells.append(c + offset)
        body.append(np.full(c.shape[0], b, dtype=np.int32))
        offset += x.shape[0]
    x = np.concatenate(xs)
    return df.MeshData(x=x, cells=np.concatenate(cells), cell_type=cell_type,
                       cell_body=np.concatenate(body), body_names=tuple(p[0] for p in parts),
                       facet_groups=dict(facet_groups or {}),
                       node_tags=np.arange(1, x.shape[0] + 1))


def _square(n: int = 4) -> df.MeshData:
    return _mesh_of([("plate", *_grid(n, n))])


def _boundary_facets(cells: np.ndarray) -> np.ndarray:
    f = topology.cell_facets(cells).reshape(-1, cells.shape[1] - 1)
    key, count = np.unique(np.sort(f, axis=1), axis=0, return_counts=True)
    return key[count == 1]


def _check_consistent(mesh: df.MeshData, dec) -> None:
    """The (subdomain, node) pairs, nodes(), pair_index() and node_subdomains() agree."""
    nsub = dec.num_subdomains
    assert dec.sub_ptr[0] == 0 and dec.sub_ptr[-1] == dec.pair_sub.size
    assert np.all(np.diff(dec.sub_ptr) > 0)
    members = [set() for _ in range(mesh.num_nodes)]
    for s in range(nsub):
        expected = np.unique(mesh.cells[dec.cell_sub == s])
        nodes = dec.nodes(s)
        np.testing.assert_array_equal(nodes, expected)
        idx = dec.pair_index(np.full(nodes.size, s), nodes)
        np.testing.assert_array_equal(idx, np.arange(dec.sub_ptr[s], dec.sub_ptr[s + 1]))
        np.testing.assert_array_equal(dec.pair_sub[idx], s)
        np.testing.assert_array_equal(dec.pair_node[idx], nodes)
        for v in nodes:
            members[v].add(s)
        assert dec.sub_body[s] == mesh.cell_body[np.flatnonzero(dec.cell_sub == s)[0]]
        # every subdomain lies in one body
        assert np.unique(mesh.cell_body[dec.cell_sub == s]).size == 1
    ptr, subs = dec.node_subdomains()
    assert ptr.size == mesh.num_nodes + 1
    for v in range(mesh.num_nodes):
        assert list(subs[ptr[v]:ptr[v + 1]]) == sorted(members[v])


# ------------------------------------------------------------------------------------------
# Recursive coordinate bisection
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 3, 5, 7, 8, 16])
@pytest.mark.parametrize("npts", [1, 9, 50, 257])
def test_rcb_balanced_and_complete(n, npts):
    pts = np.random.default_rng(npts).random((npts, 2))
    labels = rcb(pts, n)
    assert labels.shape == (npts,)
    assert labels.min() >= 0 and labels.max() < n
    counts = np.bincount(labels, minlength=n)
    assert counts.sum() == npts
    assert counts.max() - counts.min() <= 1
    if npts >= n:
        assert np.all(counts > 0)


def test_rcb_deterministic_and_geometric():
    pts = np.random.default_rng(7).random((300, 3)) * [4.0, 1.0, 1.0]
    a, b = rcb(pts, 6), rcb(pts.copy(), 6)
    np.testing.assert_array_equal(a, b)
    # points on a line are cut into consecutive intervals
    line = np.column_stack([np.linspace(0.0, 1.0, 40), np.zeros(40)])
    lab = rcb(line[::-1].copy(), 4)[::-1]
    assert np.all(np.diff(lab) <= 0) or np.all(np.diff(lab) >= 0)
    assert np.array_equal(np.bincount(lab), [10, 10, 10, 10])


def test_parts_balanced_per_body():
    mesh = _mesh_of([("a", *_grid(6, 6)), ("b", *_grid(4, 2, x0=2.0))])
    dec = decompose(mesh, Parts({"a": 3, "b": 2}), 1)
    assert dec.num_subdomains == 5
    assert sorted(np.bincount(dec.sub_body)) == [2, 3]
    for b, n in ((0, 3), (1, 2)):
        sizes = [np.sum(dec.cell_sub == s) for s in np.flatnonzero(dec.sub_body == b)]
        assert len(sizes) == n and max(sizes) - min(sizes) <= 1
    _check_consistent(mesh, dec)
    # same decomposition on a repeated call
    dec2 = decompose(mesh, Parts({"a": 3, "b": 2}), 1)
    np.testing.assert_array_equal(dec.cell_sub, dec2.cell_sub)


@pytest.mark.parametrize("n", [2, 3, 4, 7])
def test_rcb_weighted(n):
    """Weighted RCB: parts of nearly equal weight (within the largest weights), none empty."""
    rng = np.random.default_rng(n)
    pts = rng.random((400, 2))
    w = np.exp(-8 * pts[:, 0])  # heavy on the left: equal counts would not balance it
    labels = rcb(pts, n, w)
    total = np.bincount(labels, weights=w, minlength=n)
    assert np.all(np.bincount(labels, minlength=n) > 0)
    assert np.abs(total - w.sum() / n).max() <= 3 * w.max()
    assert np.abs(np.bincount(rcb(pts, n), weights=w) - w.sum() / n).max() > 3 * w.max()


def test_parts_balance_volume():
    """balance="volume" on a graded mesh: no subdomain larger than a quarter of the area (up to
    the cells cut at the bisections), where equal cell counts give one of three quarters;
    refused with PT-Scotch."""
    x, cells = _grid(12, 12)
    x = x**3  # cells graded toward the corner (0, 0)
    mesh = _mesh_of([("plate", x, cells)])
    area = np.abs(topology.cell_volumes(mesh.x, mesh.cells, mesh.cell_type))
    largest = {}
    for balance in ("volume", "cells"):
        dec = decompose(mesh, Parts(4, balance=balance), 1)
        largest[balance] = np.bincount(dec.cell_sub, weights=area).max()
        _check_consistent(mesh, dec)
    assert largest["volume"] <= area.sum() / 4 + 3 * area.max()
    assert largest["cells"] >= 0.7 * area.sum()
    with pytest.raises(df.InputError, match="balance='volume' needs method='rcb'"):
        decompose(mesh, Parts(2, method="ptscotch", balance="volume"), 1)
    with pytest.raises(df.InputError, match="Parts.balance must be one of"):
        decompose(mesh, Parts(2, balance="mass"), 1)


def test_parts_invalid():
    mesh = _square(2)
    with pytest.raises(df.InputError, match="Parts.n must be an integer >= 1"):
        decompose(mesh, Parts(0), 1)
    with pytest.raises(df.InputError, match="unknown bodies"):
        decompose(mesh, Parts({"plate": 2, "nope": 1}), 1)
    with pytest.raises(df.InputError, match="Parts.method must be one of 'rcb', 'ptscotch'"):
        decompose(mesh, Parts(2, method="metis"), 1)
    with pytest.raises(df.InputError, match="9 parts for body 'plate'"):
        decompose(mesh, Parts(9), 1)


# ------------------------------------------------------------------------------------------
# ByFunction, ByTags and the split into connected pieces
# ------------------------------------------------------------------------------------------


def test_by_function_grid_labels():
    mesh = _square(8)
    H = 0.5

    def quadrant(m):
        return (np.floor(m[:, 0] / H) + 2 * np.floor(m[:, 1] / H)).astype(np.int64)

    dec = decompose(mesh, ByFunction(quadrant), 1)
    assert dec.num_subdomains == 4
    mid = mesh.x[mesh.cells].mean(axis=1)
    q = quadrant(mid)
    # subdomains and quadrants are the same partition of the cells
    pairs = {(int(a), int(b)) for a, b in zip(dec.cell_sub, q, strict=True)}
    assert len(pairs) == 4
    assert len({a for a, _ in pairs}) == 4 and len({b for _, b in pairs}) == 4
    for s in range(4):
        assert np.sum(dec.cell_sub == s) == 32
    # numbered by first cell
    firsts = [np.flatnonzero(dec.cell_sub == s)[0] for s in range(4)]
    assert firsts == sorted(firsts)
    _check_consistent(mesh, dec)
    # the centre node is in all four subdomains, edge midpoints in two
    ptr, _ = dec.node_subdomains()
    mult = np.diff(ptr)
    centre = np.flatnonzero(np.all(np.isclose(mesh.x, 0.5), axis=1))
    assert mult[centre].tolist() == [4]
    on_cut = np.isclose(mesh.x[:, 0], 0.5) | np.isclose(mesh.x[:, 1], 0.5)
    assert np.all(mult[on_cut & ~np.all(np.isclose(mesh.x, 0.5), axis=1)] == 2)
    assert np.all(mult[~on_cut] == 1)


def test_by_function_bad_labels():
    mesh = _square(2)
    with pytest.raises(df.InputError, match="one integer label per cell"):
        decompose(mesh, ByFunction(lambda m: m[:, 0]), 1)
    with pytest.raises(df.InputError, match="one integer label per cell"):
        decompose(mesh, ByFunction(lambda m: np.zeros(3, dtype=int)), 1)


def test_label_on_two_pieces_gives_two_subdomains():
    mesh = _square(8)
    # label 0 on the two outer strips, 1 in the middle: label 0 is not connected
    dec = decompose(mesh, ByFunction(
        lambda m: (np.abs(m[:, 0] - 0.5) < 0.25).astype(np.int64)), 1)
    assert dec.num_subdomains == 3
    mid = mesh.x[mesh.cells].mean(axis=1)
    for s in range(3):
        xs = mid[dec.cell_sub == s, 0]
        # each subdomain is one strip
        assert xs.max() - xs.min() < 0.5
    _check_consistent(mesh, dec)


def test_by_tags_splits_disconnected_body():
    x1, c1 = _grid(2, 2)
    x2, c2 = _grid(2, 2, x0=3.0)
    # one body made of two separate squares
    x = np.concatenate([x1, x2])
    cells = np.concatenate([c1, c2 + x1.shape[0]])
    mesh = _mesh_of([("two", x, cells)])
    dec = decompose(mesh, ByTags(), 1)
    assert dec.num_subdomains == 2
    np.testing.assert_array_equal(dec.sub_body, [0, 0])
    np.testing.assert_array_equal(dec.cell_sub, np.repeat([0, 1], c1.shape[0]))
    _check_consistent(mesh, dec)


def test_triangles_touching_at_a_vertex_are_separate():
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    cells = np.array([[0, 1, 2], [0, 3, 4]])
    mesh = _mesh_of([("bow", x, cells)])
    dec = decompose(mesh, ByTags(), 1)
    assert dec.num_subdomains == 2
    ptr, subs = dec.node_subdomains()
    assert list(subs[ptr[0]:ptr[1]]) == [0, 1]
    assert np.diff(ptr).tolist() == [2, 1, 1, 1, 1]
    _check_consistent(mesh, dec)


def test_by_tags_one_subdomain_per_body():
    mesh = _mesh_of([("left", *_grid(3, 3)), ("right", *_grid(3, 3, x0=1.0))])
    dec = decompose(mesh, ByTags(), 1)
    assert dec.num_subdomains == 2
    np.testing.assert_array_equal(dec.sub_body, [0, 1])
    np.testing.assert_array_equal(dec.cell_sub, mesh.cell_body)
    # bodies do not share nodes: no node in two subdomains
    ptr, _ = dec.node_subdomains()
    assert np.all(np.diff(ptr) == 1)
    _check_consistent(mesh, dec)


def test_pair_index_rejects_foreign_node():
    mesh = _mesh_of([("left", *_grid(2, 2)), ("right", *_grid(2, 2, x0=1.0))])
    dec = decompose(mesh, ByTags(), 1)
    foreign = dec.nodes(1)[:1]
    with pytest.raises(ValueError):
        dec.pair_index(np.array([0]), foreign)


def test_unknown_decomposition():
    with pytest.raises(df.InputError, match="unknown decomposition"):
        decompose(_square(2), "grid", 1)


# ------------------------------------------------------------------------------------------
# Subdomains to ranks
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("size", [1, 2, 3, 4, 7])
@pytest.mark.parametrize("nsub", [1, 3, 7, 12, 30])
def test_rank_assignment(size, nsub):
    w = np.random.default_rng(nsub * 100 + size).integers(1, 50, nsub)
    r = assign_ranks(w, size)
    assert r.shape == (nsub,)
    assert r.min() >= 0 and r.max() < size
    assert np.all(np.diff(r) >= 0)  # contiguous blocks in subdomain order
    if nsub >= size:
        assert np.unique(r).size == size  # nobody left empty
    load = np.bincount(r, weights=w, minlength=size)
    assert load.max() <= w.sum() / size + w.max()


@pytest.mark.parametrize("size", [1, 2, 3, 5])
def test_decomposition_independent_of_comm_size(size):
    mesh = _mesh_of([("a", *_grid(6, 4)), ("b", *_grid(4, 4, x0=2.0))])
    ref = decompose(mesh, Parts(3), 1)
    dec = decompose(mesh, Parts(3), size)
    for name in ("cell_sub", "sub_body", "pair_sub", "pair_node", "sub_ptr"):
        np.testing.assert_array_equal(getattr(dec, name), getattr(ref, name))
    assert np.all(np.diff(dec.sub_rank) >= 0)
    assert np.unique(dec.sub_rank).size == min(size, dec.num_subdomains)
    owned = np.concatenate([dec.local_subdomains(r) for r in range(size)])
    np.testing.assert_array_equal(np.sort(owned), np.arange(dec.num_subdomains))
    # a communicator gives the same as its size
    world = decompose(mesh, Parts(3), MPI.COMM_WORLD)
    np.testing.assert_array_equal(world.sub_rank,
                                  decompose(mesh, Parts(3), MPI.COMM_WORLD.size).sub_rank)


# ------------------------------------------------------------------------------------------
# Topology and geometry
# ------------------------------------------------------------------------------------------


def test_facet_neighbours_and_locate():
    x, cells = _grid(3, 2)
    pairs = topology.facet_neighbours(cells)
    # interior edges of a 3×2 grid: 6 diagonals + 2·2 vertical + 3·1 horizontal
    assert pairs.shape == (13, 2)
    for a, b in pairs:
        assert len(set(cells[a]) & set(cells[b])) == 2
    cell, local = topology.locate_facets(cells, np.array([[0, 1], [1, 0], [0, 11]]))
    assert cell[0] >= 0 and cell[1] == cell[0] and local[0] == local[1]
    # facet j of a cell is the one opposite its vertex j
    assert cells[cell[0], local[0]] not in (0, 1)
    assert {0, 1} <= set(cells[cell[0]])
    assert cell[2] == -1 and local[2] == -1


def test_locate_few_facets_finds_what_locate_facets_finds():
    """Among the cells on the facets' vertices: the same (first) cell and local facet, -1 for
    a facet of no cell, interior facets included."""
    x, cells = _grid(6, 5)
    pairs = topology.facet_neighbours(cells)
    interior = np.sort(cells[pairs[:3, 0]][:, :2], axis=1)  # some edges, maybe interior
    facets = np.concatenate([_boundary_facets(cells)[::3], cells[[4, 9, 17]][:, 1:],
                             interior, [[0, 41], [2, 40]]])
    want = topology.locate_facets(cells, facets)
    got = topology.locate_few_facets(cells, facets)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert np.all(got[0][-2:] == -1) and np.all(got[0][:-2] >= 0)
    empty = topology.locate_few_facets(cells, np.zeros((0, 2), dtype=np.int64))
    assert empty[0].size == 0 and empty[1].size == 0


def test_facet_normals_outward_unit_square():
    x, cells = _grid(4, 4)
    facets = _boundary_facets(cells)
    assert facets.shape[0] == 16
    n, size = topology.facet_normals(x, cells, facets)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    np.testing.assert_allclose(size, 0.25)
    mid = x[facets].mean(axis=1)
    expected = np.zeros_like(mid)
    expected[np.isclose(mid[:, 0], 0.0)] = [-1.0, 0.0]
    expected[np.isclose(mid[:, 0], 1.0)] = [1.0, 0.0]
    expected[np.isclose(mid[:, 1], 0.0)] = [0.0, -1.0]
    expected[np.isclose(mid[:, 1], 1.0)] = [0.0, 1.0]
    np.testing.assert_allclose(n, expected, atol=1e-14)
    # the order of a facet's nodes does not matter
    n2, _ = topology.facet_normals(x, cells, facets[:, ::-1])
    np.testing.assert_allclose(n2, n, atol=1e-14)


def test_facet_normals_outward_tetrahedron():
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    cells = np.array([[0, 1, 2, 3]])
    facets = topology.cell_facets(cells)[0]
    n, area = topology.facet_normals(x, cells, facets)
    centroid = x.mean(axis=0)
    outward = np.einsum("ij,ij->i", n, x[facets].mean(axis=1) - centroid)
    assert np.all(outward > 0)
    np.testing.assert_allclose(np.sort(area), [0.5, 0.5, 0.5, np.sqrt(3.0) / 2])
    np.testing.assert_allclose(topology.cell_volumes(x, cells), [1.0 / 6.0])


def test_facet_normals_reject_non_facet():
    x, cells = _grid(1, 1)
    with pytest.raises(ValueError):
        topology.facet_normals(x, cells, np.array([[1, 2]]))  # the other diagonal


def test_nodal_normals_and_areas_square():
    x, cells = _grid(5, 3, lx=2.0, ly=1.5)
    facets = _boundary_facets(cells)
    nodes, normals, areas = topology.nodal_normals_and_areas(x, cells, facets)
    np.testing.assert_array_equal(nodes, np.unique(facets))
    assert areas.sum() == pytest.approx(2 * (2.0 + 1.5))
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    corner = np.flatnonzero(np.all(np.isclose(x[nodes], [2.0, 1.5]), axis=1))
    # the area-weighted mean of the top (length 0.4, normal +y) and right (0.5, +x) edges
    np.testing.assert_allclose(normals[corner[0]], np.array([0.5, 0.4]) / np.hypot(0.5, 0.4))
    # on a side (not a corner) the normal is the side's; the lumped area is one edge
    side = np.flatnonzero(np.isclose(x[nodes, 0], 0.0) & ~np.isclose(x[nodes, 1], 0.0)
                          & ~np.isclose(x[nodes, 1], 1.5))
    np.testing.assert_allclose(normals[side], np.tile([-1.0, 0.0], (side.size, 1)), atol=1e-14)
    np.testing.assert_allclose(areas[side], 0.5)


def test_nodal_areas_one_side_and_cube_surface():
    x, cells = _grid(4, 4)
    facets = _boundary_facets(cells)
    top = facets[np.all(np.isclose(x[facets][:, :, 1], 1.0), axis=1)]
    nodes, normals, areas = topology.nodal_normals_and_areas(x, cells, top)
    assert nodes.size == 5 and areas.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(areas[[0, -1]], 0.125)
    np.testing.assert_allclose(normals, np.tile([0.0, 1.0], (5, 1)), atol=1e-14)
    # 3D: the six Kuhn tetrahedra of a unit cube; surface area 6
    corners = np.array(list(itertools.product([0.0, 1.0], repeat=3)))[:, ::-1]  # x fastest
    tets = []
    for perm in itertools.permutations(range(3)):
        path = [0]
        for axis in perm:
            path.append(path[-1] + 2**axis)
        tets.append(path)
    tets = np.array(tets)
    vol = topology.cell_volumes(corners, tets)
    assert np.abs(vol).sum() == pytest.approx(1.0)
    faces = _boundary_facets(tets)
    assert faces.shape[0] == 12
    nodes, nrm, area = topology.nodal_normals_and_areas(corners, tets, faces)
    assert area.sum() == pytest.approx(6.0)
    # every node is a corner: its normal points into the corner's outward octant
    np.testing.assert_array_equal(np.sign(nrm), np.sign(corners[nodes] - 0.5))


def test_nodal_normals_cancel():
    # two triangles touching at node 0 (a bow tie): the four edges at node 0 have outward
    # normals (0,-1), (-1,0), (0,1), (1,0) of equal length, which cancel
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    cells = np.array([[0, 1, 2], [0, 3, 4]])
    edges = np.array([[0, 1], [0, 2], [0, 3], [0, 4]])
    with pytest.raises(ValueError, match="cancel"):
        topology.nodal_normals_and_areas(x, cells, edges)
    nodes, normals, _ = topology.nodal_normals_and_areas(x, cells, edges[:2])
    np.testing.assert_allclose(normals[0], -np.ones(2) / np.sqrt(2.0))
