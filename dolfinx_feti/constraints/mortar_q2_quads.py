"""Mortar coupling of biquadratic (9-node) quadrilateral facets in 3D: Q2 hexahedra.

A facet of a Q2 hexahedron (DOLFINx's degree-2 Lagrange space on hexahedra: the full tensor
product, not the 8-node serendipity element) carries 9 dof points: its 4 vertices, its 4
edge points and its centre. Its functions N = L_a(ξ) L_b(η), with the quadratic Lagrange
functions L_0 = (1 − t)(1 − 2t), L_1 = t(2t − 1), L_m = 4t(1 − t) of [0, 1], integrate to
1/36, 1/9 and 4/9 of a parallelogram's area at a vertex, an edge point and the centre: all
positive, so the dual basis ψ = A N with A = D_e M_e⁻¹ exists without the transformation that
6-node triangles need (Popp, Wohlmuth, Gee and Wall 2012 transform the 8-node serendipity
facet, whose vertex functions integrate to −1/12). As for bilinear facets
(:mod:`.mortar_quad`), A is computed per facet from its (bilinear, possibly warped)
geometry, and the overlaps are the same clipped polygons with the same inverse bilinear maps;
only the functions change. ψ_j N_l is of degree 4 per variable where both facets are
parallelograms, so the 25-point rule of each fan triangle (exact for degree 8) integrates it
exactly there.
"""

from __future__ import annotations

import numpy as np

from ..mesh.dofpoints import DofPoints
from ..mesh.topology import REFERENCE, surface_points
from . import mortar_quad
from .mortar import MortarCoupling, search

#: The edges of a quadrilateral in tensor order (basix's), whose points follow the vertices.
EDGES = REFERENCE["quadrilateral"].edges
#: Each point's position (ξ, η) on the reference square: vertices, edge points, centre.
NODES = np.array([(0, 0), (1, 0), (0, 1), (1, 1), *[(0.5 * (a % 2 + b % 2), 0.5 * (a // 2 + b // 2))
                                                    for a, b in EDGES], (0.5, 0.5)])


def _lagrange(t: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The quadratic Lagrange function of [0, 1] with node ``at`` (0, ½ or 1) at t."""
    return np.select([at == 0.0, at == 1.0],
                     [(1 - t) * (1 - 2 * t), t * (2 * t - 1)], 4 * t * (1 - t))


def shape(xi: np.ndarray) -> np.ndarray:
    """The 9 biquadratic functions at reference points ``xi`` (..., 2), shape (..., 9)."""
    s, t = xi[..., 0:1], xi[..., 1:2]
    return _lagrange(s, NODES[:, 0]) * _lagrange(t, NODES[:, 1])


def quad_points(points: DofPoints, quads: np.ndarray) -> np.ndarray:
    """The 9 dof points (in :data:`NODES` order) of quadrilaterals in tensor order (F, 4)."""
    edges = [points.lookup(1, np.sort(quads[:, list(e)], axis=1)) for e in EDGES]
    centre = points.lookup(2, np.sort(quads, axis=1))
    out = np.column_stack([quads, *edges, centre])
    if np.any(out < 0):
        raise ValueError("facets that belong to no cell")
    return out


def quad9_coupling(x: np.ndarray, cells: np.ndarray, slave: np.ndarray, master: np.ndarray,
                   points: DofPoints, search_distance: float | None = None,
                   cell_type: str | None = None, self_contact: bool = False
                   ) -> MortarCoupling:
    """The mortar coupling of two surfaces of 9-node quadrilaterals (:func:`.mortar_coupling`).

    Args:
        x: Vertex coordinates (N, 3) (a first-order mesh: bilinear facets).
        cells: Hexahedra (to orient the facets' outward normals).
        slave: Slave facets as vertex quadruples (any order).
        master: Master facets, the same.
        points: The dof points of the degree-2 space (the vertices first).
        search_distance: As for :func:`.mortar.mortar_coupling`.
        cell_type: The cells' type ("hexahedron").
        self_contact: One surface as slave and master (:mod:`.self_contact`).

    Returns:
        The coupling over dof points: ``slave_nodes`` and the columns of ``M`` are dof points.
    """
    found = search(x, cells, slave, master, search_distance, cell_type, self_contact)
    slave, ns, master, i, j = found.slave, found.ns, found.master, found.i, found.j
    sp_ = quad_points(points, slave)
    mp_ = quad_points(points, master)
    A, De = mortar_quad.dual_basis(x[slave], shape)
    nodes, normals, _ = surface_points(x, cells, slave, sp_, np.full(9, 1.0 / 9.0), cell_type)
    D = np.zeros(nodes.size)  # ∫ N_j on the facets' own geometry
    np.add.at(D, np.searchsorted(nodes, sp_), De)
    r, c, v, npairs = mortar_quad.pair_integrals(x, slave, ns, A, master, i, j, shape, sp_, mp_)
    return found.coupling(nodes, normals, D, (r, c, v), points.num_points, npairs)
