"""Parts merges the pieces a cut leaves apart: connected subdomains, about n per body.

The rule (:mod:`dolfinx_feti.mesh.connected_parts`) on hand-made piece graphs, on meshes whose
bisections fall apart (a U, a mesh graded toward a point), and the distributed version against
the serial one on every split of the cells (serially and under mpirun).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from mpi4py import MPI
from scipy.sparse.csgraph import connected_components
from test_decompose import _mesh_of
from test_distributed_decompose import SPLITS, _mine, _structured, _u_shape

from dolfinx_feti.mesh.connected_parts import merge_plan
from dolfinx_feti.mesh.decompose import ByTags, Parts, _split_components, decompose
from dolfinx_feti.mesh.distributed_decompose import decompose_distributed
from dolfinx_feti.mesh.topology import facet_neighbours

COMM = MPI.COMM_WORLD


def _graded(cell_type: str = "triangle", n: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """A structured grid pulled toward the corner (0, 0): cells shrink like x², as a mesh graded
    toward a contact point does (equal-cell bisections give thin parts that fall apart)."""
    x, cells = _structured(cell_type, (n, n) if cell_type in ("triangle", "quadrilateral")
                           else (n, n, n // 3))
    x = x / n
    r = np.linalg.norm(x, axis=1, keepdims=True)
    return x * np.where(r > 0, r, 1.0) ** 1.5, cells


def _components(mesh, cell_sub) -> int:
    """The connected (through facets) pieces of equal subdomain."""
    pairs = facet_neighbours(mesh.cells, mesh.cell_type)
    keep = cell_sub[pairs[:, 0]] == cell_sub[pairs[:, 1]]
    n = cell_sub.size
    g = sp.coo_matrix((np.ones(keep.sum()), (pairs[keep, 0], pairs[keep, 1])), shape=(n, n))
    return connected_components(g, directed=False)[0]


MESHES = {
    "u_shape": lambda: _mesh_of([("u", *_u_shape("triangle", 15))]),
    "graded": lambda: _mesh_of([("g", *_graded())]),
    "graded_tets_two_bodies": lambda: _mesh_of([
        ("a", *_graded("tetrahedron", 12)),
        ("b", *_structured("tetrahedron", (4, 4, 2), origin=(2.0, 0.0, 0.0)))],
        cell_type="tetrahedron"),
}


@pytest.mark.parametrize("name", sorted(MESHES))
@pytest.mark.parametrize("n", [3, 8, 13])
def test_parts_are_connected_and_as_many_as_asked(name, n):
    mesh = MESHES[name]()
    pieces = decompose(mesh, Parts(n, merge=False), 1)
    dec = decompose(mesh, Parts(n), 1)
    nb = len(mesh.body_names)
    assert dec.num_subdomains == _components(mesh, dec.cell_sub)  # each one piece
    assert dec.num_subdomains <= nb * n < pieces.num_subdomains or \
        dec.num_subdomains == pieces.num_subdomains
    assert dec.num_subdomains >= nb * n - 1  # a part can only vanish into pieces, rarely
    # merged only: every piece lies inside one subdomain, and bodies are not mixed
    for p in range(pieces.num_subdomains):
        assert np.unique(dec.cell_sub[pieces.cell_sub == p]).size == 1
    for s in range(dec.num_subdomains):
        assert np.unique(mesh.cell_body[dec.cell_sub == s]).size == 1
    # numbered by their first cell, as pieces are
    first = np.array([np.flatnonzero(dec.cell_sub == s)[0] for s in range(dec.num_subdomains)])
    assert np.all(np.diff(first) > 0)


def test_cases_fall_apart_without_the_merge():
    for name, n in (("u_shape", 3), ("graded", 8), ("graded_tets_two_bodies", 8)):
        mesh = MESHES[name]()
        assert decompose(mesh, Parts(n, merge=False), 1).num_subdomains > \
            len(mesh.body_names) * n


def test_merged_parts_stay_balanced():
    """The fragments are small: merging them keeps the equal-cell balance within 25 %."""
    mesh = MESHES["graded"]()
    size = np.bincount(decompose(mesh, Parts(8), 1).cell_sub)
    assert size.max() <= 1.25 * mesh.cells.shape[0] / 8


def test_plan_rules():
    # part 0: pieces 0 (10 cells) and 2 (1 cell); part 1: piece 1 (9 cells); piece 2 touches
    # piece 1 only: it joins piece 1
    plan = merge_plan(np.array([10, 9, 1]), np.array([0, 1, 0]), np.zeros(3, np.int64),
                      np.array([[0, 1, 5], [1, 2, 2]]))
    np.testing.assert_array_equal(plan, [0, 1, 1])
    # the fragment goes where it shares the most facets; ties to the first piece
    size, label = np.array([10, 9, 1]), np.array([0, 1, 0])
    body = np.zeros(3, np.int64)
    assert merge_plan(size, label, body, np.array([[0, 2, 1], [1, 2, 3]]))[2] == 1
    assert merge_plan(size, label, body, np.array([[0, 2, 3], [1, 2, 3]]))[2] == 0
    # big pieces of a part stay (at least half the mean part size)
    plan = merge_plan(np.array([10, 9, 7]), np.array([0, 1, 0]), body,
                      np.array([[0, 1, 5], [1, 2, 2]]))
    np.testing.assert_array_equal(plan, [0, 1, 2])
    # never across bodies: a fragment touching only another body stays alone
    plan = merge_plan(np.array([10, 9, 1]), np.array([0, 1, 0]), np.array([0, 1, 0]),
                      np.array([[1, 2, 4]]))
    np.testing.assert_array_equal(plan, [0, 1, 2])
    # two fragments touching only each other: one subdomain; numbering by the first piece
    plan = merge_plan(np.array([1, 10, 1, 9]), np.array([0, 0, 1, 1]), np.zeros(4, np.int64),
                      np.array([[0, 2, 1]]))
    np.testing.assert_array_equal(plan, [0, 1, 0, 2])
    assert merge_plan(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64),
                      np.zeros((0, 3), np.int64)).size == 0


def test_other_decompositions_do_not_merge():
    mesh = MESHES["u_shape"]()
    np.testing.assert_array_equal(decompose(mesh, ByTags(), 1).cell_sub,
                                  _split_components(mesh.cells, mesh.cell_body.astype(np.int64)))


@pytest.mark.parametrize("split", SPLITS)
@pytest.mark.parametrize("name", sorted(MESHES))
def test_distributed_merge_is_the_serial_one(name, split):
    mesh = MESHES[name]()
    for how in (Parts(8), Parts(5, balance="volume")):
        ref = decompose(mesh, how, 1)
        ids = _mine(mesh.cells.shape[0], split, seed=mesh.cells.shape[0])
        cells = mesh.cells[ids]
        sub, sub_body = decompose_distributed(cells, mesh.x[cells], ids, mesh.cell_body[ids],
                                              mesh.cell_type, mesh.body_names,
                                              mesh.cells.shape[0], how, COMM)
        np.testing.assert_array_equal(sub, ref.cell_sub[ids])
        assert sub.dtype == ref.cell_sub.dtype
        np.testing.assert_array_equal(sub_body, ref.sub_body)
