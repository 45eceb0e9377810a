"""Unit tests of the constraint rows (gluing, Dirichlet, contact, obstacles) on small meshes.

Everything here is NumPy: ``build_rows`` on a decomposition, no assembly and no solve.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from serial_setup import build_rows

import dolfinx_feti as df
from dolfinx_feti.constraints import Kind, Rows
from dolfinx_feti.mesh.decompose import decompose

MESHES = Path(__file__).resolve().parents[2] / "meshes"
S2 = 1.0 / np.sqrt(2.0)


@pytest.fixture(scope="module")
def membranes() -> df.MeshData:
    return df.read_gmsh(MESHES / "membranes_8.msh")


def _grid_2x2(m: np.ndarray) -> np.ndarray:
    """Cells of x in [0, 2) × [0, 1) labelled by the 0.5 × 0.5 square of their midpoint."""
    return (np.floor(2 * m[:, 0]) + 4 * np.floor(2 * m[:, 1])).astype(np.int64)


GRID = df.ByFunction(_grid_2x2)


def _problem(mesh, *, vector=False, dirichlet=None, contact=(), decomposition=GRID,
             gluing="orthonormal") -> df.ContactProblem:
    forms = df.Elasticity(1.0, 0.3) if vector else df.Poisson(-1.0)
    if dirichlet is None:
        dirichlet = [df.Dirichlet("dirichlet")]
    return df.ContactProblem(mesh, forms, dirichlet=dirichlet, contact=list(contact),
                             decomposition=decomposition, gluing=gluing)


def _rows(problem, comm_size=1):
    dec = decompose(problem.mesh, problem.decomposition, comm_size)
    return build_rows(problem, dec), dec


def _dense_B(rows: Rows, dec, bs: int) -> np.ndarray:
    """B as a dense array, columns = bs * pair_index(subdomain, node) + component."""
    col = bs * dec.pair_index(rows.e_sub, rows.e_node) + rows.e_comp
    B = np.zeros((rows.size, bs * dec.pair_sub.size))
    np.add.at(B, (rows.e_row, col), rows.e_coef)
    return B


def _node_at(mesh, x, y, body=None) -> int:
    hit = np.flatnonzero(np.all(np.isclose(mesh.x, [x, y]), axis=1))
    if body is not None:
        in_body = np.unique(mesh.cells[mesh.cell_body == mesh.body_index(body)])
        hit = np.intersect1d(hit, in_body)
    assert hit.size == 1, (x, y, body, hit)
    return int(hit[0])


def _rows_of_node(rows: Rows, kind: Kind, node: int) -> np.ndarray:
    return np.flatnonzero((rows.kind == kind) & (rows.node == node))


# ------------------------------------------------------------------------------------------
# Gluing
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("vector", [False, True])
def test_orthonormal_gluing_rows_are_orthonormal(membranes, vector):
    bs = 2 if vector else 1
    rows, dec = _rows(_problem(membranes, vector=vector))
    assert dec.num_subdomains == 8
    B = _dense_B(rows, dec, bs)
    glue = rows.kind == Kind.GLUE
    Bg = B[glue]
    np.testing.assert_allclose(Bg @ Bg.T, np.eye(Bg.shape[0]), atol=1e-14)
    # each cross point (in 4 subdomains) has bs * 3 gluing rows
    for x, y, body in ((0.5, 0.5, "left"), (1.5, 0.5, "right")):
        node = _node_at(membranes, x, y, body)
        r = _rows_of_node(rows, Kind.GLUE, node)
        assert r.size == bs * 3
        assert np.unique(rows.e_sub[np.isin(rows.e_row, r)]).size == 4


def _continuous_field(dec, bs: int, rng) -> np.ndarray:
    """A primal vector equal on every subdomain copy of a node (what gluing must accept)."""
    values = rng.standard_normal((dec.num_nodes, bs))
    return values[dec.pair_node].ravel()


@pytest.mark.parametrize("scheme, rows_at_cross", [("orthonormal", 3), ("redundant", 6),
                                                   ("nonredundant", 3)])
def test_gluing_schemes_count_and_kernel(membranes, scheme, rows_at_cross):
    rows, dec = _rows(_problem(membranes, gluing=scheme))
    B = _dense_B(rows, dec, 1)
    glue = rows.kind == Kind.GLUE
    rng = np.random.default_rng(3)
    # a continuous field satisfies every gluing row; all rows have rhs 0 and unit norm
    np.testing.assert_allclose(B[glue] @ _continuous_field(dec, 1, rng), 0.0, atol=1e-12)
    np.testing.assert_array_equal(rows.rhs[glue], 0.0)
    np.testing.assert_allclose(np.linalg.norm(B[glue], axis=1), 1.0)
    ptr, _ = dec.node_subdomains()
    mult = np.diff(ptr)
    for x, y, body in ((0.5, 0.5, "left"), (1.5, 0.5, "right")):
        node = _node_at(membranes, x, y, body)
        assert mult[node] == 4
        r = _rows_of_node(rows, Kind.GLUE, node)
        assert r.size == rows_at_cross  # k(k-1)/2 = 6 redundant, k-1 = 3 otherwise
        assert np.linalg.matrix_rank(B[r]) == 3  # they all say the same: 4 copies equal
    # a node on one interface (k = 2) has one row in every scheme
    node = _node_at(membranes, 0.5, 0.25, "left")
    assert mult[node] == 2 and _rows_of_node(rows, Kind.GLUE, node).size == 1
    # a node inside one subdomain has none
    node = _node_at(membranes, 0.25, 0.25, "left")
    assert mult[node] == 1 and _rows_of_node(rows, Kind.GLUE, node).size == 0


def test_redundant_rows_are_all_pairs(membranes):
    rows, dec = _rows(_problem(membranes, gluing="redundant"))
    B = _dense_B(rows, dec, 1)
    node = _node_at(membranes, 0.5, 0.5, "left")
    r = _rows_of_node(rows, Kind.GLUE, node)
    pairs = set()
    for i in r:
        e = rows.e_row == i
        assert e.sum() == 2
        np.testing.assert_allclose(np.sort(rows.e_coef[e]), [-S2, S2])
        pairs.add(tuple(sorted(rows.e_sub[e])))
    assert len(pairs) == 6
    assert np.linalg.matrix_rank(B[r]) == 3


# ------------------------------------------------------------------------------------------
# Dirichlet
# ------------------------------------------------------------------------------------------


def test_dirichlet_rows_once_per_subdomain_copy(membranes):
    rows, dec = _rows(_problem(membranes, dirichlet=[df.Dirichlet("dirichlet", value=0.7)]))
    dir_rows = np.flatnonzero(rows.kind == Kind.DIRICHLET)
    nodes_x0 = np.flatnonzero(np.isclose(membranes.x[:, 0], 0.0))
    assert nodes_x0.size == 9
    # 9 nodes on x = 0, one of them (y = 0.5) in two subdomains
    assert dir_rows.size == 10
    np.testing.assert_allclose(rows.rhs[dir_rows], 0.7)
    assert set(rows.node[dir_rows]) == set(nodes_x0)
    shared = _node_at(membranes, 0.0, 0.5)
    r = _rows_of_node(rows, Kind.DIRICHLET, shared)
    assert r.size == 2
    subs = [rows.e_sub[rows.e_row == i] for i in r]
    assert all(s.size == 1 for s in subs) and subs[0][0] != subs[1][0]
    np.testing.assert_array_equal(rows.e_coef[np.isin(rows.e_row, r)], 1.0)
    # no gluing row at a node whose copies are all fixed
    assert _rows_of_node(rows, Kind.GLUE, shared).size == 0
    # each Dirichlet row has one entry
    assert np.all(np.bincount(rows.e_row)[dir_rows] == 1)


def test_dirichlet_components_and_gluing(membranes):
    """Dirichlet on component 0 only: gluing keeps the other component."""

    def value(x):
        return 0.1 * x[:, 1]

    prob = _problem(membranes, vector=True,
                    dirichlet=[df.Dirichlet("dirichlet", value=value, components=(0,))])
    rows, dec = _rows(prob)
    shared = _node_at(membranes, 0.0, 0.5)
    r = _rows_of_node(rows, Kind.DIRICHLET, shared)
    assert r.size == 2
    np.testing.assert_array_equal(rows.e_comp[np.isin(rows.e_row, r)], 0)
    np.testing.assert_allclose(rows.rhs[r], 0.05)
    g = _rows_of_node(rows, Kind.GLUE, shared)
    assert g.size == 1
    np.testing.assert_array_equal(rows.e_comp[rows.e_row == g[0]], 1)
    dir_rows = rows.kind == Kind.DIRICHLET
    np.testing.assert_allclose(rows.rhs[dir_rows], 0.1 * membranes.x[rows.node[dir_rows], 1])


def test_later_dirichlet_condition_wins(membranes):
    prob = _problem(membranes, dirichlet=[df.Dirichlet("dirichlet", 1.0),
                                          df.Dirichlet("dirichlet", 2.0)])
    rows, _ = _rows(prob)
    d = rows.kind == Kind.DIRICHLET
    assert d.sum() == 10
    np.testing.assert_allclose(rows.rhs[d], 2.0)


# ------------------------------------------------------------------------------------------
# Node-to-node contact
# ------------------------------------------------------------------------------------------


def test_b1_contact_rows(membranes):
    prob = _problem(membranes, contact=[df.NodeToNode("contact_left", "contact_right")],
                    decomposition=df.ByTags())
    rows, dec = _rows(prob)
    c = np.flatnonzero(rows.kind == Kind.CONTACT)
    assert c.size == 9
    np.testing.assert_array_equal(rows.inequality, rows.kind == Kind.CONTACT)
    np.testing.assert_array_equal(rows.rhs[c], 0.0)
    np.testing.assert_allclose(rows.scale[c], S2)
    left, right = membranes.body_index("left"), membranes.body_index("right")
    for i in c:
        e = np.flatnonzero(rows.e_row == i)
        assert e.size == 2
        nodes = rows.e_node[e]
        np.testing.assert_allclose(membranes.x[nodes, 0], 1.0)
        assert membranes.x[nodes[0], 1] == pytest.approx(membranes.x[nodes[1], 1])
        coef = dict(zip(dec.sub_body[rows.e_sub[e]], rows.e_coef[e], strict=True))
        # u_left − u_right <= 0, scaled by 1/sqrt(2)
        assert coef[left] == pytest.approx(S2) and coef[right] == pytest.approx(-S2)
        assert rows.node[i] in nodes and rows.partner[i] in nodes
        assert rows.node[i] != rows.partner[i]
    ys = np.sort(membranes.x[rows.node[c], 1])
    np.testing.assert_allclose(ys, np.linspace(0.0, 1.0, 9))


def test_elastic_contact_rows_normal_and_gap(membranes):
    prob = _problem(membranes, vector=True,
                    contact=[df.NodeToNode("contact_right", "contact_left", gap=0.1)],
                    decomposition=df.ByTags())
    rows, dec = _rows(prob)
    c = np.flatnonzero(rows.kind == Kind.CONTACT)
    assert c.size == 9
    # the master (left) faces +x: (u_right − u_left)·n >= −gap, i.e. u_left,x − u_right,x <= gap
    np.testing.assert_allclose(rows.normal[c], np.tile([1.0, 0.0], (9, 1)))
    np.testing.assert_allclose(rows.rhs[c], 0.1 * S2)
    e = np.isin(rows.e_row, c)
    np.testing.assert_array_equal(rows.e_comp[e], 0)  # zero y entries are dropped
    left = membranes.body_index("left")
    sign = np.where(dec.sub_body[rows.e_sub[e]] == left, 1.0, -1.0)
    np.testing.assert_allclose(rows.e_coef[e], sign * S2)


# ------------------------------------------------------------------------------------------
# Order and independence of the number of ranks
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("vector", [False, True])
def test_rows_sorted_by_owner(membranes, vector):
    contact = [df.NodeToNode("contact_left", "contact_right")] if not vector else \
        [df.NodeToNode("contact_right", "contact_left")]
    rows, _ = _rows(_problem(membranes, vector=vector, contact=contact))
    owner = rows.min_subdomain()
    assert np.all(np.diff(owner) >= 0)
    assert rows.e_row.min() == 0 and rows.e_row.max() == rows.size - 1
    assert np.all(np.diff(rows.e_row) >= 0)  # entries grouped by row


def _same_rows(a: Rows, b: Rows) -> None:
    for f in fields(Rows):
        np.testing.assert_array_equal(getattr(a, f.name), getattr(b, f.name), err_msg=f.name)


@pytest.mark.parametrize("how", [GRID, df.Parts(3), df.ByTags()])
def test_rows_independent_of_comm_size(membranes, how):
    prob = _problem(membranes, contact=[df.NodeToNode("contact_left", "contact_right")],
                    decomposition=how)
    ref, dec1 = _rows(prob, 1)
    for size in (2, 3):
        rows, dec = _rows(prob, size)
        _same_rows(rows, ref)
        np.testing.assert_array_equal(dec.cell_sub, dec1.cell_sub)
    world = build_rows(prob, decompose(membranes, how, MPI.COMM_WORLD))
    _same_rows(world, ref)


def test_rows_owned_by_rank_are_contiguous(membranes):
    prob = _problem(membranes, contact=[df.NodeToNode("contact_left", "contact_right")])
    rows, dec = _rows(prob, 3)
    owner_rank = dec.sub_rank[rows.min_subdomain()]
    assert np.all(np.diff(owner_rank) >= 0)
    assert set(owner_rank) == {0, 1, 2}


# ------------------------------------------------------------------------------------------
# Rigid obstacles
# ------------------------------------------------------------------------------------------


def _obstacle_rows(mesh, obstacle, group="dirichlet"):
    prob = df.ContactProblem(mesh, df.Elasticity(1.0, 0.3),
                             dirichlet=[df.Dirichlet("contact_left")],
                             contact=[df.RigidObstacle(group, obstacle)])
    rows, dec = _rows(prob)
    return rows, np.flatnonzero(rows.kind == Kind.OBSTACLE), dec


@pytest.mark.parametrize("offset", [0.1, -0.05])
def test_plane_obstacle_rows(membranes, offset):
    # the obstacle x <= -offset, its outward normal +x (given unnormalized)
    rows, o, dec = _obstacle_rows(membranes, df.Plane(point=(-offset, 0.3), normal=(2.0, 0.0)))
    assert o.size == 9
    np.testing.assert_allclose(membranes.x[rows.node[o], 0], 0.0)
    np.testing.assert_allclose(rows.normal[o], np.tile([1.0, 0.0], (9, 1)))
    # gap = distance to the plane; negative: an initial penetration kept as it is
    np.testing.assert_allclose(rows.rhs[o], offset)
    np.testing.assert_array_equal(rows.partner[o], -1)
    B = _dense_B(rows, dec, 2)
    for i in o:
        # the row is −n·u(node) <= gap
        col = 2 * dec.pair_index(rows.e_sub[rows.e_row == i][:1], [rows.node[i]])[0]
        np.testing.assert_allclose(B[i, col:col + 2], [-1.0, 0.0])
        assert np.count_nonzero(B[i]) == 1
    assert rows.inequality[o].all()


def test_sphere_obstacle_rows(membranes):
    c, r = np.array([-1.0, 0.5]), 0.5
    rows, o, dec = _obstacle_rows(membranes, df.Sphere(center=tuple(c), radius=r))
    x = membranes.x[rows.node[o]]
    d = x - c
    dist = np.linalg.norm(d, axis=1)
    np.testing.assert_allclose(rows.rhs[o], dist - r)
    np.testing.assert_allclose(rows.normal[o], d / dist[:, None])
    # the closest node, (0, 0.5), has gap 0.5 and normal +x
    k = np.argmin(rows.rhs[o])
    np.testing.assert_allclose(x[k], [0.0, 0.5])
    assert rows.rhs[o][k] == pytest.approx(0.5)
    B = _dense_B(rows, dec, 2)
    for i, n in zip(o, rows.normal[o], strict=True):
        col = 2 * dec.pair_index(rows.e_sub[rows.e_row == i][:1], [rows.node[i]])[0]
        np.testing.assert_allclose(B[i, col:col + 2], -n)


def test_signed_distance_obstacle_scaled_gradient(membranes):
    """A distance whose gradient is not unit: rows use ∇φ/|∇φ| and φ/|∇φ|."""

    def phi(x):
        return 3.0 * (x[:, 0] + 0.2), np.tile([3.0, 0.0], (x.shape[0], 1))

    rows, o, _ = _obstacle_rows(membranes, df.SignedDistance(phi))
    np.testing.assert_allclose(rows.rhs[o], 0.2)
    np.testing.assert_allclose(rows.normal[o], np.tile([1.0, 0.0], (o.size, 1)))


def test_obstacle_rows_inconsistent_normal(membranes):
    with pytest.raises(df.InputError, match="inconsistent normals"):
        _obstacle_rows(membranes, df.Plane(point=(-0.1, 0.0), normal=(-1.0, 0.0)))
