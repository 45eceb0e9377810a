"""The normal of a mortar row: the slave's averaged normal, or the flatter side's.

A mortar row measures the gap and carries its force along one normal per slave node, by
default the average of the slave facets' normals around it (Popp, Gee and Wall 2009). Where
the slave surface bends within the contact zone and the master does not — a punch's flat
meeting its fillet on a flat block — the averaged slave normals tilt off the interface's
normal, so the normal forces carry part of the tangential load: the sum of the friction
forces is not the applied shear, and a friction bound |t| <= μ p is checked in a tilted frame.
The interface there is the master surface, and its normal is the one to use.

``Mortar(..., normals="flatter")`` takes, per slave node j, the normal of the flatter of the two
surfaces over the node's support:

- the slave's: n_j (the averaged normal), bent by cos_s = min over the slave facets f ∋ j of
  b_f, b_f = min over the vertices v of f of n_f · n_v (the facet's normal against the
  averaged normals at its vertices: an edge point of a 3-node segment bends as its ends);
- the master's: m_j = −normalize(Σ_k |M_jk| m_k) with m_k the master's averaged normal at the
  master points k the row couples to (M_jk ≠ 0), bent by cos_m = min over those k of
  min(m_k · (−m_j), the same b_g over the master facets g ∋ k);

and uses the master's where cos_m > cos_s. On a flat master every row of the slave's curved
or kinked part gets the master's normal exactly; on a flat slave against a curved or kinked
master (a punch as master) the slave's stays. Both are unit vectors facing the same way, and
the gap of the row is measured along the chosen one (:meth:`.MortarCoupling.weighted_gap`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..mesh.data import MeshData
from ..mesh.dofpoints import DofPoints, dof_points
from ..mesh.topology import facet_normals, surface_points
from .mortar import MortarCoupling

#: The normal choices of a :class:`~dolfinx_feti.Mortar` condition.
CHOICES = ("slave", "flatter")


def _bend(mesh: MeshData, facets: np.ndarray, facet_points: np.ndarray,
          points: np.ndarray) -> np.ndarray:
    """cos of how much the surface bends about each of ``points``.

    A facet bends by the largest angle between its normal and the averaged normals at its
    vertices; a point by the most any facet holding it bends. Measured at the vertices, an
    edge point of a 3-node segment (on one facet only) bends as its segment's ends do.
    """
    fn, _ = facet_normals(mesh.x, mesh.cells, facets, mesh.cell_type)
    nv = facets.shape[1]
    verts, vn, _ = surface_points(mesh.x, mesh.cells, facets, facets, np.ones(nv),
                                  mesh.cell_type)
    at = np.searchsorted(verts, facets)
    per_facet = np.einsum("fd,fvd->fv", fn, vn[at]).min(axis=1)
    pos = np.minimum(np.searchsorted(points, facet_points), points.size - 1)
    f, k = np.nonzero(points[pos] == facet_points)  # facet points among ``points``
    cos = np.ones(points.size)
    np.minimum.at(cos, pos[f, k], per_facet[f])
    return cos


def flatter_normals(mesh: MeshData, slave: str, master: str, coupling: MortarCoupling,
                    points: DofPoints | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per slave node of ``coupling``, the outward slave normal of the flatter side.

    Args:
        mesh: The mesh.
        slave: The slave boundary group (for self-contact its zones, ``coupling.zones[0]``).
        master: The master boundary group.
        coupling: The mortar coupling.
        points: The space's dof points; the vertices when None.

    Returns:
        ``(normals, from_master)``: unit normals (slave outward, as ``coupling.normals``) and
        the mask of the nodes that took the master's.
    """
    pts = dof_points(mesh, 1) if points is None else points
    nodes, n_s = coupling.slave_nodes, coupling.normals
    s_facets = mesh.facets(slave) if coupling.zones is None else coupling.zones[0]
    cos_s = _bend(mesh, s_facets, pts.facet_points(mesh, s_facets), nodes)
    m_facets = mesh.facets(master)
    m_fp = pts.facet_points(mesh, m_facets)
    m_nodes, m_n, _ = surface_points(mesh.x, mesh.cells, m_facets, m_fp, pts.facet_weights,
                                     mesh.cell_type)
    cos_pm = _bend(mesh, m_facets, m_fp, m_nodes)
    W = abs(coupling.M).tocoo()
    at = np.searchsorted(m_nodes, W.col)
    ok = (at < m_nodes.size) & (m_nodes[np.minimum(at, m_nodes.size - 1)] == W.col)
    row, at, w = W.row[ok], at[ok], W.data[ok]
    acc = np.zeros_like(n_s)
    np.add.at(acc, row, w[:, None] * m_n[at])
    norm = np.linalg.norm(acc, axis=1)
    covered = norm > 0.0
    m_row = acc / np.where(covered, norm, 1.0)[:, None]  # the master's normal at each row
    cos_m = np.ones(nodes.size)
    np.minimum.at(cos_m, row, np.minimum(cos_pm[at], np.einsum("ij,ij->i", m_n[at], m_row[row])))
    take = covered & (cos_m > cos_s + 1e-12)
    return np.where(take[:, None], -m_row, n_s), take


def with_normals(mesh: MeshData, slave: str, master: str, coupling: MortarCoupling,
                 choice: str, points: DofPoints | None = None) -> MortarCoupling:
    """The coupling with the normals of ``choice`` (one of :data:`CHOICES`)."""
    if choice == "slave":
        return coupling
    normals, _ = flatter_normals(mesh, slave, master, coupling, points)
    return dataclasses.replace(coupling, normals=normals)
