"""FETI-DP on a distributed mesh: the corners and floating motions built in parallel
(dolfinx_feti.fem.distributed_corners) are those rank 0 computes from the whole mesh.

The replicated set-up (the oracle ``serial_setup.fetidp_parts`` on the global arrays) is the
specification: the same
corner unknown for every (subdomain, point, component), the same counts, the same span of
floating motions and bodies; hence the same FETI-DP solution and the same choice of
``method="auto"``, on 1, 2 and 3 ranks.
"""

from __future__ import annotations

from dataclasses import replace

import element_models as em
import numpy as np
import pytest
import reference as ref
import scipy.linalg
import serial_setup
from mpi4py import MPI
from serial_setup import serial_dual_qp
from test_distributed_input import CASES as INPUT_CASES

import dolfinx_feti as df
from dolfinx_feti.setup import stages as dual

COMM = MPI.COMM_WORLD


def _islands(m):
    """Left and right halves, each with an island inside."""
    half = (m[:, 0] > 1.0).astype(int)
    inside = np.hypot(m[:, 0] - 0.5 - half, m[:, 1] - 0.5) < 0.25
    return np.where(inside, 2 + half, half)


def island(root, distribute):
    """A subdomain inside another, twice (their subdomains on different ranks): the interface
    of each is a closed curve with no vertex, so the serial corner choice adds shared nodes to
    join the pair rigidly (greedy additions)."""
    mesh = df.build_mesh(em.rectangle, False, 0.12, distribute=distribute)
    return df.ContactProblem(
        mesh, df.Elasticity(1.0, 0.3, tractions={"right": (0.0, -0.01)}),
        dirichlet=[df.Dirichlet("left")], decomposition=df.ByFunction(_islands))


CASES = {name: INPUT_CASES[name] for name in
         ("membranes_P1", "membranes_P2", "hertz_mortar", "tied_blocks_3d", "hexahedra_P2")}
CASES["island"] = island


@pytest.fixture(scope="module", params=list(CASES))
def case(root, request):
    """The problem read whole and distributed, and their FETI-DP QPs."""
    make = CASES[request.param]
    whole, spread = make(root, False), make(root, True)
    return (request.param, whole, spread, serial_dual_qp(whole, method="fetidp"),
            df.dual_qp(spread, method="fetidp"))


