"""A rank's rows of B built from distributed data (constraints.distributed_rows) are the serial
ones: the rows rank 0's build_rows makes and share.py would hand the rank, field by field.

Every rank builds the same small global problem and its serial decomposition and rows; its
inputs (the dof points of its subdomains' cells, each point's subdomains, its facets of each
Dirichlet group) are cut from them, as the distributed set-up will hand them over. Run serially
and under ``mpirun -n 2`` (and 3).
"""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest
from distributed_inputs import RankInputs
from mpi4py import MPI
from serial_setup import build_rows, row_ranges

import dolfinx_feti as df
from dolfinx_feti.constraints import Rows
from dolfinx_feti.constraints.build import surface_rows
from dolfinx_feti.constraints.dirichlet import dirichlet_mask
from dolfinx_feti.constraints.distributed_rows import (
    dirichlet_mask_distributed,
    own_rows,
    shared_points,
)
from dolfinx_feti.io import meshes
from dolfinx_feti.mesh.decompose import decompose
from dolfinx_feti.setup.share import row_slice

COMM = MPI.COMM_WORLD
SCHEMES = ["orthonormal", "redundant", "nonredundant"]


@pytest.fixture(scope="module")
def membranes() -> df.MeshData:
    """B1's two membranes (4 × 4 squares each, triangles), with a group "bottom" at y = 0."""
    mesh = df.build_mesh(meshes.membranes, 4)
    edges = mesh.cells[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2)
    bottom = np.unique(np.sort(edges[np.all(mesh.x[edges, 1] == 0.0, axis=1)], axis=1), axis=0)
    return replace(mesh, facet_groups={**mesh.facet_groups, "bottom": bottom})


@pytest.fixture(scope="module")
def blocks() -> df.MeshData:
    return df.build_mesh(meshes.blocks3d, 2)


def _diagonal(m: np.ndarray) -> np.ndarray:
    """Left membrane: below / above its diagonal y = x (each touches x = 0 or y = 0 at the
    vertex (0, 0) only); right membrane: y < 0.5 / y > 0.5."""
    left = m[:, 0] < 1.0
    return np.where(left, m[:, 1] > m[:, 0], 2 + (m[:, 1] > 0.5)).astype(np.int64)


def _ramp(x: np.ndarray) -> np.ndarray:
    return 1.0 + 0.5 * x[:, 0] - 0.25 * x[:, 1]


def _field(x: np.ndarray) -> np.ndarray:
    return np.c_[x[:, 0] + 2.0 * x[:, 1], -x[:, 2]]


DIAGONAL = df.ByFunction(_diagonal)


def _problem_2d(mesh, degree, scheme, vector=True, decomposition=DIAGONAL):
    forms = df.Elasticity(1.0, 0.3, degree=degree) if vector else df.Poisson(-1.0, degree=degree)
    dirichlet = [df.Dirichlet("dirichlet", (0.1, -0.2) if vector else 0.3),
                 df.Dirichlet("bottom", _ramp, components=(1,) if vector else None)]
    return df.ContactProblem(mesh, forms, dirichlet=dirichlet,
                             contact=[df.NodeToNode("contact_left", "contact_right")],
                             decomposition=decomposition, gluing=scheme)


def _problem_3d(mesh, degree, scheme):
    dirichlet = [df.Dirichlet("bottom", (0.1, 0.2, 0.3)),
                 df.Dirichlet("sides_lower", _field, components=(0, 2)),
                 df.Dirichlet("top", -0.05, components=(2,)),
                 df.Dirichlet("sides_upper", 0.0, components=(1,))]
    # on quadratic triangular facets the rows of the transformed basis (several nodes each)
    contact = [df.NodeToNode("contact_upper", "contact_lower")]
    return df.ContactProblem(mesh, df.Elasticity(1.0, 0.3, degree=degree), dirichlet=dirichlet,
                             contact=contact, decomposition=df.Parts(3), gluing=scheme)


