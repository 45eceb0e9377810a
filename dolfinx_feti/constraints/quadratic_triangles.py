"""Nodal contact rows on quadratic (6-node) triangular facets: the transformed basis.

The vertex functions of a 6-node triangle integrate to zero over it (the edge functions to
|T|/3 each), so a nodal contact row at a vertex of a P2 tetrahedron's surface carries no area:
a uniform pressure gives it no force, and the force over the lumped area is no pressure. The
remedy of Popp, Wohlmuth, Gee and Wall (2012) (also Wohlmuth, Popp, Gee and Wall 2012) is a
local change of basis on the contact surface,

    Ñ_v = N_v + α Σ_{edges e ∋ v} N_e,        Ñ_e = (1 − 2α) N_e,        α = 1/5,

which is still a partition of unity and has positive integrals ∫ Ñ_v = 2|T|/15 and
∫ Ñ_e = |T|/5 per facet. In it a displacement u = Σ N_k u_k = Σ Ñ_k ũ_k has the coefficients
ũ_v = u_v at the vertices and ũ_e = (u_e − α(u_a + u_b)) / (1 − 2α) at the point of the edge
(a, b). So the rows are the usual nodal rows (node-to-node, rigid obstacle) written for ũ: an
entry c·u_e of a row becomes c/(1 − 2α)·u_e − cα/(1 − 2α)·(u_a + u_b); a row's multiplier is then
the force conjugate to ũ_j, and the pressure the force over ∫ Ñ_j
(:data:`.mesh.dofpoints` weights of degree-2 triangles). On straight-sided (first-order)
geometry the position of the edge point in the new basis is the edge's midpoint, the same
point, so the gaps stay (a curved mesh would move it off the surface: refused for now). A
linear displacement keeps ũ = u, so the patch test stays exact.
"""

from __future__ import annotations

import numpy as np

from ..mesh.data import MeshData
from ..mesh.dofpoints import DofPoints
from .rows import Rows

#: The transformation's coefficient (Popp, Wohlmuth, Gee and Wall 2012).
ALPHA = 0.2
#: The vertices (local) of the edges of a triangle, in the order of its edge points (basix).
EDGES = ((1, 2), (0, 2), (0, 1))


def needs_transform(mesh: MeshData, points: DofPoints | None) -> bool:
    """Whether the contact surfaces are 6-node triangles (P2 tetrahedra)."""
    return points is not None and points.degree == 2 and mesh.cell_type == "tetrahedron"


def edge_vertices(mesh: MeshData, points: DofPoints, groups) -> tuple[np.ndarray, np.ndarray]:
    """The edge points of the groups' facets (sorted) and their two vertices (E, 2)."""
    fp = np.concatenate([points.facet_points(mesh, mesh.facets(g)) for g in groups])
    e = fp[:, 3:].ravel()
    ab = np.stack([fp[:, list(v)] for v in EDGES], axis=1).reshape(-1, 2)
    e, first = np.unique(e, return_index=True)
    return e, ab[first]


def transform_rows(rows: Rows, mesh: MeshData, points: DofPoints, groups,
                   own_only: bool = False) -> Rows:
    """The rows written for the transformed coefficients ũ (see the module's text).

    Args:
        rows: Nodal contact rows (node-to-node or obstacle) at the dof points of ``groups``.
        mesh: The mesh.
        points: Its dof points (degree 2).
        groups: The boundary groups the rows' nodes lie on (slave and master).
        own_only: Transform only each row's entries at its own node (mortar rows: the slave
            side is in ũ, the master side keeps the plain basis; :mod:`.mortar_p2_triangles`).
    """
    e, ab = edge_vertices(mesh, points, groups)
    if e.size == 0:
        return rows
    pos = np.minimum(np.searchsorted(e, rows.e_node), e.size - 1)
    hit = e[pos] == rows.e_node
    if own_only:
        hit &= rows.e_node == rows.node[rows.e_row]
    k = np.flatnonzero(hit)
    c = rows.e_coef[k] / (1.0 - 2.0 * ALPHA)
    coef = rows.e_coef.copy()
    coef[k] = c
    extra_node = ab[pos[k]].ravel()  # the two vertices of each edge entry
    extra = {"e_row": np.repeat(rows.e_row[k], 2), "e_node": extra_node,
             # the edge point's subdomain: its cell holds the edge's vertices too, so the
             # row stays with the subdomains (and the rank) of its own point
             "e_sub": np.repeat(rows.e_sub[k], 2),
             "e_comp": np.repeat(rows.e_comp[k], 2), "e_coef": np.repeat(-ALPHA * c, 2)}
    out = {"e_row": rows.e_row, "e_node": rows.e_node, "e_sub": rows.e_sub,
           "e_comp": rows.e_comp, "e_coef": coef}
    merged = {name: np.concatenate([out[name], extra[name]]) for name in out}
    order = np.lexsort((merged["e_comp"], merged["e_node"], merged["e_row"]))
    return Rows(**{name: merged[name][order] for name in merged}, rhs=rows.rhs,
                kind=rows.kind, scale=rows.scale, node=rows.node, partner=rows.partner,
                normal=rows.normal, spec=rows.spec)
