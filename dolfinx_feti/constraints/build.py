"""Building all constraint rows of a decomposed problem, in a rank-independent order."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..mesh.decompose import Decomposition
from ..problem import ContactProblem, Mortar, NodeToNode, RigidObstacle
from .contact import node_to_node_rows, obstacle_rows
from .dirichlet import dirichlet_mask, dirichlet_rows
from .friction import with_tangential_rows
from .gluing import gluing_rows
from .mortar_rows import MortarInfo, mortar_contact_rows, tie_rows
from .quadratic_triangles import needs_transform, transform_rows
from .rows import Rows


def surface_rows(problem: ContactProblem, node_ptr: np.ndarray, node_subs: np.ndarray,
                 fixed: np.ndarray, mortar: list[MortarInfo] | None = None) -> list[Rows]:
    """The rows of the ties and the contact conditions, in the problem's order.

    They read only the contact surfaces, so ``problem`` may be a problem on a mesh of the
    cells along them (a distributed mesh gathers those on one rank).

    Args:
        problem: The problem.
        node_ptr: Dof point → subdomains holding it (CSR pointer) ...
        node_subs: ... and the subdomains.
        fixed: (points, bs) mask of the Dirichlet-constrained components.
        mortar: Receives what the search found for each mortar condition, when given.
    """
    mesh, bs, points = problem.mesh, problem.value_size, problem.dof_points
    blocks = []
    found = [] if mortar is None else mortar
    for i, t in enumerate(problem.ties):
        block, info = tie_rows(mesh, t, i, node_ptr, node_subs, fixed, bs, points)
        blocks.append(block)
        found.append(info)
    for i, c in enumerate(problem.contact):
        if isinstance(c, Mortar):
            block, info = mortar_contact_rows(mesh, c, i, node_ptr, node_subs, bs, points)
            blocks.append(block)
            found.append(info)
        elif isinstance(c, NodeToNode):
            blocks.append(node_to_node_rows(mesh, c, i, node_ptr, node_subs, bs, points))
        elif isinstance(c, RigidObstacle):
            blocks.append(obstacle_rows(mesh, c, i, node_ptr, node_subs, points))
        if needs_transform(mesh, points) and not isinstance(c, Mortar):  # 6-node triangles
            groups = (c.group,) if isinstance(c, RigidObstacle) else (c.slave, c.master)
            blocks[-1] = transform_rows(blocks[-1], mesh, points, groups)
        if getattr(c, "friction", None) is not None:  # tangential rows next to the normal ones
            blocks[-1] = with_tangential_rows(blocks[-1])
    return blocks


def build_rows(problem: ContactProblem, dec: Decomposition,
               mortar: list[MortarInfo] | None = None) -> Rows:
    """Gluing, Dirichlet and contact rows, sorted by the subdomain that owns them.

    ``mortar``, when given, receives what the contact search found for each :class:`Mortar`
    and :class:`Tie` condition (for the report and the post-solve checks).

    Rows are sorted (stably) by the smallest subdomain they touch, so the rows owned by a rank
    are contiguous and the global order does not depend on the number of ranks. The normal and
    tangential (friction) rows of a contact node touch the same subdomains, so they stay
    consecutive.
    """
    mesh, bs = problem.mesh, problem.value_size
    node_ptr, node_subs = dec.node_subdomains()
    fixed, values = dirichlet_mask(problem, mesh)
    blocks = [gluing_rows(node_ptr, node_subs, fixed, bs, mesh.gdim, problem.gluing),
              dirichlet_rows(node_ptr, node_subs, fixed, values, bs, mesh.gdim),
              *surface_rows(problem, node_ptr, node_subs, fixed, mortar)]
    rows = Rows.concatenate(blocks)
    if not np.all(np.isfinite(rows.rhs)) or not np.all(np.isfinite(rows.e_coef)):
        raise InputError("non-finite constraint data (a Dirichlet value, a gap or an obstacle "
                         "distance is NaN or Inf)")
    return rows.permuted(np.argsort(rows.min_subdomain(), kind="stable"))
