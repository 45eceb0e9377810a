"""Building all constraint rows of a decomposed problem, in a rank-independent order."""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..problem.conditions import Mortar, NodeToNode, RigidObstacle, Tie
from ..problem.contact_problem import ContactProblem
from .contact import node_to_node_rows, obstacle_rows
from .friction import with_tangential_rows
from .mortar_rows import MortarInfo, mortar_contact_rows, tie_rows
from .quadratic_triangles import needs_transform, transform_rows
from .rows import Rows


class SurfaceCondition(NamedTuple):
    """What a row builder gets: the problem, the condition and where its rows go."""

    problem: ContactProblem
    spec: object
    index: int
    node_ptr: np.ndarray
    node_subs: np.ndarray
    fixed: np.ndarray


#: Condition type → its row builder, ``builder(SurfaceCondition) -> (Rows, MortarInfo | None)``
#: (the info for the report's search summary of mortar conditions). A new kind of contact
#: or tie is a dataclass in ``problem.py`` and a builder registered here by :func:`rows_of`.
ROW_BUILDERS: dict[type, Callable[[SurfaceCondition], tuple[Rows, MortarInfo | None]]] = {}


def rows_of(kind: type):
    """Register the decorated function as the row builder of conditions of type ``kind``."""
    def register(builder):
        ROW_BUILDERS[kind] = builder
        return builder
    return register


@rows_of(Mortar)
def _mortar(c: SurfaceCondition):
    p = c.problem
    return mortar_contact_rows(p.mesh, c.spec, c.index, c.node_ptr, c.node_subs, p.value_size,
                               p.dof_points)


@rows_of(Tie)
def _tie(c: SurfaceCondition):
    p = c.problem
    return tie_rows(p.mesh, c.spec, c.index, c.node_ptr, c.node_subs, c.fixed, p.value_size,
                    p.dof_points)


@rows_of(NodeToNode)
def _node_to_node(c: SurfaceCondition):
    p = c.problem
    # solved by Newton, a pair's normal turns with the deformed master surface
    newton = getattr(p.forms, "solve_by", None) == "newton"
    return node_to_node_rows(p.mesh, c.spec, c.index, c.node_ptr, c.node_subs, p.value_size,
                             p.dof_points, all_components=newton), None


@rows_of(RigidObstacle)
def _obstacle(c: SurfaceCondition):
    p = c.problem
    return obstacle_rows(p.mesh, c.spec, c.index, c.node_ptr, c.node_subs, p.dof_points), None


def surface_rows(problem: ContactProblem, node_ptr: np.ndarray, node_subs: np.ndarray,
                 fixed: np.ndarray, mortar: list[MortarInfo] | None = None) -> list[Rows]:
    """The rows of the ties and the contact conditions, in the problem's order.

    They read only the contact surfaces, so ``problem`` may be a problem on a mesh of the
    cells along them (a distributed mesh gathers those on one rank). Each condition's rows
    come from the builder registered for its type (:data:`ROW_BUILDERS`); a condition with
    friction gets its tangential rows next to its normal ones.

    Args:
        problem: The problem.
        node_ptr: Dof point → subdomains holding it (CSR pointer) ...
        node_subs: ... and the subdomains.
        fixed: (points, bs) mask of the Dirichlet-constrained components.
        mortar: Receives what the search found for each mortar condition, when given.
    """
    blocks = []
    found = [] if mortar is None else mortar
    for conditions in (problem.ties, problem.contact):
        for i, spec in enumerate(conditions):
            block, info = ROW_BUILDERS[type(spec)](
                SurfaceCondition(problem, spec, i, node_ptr, node_subs, fixed))
            if info is not None:
                found.append(info)
            if needs_transform(problem.mesh, problem.dof_points):  # 6-node triangles
                # mortar rows: the slave side only (its own entries), in the basis ũ
                block = transform_rows(block, problem.mesh, problem.dof_points,
                                       (spec.slave,) if info is not None else spec.groups,
                                       own_only=info is not None)
            if getattr(spec, "friction", None) is not None:  # tangential rows beside normal
                block = with_tangential_rows(block, fixed)
            blocks.append(block)
    return blocks
