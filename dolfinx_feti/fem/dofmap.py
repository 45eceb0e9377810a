"""The bridge between DOLFINx's dof numbering and the library's global dof points.

A dof of a Lagrange space of degree 1 or 2 sits on one entity of a cell (a vertex, an edge, a
face or the interior); the entity is known by its vertices, and through the global vertex
numbers of the mesh by the global dof point (:mod:`..mesh.dofpoints`). The map is topological
(no coordinates are compared), so it is exact, and it serves the serial subdomain meshes (to
put K_i and f_i into the canonical order) as well as the user's distributed mesh (to put the
solution into a Function on it).
"""

from __future__ import annotations

import numpy as np

from .. import compat
from ..mesh.dofpoints import DofPoints
from ..mesh.topology import REFERENCE


def local_entities(cell_type: str) -> dict[int, tuple[tuple[int, ...], ...]]:
    """dim → the reference entities of that dimension as lists of local vertices."""
    ref = REFERENCE[cell_type]
    out = {0: tuple((i,) for i in range(ref.num_vertices)), 1: ref.edges,
           ref.tdim: (tuple(range(ref.num_vertices)),)}
    if ref.tdim == 3:
        out[2] = ref.facets
    return out


def cell_dof_points(V, vertex_id: np.ndarray, points: DofPoints
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The dofs of each local cell of ``V`` and the global dof points they sit on.

    Args:
        V: A Lagrange space of degree ``points.degree``.
        vertex_id: The global vertex number of each local geometry node of V's mesh (only the
            entries of vertices are read).
        points: The global dof points.

    Returns:
        ``(dofs, pts)``, both (C, dofs per cell): V's (blocked) dofs and their dof points.

    Raises:
        ValueError: If an entity of the mesh has no dof point (the mesh is not the one the
            points were made for).
    """
    local = local_entities(points.cell_type)
    nv = len(local[0])
    geom = compat.cell_geometry_nodes(compat.space_mesh(V))[:, :nv]  # the vertices come first
    cv = np.asarray(vertex_id, dtype=np.int64)[geom]
    dofs = compat.cell_dofs(V)
    layout = compat.dof_entities(V, {dim: len(ents) for dim, ents in local.items()})
    pts = np.empty(dofs.shape, dtype=np.int64)
    for dim in sorted({d for d, _ in layout}):
        cols = [j for j, (d, _) in enumerate(layout) if d == dim]
        ents = np.array([local[dim][layout[j][1]] for j in cols])  # (ncols, vertices)
        v = cv[:, ents]  # (C, ncols, vertices)
        found = points.lookup(dim, v.reshape(-1, v.shape[2]))
        pts[:, cols] = found.reshape(v.shape[:2])
    if np.any(pts < 0):
        raise ValueError("a mesh entity carries a dof but has no dof point")
    return dofs, pts


def dof_points_of_space(V, vertex_id: np.ndarray, points: DofPoints) -> np.ndarray:
    """The global dof point of each local (blocked) dof of ``V``, owned and ghost."""
    dofs, pts = cell_dof_points(V, vertex_id, points)
    out = np.full(compat.dof_count(V), -1, dtype=np.int64)
    out[dofs] = pts
    return out


__all__ = ["cell_dof_points", "dof_points_of_space"]
