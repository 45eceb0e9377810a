"""What a rank holds after the set-up (dolfinx_feti.setup.share): its part, not the whole problem.

Under ``mpirun -n 2`` each rank must hold about half of the cells, dof points, pairs and rows,
and the shares together must be exactly the global decomposition and rows that rank 0 built.
"""

from __future__ import annotations

from dataclasses import fields

import element_models as em
import numpy as np
import pytest
import reference as ref
from mpi4py import MPI
from serial_setup import build_rows, share_out

import dolfinx_feti as df
from dolfinx_feti.constraints import Rows
from dolfinx_feti.mesh.decompose import decompose
from dolfinx_feti.mesh.dofpoints import degree2_entities
from dolfinx_feti.mesh.topology import row_keys

COMM = MPI.COMM_WORLD


def membranes(mesh, degree):
    """B1's two membranes in contact, Parts(8) per membrane."""
    return df.ContactProblem(
        mesh, df.Poisson(source=ref.membrane_source, degree=degree),
        dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")],
        decomposition=df.Parts(8))


@pytest.fixture(scope="module", params=[1, 2], ids=["P1", "P2"])
def case(root, request):
    problem = membranes(df.read_gmsh(root / "meshes/membranes_8.msh"), request.param)
    return problem, df.dual_qp(problem)


def test_shares_partition_the_cells_and_subdomains(case):
    problem, qp = case
    share = qp.share
    cells = np.concatenate(COMM.allgather(share.cell_ids))
    assert np.array_equal(np.sort(cells), np.arange(problem.mesh.cells.shape[0]))
    subs = np.concatenate(COMM.allgather(share.dec.subs))
    assert np.array_equal(subs, np.arange(share.dec.num_subdomains))
    assert share.mesh.cells.shape[0] == share.cell_ids.size


def test_a_rank_holds_about_its_part(case):
    """On n ranks no rank's share is much more than 1/n of the problem (the test's point)."""
    problem, qp = case
    share, n = qp.share, COMM.size
    C, N = problem.mesh.cells.shape[0], problem.dof_points.num_points
    bound = 1.0 / n + 0.15 if n > 1 else 1.0  # interface points are held by two ranks
    assert share.cell_ids.size <= bound * C
    assert share.point_ids.size <= bound * N
    assert share.mesh.x.shape[0] <= bound * problem.mesh.num_nodes
    assert share.points.x.shape[0] == share.point_ids.size
    assert share.dec.pair_node.size <= bound * COMM.allreduce(share.dec.pair_node.size)
    assert share.rows.own.size <= bound * share.rows.size
    # every array of the share besides the per-subdomain and contact data is local
    for name, a in (("cells", share.mesh.cells), ("cell_sub", share.dec.cell_sub),
                    ("cell_points", share.points.cell_points)):
        assert a.shape[0] == share.cell_ids.size, name


def test_shares_are_the_global_decomposition_and_rows(case):
    problem, qp = case
    share = qp.share
    dec = decompose(problem.mesh, problem.decomposition, COMM.size, problem.dof_points)
    rows = build_rows(problem, dec)
    # the local dof points are the global ones in the same order
    pairs = dec.rank_pairs(COMM.rank)
    assert np.array_equal(share.pair_points, dec.pair_node[pairs])
    assert np.allclose(share.points.x, problem.dof_points.x[share.point_ids])
    # the rows, stacked in rank order, are rank 0's global rows
    own = COMM.allgather(share.rows.own)
    starts = COMM.allgather(share.rows.start)
    assert starts == list(np.cumsum([0] + [o.size for o in own[:-1]]))
    for f in fields(Rows):
        parts = [getattr(o, f.name) + (s if f.name == "e_row" else 0)
                 for o, s in zip(own, starts, strict=True)]
        assert np.array_equal(np.concatenate(parts), getattr(rows, f.name)), f.name
    # the columns are the global primal dofs of the entries
    col = problem.value_size * dec.pair_index(rows.e_sub, rows.e_node) + rows.e_comp
    assert np.array_equal(np.concatenate(COMM.allgather(share.rows.cols)), col)
    c = share.rows.contact
    assert np.array_equal(share.rows.contact_index,
                          np.flatnonzero(rows.inequality | rows.tangential))
    assert np.array_equal(c.node, rows.node[share.rows.contact_index])


