"""A smoothed contact pressure: the force over the area of each contact node's patch.

The solver's contact result is a nodal force f_j per contact row. Two pressures follow from it:

- ``ContactData.pressure`` = f_j / D_j, D_j = ∫ N_j (the force over the node's lumped area).
  For mortar rows it is exactly the coefficient of the discrete multiplier field
  Σ_j (f_j / D_j) ψ_j in the dual basis (∫ ψ_j N_k = δ_jk D_j); for node-to-node and
  obstacle rows the same formula. It is local and exact for a uniform pressure, but it
  scatters from node to node on unstructured meshes.
- :func:`smoothed_pressure`: p̄_j = Σ_{k ∈ P(j)} f_k / Σ_{k ∈ P(j)} D_k over the patch P(j) of
  the points that share a facet with j (j included): the mean traction over the facets around
  the node, by the forces they carry. Exact for a uniform pressure; on a smooth pressure it
  errs by O(h²) (it averages over about two facet sizes), and it smears a sharp front (the edge
  of the contact zone) over one more facet.

Not offered: the L2 projection of the forces onto the surface's Lagrange space (M_s p = f
with the consistent mass matrix), which reproduces any pressure of that space exactly but
amplifies the node-to-node noise of the forces: on the sphere of ``tests/test_contact_fields.py``
its error against Hertz was 15 % RMS, against 6.7 % for f_j / D_j and 2.1 % for p̄
(``bench/contact_pressure_fields.py``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..constraints.quadratic_triangles import ALPHA
from ..constraints.quadratic_triangles import EDGES as _TRI_EDGES
from ..constraints.segment3 import shape as shape3
from ..mesh.topology import FACET_TYPE

_G, _GW = np.polynomial.legendre.leggauss(4)
_G, _GW = 0.5 + 0.5 * _G, 0.5 * _GW  # on [0, 1], exact for degree 7


def _l2(t: np.ndarray) -> np.ndarray:
    """1D quadratic Lagrange functions (0, 1, midpoint) at t, shape t.shape + (3,)."""
    return shape3(t)


def _rule(facet: str) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature points (q, tdim) and weights on the reference facet (measure 1 or 1/2)."""
    if facet == "interval":
        return _G[:, None], _GW
    if facet == "quadrilateral":
        r, s = np.meshgrid(_G, _G, indexing="ij")
        return np.c_[r.ravel(), s.ravel()], np.outer(_GW, _GW).ravel()
    # triangle: the collapsed square (Duffy), exact for polynomials of degree 6
    r, s = np.meshgrid(_G, _G, indexing="ij")
    w = np.outer(_GW, _GW) * (1.0 - r)
    return np.c_[r.ravel(), (s * (1.0 - r)).ravel()], w.ravel()


def _shape(facet: str, degree: int, q: np.ndarray) -> np.ndarray:
    """The shape functions of the facet's dof points at q, shape (q, k).

    In the order of :meth:`.DofPoints.facet_points`: vertices, then edges, then the face.
    """
    if facet == "interval":
        t = q[:, 0]
        return np.c_[1.0 - t, t] if degree == 1 else _l2(t)
    r, s = q[:, 0], q[:, 1]
    if facet == "triangle":
        L = np.c_[1.0 - r - s, r, s]
        if degree == 1:
            return L
        # the transformed basis of the contact rows (constraints/quadratic_triangles.py)
        Ne = np.stack([4.0 * L[:, i] * L[:, j] for i, j in _TRI_EDGES], axis=1)
        Nv = L * (2.0 * L - 1.0)
        Nv = Nv + ALPHA * np.stack([Ne[:, [k for k, e in enumerate(_TRI_EDGES) if v in e]]
                                    .sum(axis=1) for v in range(3)], axis=1)
        return np.c_[Nv, (1.0 - 2.0 * ALPHA) * Ne]
    if degree == 1:
        return np.c_[(1 - r) * (1 - s), r * (1 - s), (1 - r) * s, r * s]
    a, b = _l2(r), _l2(s)  # (q, 3): 0, 1, mid
    # vertices in tensor order; the edges (0,1), (0,2), (1,3), (2,3); the face
    return np.c_[a[:, 0] * b[:, 0], a[:, 1] * b[:, 0], a[:, 0] * b[:, 1], a[:, 1] * b[:, 1],
                 a[:, 2] * b[:, 0], a[:, 0] * b[:, 2], a[:, 1] * b[:, 2], a[:, 2] * b[:, 1],
                 a[:, 2] * b[:, 2]]


