"""Dirichlet rows of Total FETI: u = u_D on every subdomain copy of a constrained node."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..mesh.data import MeshData
from ..problem.conditions import Dirichlet
from ..problem.contact_problem import ContactProblem
from ..validation import evaluate
from .rows import Kind, Rows


def dirichlet_mask(problem: ContactProblem, mesh: MeshData) -> tuple[np.ndarray, np.ndarray]:
    """(N, bs) masks of constrained components and their values (later conditions win).

    N is the number of dof points: every dof point on a group's facets (vertices, and for
    degree 2 the edge and face points too) is constrained, with the value at its position.
    """
    bs = problem.value_size
    points = problem.dof_points
    fixed = np.zeros((points.num_points, bs), dtype=bool)
    values = np.zeros((points.num_points, bs))
    for bc in problem.dirichlet:
        nodes = points.group_points(mesh, bc.group)
        comps, v = condition_values(bc, points.x[nodes], bs)
        for j, c in enumerate(comps):
            fixed[nodes, c] = True
            values[nodes, c] = v[:, j]
    return fixed, values


def condition_values(bc: Dirichlet, x: np.ndarray, bs: int) -> tuple[list[int], np.ndarray]:
    """The components a condition fixes and its values at the points ``x`` (n, gdim).

    Returns:
        The components, and the values (n, len(components)).

    Raises:
        InputError: Naming the condition, for a wrong number of values, a value function that
            fails or returns another shape, or a value that is not finite.
    """
    n = x.shape[0]
    comps = list(range(bs)) if bc.components is None else [int(c) for c in bc.components]
    if callable(bc.value):
        v = evaluate(bc.value, x, f"Dirichlet({bc.group!r}).value",
                     [(n,), (n, len(comps))]).reshape(n, -1)
        if v.shape[1] == 1:
            v = np.repeat(v, len(comps), axis=1)
    else:
        v = np.asarray(bc.value, dtype=float).ravel()
        if v.size not in (1, len(comps)):
            raise InputError(f"Dirichlet on {bc.group!r}: {v.size} values for "
                             f"{len(comps)} components")
        v = np.broadcast_to(v, (n, len(comps)))
    if v.shape[1] != len(comps):
        raise InputError(f"Dirichlet on {bc.group!r}: {v.shape[1]} values for "
                         f"{len(comps)} components")
    if not np.all(np.isfinite(v)):
        raise InputError(f"Dirichlet on {bc.group!r}: the value is not finite")
    return comps, v


def dirichlet_rows(node_ptr: np.ndarray, node_subs: np.ndarray, fixed: np.ndarray,
                   values: np.ndarray, bs: int, gdim: int) -> Rows:
    """One row e_(s,node,c) = u_D per constrained component and per subdomain holding the node."""
    node, comp = np.nonzero(fixed)
    count = np.diff(node_ptr)[node]
    row_node = np.repeat(node, count)
    row_comp = np.repeat(comp, count)
    start = np.repeat(node_ptr[node], count)
    offset = np.arange(row_node.size) - np.repeat(np.cumsum(count) - count, count)
    subs = node_subs[start + offset]
    n = row_node.size
    return Rows(e_row=np.arange(n), e_sub=subs.astype(np.int32), e_node=row_node,
                e_comp=row_comp.astype(np.int8), e_coef=np.ones(n),
                rhs=values[row_node, row_comp], kind=np.full(n, Kind.DIRICHLET, dtype=np.int8),
                scale=np.ones(n), node=row_node, partner=np.full(n, -1),
                normal=np.zeros((n, gdim)), spec=np.full(n, -1, dtype=np.int32))