def test_solution_from_shares_matches_one_rank(case, root):
    """The solve on the shares gives the solution of the whole problem on one rank."""
    problem, _ = case
    sol = df.solve(problem, rtol=1e-10)
    assert sol.report.converged
    if COMM.size == 1:
        return
    one = None
    if COMM.rank == 0:
        mesh = df.read_gmsh(root / "meshes/membranes_8.msh", comm=MPI.COMM_SELF)
        p1 = df.ContactProblem(mesh, problem.forms, dirichlet=problem.dirichlet,
                               contact=problem.contact, decomposition=problem.decomposition)
        one = df.solve(p1, comm=MPI.COMM_SELF, rtol=1e-10).nodal_values()
    one = COMM.bcast(one, root=0)
    assert ref.rel_max_diff(sol.nodal_values(), one) <= 1e-8


def test_entity_keys_sort_as_the_sorted_rows():
    """Integer and byte keys order entities as their sorted vertex rows, lexicographically.

    A rank numbers its local degree-2 entities by their keys in local vertex numbers and takes
    that for the global order; it is, because a monotone renumbering keeps lexicographic order.
    Byte keys of little-endian integers sorted otherwise once a vertex number reached 256.
    """
    rng = np.random.default_rng(1)
    small = rng.permuted(rng.integers(0, 150, (400, 8)), axis=1)  # local vertex numbers
    rows = 13 * small + 7  # global ones: a monotone renumbering, crossing 256
    s = np.sort(rows, axis=1)
    want = np.lexsort(s.T[::-1])
    keys = row_keys(rows, int(rows.max()) + 1)
    assert keys.dtype.kind == "V"  # 1958**8 > 2**62: the rows' bytes
    assert np.array_equal(np.argsort(keys, kind="stable"), want)
    assert np.array_equal(np.argsort(row_keys(rows), kind="stable"), want)
    local = row_keys(small, 150)
    assert local.dtype.kind == "i"  # 150**8 < 2**62: int64 keys, the same order
    assert np.array_equal(np.argsort(local, kind="stable"), want)


def hexahedra_q2(comm=COMM, distribute: bool = False):
    """Degree-2 elasticity on 6³ hexahedra: 343 vertices, so cell keys are bytes."""
    mesh = df.build_mesh(em.box, True, 6, comm=comm, distribute=distribute)
    return df.ContactProblem(
        mesh, df.Elasticity(1.0, 0.3, degree=2, tractions={"x1": (0.0, 0.0, -0.1)}),
        dirichlet=[df.Dirichlet("x0"),
                   df.Dirichlet("z0", lambda x: 0.01 * x[:, 0], components=[2])],
        decomposition=df.Parts(4))


@pytest.fixture(scope="module")
def hexahedra():
    return hexahedra_q2()


def test_a_share_looks_up_its_degree2_entities_as_the_whole_mesh(hexahedra):
    """Every edge, face and interior point of a rank's cells is found by its local vertices."""
    dec = decompose(hexahedra.mesh, hexahedra.decomposition, COMM.size, hexahedra.dof_points)
    share = share_out(hexahedra.mesh, hexahedra.dof_points, dec, build_rows(hexahedra, dec), 3,
                      COMM)
    points, cells = share.points, share.mesh.cells
    assert np.array_equal(share.point_ids[points.cell_points],
                          hexahedra.dof_points.cell_points[share.cell_ids])
    column = cells.shape[1]
    for dim, local in degree2_entities("hexahedron"):
        v = cells[:, np.array(local)]
        got = points.lookup(dim, v.reshape(-1, v.shape[2])).reshape(v.shape[:2])
        assert np.array_equal(got, points.cell_points[:, column:column + len(local)]), dim
        column += len(local)