def _jacobians(xv: np.ndarray, facet: str, q: np.ndarray) -> np.ndarray:
    """|det| of the map from the reference facet at each point, (F, q).

    Straight segments, flat triangles, bilinear quadrilaterals (vertices in tensor order).
    """
    if facet == "interval":
        return np.repeat(np.linalg.norm(xv[:, 1] - xv[:, 0], axis=1)[:, None], q.shape[0], 1)
    if facet == "triangle":  # facets of tetrahedra: 3D
        area2 = np.linalg.norm(np.cross(xv[:, 1] - xv[:, 0], xv[:, 2] - xv[:, 0]), axis=1)
        return np.repeat(area2[:, None], q.shape[0], 1)
    r, s = q[:, 0], q[:, 1]
    dr = (xv[:, None, 1] - xv[:, None, 0]) * (1 - s)[None, :, None] + \
        (xv[:, None, 3] - xv[:, None, 2]) * s[None, :, None]
    ds = (xv[:, None, 2] - xv[:, None, 0]) * (1 - r)[None, :, None] + \
        (xv[:, None, 3] - xv[:, None, 1]) * r[None, :, None]
    return np.linalg.norm(np.cross(dr, ds), axis=-1)


def surface_mass(x: np.ndarray, facet_points: np.ndarray, cell_type: str, degree: int,
                 num_points: int) -> sp.csr_matrix:
    """The consistent mass matrix ∫ N_i N_j of a surface, over the dof points (all of them).

    Args:
        x: Vertex coordinates.
        facet_points: The points of each facet, (F, k), from :meth:`.DofPoints.facet_points`
            (the first ``vertices per facet`` columns are the facet's vertices).
        cell_type: The cells' type.
        degree: The Lagrange degree.
        num_points: Number of dof points (the size of the matrix).
    """
    facet = FACET_TYPE[cell_type]
    q, w = _rule(facet)
    N = _shape(facet, degree, q)
    nv = {"interval": 2, "triangle": 3, "quadrilateral": 4}[facet]
    J = _jacobians(x[facet_points[:, :nv]], facet, q)
    Me = np.einsum("fq,q,qi,qj->fij", J, w, N, N)
    k = facet_points.shape[1]
    rows = np.repeat(facet_points, k, axis=1).ravel()
    cols = np.tile(facet_points, (1, k)).ravel()
    M = sp.csr_matrix((Me.ravel(), (rows, cols)), shape=(num_points, num_points))
    M.sum_duplicates()
    return M


def smoothed_pressure(x: np.ndarray, facet_points: np.ndarray, cell_type: str, degree: int,
                      num_points: int, node: np.ndarray, force: np.ndarray) -> np.ndarray:
    """The patch-averaged pressure p̄ of one surface, at the given contact nodes.

    Args:
        x: Vertex coordinates (or the dof points', whose first rows are the vertices).
        facet_points: As for :func:`surface_mass`.
        cell_type: The cells' type.
        degree: The Lagrange degree.
        num_points: Number of dof points.
        node: The dof points of the contact rows on this surface.
        force: Their nodal forces (points of the surface without a row carry none).

    Returns:
        p̄ at ``node``.
    """
    D = np.asarray(surface_mass(x, facet_points, cell_type, degree, num_points)
                   .sum(axis=1)).ravel()  # ∫ N_j
    F, k = facet_points.shape
    inc = sp.csr_matrix((np.ones(F * k), (np.repeat(np.arange(F), k), facet_points.ravel())),
                        shape=(F, num_points))
    patch = (inc.T @ inc)[node]  # the points sharing a facet with each node
    patch.data[:] = 1.0
    f = np.zeros(num_points)
    np.add.at(f, node, force)
    return (patch @ f) / (patch @ D)
