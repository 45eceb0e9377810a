"""Mortar coupling of two surfaces on two meshes: bodies of different cell types.

A model whose bodies are of several cell types is held as one mesh per type
(:class:`~dolfinx_feti.mesh.mixed.MixedMesh`); a contact or tie between a body of one type and
a body of another couples a surface of one mesh to a surface of the other. The search and
the integrals are those of :mod:`.mortar` on the two meshes' nodes side by side (the master
mesh's numbered after the slave's); a triangle against a quadrilateral (a tetrahedral body on
a hexahedral one) is clipped like two quadrilaterals, each facet with its own reference map
and functions (:data:`.mortar_quad.TRIANGLE`, :data:`.mortar_quad.QUADRILATERAL`). In 2D both
sides are segments, whatever the cells.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..mesh.data import MeshData
from ..mesh.topology import facet_normals, facets_in_cell_order, nodal_normals_and_areas
from .mortar import (
    MortarCoupling,
    Search,
    candidate_pairs,
    default_search_distance,
    facet_integrals,
)


def mortar_coupling_between(slave_mesh: MeshData, slave: np.ndarray, master_mesh: MeshData,
                            master: np.ndarray, search_distance: float | None = None
                            ) -> MortarCoupling:
    """Search and integrate the mortar coupling of a surface of one mesh to one of another.

    Args:
        slave_mesh: The mesh of the slave surface (first order).
        slave: Its facets (vertices, node numbers of ``slave_mesh``).
        master_mesh: The mesh of the master surface (first order, same dimension).
        master: Its facets (node numbers of ``master_mesh``).
        search_distance: As for :func:`.mortar.mortar_coupling`.

    Returns:
        The coupling (:class:`.mortar.MortarCoupling`): slave nodes of ``slave_mesh``, M with
        one column per node of ``master_mesh``.
    """
    if slave_mesh.gdim != master_mesh.gdim:
        raise InputError("mortar coupling of meshes of different dimensions "
                         f"({slave_mesh.gdim} and {master_mesh.gdim})")
    if max(slave_mesh.geometry_degree, master_mesh.geometry_degree) != 1:
        raise InputError("mortar coupling between meshes of different cell types is "
                         "implemented for first-order meshes")
    xs, xm = slave_mesh.x, master_mesh.x
    slave = facets_in_cell_order(slave_mesh.cells, slave, slave_mesh.cell_type)
    master = facets_in_cell_order(master_mesh.cells, master, master_mesh.cell_type)
    ns, _ = facet_normals(xs, slave_mesh.cells, slave, slave_mesh.cell_type)
    nm, _ = facet_normals(xm, master_mesh.cells, master, master_mesh.cell_type)
    offset = xs.shape[0]
    x, master_x = np.vstack([xs, xm]), master + offset  # the two meshes' nodes side by side
    if search_distance is None:
        search_distance = default_search_distance(x, slave, master_x)
    i, j = candidate_pairs(x, slave, ns, master_x, nm, search_distance)
    nodes, normals, D = nodal_normals_and_areas(xs, slave_mesh.cells, slave,
                                                slave_mesh.cell_type)
    (r, c, v), npairs, D = facet_integrals(x, slave, ns, master_x, i, j, nodes, D)
    found = Search(slave, master, ns, i, j, float(search_distance), None)
    return found.coupling(nodes, normals, D, (r, c - offset, v), xm.shape[0], npairs)


__all__ = ["mortar_coupling_between"]
