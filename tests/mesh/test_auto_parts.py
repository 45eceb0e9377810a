"""Auto(): the default decomposition, Parts by the mesh's size and the number of ranks."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from test_connected_parts import MESHES
from test_decompose import _grid, _mesh_of
from test_distributed_decompose import _mine

import dolfinx_feti as df
from dolfinx_feti.mesh.auto_parts import MIN_CELLS, TARGET_CELLS, Auto, auto_parts
from dolfinx_feti.mesh.decompose import ByTags, decompose
from dolfinx_feti.mesh.distributed_decompose import decompose_distributed

COMM = MPI.COMM_WORLD


def test_parts_by_size():
    t = TARGET_CELLS["tetrahedron"]
    how = auto_parts(Auto(), [10 * t, 3 * t + 1, t // 3], ["a", "b", "c"], "tetrahedron", 1)
    assert how == {"a": 10, "b": 3, "c": 1}
    assert auto_parts(Auto(cells=100), [1000], ["a"], "triangle", 1) == {"a": 10}


def test_one_subdomain_per_rank_or_more_on_large_meshes():
    # 4 ranks, a mesh of one part: four parts, shared by the bodies by their size
    t = TARGET_CELLS["triangle"]
    how = auto_parts(Auto(), [t // 2, t // 4], ["a", "b"], "triangle", 4)
    assert sum(how.values()) == (4 if 3 * t // 4 >= 4 * MIN_CELLS else 2)
    how = auto_parts(Auto(cells=10**6), [3 * MIN_CELLS, MIN_CELLS], ["a", "b"], "triangle", 4)
    assert how == {"a": 3, "b": 1}
    # a small mesh keeps one part per body however many ranks
    assert auto_parts(Auto(), [MIN_CELLS], ["a"], "triangle", 2) == {"a": 1}
    # never more parts than enough: 3 ranks, parts by size already more
    how = auto_parts(Auto(cells=100), [1000, 500], ["a", "b"], "triangle", 3)
    assert how == {"a": 10, "b": 5}


def test_small_meshes_keep_one_subdomain_per_body():
    """Below a part's size Auto() is ByTags(): the same subdomains, numbered alike."""
    mesh = _mesh_of([("a", *_grid(6, 6)), ("b", *_grid(3, 3, x0=2.0))])
    for size in (1, 2, 4):
        np.testing.assert_array_equal(decompose(mesh, Auto(), size).cell_sub,
                                      decompose(mesh, ByTags(), size).cell_sub)


def test_the_default_of_a_problem():
    mesh = _mesh_of([("a", *_grid(2, 2))])
    problem = df.ContactProblem(mesh, df.Elasticity(1.0, 0.3))
    assert problem.decomposition == Auto()
    with pytest.raises(df.InputError, match="cells"):
        Auto(cells=0)


@pytest.mark.parametrize("name", sorted(MESHES))
def test_distributed_auto_is_the_serial_one(name):
    mesh = MESHES[name]()
    how = Auto(cells=mesh.cells.shape[0] // 7)
    ref = decompose(mesh, how, COMM.size)
    assert ref.num_subdomains >= 7 * len(mesh.body_names) // 2
    ids = _mine(mesh.cells.shape[0], "uneven")
    cells = mesh.cells[ids]
    sub, sub_body = decompose_distributed(cells, mesh.x[cells], ids, mesh.cell_body[ids],
                                          mesh.cell_type, mesh.body_names,
                                          mesh.cells.shape[0], how, COMM)
    np.testing.assert_array_equal(sub, ref.cell_sub[ids])
    np.testing.assert_array_equal(sub_body, ref.sub_body)
