"""Messages that name the real cause, MeshTags of another mesh, options that differ between
ranks (issue 26). Serially and under ``mpirun -n 2``: every rank raises the same InputError,
nothing hangs (a watchdog in tests/scratch.py ends a hanging test).
"""

from __future__ import annotations

import dataclasses

import dolfinx
import dolfinx.mesh
import numpy as np
import pytest
import ufl
from hand_meshes import stacked
from mpi4py import MPI
from scratch import scratch_cwd_fixture

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.options import SolverOptions, check_same_on_ranks

COMM = MPI.COMM_WORLD
scratch_cwd = scratch_cwd_fixture("feti-causes-")


def raises(fn, *words):
    with pytest.raises(df.InputError) as info:
        fn()
    msg = str(info.value)
    assert all(w in msg for w in words), msg
    # the same message on every rank
    assert len(set(COMM.allgather(msg.split(" (in ")[0]))) == 1
    return msg


def held(mesh, forms, **kw) -> df.ContactProblem:
    return df.ContactProblem(mesh, forms, value_size=2,
                             dirichlet=[df.Dirichlet("lower_bottom"), df.Dirichlet("upper_top")],
                             contact=[df.Mortar("upper_bottom", "lower_top")], **kw)


# ------------------------------------------------------------------------------------------
# Options that differ between ranks
# ------------------------------------------------------------------------------------------


class TwoRanks:
    """A stand-in communicator of two ranks whose other rank has ``other`` options."""

    size = 2

    def __init__(self, other: SolverOptions) -> None:
        self.other = other

    def allgather(self, mine):
        return [mine, {k: repr(v) for k, v in self.other.to_dict().items()}]


def test_options_that_differ_are_named_with_their_values():
    a = SolverOptions.create(rtol=1e-8, method="tfeti")
    check_same_on_ranks(a, TwoRanks(a))  # equal: nothing to say
    b = a.replace(rtol=2e-8, method="feti1")
    msg = raises(lambda: check_same_on_ranks(a, TwoRanks(b)), "differ between the ranks",
                 "method", "rtol", "rank 0 1e-08", "rank 1 2e-08", "rank 1 'feti1'")
    assert "max_it" not in msg
    # a difference in the last bit is a different stopping test
    c = a.replace(rtol=float(np.nextafter(1e-8, 1.0)))
    raises(lambda: check_same_on_ranks(a, TwoRanks(c)), "rtol")


@pytest.mark.skipif(COMM.size == 1, reason="needs several ranks (mpirun -n 2)")
@pytest.mark.parametrize("per_rank", ["rtol", "method", "both"])
def test_options_per_rank_are_an_error_on_every_rank(per_rank):
    # an rtol computed per rank hung the job; a method per rank was taken from rank 0
    mesh = stacked()
    p = df.ContactProblem(mesh, df.Elasticity(E=1.0, nu=0.3,
                                              tractions={"upper_top": (0.0, -0.01)}),
                          dirichlet=[df.Dirichlet("lower_bottom"),
                                     df.Dirichlet("upper_left", components=(0,))],
                          contact=[df.Mortar("upper_bottom", "lower_top")])
    kw = {}
    if per_rank in ("rtol", "both"):
        kw["rtol"] = 1e-8 * (1 + COMM.rank)
    if per_rank in ("method", "both"):
        kw["method"] = "tfeti" if COMM.rank == 0 else "feti1"
    words = [w for w in ("rtol", "method") if w in kw]
    raises(lambda: df.solve(p, **kw), "solver options differ between the ranks", *words)


# ------------------------------------------------------------------------------------------
# MeshTags of another mesh
# ------------------------------------------------------------------------------------------


