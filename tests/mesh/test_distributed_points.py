"""Dof points and the point → subdomain directory on a distributed mesh (mesh.distributed_points).

Every rank builds the same small global mesh, keeps a block of its cells as the scatter of the
distributed set-up would (even blocks, uneven blocks, rank 0 without cells), runs the
distributed functions, and compares with the serial dof points and decomposition of the whole
mesh restricted to its cells: the numbers must be equal, not close. Run serially and under
``mpirun -n 2`` (and by hand on 3 ranks).
"""

from __future__ import annotations

import dataclasses

import element_models as em
import numpy as np
import pytest
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.errors import InputError
from dolfinx_feti.io import meshes
from dolfinx_feti.mesh import distributed_points as dp
from dolfinx_feti.mesh.decompose import Parts, decompose
from dolfinx_feti.mesh.dofpoints import dof_points
from dolfinx_feti.mesh.topology import REFERENCE, row_keys

COMM = MPI.COMM_WORLD

#: name → (generator of the MeshData, parts per body).
MESHES = {
    "triangles, two bodies": (lambda: df.build_mesh(meshes.membranes, 4, gdim=2), 3),
    "quadrilaterals": (lambda: df.build_mesh(em.rectangle, quads=True, gdim=2), 4),
    "tetrahedra, two bodies": (lambda: df.build_mesh(meshes.blocks3d, 2), 2),
    "hexahedra": (lambda: df.build_mesh(em.box, hexes=True, n=3), 3),
    # 50 653 vertices: the keys of the faces (4 vertices) and cells (8) do not fit an int64
    "hexahedra, byte keys": (lambda: shuffled(em.distorted_hexahedra(n=36)), 5),
}


def shuffled(mesh: df.MeshData) -> df.MeshData:
    """The mesh with its vertices renumbered at random: a cell's vertices no longer ascend, as
    on gmsh's unstructured meshes (the two cells of a face list its vertices in other orders)."""
    perm = np.random.default_rng(3).permutation(mesh.num_nodes)
    new = np.argsort(perm)  # old number → new number
    return dataclasses.replace(mesh, x=mesh.x[perm], cells=new[mesh.cells],
                               facet_groups={k: new[f] for k, f in mesh.facet_groups.items()},
                               node_tags=mesh.node_tags[perm])


def blocks(num_cells: int, split: str, size: int = COMM.size) -> np.ndarray:
    """The first cell of each rank's contiguous block (and the end), as a scatter would give."""
    if split == "even":
        weights = np.ones(size)
    elif split == "uneven":
        weights = np.arange(1, size + 1) ** 2.0
    else:  # "rank 0 empty" (on one rank the whole mesh)
        weights = np.r_[0.0 if size > 1 else 1.0, np.ones(size - 1)]
    return np.r_[0, np.round(np.cumsum(weights) / weights.sum() * num_cells)].astype(np.int64)


_SERIAL: dict = {}


def serial(name: str, degree: int):
    """The mesh, its serial dof points and decomposition (built once per module)."""
    if (name, degree) not in _SERIAL:
        if name not in _SERIAL:
            make, _ = MESHES[name]
            _SERIAL[name] = make()
        mesh = _SERIAL[name]
        points = dof_points(mesh, degree)
        dec = decompose(mesh, Parts(MESHES[name][1]), COMM.size, points)
        _SERIAL[name, degree] = mesh, points, dec
    return _SERIAL[name, degree]


class Local:
    """The share of a rank after the scatter: its block of cells and their data."""

    def __init__(self, name: str, degree: int, split: str):
        self.mesh, self.points, self.dec = serial(name, degree)
        lo = blocks(self.mesh.num_cells, split)
        self.ids = np.arange(lo[COMM.rank], lo[COMM.rank + 1])
        self.cells = self.mesh.cells[self.ids]
        self.cell_x = self.mesh.x[self.cells]
        self.cell_sub = self.dec.cell_sub[self.ids]
        self.degree = degree

    def number(self):
        return dp.number_points(self.cells, self.mesh.cell_type, self.degree,
                                self.mesh.num_nodes, COMM)