def _global(qp) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(subdomain, global point, component) of every dof of every rank (sorted), and the
    corner unknown and the floating motions of each (every rank)."""
    share, extra = qp.share, qp.share.extra
    npair = share.dec.pair_node.size
    bs = COMM.allreduce(extra["corners"].size // npair if npair else 0, op=MPI.MAX)
    sub = np.repeat(np.repeat(share.dec.subs, np.diff(share.dec.pair_ptr)), bs)
    point = np.repeat(share.pair_points, bs)
    comp = np.tile(np.arange(bs), npair)
    keys = np.concatenate(COMM.allgather(np.column_stack([sub, point, comp])))
    corners = np.concatenate(COMM.allgather(extra["corners"]))
    modes = np.concatenate(COMM.allgather(extra["modes"]))
    order = np.lexsort(keys.T[::-1])
    return keys[order], corners[order], modes[order]


def test_the_corners_are_those_of_the_whole_mesh(case):
    name, _, _, qw, qs = case
    assert qw.method == qs.method == "fetidp"
    a, b = qw.share.extra, qs.share.extra
    assert a["count"] == b["count"] > 0
    assert a["info"] == b["info"] == qs.info
    assert a["bodies"] == b["bodies"]
    ka, ca, _ = _global(qw)
    kb, cb, _ = _global(qs)
    assert np.array_equal(ka, kb)
    assert np.array_equal(ca, cb)
    assert np.array_equal(np.unique(ca[ca >= 0]), np.arange(a["count"]))
    np.testing.assert_array_equal(a["corners"], b["corners"])  # the same layout of the dofs
    if name == "island":  # the pairs with no vertex were joined by nodes the greedy loop added
        assert a["info"]["vertices"] + 4 <= a["info"]["corner_nodes"]


def test_the_floating_motions_span_the_same_space(case):
    _, _, _, qw, qs = case
    *_, za = _global(qw)
    *_, zb = _global(qs)
    assert za.shape == zb.shape
    if za.shape[1]:
        assert np.max(scipy.linalg.subspace_angles(za, zb)) < 1e-10
        fixed = np.all(za == 0.0, axis=1)
        assert np.all(zb[fixed] == 0.0)  # zero on the fixed dofs


def test_the_solution_is_the_same(case):
    name, whole, spread, *_ = case
    a = df.solve(whole, method="fetidp", rtol=1e-10)
    b = df.solve(spread, method="fetidp", rtol=1e-10)
    assert a.report.converged and b.report.converged
    # the Gram matrices are summed in another order: the motions' basis may rotate
    assert abs(a.report.hessian_mults - b.report.hessian_mults) <= 1
    na, nb = a.nodal_values_on_root(), b.nodal_values_on_root()
    if COMM.rank == 0:
        assert ref.rel_max_diff(na, nb) <= 1e-8


def membranes_by_tags(root, distribute):
    """B1 with one subdomain per membrane: no gluing rows."""
    return replace(INPUT_CASES["membranes_P1"](root, distribute), decomposition=df.ByTags())


def membranes_many(root, distribute):
    """B1 in 32 parts per membrane: more than setup.method_rule.MANY_PER_BODY."""
    return replace(INPUT_CASES["membranes_P1"](root, distribute), decomposition=df.Parts(32))


@pytest.mark.parametrize("name, expected", [
    ("membranes_P1", "feti1"), ("hexahedra_P2", "feti1"), ("island", "feti1"),
    ("membranes_by_tags", "feti1"), ("membranes_many", "fetidp")])
def test_auto_chooses_as_on_the_whole_mesh(root, name, expected):
    """No gluing or few subdomains per body → feti1; many → fetidp, floating bodies too (the
    rule of choose_method, setup/method_rule.py)."""
    make = {"membranes_by_tags": membranes_by_tags,
            "membranes_many": membranes_many}.get(name) or CASES[name]
    chosen = [df.dual_qp(make(root, d), method="auto").method for d in (False, True)]
    assert chosen == [expected, expected]


def test_corners_off_contact_are_refused(root, monkeypatch):
    monkeypatch.setattr(dual, "CORNERS_ON_CONTACT", False)
    with pytest.raises(df.InputError, match="CORNERS_ON_CONTACT"):
        df.dual_qp(INPUT_CASES["hertz_mortar"](root, True), method="fetidp")


@pytest.mark.parametrize("name", ["tied_blocks_3d", "hertz_mortar"])
def test_each_fixed_point_counts_once_in_the_gram_matrices(root, name, monkeypatch):
    """The reduced Gram matrices of the components' fixed rows are the serial ones (a point
    of several subdomains counted once), not only of the same null space."""
    from dolfinx_feti.constraints.dirichlet import dirichlet_mask
    from dolfinx_feti.fem import corners, distributed_corners
    from dolfinx_feti.mesh.decompose import decompose

    whole, spread = CASES[name](root, False), CASES[name](root, True)
    serial, spread_grams = [], []
    free_motions, free_of_gram = corners._free_motions, distributed_corners.free_of_gram
    monkeypatch.setattr(corners, "_free_motions",
                        lambda Y: serial.append((Y.T @ Y, Y.shape[0])) or free_motions(Y))
    monkeypatch.setattr(distributed_corners, "free_of_gram",
                        lambda G, n: spread_grams.append((G, n)) or free_of_gram(G, n))
    dec = decompose(whole.mesh, whole.decomposition, 1, whole.dof_points)
    fixed, _ = dirichlet_mask(whole, whole.mesh)
    none = np.zeros(0, dtype=np.int64)
    serial_setup.floating_motions(whole.mesh, dec, None, fixed, whole.value_size,
                                  [(none, none, none)], whole.dof_points.x,
                                  serial_setup.primal_components(whole.mesh, dec))
    monkeypatch.setattr(corners, "_free_motions", free_motions)  # (the pairs use it too)
    df.dual_qp(spread, method="fetidp")
    if COMM.rank == 0:  # rank 0 reduces them
        assert len(serial) == len(spread_grams) > 0
        for (a, n), (b, m) in zip(serial, spread_grams, strict=True):
            assert n == m
            assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(a).max())
