"""Output Functions filled from the distributed solution (no array of the whole mesh's values):
the directory exchange, and the Functions against the gathered nodal values."""

from __future__ import annotations

import element_models as em
import numpy as np
import pytest
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.fem.dofmap import dof_points_of_space
from dolfinx_feti.results.output import distributed_function, node_values

COMM = MPI.COMM_WORLD


def test_node_values_is_the_mean_over_all_ranks_pairs():
    rng = np.random.default_rng(0)  # the same global data on every rank
    N, pairs, bs = 50, 400, 2
    nodes = rng.integers(0, N - 5, pairs)  # the last 5 nodes have no pair
    vals = rng.standard_normal((pairs, bs))
    mine = np.arange(pairs) % COMM.size == COMM.rank
    wanted = rng.permutation(N)[: 30 + 3 * COMM.rank]
    got = node_values(nodes[mine], vals[mine], wanted, N, COMM)
    acc = np.zeros((N, bs))
    np.add.at(acc, nodes, vals)
    mean = acc / np.maximum(np.bincount(nodes, minlength=N), 1)[:, None]
    assert np.allclose(got, mean[wanted], rtol=1e-14, atol=1e-14)


@pytest.fixture(scope="module")
def solution():
    mesh = df.read_gmsh("meshes/blocks3d.msh")
    return df.solve(df.ContactProblem(
        mesh, df.Elasticity(1000.0, 0.3, tractions={"top": (0.0, 0.0, -1.0)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sides_upper", components=[0, 1])],
        contact=[df.NodeToNode("contact_upper", "contact_lower")], decomposition=df.Parts(2)),
        rtol=1e-10)


def dof_point_of_each_dof(V, points):
    """The global dof point of each local dof of a Function space on a parent mesh."""
    return dof_points_of_space(V, compat.node_input_indices(V.mesh), points)


def check_against_gathered(solution, degree=None):
    """solution.u and the pressure Function equal the gathered nodal values at every dof."""
    points = solution.problem.dof_points
    bs = solution.problem.value_size
    u = solution.u
    node = dof_point_of_each_dof(u.function_space, points)
    nodal = solution.nodal_values()
    assert np.allclose(u.x.array.reshape(-1, bs), nodal[node],
                       rtol=0, atol=1e-15 * np.abs(nodal).max())
    full = np.zeros(solution.share.num_points)
    np.add.at(full, solution.contact.node, solution.contact.pressure)
    p = solution.pressure_function()
    assert np.array_equal(p.x.array, full[dof_point_of_each_dof(p.function_space, points)])
    assert COMM.allreduce(float(np.abs(p.x.array).max()), op=MPI.MAX) > 0
    if points.degree == 2:  # degree-1 Functions of the degree-2 values: the vertex values
        p1 = solution.pressure_function(degree=1)
        vertex = dof_point_of_each_dof(p1.function_space, df.mesh.dofpoints.dof_points(
            solution.problem.mesh, 1))
        assert compat.space_degree(p1.function_space) == 1
        assert np.array_equal(p1.x.array, full[vertex])
        share = solution.share
        u1 = distributed_function(solution.problem.mesh, share.pair_points,
                                  solution.u_vec.array_r.reshape(-1, bs), COMM, "u1", points,
                                  degree=1)
        assert np.allclose(u1.x.array.reshape(-1, bs),
                           nodal[dof_point_of_each_dof(u1.function_space, points)],
                           rtol=0, atol=1e-15 * np.abs(nodal).max())


def test_functions_equal_the_gathered_values(solution):
    check_against_gathered(solution)


@pytest.mark.parametrize("quads", [False, True], ids=["P2-triangles", "Q2-quadrilaterals"])
def test_degree2_functions_equal_the_gathered_values(quads):
    """Degree 2 (edge and face dofs) on triangles and quadrilaterals, with contact."""
    mesh = df.build_mesh(em.rectangle, quads=quads)
    sol = df.solve(df.ContactProblem(
        mesh, df.Elasticity(100.0, 0.3, tractions={"top": (0.0, -1.0)}, degree=2),
        dirichlet=[df.Dirichlet("left", components=[0])],
        contact=[df.RigidObstacle("bottom", df.Plane((0.0, 0.0), (0.0, 1.0)))],
        decomposition=df.Parts(3)), rtol=1e-10)
    check_against_gathered(sol)


def test_q2_hexahedra_function_equals_the_gathered_values():
    mesh = df.build_mesh(em.box, hexes=True)
    sol = df.solve(df.ContactProblem(
        mesh, df.Elasticity(100.0, 0.3, tractions={"z1": (0.0, 0.0, -1.0)}, degree=2),
        dirichlet=[df.Dirichlet("x0", components=[0]), df.Dirichlet("y0", components=[1])],
        contact=[df.RigidObstacle("z0", df.Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)))],
        decomposition=df.Parts(3)), rtol=1e-10)
    check_against_gathered(sol)


def test_xdmf_is_written(solution, tmp_path_factory):
    path = COMM.bcast(str(tmp_path_factory.mktemp("xdmf") / "sol.xdmf"), root=0)
    solution.write_xdmf(path)
    from pathlib import Path

    assert Path(path).is_file() and Path(path).with_suffix(".h5").is_file()


def test_von_mises_from_the_local_cells(solution):
    from dolfinx_feti.results.postprocess import output_functions, von_mises

    vm = {f.name: f for f in output_functions(solution)}["von_mises"]
    Q = vm.function_space
    cells = compat.cell_input_indices(Q.mesh)
    dofs = compat.cell_dofs(Q).ravel()[:cells.size]
    ref = von_mises(solution.problem.mesh, solution.nodal_values(), 1000.0, 0.3)
    assert np.allclose(vm.x.array[dofs], ref[cells], rtol=1e-10, atol=1e-12 * ref.max())