def tagged(n: int):
    """A 2n × n rectangle [0, 2] × [0, 1] on all ranks: cell tag 1, facet tags left 1, right 2."""
    m = dolfinx.mesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([2.0, 1.0])],
                                      [2 * n, n])
    tdim = m.topology.dim
    imap = m.topology.index_map(tdim)
    nc = imap.size_local + imap.num_ghosts
    ct = compat.cell_tags(m, np.arange(nc, dtype=np.int32), np.ones(nc, dtype=np.int32))
    m.topology.create_connectivity(tdim - 1, tdim)
    left = dolfinx.mesh.locate_entities_boundary(m, tdim - 1, lambda x: np.isclose(x[0], 0.0))
    right = dolfinx.mesh.locate_entities_boundary(m, tdim - 1, lambda x: np.isclose(x[0], 2.0))
    idx = np.concatenate([left, right])
    val = np.concatenate([np.full(left.size, 1), np.full(right.size, 2)])
    o = np.argsort(idx)
    ft = dolfinx.mesh.meshtags(m, tdim - 1, idx[o].astype(np.int32), val[o].astype(np.int32))
    return m, ct, ft


NAMES = {"plate": (2, 1), "left": (1, 1), "right": (1, 2)}


def test_tags_of_a_finer_mesh_are_refused_before_dolfinx_sees_them():
    # out-of-range entity indices segfaulted inside DOLFINx
    m, ct, ft = tagged(4)
    fine, fct, fft = tagged(8)
    raises(lambda: df.from_dolfinx(m, ct, fft, NAMES), "facet_tags belong to another mesh")
    raises(lambda: df.from_dolfinx(m, fct, ft, NAMES), "cell_tags belong to another mesh")


def test_tags_of_a_coarser_mesh_in_range_are_refused():
    # in range, the indices tag other facets: a Dirichlet group inside the plate, 230 % off
    m, ct, ft = tagged(4)
    _, _, cft = tagged(2)
    raises(lambda: df.from_dolfinx(m, ct, cft, NAMES), "facet_tags belong to another mesh",
           "other vertices")


def test_tags_of_the_same_mesh_made_twice_are_accepted():
    m, ct, ft = tagged(4)
    m2, ct2, ft2 = tagged(4)
    a = df.from_dolfinx(m, ct, ft, NAMES)
    b = df.from_dolfinx(m2, ct, ft, NAMES)  # the same mesh built again: the same entities
    assert np.array_equal(a.x, b.x) and np.array_equal(a.facet_groups["left"],
                                                      b.facet_groups["left"])


def test_two_names_for_one_tag_are_refused():
    # the last name was kept silently, and the first reported as an unknown group later
    m, ct, ft = tagged(2)
    raises(lambda: df.from_dolfinx(m, ct, ft, {**NAMES, "clamp": (1, 1)}),
           "'left' and 'clamp' both name the facet tag 1")


# ------------------------------------------------------------------------------------------
# Forms: not bilinear/linear, not symmetric, too large
# ------------------------------------------------------------------------------------------


def _grad_form(V):
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    return u, v, ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx


def non_symmetric(V, sub):
    u, v, a = _grad_form(V)
    return a + ufl.inner(ufl.grad(u)[:, 0], v) * ufl.dx, None  # an advection term


def residual(V, sub):
    w, v = dolfinx.fem.Function(V), ufl.TestFunction(V)
    return ufl.inner(ufl.grad(w), ufl.grad(v)) * ufl.dx, None


def nonlinear(V, sub):
    u, v, a = _grad_form(V)
    return a + ufl.inner(ufl.dot(u, u) * u, v) * ufl.dx, None


def swapped_load(V, sub):
    u, v, a = _grad_form(V)
    return a, ufl.inner(u, ufl.as_vector((0.0, 1.0))) * ufl.dx


def not_a_pair(V, sub):
    return _grad_form(V)[2]