def _assignments(nsub: int, size: int, balanced: np.ndarray) -> dict[str, np.ndarray]:
    """Owners of the subdomains (contiguous): the decomposition's, subdomain 0 alone on rank 0
    and 1 alone on rank 1, all on the last rank (the others hold nothing)."""
    return {"balanced": balanced,
            "first alone": np.minimum(np.arange(nsub), size - 1),
            "all on last": np.full(nsub, size - 1)}


def _extra(problem, node_ptr, node_subs, fixed) -> Rows:
    """The tie and contact rows as build_rows concatenates them after gluing and Dirichlet."""
    blocks = surface_rows(problem, node_ptr, node_subs, fixed)
    return Rows.concatenate([Rows.empty(problem.mesh.gdim), *blocks])


def _mask(problem, inputs, sub_rank, shared=True):
    bs, n = problem.value_size, problem.dof_points.num_points
    mask = shared_points(inputs.ptr, inputs.subs, sub_rank, COMM.rank) if shared else None
    return dirichlet_mask_distributed(inputs.points, inputs.conditions, bs, n, COMM, mask)


def _check(problem):
    """Distributed mask and rows of every owner assignment against the serial ones.

    Returns the number of fixed points (summed over the ranks and assignments) whose rank holds
    none of the facets that fix them. A mismatch fails on every rank (no rank is left waiting
    in a collective call of the next step).
    """
    mesh, bs = problem.mesh, problem.value_size
    dec = decompose(mesh, problem.decomposition, COMM.size, problem.dof_points)
    serial = build_rows(problem, dec)
    fixed_all, values_all = dirichlet_mask(problem, mesh)
    node_ptr, node_subs = dec.node_subdomains()
    extra = _extra(problem, node_ptr, node_subs, fixed_all)
    assert (extra.size > 0) == bool(problem.contact)
    wrong, crossing = [], 0
    for name, sub_rank in _assignments(dec.num_subdomains, COMM.size, dec.sub_rank).items():
        inputs = RankInputs(problem, dec, sub_rank, COMM.rank)
        for shared in (True, False):
            fixed, values = _mask(problem, inputs, sub_rank, shared)
            for what, a, b in (("fixed", fixed, fixed_all[inputs.points]),
                               ("values", values, values_all[inputs.points])):
                if a.dtype != b.dtype or not np.array_equal(a, b):
                    wrong.append(f"{name}, shared={shared}: {what}")
        own = np.zeros(fixed.shape, dtype=bool)  # fixed through facets of this rank
        for (_, on, _), comps in zip(inputs.conditions, _components(problem), strict=True):
            own[np.searchsorted(inputs.points, on)[:, None], comps] = True
        crossing += COMM.allreduce(int(np.count_nonzero(fixed & ~own)))
        rows, start, size = own_rows(inputs.points, inputs.ptr, inputs.subs, fixed, values, bs,
                                     mesh.gdim, problem.gluing, sub_rank, COMM, extra)
        ranges = row_ranges(serial, replace(dec, sub_rank=sub_rank), COMM.size)
        if (start, size) != (ranges[COMM.rank], serial.size):
            wrong.append(f"{name}: start, size {start, size}")
        theirs = row_slice(serial, ranges[COMM.rank], ranges[COMM.rank + 1])
        wrong += [f"{name}: rows.{f}" for f in _differ(rows, theirs)]
    wrong = [f"rank {r}: {w}" for r, ws in enumerate(COMM.allgather(wrong)) for w in ws]
    assert not wrong
    return crossing


def _components(problem):
    bs = problem.value_size
    return [list(range(bs)) if bc.components is None else list(bc.components)
            for bc in problem.dirichlet]