CASES = [pytest.param(name, degree, split, id=f"{name}-P{degree}-{split}")
         for name in MESHES for degree in (1, 2) for split in ("even", "uneven", "rank 0 empty")]


@pytest.mark.parametrize("name,degree,split", CASES)
def test_points_are_the_serial_points(name, degree, split):
    """Point numbers, their total and the first point of each dimension, as in the serial code;
    the coordinates bit for bit."""
    loc = Local(name, degree, split)
    cell_points, num_points, first = loc.number()
    assert cell_points.dtype == np.int64
    assert np.array_equal(cell_points, loc.points.cell_points[loc.ids])
    assert num_points == loc.points.num_points
    assert first == {dim: offset for dim, (_, offset) in loc.points.entities.items()}
    points, x = dp.point_coordinates(cell_points, loc.cells, loc.cell_x, loc.mesh.cell_type,
                                     degree)
    assert np.array_equal(points, np.unique(loc.points.cell_points[loc.ids]))
    assert np.array_equal(x, loc.points.x[points])


@pytest.mark.parametrize("name,degree,split", CASES)
def test_point_subdomains_are_the_serial_directory(name, degree, split):
    """Each local point's subdomains over all ranks and the subdomain sizes, as in the serial
    decomposition; owners and the migration deliver exactly the cells of the rank's subdomains,
    whose directory is again the serial one."""
    loc = Local(name, degree, split)
    cell_points, num_points, _ = loc.number()
    nsub = loc.dec.num_subdomains
    points, ptr, subs, sub_size = dp.point_subdomains(cell_points, loc.cell_sub, num_points,
                                                      nsub, COMM)
    check_directory(loc.dec, points, ptr, subs, np.unique(cell_points))
    assert np.array_equal(sub_size, np.diff(loc.dec.sub_ptr))

    sub_rank = dp.owners(sub_size, COMM.size)
    assert np.array_equal(sub_rank, loc.dec.sub_rank)
    moved = dp.migrate(sub_rank[loc.cell_sub], loc.cells, loc.cell_x, loc.mesh.cell_body[loc.ids],
                       loc.ids, loc.cell_sub, cell_points, comm=COMM)
    cells, cell_x, body, ids, cell_sub, moved_points = moved
    want = np.flatnonzero(loc.dec.sub_rank[loc.dec.cell_sub] == COMM.rank)
    assert np.array_equal(ids, want)
    assert np.array_equal(cells, loc.mesh.cells[want])
    assert np.array_equal(cell_x, loc.mesh.x[loc.mesh.cells[want]])
    assert np.array_equal(body, loc.mesh.cell_body[want])
    assert np.array_equal(cell_sub, loc.dec.cell_sub[want])
    assert np.array_equal(moved_points, loc.points.cell_points[want])
    assert cells.dtype == loc.cells.dtype and cell_sub.dtype == loc.cell_sub.dtype
    points, ptr, subs, again = dp.point_subdomains(moved_points, cell_sub, num_points, nsub, COMM)
    check_directory(loc.dec, points, ptr, subs, np.unique(loc.points.cell_points[want]))
    assert np.array_equal(again, sub_size)
    # a directory built before the move answers for the moved cells' points
    before = dp.SubdomainDirectory(cell_points, loc.cell_sub, num_points, nsub, COMM)
    assert np.array_equal(before.sub_size, sub_size)
    asked_ptr, asked_subs = before.ask(points)
    assert np.array_equal(asked_ptr, ptr) and np.array_equal(asked_subs, subs)
    # from the migrated cells (no longer blocks of ascending ids), dealt out round robin
    ids, cells = dp.migrate(ids % COMM.size, ids, cells, comm=COMM, key=ids)
    want = np.flatnonzero(np.arange(loc.mesh.num_cells) % COMM.size == COMM.rank)
    assert np.array_equal(ids, want)
    assert np.array_equal(cells, loc.mesh.cells[want])