def test_degree2_hexahedra_give_the_one_rank_solution(hexahedra):
    sol = df.solve(hexahedra, method="tfeti", rtol=1e-10)
    assert sol.report.converged
    if COMM.size == 1:
        return
    one = None
    if COMM.rank == 0:
        p1 = hexahedra_q2(MPI.COMM_SELF)
        one = df.solve(p1, comm=MPI.COMM_SELF, method="tfeti", rtol=1e-10).nodal_values()
    one = COMM.bcast(one, root=0)
    assert ref.rel_max_diff(sol.nodal_values(), one) <= 1e-8


@pytest.mark.parametrize("degree", [1, 2], ids=["P1", "P2"])
def test_a_mesh_only_rank_0_holds_gives_the_same_solution(root, degree, tmp_path_factory):
    """read_gmsh(replicate=False): no other rank holds the mesh; solution and output unchanged."""
    path = root / "meshes/membranes_8.msh"
    held = df.read_gmsh(path, replicate=False)
    whole = df.read_gmsh(path)
    if COMM.rank > 0:
        assert held.x.shape[0] == held.cells.shape[0] == 0
        assert held.num_cells == whole.cells.shape[0] and held.num_nodes == whole.num_nodes
    a = df.solve(membranes(held, degree), rtol=1e-10)
    b = df.solve(membranes(whole, degree), rtol=1e-10)
    assert a.report.converged and b.report.sizes == a.report.sizes
    on_root = a.nodal_values_on_root()  # collective; the whole-mesh array on rank 0 only
    assert (on_root is None) == (COMM.rank > 0)
    assert ref.rel_max_diff(a.nodal_values(), b.nodal_values()) <= 1e-12
    if COMM.rank == 0:
        assert np.array_equal(on_root, a.nodal_values())
    assert np.array_equal(a.contact.node, b.contact.node)
    assert np.allclose(a.contact.pressure, b.contact.pressure, rtol=1e-10, atol=0)
    assert np.allclose(a.contact.x, b.contact.x)
    # the Functions on the parent mesh: the same values at the same global dof points
    for fa, fb in ((a.u, b.u), (a.pressure_function(), b.pressure_function())):
        assert np.allclose(np.sort(fa.x.array), np.sort(fb.x.array), rtol=1e-10,
                           atol=1e-14 * max(np.abs(fb.x.array).max(initial=0), 1.0))
    out = tmp_path_factory.mktemp("held") if COMM.rank == 0 else None
    out = COMM.bcast(out, root=0)
    a.write_xdmf(out / "held.xdmf")
    assert (out / "held.xdmf").exists()


def test_a_mesh_only_rank_0_holds_needs_its_communicator(root):
    held = df.read_gmsh(root / "meshes/membranes_8.msh", replicate=False)
    problem = df.ContactProblem(held, df.Poisson(source=ref.membrane_source),
                                dirichlet=[df.Dirichlet("dirichlet")])
    if COMM.size == 1:
        return
    with pytest.raises(df.InputError, match="rank 0 of its communicator"):
        df.solve(problem, comm=MPI.COMM_SELF)


def test_a_failure_while_handing_out_ends_every_rank(root, monkeypatch):
    """Rank 0 makes the blocks of a mesh only it holds one by one; if one fails, every rank
    raises the same error."""
    from dolfinx_feti.mesh import distributed

    if COMM.size == 1:
        pytest.skip("on one rank a mesh is whole there: nothing is handed out")

    real = distributed.hand_out

    def failing(comm, make, what):
        def broken(r):
            if r == comm.size - 1:  # the last rank's block
                raise MemoryError("no room for this piece")
            return make(r)
        return real(comm, None if make is None else broken, what)

    monkeypatch.setattr(distributed, "hand_out", failing)
    problem = membranes(df.read_gmsh(root / "meshes/membranes_8.msh", replicate=False), 1)
    with pytest.raises(df.SolveError, match="handing out the mesh failed on rank 0 "
                       r"\(MemoryError: no room for this piece\)") as info:
        df.dual_qp(problem)
    assert COMM.allgather(str(info.value)) == [str(info.value)] * COMM.size