def _differ(mine: Rows, theirs: Rows) -> list[str]:
    """The fields of two Rows that differ (in values, shape or type)."""
    out = []
    for f in fields(Rows):
        a, b = getattr(mine, f.name), getattr(theirs, f.name)
        if a.dtype != b.dtype or not np.array_equal(a, b):
            out.append(f.name)
    return out


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("degree", [1, 2])
def test_2d_vertex_touching_subdomains(membranes, degree, scheme):
    """Vector problem, Dirichlet on two groups meeting at (0, 0) (constant, and a function on
    one component), subdomains touching them at that vertex only."""
    crossing = _check(_problem_2d(membranes, degree, scheme))
    if COMM.size > 1:  # subdomain 0 or 1 on rank 0 touches a group at (0, 0) only
        assert crossing > 0


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("degree", [1, 2])
def test_2d_scalar_parts(membranes, degree, scheme):
    """Scalar problem, Parts(4) per membrane (points in four subdomains)."""
    problem = _problem_2d(membranes, degree, scheme, vector=False, decomposition=df.Parts(4))
    _check(problem)


@pytest.mark.parametrize("scheme", ["orthonormal", "redundant"])
@pytest.mark.parametrize("degree", [1, 2])
def test_3d_overlapping_groups(blocks, degree, scheme):
    """Two boxes, Parts(3) each, four overlapping Dirichlet groups with component subsets, a
    contact pair (P1)."""
    _check(_problem_3d(blocks, degree, scheme))


def test_a_failing_value_function_fails_on_every_rank(membranes):
    """The function raises only at points some ranks hold: every rank raises, naming it."""
    def bad(x):
        if np.any(x[:, 0] > 1.5):
            raise RuntimeError("too far")
        return np.zeros(x.shape[0])

    problem = _problem_2d(membranes, 1, "orthonormal")
    dec = decompose(membranes, problem.decomposition, COMM.size, problem.dof_points)
    inputs = RankInputs(problem, dec, dec.sub_rank, COMM.rank)
    inputs.conditions[1] = inputs.conditions[1]._replace(
        condition=df.Dirichlet("bottom", bad, components=(1,)))
    with pytest.raises(df.InputError, match=r"Dirichlet\('bottom'\)\.value\(x\) raised "
                                            "RuntimeError: too far"):
        _mask(problem, inputs, dec.sub_rank)


def test_non_finite_values_and_rows_are_refused_on_every_rank(membranes):
    problem = _problem_2d(membranes, 1, "orthonormal")
    dec = decompose(membranes, problem.decomposition, COMM.size, problem.dof_points)
    inputs = RankInputs(problem, dec, dec.sub_rank, COMM.rank)
    nan_far = df.Dirichlet("bottom", lambda x: np.where(x[:, 0] > 1.5, np.nan, 0.0),
                           components=(1,))
    broken = list(inputs.conditions)
    broken[1] = broken[1]._replace(condition=nan_far)
    inputs.conditions, good = broken, inputs.conditions
    with pytest.raises(df.InputError, match="Dirichlet on 'bottom': the value is not finite"):
        _mask(problem, inputs, dec.sub_rank)
    inputs.conditions = good
    fixed, values = _mask(problem, inputs, dec.sub_rank)
    node_ptr, node_subs = dec.node_subdomains()
    extra = _extra(problem, node_ptr, node_subs, dirichlet_mask(problem, membranes)[0])
    extra.rhs[-1] = np.inf  # a gap on one rank's row only
    with pytest.raises(df.InputError, match="non-finite constraint data"):
        own_rows(inputs.points, inputs.ptr, inputs.subs, fixed, values, 2, 2, "orthonormal",
                 dec.sub_rank, COMM, extra)


def test_shared_points():
    ptr = np.array([0, 1, 3, 5, 5])
    subs = np.array([0, 0, 2, 1, 2])
    sub_rank = np.array([0, 1, 1])
    assert shared_points(ptr, subs, sub_rank, 0).tolist() == [False, True, True, False]
    assert shared_points(ptr, subs, sub_rank, 1).tolist() == [True, True, False, False]
