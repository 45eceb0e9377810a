"""A mesh read with ``distribute=True``: every rank builds its share from its block of cells.

The distributed set-up (dolfinx_feti.setup.share_distributed) must give exactly the shares that
rank 0
hands out when it holds the whole mesh — the same subdomains, dof points, pairs, rows and
columns — and so the same solution, on 1, 2 and 3 ranks; no rank may hold the whole mesh.
"""

from __future__ import annotations

import element_models as em
import numpy as np
import pytest
import reference as ref
import stress_cases as sc
import ufl
from mpi4py import MPI
from serial_setup import assert_same_shares, serial_dual_qp
from test_share import hexahedra_q2

import dolfinx_feti as df
from dolfinx_feti.io.meshes_occ import stacked_blocks

COMM = MPI.COMM_WORLD


def membranes(root, degree, distribute):
    mesh = df.read_gmsh(root / "meshes/membranes_8.msh", distribute=distribute)
    return df.ContactProblem(
        mesh, df.Poisson(source=ref.membrane_source, degree=degree),
        dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")],
        decomposition=df.Parts(8))


def hertz_mortar(root, distribute):
    mesh = df.read_gmsh(root / "meshes/hertz2d.msh", distribute=distribute)
    return df.ContactProblem(
        mesh, df.Elasticity(1.0, 0.3, tractions={"load": (0.0, -0.01)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar("disk_contact", "block_contact")], decomposition=df.Parts(3))


def tied_blocks(root, distribute):
    mesh = df.build_mesh(stacked_blocks, 3, 0.3, 0.45, distribute=distribute)
    return df.ContactProblem(
        mesh, df.Elasticity(100.0, 0.3, tractions={"top": (0.0, 0.0, -1.0)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sym0", components=[0])],
        ties=[df.Tie("upper_bottom", "lower_top")], decomposition=df.Parts(4))


def quads_by_function(root, distribute):
    mesh = df.build_mesh(em.rectangle, True, 0.2, distribute=distribute)
    return df.ContactProblem(
        mesh, df.Poisson(source=1.0), dirichlet=[df.Dirichlet("left"), df.Dirichlet("top", 0.5)],
        decomposition=df.ByFunction(lambda m: (m[:, 0] > 0.7).astype(int)
                                    + 2 * (m[:, 1] > 0.4).astype(int)))


def hertz_friction(root, distribute):
    mesh = df.read_gmsh(root / "meshes/hertz2d.msh", distribute=distribute)
    return df.ContactProblem(
        mesh, df.Elasticity(1.0, 0.3, tractions={"load": (0.002, -0.01)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.NodeToNode("disk_contact", "block_contact",
                               friction=df.Tresca(lambda x: 0.002 + 0.01 * x[:, 0] ** 2))],
        decomposition=df.Parts(4))


CASES = {"membranes_P1": lambda root, d: membranes(root, 1, d),
         "membranes_P2": lambda root, d: membranes(root, 2, d),
         "hertz_mortar": hertz_mortar, "tied_blocks_3d": tied_blocks,
         "hexahedra_P2": lambda root, d: hexahedra_q2(distribute=d),
         "quads_by_function": quads_by_function, "hertz_tresca": hertz_friction}


@pytest.fixture(scope="module", params=list(CASES))
def pair(root, request):
    """The problem read whole (rank 0 builds the shares) and distributed, and their QPs."""
    make = CASES[request.param]
    whole, spread = make(root, False), make(root, True)
    return whole, spread, serial_dual_qp(whole, method="tfeti"), df.dual_qp(spread, method="tfeti")


def test_the_shares_are_those_rank_0_hands_out(pair):
    *_, qw, qs = pair
    assert_same_shares(qw, qs)


def test_no_rank_holds_the_whole_mesh(pair):
    """From the input on, a rank holds its block, then its subdomains: about 1/n of the mesh."""
    whole, spread, _, qs = pair
    n, C = COMM.size, whole.mesh.num_cells
    bound = 1.0 / n + 0.15 if n > 1 else 1.0
    assert spread.mesh.cells.shape[0] <= bound * C  # the input block, and its vertices only
    assert spread.mesh.x.shape[0] == np.unique(spread.mesh.cells).size
    assert not spread.mesh.holds_arrays
    assert COMM.allreduce(spread.mesh.cells.shape[0]) == C
    if qs.share.dec.num_subdomains >= 8:  # whole subdomains per rank: a few are not even
        assert qs.share.cell_ids.size <= bound * C
        assert qs.share.point_ids.size <= bound * qs.share.num_points


def test_the_solution_is_the_same(pair):
    whole, spread, *_ = pair
    a = df.solve(whole, method="tfeti", rtol=1e-10)
    b = df.solve(spread, method="tfeti", rtol=1e-10)
    assert a.report.converged and b.report.converged
    assert a.report.hessian_mults == b.report.hessian_mults
    na, nb = a.nodal_values_on_root(), b.nodal_values_on_root()
    if COMM.rank == 0:
        assert ref.rel_max_diff(na, nb) <= 1e-12
    assert np.array_equal(a.contact.node, b.contact.node), "contact nodes"
    assert np.allclose(a.contact.pressure, b.contact.pressure, rtol=1e-10, atol=1e-12)
    assert np.allclose(a.contact.x, b.contact.x, rtol=0, atol=1e-14)
    ma, mb = a.report.extra.get("mortar") or [], b.report.extra.get("mortar") or []
    assert len(ma) == len(mb)
    for x, y in zip(ma, mb, strict=True):  # the search summaries; the penetrations to rounding
        assert x.keys() == y.keys()
        for k in x:
            assert x[k] == (pytest.approx(y[k], rel=1e-8) if isinstance(y[k], float) else y[k])
    if a.contact.tangential_force is not None:
        assert np.allclose(a.contact.tangential_force, b.contact.tangential_force, rtol=1e-10,
                           atol=1e-12)


def _norm2(u):
    import dolfinx.fem
    return COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(ufl.inner(u, u) * ufl.dx)))


@pytest.mark.parametrize("degree", [1, 2], ids=["P1", "P2"])
def test_functions_and_xdmf_from_a_distributed_mesh(root, degree, tmp_path_factory):
    """The Functions on the parent mesh built from the ranks' blocks equal the whole mesh's."""
    out = COMM.bcast(str(tmp_path_factory.mktemp("dist")) if COMM.rank == 0 else None)
    sols = [df.solve(membranes(root, degree, d), rtol=1e-10) for d in (False, True)]
    norms = [_norm2(s.u) for s in sols]
    assert norms[0] > 0 and abs(norms[1] - norms[0]) <= 1e-10 * norms[0]
    assert abs(_norm2(sols[1].pressure_function()) - _norm2(sols[0].pressure_function())) \
        <= 1e-9 * _norm2(sols[0].pressure_function())
    sols[1].write_xdmf(f"{out}/membranes.xdmf")
    if COMM.rank == 0:
        import os
        assert os.path.getsize(f"{out}/membranes.h5") > 0


def test_the_checks_of_the_whole_mesh_apply():
    """Rank 0 checked the whole mesh at input; the problem gets the same refusals."""
    mesh = df.build_mesh(sc.composite, 0.2, 1, distribute=True)
    with pytest.raises(df.InputError, match="contact surface 'interface'.*inside the mesh"):
        df.ContactProblem(mesh, sc.ConstElasticity(1.0, 0.3), dirichlet=[df.Dirichlet("top")],
                          contact=[df.RigidObstacle("interface", df.Plane((0, 0), (0, 1)))])
    with pytest.raises(df.InputError, match="tractions on the group 'interface'"):
        df.ContactProblem(mesh, df.Elasticity(1.0, 0.3, tractions={"interface": (0.0, -1.0)}),
                          dirichlet=[df.Dirichlet("bottom")])
    loose = df.build_mesh(sc.two_squares_one_body, 4, False, 6, distribute=True)
    with pytest.raises(df.InputError, match="not conforming.*'plate'"):
        df.ContactProblem(loose, sc.ConstElasticity(1.0, 0.3, tractions={"right": (0.1, 0.0)}),
                          dirichlet=[df.Dirichlet("left")])
    with pytest.raises(df.InputError, match="unknown boundary group 'nowhere'"):
        df.ContactProblem(loose, df.Poisson(1.0), dirichlet=[df.Dirichlet("nowhere")])


def test_what_is_not_built_yet_is_refused_by_name(root):
    with pytest.raises(df.InputError, match="curved"):
        df.build_mesh(em.plate_with_hole, False, 0.5, 2, distribute=True)


@pytest.mark.skipif(COMM.size == 1, reason="another communicator needs two ranks")
def test_a_distributed_mesh_needs_its_communicator(root):
    problem = hertz_mortar(root, True)
    with pytest.raises(df.InputError, match="another communicator"):
        df.dual_qp(problem, MPI.COMM_SELF)


@pytest.mark.parametrize("spread", [1, 1000], ids=["dense", "sparse"])
def test_local_vertex_numbers_are_those_of_unique(spread):
    """The rank's vertices and its cells in local numbers, by a mask over a dense range of
    global numbers or by a sort over a sparse one: np.unique's values and inverse."""
    from dolfinx_feti.setup.share_distributed import _compact

    rng = np.random.default_rng(3)
    cells = 5000 + spread * rng.integers(0, 700, size=(400, 3))
    vids, local = _compact(cells)
    want, inverse = np.unique(cells, return_inverse=True)
    assert np.array_equal(vids, want)
    assert np.array_equal(local, inverse.reshape(cells.shape))
    empty = _compact(np.zeros((0, 3), dtype=np.int64))
    assert empty[0].size == 0 and empty[1].shape == (0, 3)


def _unmatched_facets(mesh, owner, size):
    """The fraction of the blocks' facets that no other cell of the same block has."""
    from dolfinx_feti.mesh.topology import cell_facets, row_keys

    single = total = 0
    for r in range(size):
        cells = mesh.cells[owner == r]
        f = cell_facets(cells, mesh.cell_type)
        keys = row_keys(np.sort(f.reshape(-1, f.shape[-1]), axis=1), mesh.num_nodes)
        _, count = np.unique(keys, return_counts=True)
        single += int(np.sum(count == 1))
        total += keys.size
    return single / total


@pytest.mark.serial
@pytest.mark.parametrize("size", [2, 4, 8])
def test_the_blocks_of_the_input_are_compact(root, size):
    """Blocks along a Morton curve: equal sizes and few facets between blocks, where on 4 and
    more ranks the file's order gives blocks whose cells share hardly any facet."""
    from dolfinx_feti.mesh.distributed import compact_blocks

    mesh = df.read_gmsh(root / "meshes/membranes_8.msh")
    owner = compact_blocks(mesh.x[mesh.cells].mean(axis=1), size)
    sizes = np.bincount(owner, minlength=size)
    assert sizes.max() - sizes.min() <= 1
    assert np.array_equal(owner, compact_blocks(mesh.x[mesh.cells].mean(axis=1), size))
    compact = _unmatched_facets(mesh, owner, size)
    file_order = _unmatched_facets(mesh, np.arange(mesh.num_cells) * size // mesh.num_cells,
                                   size)
    assert compact < 0.25, compact
    if size >= 4:  # two blocks of the file's order are the two membranes, compact too
        assert file_order > 0.5 and compact < file_order / 4, (compact, file_order)