def check_directory(dec, points, ptr, subs, want_points):
    """The directory of ``points`` is the serial ``node_subdomains`` of those points."""
    assert np.array_equal(points, want_points)
    sptr, ssubs = dec.node_subdomains()
    start, stop = sptr[points], sptr[points + 1]
    assert np.array_equal(np.diff(ptr), stop - start)
    assert np.array_equal(subs, ssubs[dp.index_ranges(start, stop - start)])


def test_hexahedron_keys_are_bytes_on_the_large_mesh():
    """The large hexahedral case exercises the byte keys: faces and interiors are void keys,
    whose order is bytewise (not that of the vertex numbers)."""
    mesh = serial("hexahedra, byte keys", 2)[0]
    faces = mesh.cells[:, np.array(REFERENCE["hexahedron"].facets)].reshape(-1, 4)
    assert row_keys(faces, mesh.num_nodes).dtype.kind == "V"
    assert row_keys(mesh.cells, mesh.num_nodes).dtype.kind == "V"
    edges = mesh.cells[:, np.array(REFERENCE["hexahedron"].edges)].reshape(-1, 2)
    assert row_keys(edges, mesh.num_nodes).dtype == np.int64


@pytest.mark.parametrize("kind", ["int64", "void"])
def test_sample_sort_ranks_keys_in_the_union(kind):
    """_rank_in_union on skewed keys with many shared between ranks: each key's position in
    the sorted union of all ranks' keys, as np.unique of the union orders them."""
    rng = np.random.default_rng(7)
    everyone = [np.unique(_keys(rng, kind, 50 * (r % 3) + 5)) for r in range(COMM.size)]
    first = everyone[0] if COMM.rank == 0 else everyone[0][:0]  # the keys of rank 0 alone
    numbers, totals = dp._rank_in_union([everyone[COMM.rank], first], COMM)
    union = np.unique(np.concatenate(everyone))
    assert totals == [union.size, everyone[0].size]
    assert np.array_equal(union[numbers[0]], everyone[COMM.rank])
    assert np.array_equal(everyone[0][numbers[1]], first)


def _keys(rng, kind, n):
    """Keys of random sorted rows of small integers: many repeats, skewed (squared) values."""
    rows = np.sort(rng.integers(0, 6, (n, 4)) ** 2, axis=1)
    return row_keys(rows, 36 if kind == "int64" else None)


def test_bad_input_raises_on_every_rank():
    """A fault on one rank (the last) raises InputError on all, with no hang."""
    last = COMM.rank == COMM.size - 1
    cells = np.array([[0, 1, 2], [1, 2, 3 + 10 * last]])
    with pytest.raises(InputError, match="cells has entries outside"):
        dp.number_points(cells, "triangle", 2, 4, COMM)
    with pytest.raises(InputError, match="degree 3"):
        dp.number_points(cells[:1], "triangle", 3, 4, COMM)
    with pytest.raises(InputError, match="need 3 vertices"):
        dp.number_points(np.zeros((1, 2 if last else 3), dtype=np.int64), "triangle", 1, 4, COMM)
    with pytest.raises(InputError, match="cell_sub has entries outside"):
        dp.point_subdomains(cells[:1], np.array([2 * last]), 4, 1, COMM)
    with pytest.raises(InputError, match="dest"):
        dp.migrate(np.array([COMM.size * last]), np.array([0]), comm=COMM)
    with pytest.raises(InputError, match="array 1 has shape"):
        dp.migrate(np.array([0]), np.array([0]), np.zeros(1 + last), comm=COMM)
    with pytest.raises(InputError, match="key has shape"):
        dp.migrate(np.array([0]), np.array([0]), comm=COMM, key=np.zeros(1 + last))