@pytest.mark.parametrize("forms, words", [
    (non_symmetric, ("the bilinear form is not symmetric", "|K - K^T|")),
    (residual, ("the bilinear form has the arguments (test) instead of (test, trial)",
                "ufl.derivative")),
    (nonlinear, ("the bilinear form is not bilinear",)),
    (swapped_load, ("the linear form has the arguments (trial) instead of (test)",)),
    (not_a_pair, ("returned Form", "not a pair (a, L)")),
], ids=["non-symmetric", "residual", "nonlinear", "trial-in-L", "one-form"])
def test_forms_are_refused_for_what_they_are(forms, words):
    raises(lambda: df.solve(held(stacked(), forms), rtol=1e-8), *words)


def test_a_huge_traction_is_a_named_input_error_before_the_qp_solver():
    # a bare ValueError came from inside the QP solver
    p = df.ContactProblem(stacked(), df.Elasticity(E=1.0, nu=0.3,
                                                   tractions={"upper_top": (0.0, -1e300)}),
                          dirichlet=[df.Dirichlet("lower_bottom"),
                                     df.Dirichlet("upper_left", components=(0,))],
                          contact=[df.Mortar("upper_bottom", "lower_top")])
    raises(lambda: df.solve(p), "the assembled load vector has entries up to", "other units")


# ------------------------------------------------------------------------------------------
# Groups, paths, files
# ------------------------------------------------------------------------------------------


def test_one_surface_under_two_names_is_not_an_interface():
    mesh = stacked()
    mesh = dataclasses.replace(mesh, facet_groups={**mesh.facet_groups,
                                                   "glue": mesh.facet_groups["lower_top"]})
    for make in (lambda: df.Tie("glue", "lower_top"), lambda: df.Mortar("glue", "lower_top"),
                 lambda: df.NodeToNode("glue", "lower_top")):
        c = make()
        kw = {"ties": [c]} if isinstance(c, df.Tie) else {"contact": [c]}
        raises(lambda kw=kw: df.ContactProblem(mesh, df.Elasticity(E=1.0, nu=0.3), **kw),
               "'glue'", "'lower_top'", "the same 4 facets", "one surface under two names")


def test_an_empty_or_folder_mesh_path(tmp_path):
    raises(lambda: df.read_gmsh(""), "the mesh path is empty")
    folder = tmp_path if COMM.size == 1 else None
    folder = COMM.bcast(folder, root=0)
    if COMM.size == 1:
        raises(lambda: df.read_gmsh(folder), "is a folder, not a gmsh .msh file")
    from dolfinx_feti.io.problemfile import ProblemFileError, load
    for mesh, words in (('""', ("mesh: empty",)), ('"."', ("is a folder",))):
        path = tmp_path / "p.toml"
        path.write_text(f"mesh = {mesh}\n[model]\ntype = \"poisson\"\n")
        with pytest.raises(ProblemFileError) as info:
            load(path, MPI.COMM_SELF)
        assert all(w in str(info.value) for w in words), str(info.value)
        assert "not found" not in str(info.value)


V4_REPEATED_NODE = """$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
2
1 11 "edge"
2 1 "plate"
$EndPhysicalNames
$Entities
0 1 1 0
1 0 0 0 0 1 0 1 11 0
1 0 0 0 1 1 0 1 1 0
$EndEntities
$Nodes
2 5 1 4
1 1 0 2
1
4
0 0 0
0 1 0
2 1 0 3
2
3
3
1 0 0
1 1 0
2 2 0
$EndNodes
$Elements
2 3 1 3
1 1 1 1
1 4 1
2 1 2 2
2 1 2 3
3 3 4 1
$EndElements
"""


def test_a_repeated_node_tag_in_a_version_4_file_is_refused(tmp_path):
    # gmsh says only "Info: Skipping duplicate node 3" and lists node 3 twice: one node moved
    path = COMM.bcast(tmp_path / "repeated.msh" if COMM.rank == 0 else None, root=0)
    if COMM.rank == 0:
        path.write_text(V4_REPEATED_NODE)
    COMM.barrier()
    raises(lambda: df.read_gmsh(path), "malformed mesh data", "duplicate node 3")
