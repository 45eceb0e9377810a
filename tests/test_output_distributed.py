"""Output Functions filled from the distributed solution (no array of the whole mesh's values):
the directory exchange, and the Functions against the gathered nodal values."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.output import node_values

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


def test_functions_equal_the_gathered_values(solution):
    u = solution.u
    V = u.function_space
    node = compat.node_input_indices(V.mesh)[compat.vertex_dof_nodes(V)]
    assert np.allclose(u.x.array.reshape(-1, 3), solution.nodal_values()[node],
                       rtol=0, atol=1e-15 * np.abs(solution.nodal_values()).max())
    p = solution.pressure_function()
    full = np.zeros(solution.dec.num_nodes)
    np.add.at(full, solution.contact.node, solution.contact.pressure)
    assert np.array_equal(p.x.array, full[node])
    assert COMM.allreduce(float(np.abs(p.x.array).max()), op=MPI.MAX) > 0


def test_xdmf_is_written(solution, tmp_path_factory):
    path = COMM.bcast(str(tmp_path_factory.mktemp("xdmf") / "sol.xdmf"), root=0)
    solution.write_xdmf(path)
    from pathlib import Path

    assert Path(path).is_file() and Path(path).with_suffix(".h5").is_file()


def test_von_mises_from_the_local_cells(solution):
    from dolfinx_feti.postprocess import output_functions, von_mises

    vm = {f.name: f for f in output_functions(solution)}["von_mises"]
    Q = vm.function_space
    cells = compat.cell_input_indices(Q.mesh)
    dofs = compat.cell_dofs(Q).ravel()[:cells.size]
    ref = von_mises(solution.problem.mesh, solution.nodal_values(), 1000.0, 0.3)
    assert np.allclose(vm.x.array[dofs], ref[cells], rtol=1e-10, atol=1e-12 * ref.max())
