"""Mortar coupling of quadratic (3-node) segments in 2D: P2 triangles, Q2 quadrilaterals.

The facets of a degree-2 space in 2D carry three dof points: the two vertices a, b and the
edge point e. On a straight segment with parameter s ∈ [0, 1] (a → b) the shape functions are
N_a = (1 − s)(1 − 2s), N_b = s(2s − 1), N_e = 4s(1 − s), whose integrals over the segment,
L/6, L/6 and 2L/3, are all positive. So the dual (biorthogonal) basis exists without the basis
transformation that quadratic triangles in 3D need (Popp, Wohlmuth, Gee and Wall 2012: there
the vertex functions integrate to zero): ψ_j = Σ_k A_jk N_k with A = D_e M_e⁻¹, D_e the
diagonal of the integrals, M_e the mass matrix of one segment (both proportional to L, so A is
one constant matrix), which gives ∫ ψ_j N_k = δ_jk ∫ N_k (Wohlmuth 2000).

The overlap of a slave segment with a master segment projected onto its line along its normal
is an interval, as for linear segments (:mod:`.mortar`); ψ_j N_k∘π is of degree 4 on it, so a
3-point Gauss rule integrates M exactly. The rows are those of linear mortar
(:mod:`.mortar_rows`), at the dof points: u_j − Σ_k (M_jk / C_j) u_k. The facets are taken as
straight (first-order geometry): a curved (second-order) mesh is refused by the problem's
checks for mortar until its facets are integrated as curves.
"""

from __future__ import annotations

import numpy as np

from ..mesh.dofpoints import DofPoints
from ..mesh.topology import surface_points
from . import mortar_p2_curved
from .mortar import MortarCoupling, search, segment_overlaps
from .mortar_p2_triangles import triangle6_coupling
from .mortar_q2_quads import quad9_coupling
from .segment3 import WEIGHTS, shape

# Gauss–Legendre on [0, 1], 3 points: exact for degree 5.
_GX = 0.5 + 0.5 * np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GW = np.array([5.0, 8.0, 5.0]) / 18.0


def dual_coefficients() -> np.ndarray:
    """A with ψ = A N on every straight segment: A = D_e M_e⁻¹ (per unit length)."""
    N = shape(_GX)  # (3 points, 3 functions); the mass matrix is of degree 4: exact
    Me = np.einsum("q,qi,qj->ij", _GW, N, N)
    return np.diag(WEIGHTS) @ np.linalg.inv(Me)


_A = dual_coefficients()


def segment_points(points: DofPoints, facets: np.ndarray) -> np.ndarray:
    """The dof points (a, b, e) of each segment given by its vertices (a, b)."""
    e = points.lookup(1, np.sort(facets, axis=1))
    if np.any(e < 0):
        raise ValueError("facets that belong to no cell")
    return np.c_[facets, e]


def _curved(points: DofPoints, seg: np.ndarray) -> bool:
    """Whether any segment's edge point is off its chord's midpoint (a curved mesh)."""
    X = points.x[seg]
    off = np.linalg.norm(X[:, 2] - 0.5 * (X[:, 0] + X[:, 1]), axis=1)
    return bool(np.any(off > 1e-12 * np.linalg.norm(X[:, 1] - X[:, 0], axis=1)))


def _pair_integrals(x, slave, master, sp_, mp_, i, j):
    """(slave point, master point, M entry) of each pair's overlap, and the pairs kept."""
    i, j, lo, hi, xi0, span, L = segment_overlaps(x, slave, master, i, j)
    vals = np.zeros((i.size, 3, 3))
    for q, w in zip(_GX, _GW, strict=True):
        s = lo + q * (hi - lo)
        eta = (s - xi0) / span
        psi = shape(s) @ _A.T
        vals += (w * (hi - lo) * L)[:, None, None] * psi[:, :, None] * shape(eta)[:, None, :]
    rows = np.repeat(sp_[i], 3, axis=1).ravel()
    cols = np.tile(mp_[j], (1, 3)).ravel()
    return rows, cols, vals.ravel(), i.size


def quadratic_coupling(x: np.ndarray, cells: np.ndarray, slave: np.ndarray, master: np.ndarray,
                       points: DofPoints, search_distance: float | None = None,
                       cell_type: str | None = None, self_contact: bool = False
                       ) -> MortarCoupling:
    """The mortar coupling of two surfaces of 3-node segments (see :func:`.mortar_coupling`).

    In 3D: of 6-node triangles (:func:`.mortar_p2_triangles.triangle6_coupling`) or 9-node
    quadrilaterals (:func:`.mortar_q2_quads.quad9_coupling`).

    Args:
        x: Vertex coordinates (N, 2).
        cells: Cells (to orient the facets' outward normals).
        slave: Slave facets as vertex pairs.
        master: Master facets as vertex pairs.
        points: The dof points of the degree-2 space (the vertices first).
        search_distance: As for :func:`.mortar.mortar_coupling`.
        cell_type: The cells' type.
        self_contact: One surface as slave and master (:mod:`.self_contact`).

    Returns:
        The coupling over dof points: ``slave_nodes`` and the columns of ``M`` are dof points.
    """
    if x.shape[1] == 3:  # 6-node triangles (the transformed dual basis) or 9-node quads
        coupling = quad9_coupling if slave.shape[1] == 4 else triangle6_coupling
        return coupling(x, cells, slave, master, points, search_distance, cell_type,
                        self_contact)
    found = search(x, cells, slave, master, search_distance, cell_type, self_contact)
    slave, master, i, j = found.slave, found.master, found.i, found.j
    sp_ = segment_points(points, slave)
    mp_ = segment_points(points, master)
    nodes, normals, D = surface_points(x, cells, slave, sp_, WEIGHTS, cell_type)
    if _curved(points, sp_) or _curved(points, mp_):
        A, De = mortar_p2_curved.dual_coefficients(points.x[sp_])
        D = np.zeros(nodes.size)  # ∫ N_j along the curves, not the chords
        np.add.at(D, np.searchsorted(nodes, sp_), De)
        vals, ok = mortar_p2_curved.pair_integrals(points.x[sp_[i]], points.x[mp_[j]], A[i])
        i, j, vals = i[ok], j[ok], vals[ok]
        r = np.repeat(sp_[i], 3, axis=1).ravel()
        c = np.tile(mp_[j], (1, 3)).ravel()
        v, npairs = vals.ravel(), i.size
    else:
        r, c, v, npairs = _pair_integrals(x, slave, master, sp_, mp_, i, j)
    return found.coupling(nodes, normals, D, (r, c, v), points.num_points, npairs)
