"""Mortar coupling of two non-matching surfaces: contact search, segment-to-segment integrals.

For a slave surface Γs and a master surface Γm (first-order facets: segments in 2D, triangles
or quadrilaterals in 3D) this module computes, with dual (biorthogonal) Lagrange multipliers
on the slave side (Wohlmuth 2000; Popp, Gee and Wall 2009; Puso and Laursen 2004)::

    D_j  = ∫_Γs N_j                     (diagonal: ∫ ψ_j N_k = δ_jk ∫ N_k)
    M_jk = ∫_{Γs ∩ π(Γm)} ψ_j N_k^m∘π   (π: projection onto the slave facet's plane)

with ψ_j = 3N_j − 1 on a segment and ψ_j = 4N_j − 1 on a triangle (bilinear quadrilaterals,
the facets of hexahedra, get a dual basis of their own per facet: :mod:`.mortar_quad`). Each
overlap of a slave facet with a master facet projected onto the slave facet's plane along its
normal is computed exactly (an interval in 2D; Sutherland–Hodgman clipping of two triangles
in 3D, :mod:`.clipping`), cut into
triangles and integrated with a rule exact for the product of two linear functions. All
pairs are processed at once: the loops run over the vertices of a facet, never over facets.

Contact search: the user may name candidate surfaces much larger than the contact zone.
Candidate pairs come from a k-d tree on the master facets' centroids, queried along each slave
facet's normal line (within the search distance plus the two facets' circumradii); a pair is
kept when the facets face each other, their projections onto the slave facet's plane may
overlap, and the master facet lies within the search distance of that plane, on either side.

A slave node j gets a row when the master surface covers at least half of the weight of its
support, Σ_k M_jk >= ½ D_j (Σ_k M_jk = ∫ over the covered part of ψ_j, which equals D_j where
the support is fully covered). Its coupling weights are then normalized by C_j = Σ_k M_jk::

    u_j − Σ_k (M_jk / C_j) u_k^m

which is D_j u_j − Σ_k M_jk u_k^m divided by D_j where the support is fully covered, and on
the rim of the master surface still moves rigidly with a rigid motion of both bodies.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..mesh.topology import facet_normals, facets_in_cell_order, nodal_normals_and_areas
from . import mortar_quad
from .clipping import clip_polygons
from .self_contact import one_sided_pairs

#: A slave node gets a row when Σ_k M_jk >= COVERAGE_MIN · D_j.
COVERAGE_MIN = 0.5
#: Coverage below 1 − COVERAGE_FULL_TOL: the slave node's support is only partly covered.
COVERAGE_FULL_TOL = 1e-6
#: Facets whose normals satisfy n_s · n_m > −FACING_MIN do not face each other.
FACING_MIN = 0.05
#: A body's boundary goes on smoothly past a surface's rim where the normals agree this well.
SMOOTH_COS = np.cos(np.radians(30.0))

# Quadrature exact for degree 2: on [0, 1] (Gauss, 2 points) and on the reference triangle.
_GAUSS_X = np.array([0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)])
_GAUSS_W = np.array([0.5, 0.5])
_TRI_X = np.array([[1.0 / 6.0, 1.0 / 6.0], [2.0 / 3.0, 1.0 / 6.0], [1.0 / 6.0, 2.0 / 3.0]])
_TRI_W = np.full(3, 1.0 / 3.0)  # weights relative to the triangle's area


@dataclass
class MortarCoupling:
    """The mortar coupling of one slave surface to one master surface.

    Attributes:
        slave_nodes: The slave surface's nodes (sorted global node numbers).
        normals: Averaged outward unit normal of the slave surface at each slave node.
        D: ∫ N_j over the slave surface (the lumped area) per slave node.
        M: Sparse (slave node × global master node) matrix of the integrals M_jk.
        coverage: Σ_k M_jk / D_j per slave node (1 where its support is fully covered).
        search_distance: The search distance used.
        pairs: Number of (slave facet, master facet) pairs with a non-empty overlap.
        zones: For self-contact (one surface as slave and master), the facets (of the
            surface) that are a slave of some pair, and those that are a master; else None.
    """

    slave_nodes: np.ndarray
    normals: np.ndarray
    D: np.ndarray
    M: sp.csr_matrix
    coverage: np.ndarray
    search_distance: float
    pairs: int
    zones: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def coupled(self) -> np.ndarray:
        """Mask of the slave nodes that get a row."""
        return self.coverage >= COVERAGE_MIN

    def weights(self) -> sp.csr_matrix:
        """The normalized master weights M_jk / C_j of the coupled slave nodes (rows)."""
        keep = np.flatnonzero(self.coupled)
        C = np.asarray(self.M[keep].sum(axis=1)).ravel()
        return sp.diags(1.0 / C) @ self.M[keep]

    def weighted_gap(self, x: np.ndarray) -> np.ndarray:
        """n_j · (Σ_k (M_jk / C_j) x_k − x_j) for the coupled slave nodes (geometry ``x``)."""
        keep = np.flatnonzero(self.coupled)
        xm = self.weights() @ x
        return np.einsum("ij,ij->i", self.normals[keep], xm - x[self.slave_nodes[keep]])


def mean_facet_size(x: np.ndarray, facets: np.ndarray) -> float:
    """Mean edge length of a set of facets (quadrilaterals in tensor order)."""
    if facets.shape[1] == 4:
        facets = facets[:, mortar_quad.CYCLIC]
    e = x[np.roll(facets, -1, axis=1)] - x[facets]
    return float(np.mean(np.linalg.norm(e, axis=2)))


def default_search_distance(x: np.ndarray, slave: np.ndarray, master: np.ndarray) -> float:
    """Twice the larger mean facet size, and at least 5 % of the slave surface's extent.

    Rows whose gap stays open cost one inactive bound each; a slave node that comes into
    contact but has no row is what must not happen, and the post-solve check warns if it
    does.
    """
    h = max(mean_facet_size(x, slave), mean_facet_size(x, master))
    p = x[np.unique(slave)]
    extent = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))
    return max(2.0 * h, 0.05 * extent)


def surface_rim(facets: np.ndarray) -> np.ndarray:
    """Nodes on the boundary of a surface (of edges in one facet only; ends of a 2D curve).

    Quadrilateral facets are taken in tensor order (:func:`.topology.facets_in_cell_order`).
    """
    if facets.shape[1] == 2:
        nodes, count = np.unique(facets, return_counts=True)
        return nodes[count == 1]
    cyc = facets[:, mortar_quad.CYCLIC] if facets.shape[1] == 4 else facets
    edges = np.sort(np.stack([cyc.ravel(), np.roll(cyc, -1, axis=1).ravel()], axis=1), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    return np.unique(uniq[count == 1])


def open_rim(x: np.ndarray, cells: np.ndarray, group: np.ndarray, boundary: np.ndarray,
             cell_type: str | None = None) -> np.ndarray:
    """The rim nodes of a surface where the body's boundary goes on smoothly beyond it.

    A surface that ends at an edge of its body (a corner in 2D) ends where the body does; one
    that ends inside a smooth part of the body's boundary was cut short by whoever named it,
    and contact may reach beyond it.

    Args:
        x: Node coordinates.
        cells: Cells (to orient normals).
        group: The surface's facets.
        boundary: All boundary facets of the mesh.
        cell_type: The cells' type (simplices when None).
    """
    rim = surface_rim(facets_in_cell_order(cells, group, cell_type))
    if rim.size == 0:
        return rim
    nodes, normals, _ = nodal_normals_and_areas(x, cells, group, cell_type)
    n_rim = normals[np.searchsorted(nodes, rim)]
    key = np.sort(group, axis=1)
    others = boundary[~_rows_in(np.sort(boundary, axis=1), key)]
    nb, _ = facet_normals(x, cells, others, cell_type)
    # Pairs (rim node, other boundary facet that contains it).
    hit = np.isin(others, rim)
    f_idx, v_idx = np.nonzero(hit)
    r_idx = np.searchsorted(rim, others[f_idx, v_idx])
    smooth = np.einsum("ij,ij->i", n_rim[r_idx], nb[f_idx]) > SMOOTH_COS
    return np.unique(rim[r_idx[smooth]])


def _rows_in(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mask of the rows of ``a`` that are rows of ``b`` (both integer, rows sorted)."""
    if b.shape[0] == 0:
        return np.zeros(a.shape[0], dtype=bool)
    width = a.shape[1]
    va = np.ascontiguousarray(a, dtype=np.int64).view(np.dtype((np.void, 8 * width))).ravel()
    vb = np.ascontiguousarray(b, dtype=np.int64).view(np.dtype((np.void, 8 * width))).ravel()
    return np.isin(va, vb)


def _near_normal_lines(cs: np.ndarray, ns: np.ndarray, rs: np.ndarray, cm: np.ndarray,
                       rm: np.ndarray, distance: float) -> tuple[np.ndarray, np.ndarray]:
    """(slave, master) facet pairs that may face each other, a superset of the final ones.

    A pair survives :func:`candidate_pairs` only if the master centroid lies within
    rs_i + rm_j of the slave facet's normal line through cs_i (its projection must overlap
    the slave facet) and within distance + rm_j of the slave plane (a master vertex must lie
    within ``distance``). That region is a cylinder, not a ball: one k-d tree query with a
    ball of radius distance + rs + rm returns (distance / h)^(d−1) times too many pairs on
    fine meshes. So each slave facet's segment of the normal line is bisected, breadth
    first, keeping the pieces whose enclosing ball holds a master centroid (a count, no
    list) until a piece is no longer than the cylinder is wide; the balls of those pieces
    give the pairs. The master facets are split into size classes (factors of 2) so that the
    cylinder's radius fits the masters of each class on graded meshes.
    """
    slack = 1.0 + 1e-9
    cls = np.floor(np.log2(rm.max() / rm)).astype(np.int64)  # 0: the largest master facets
    found_i, found_j = [], []
    for c in np.unique(cls):  # a few size classes, not facets
        J = np.flatnonzero(cls == c)
        tree = cKDTree(cm[J])
        r_c = rm[J].max()
        R = (rs + r_c) * slack  # the cylinder's radius, per slave facet
        # Pieces of the normal lines: owner slave facet, centre t, half-length.
        owner = np.arange(cs.shape[0])
        t = np.zeros(owner.size)
        half = np.full(owner.size, (distance + r_c) * slack)
        while owner.size:  # about log2(distance / h) rounds
            ball = cs[owner] + t[:, None] * ns[owner]
            rho = np.sqrt(R[owner] ** 2 + half**2) * slack  # the ball around a piece's slice
            leaf = half <= R[owner]
            hits = tree.query_ball_point(ball[leaf], rho[leaf], return_sorted=False)
            count = np.fromiter(map(len, hits), dtype=np.int64, count=len(hits))
            found_j.append(J[np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64,
                                         count=int(count.sum()))])
            found_i.append(np.repeat(owner[leaf], count))
            split = np.flatnonzero(~leaf)
            split = split[tree.query_ball_point(ball[split], rho[split],
                                                return_length=True) > 0]
            owner = np.repeat(owner[split], 2)
            half = np.repeat(0.5 * half[split], 2)
            t = np.repeat(t[split], 2) + np.tile([-1.0, 1.0], split.size) * half
    key = np.unique(np.concatenate(found_i) * cm.shape[0] + np.concatenate(found_j))
    return key // cm.shape[0], key % cm.shape[0]


def candidate_pairs(x: np.ndarray, slave: np.ndarray, ns: np.ndarray, master: np.ndarray,
                    nm: np.ndarray, distance: float) -> tuple[np.ndarray, np.ndarray]:
    """(slave facet, master facet) pairs that face each other within ``distance``."""
    cs, cm = x[slave].mean(axis=1), x[master].mean(axis=1)
    rs = np.linalg.norm(x[slave] - cs[:, None], axis=2).max(axis=1)
    rm = np.linalg.norm(x[master] - cm[:, None], axis=2).max(axis=1)
    i, j = _near_normal_lines(cs, ns, rs, cm, rm, distance)
    d = np.linalg.norm(cm[j] - cs[i], axis=1)
    keep = d <= distance + rs[i] + rm[j]
    keep &= np.einsum("ij,ij->i", ns[i], nm[j]) < -FACING_MIN
    i, j = i[keep], j[keep]
    # The projections onto the slave facet's plane must overlap: the slave facet lies in the
    # disc of radius rs about its centroid, the projected master facet in the disc of radius rm
    # about its projected centroid (a projection shortens distances). Most pairs within the
    # search distance fail this, and it is far cheaper than clipping them.
    dc = cm[j] - cs[i]
    dn = np.einsum("ij,ij->i", dc, ns[i])
    reach = (rs[i] + rm[j]) * (1.0 + 1e-9)
    keep = np.einsum("ij,ij->i", dc, dc) - dn**2 <= reach**2
    i, j = i[keep], j[keep]
    # Signed distances of the master vertices from the slave facet's plane.
    h = np.einsum("ikl,il->ik", x[master[j]] - x[slave[i, :1]], ns[i])
    keep = (h.min(axis=1) <= distance) & (h.max(axis=1) >= -distance)
    order = np.lexsort((j[keep], i[keep]))
    return i[keep][order], j[keep][order]


def segment_overlaps(x: np.ndarray, slave: np.ndarray, master: np.ndarray, i: np.ndarray,
                     j: np.ndarray) -> tuple[np.ndarray, ...]:
    """2D: the overlap of each (slave, master) pair of straight segments, if not empty.

    Returns:
        ``(i, j, lo, hi, xi0, span, L)`` of the overlapping pairs: the overlap is
        [lo, hi] in the slave parameter s ∈ [0, 1]; the master parameter is
        η = (s − xi0) / span; L the slave segment's length.
    """
    a, b = x[slave[i, 0]], x[slave[i, 1]]
    L = np.linalg.norm(b - a, axis=1)
    t = (b - a) / L[:, None]
    xi = np.einsum("ikl,il->ik", x[master[j]] - a[:, None], t) / L[:, None]  # (P, 2)
    lo = np.clip(xi.min(axis=1), 0.0, 1.0)
    hi = np.clip(xi.max(axis=1), 0.0, 1.0)
    span = xi[:, 1] - xi[:, 0]
    ok = (hi - lo > 1e-12) & (np.abs(span) > 1e-14 * np.abs(xi).max(axis=1))
    return i[ok], j[ok], lo[ok], hi[ok], xi[ok, 0], span[ok], L[ok]


def _segment_integrals(x, slave, master, i, j):
    """2D: (slave node, master node, M entry) of each pair's overlap."""
    i, j, lo, hi, xi0, span, L = segment_overlaps(x, slave, master, i, j)
    s_node = slave[i]
    vals = np.zeros((i.size, 2, 2))
    for q, w in zip(_GAUSS_X, _GAUSS_W, strict=True):
        s = lo + q * (hi - lo)  # slave parameter
        eta = (s - xi0) / span  # master parameter: N^m = (1 − η, η)
        psi = np.stack([2.0 - 3.0 * s, 3.0 * s - 1.0], axis=1)
        Nm = np.stack([1.0 - eta, eta], axis=1)
        vals += (w * (hi - lo) * L)[:, None, None] * psi[:, :, None] * Nm[:, None, :]
    rows = np.repeat(s_node, 2, axis=1).ravel()
    cols = np.tile(master[j], (1, 2)).ravel()
    return rows, cols, vals.ravel(), i.size


def _triangle_integrals(x, slave, ns, master, i, j):
    """3D: (slave node, master node, M entry) of each pair's overlap polygon."""
    a = x[slave[i, 0]]
    t1 = x[slave[i, 1]] - a
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    t2 = np.cross(ns[i], t1)  # (t1, t2, n) right-handed: the slave triangle is counter-clockwise

    def plane(p):
        d = p - a[:, None]
        return np.stack([np.einsum("ikl,il->ik", d, t1), np.einsum("ikl,il->ik", d, t2)], axis=2)

    S = plane(x[slave[i]])
    Mp = plane(x[master[j]])
    ccw = (S[:, 1, 0] - S[:, 0, 0]) * (S[:, 2, 1] - S[:, 0, 1]) - \
        (S[:, 1, 1] - S[:, 0, 1]) * (S[:, 2, 0] - S[:, 0, 0])
    S = np.where((ccw < 0)[:, None, None], S[:, ::-1], S)  # guard: clip by a ccw triangle
    s_perm = np.where(ccw < 0, 1, 0)
    poly, count = clip_polygons(Mp, np.full(i.size, 3), S)
    # Affine maps plane → barycentric coordinates of the slave and the master triangle.
    def bary_map(T):
        E = np.stack([T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]], axis=2)  # columns
        det = E[:, 0, 0] * E[:, 1, 1] - E[:, 0, 1] * E[:, 1, 0]
        return T[:, 0], E, det

    s0, SE, sdet = bary_map(S)
    m0, ME, mdet = bary_map(Mp)
    ok = (count >= 3) & (np.abs(mdet) > 1e-12 * np.abs(sdet))
    rows_, cols_, vals_ = [], [], []

    def bary(p, o, E, det):
        d = p - o
        l1 = (d[:, 0] * E[:, 1, 1] - d[:, 1] * E[:, 0, 1]) / det
        l2 = (E[:, 0, 0] * d[:, 1] - E[:, 1, 0] * d[:, 0]) / det
        return np.stack([1.0 - l1 - l2, l1, l2], axis=1)

    # Only the pairs that overlap are integrated (row by row: the others would add zeros).
    idx = np.flatnonzero(ok)
    poly, count = poly[idx], count[idx]
    s0, SE, sdet, m0, ME, mdet = s0[idx], SE[idx], sdet[idx], m0[idx], ME[idx], mdet[idx]
    c = poly.sum(axis=1) / np.maximum(count, 1)[:, None]  # the overlap's centroid (convex)
    acc_ok = np.zeros((idx.size, 3, 3))
    safe_sdet = np.where(sdet == 0.0, 1.0, sdet)
    rng = np.arange(idx.size)
    for k in range(int(count.max(initial=0))):  # fan triangles (centroid, vertex k, vertex k + 1)
        use = k < count
        p1 = poly[:, k]
        p2 = poly[rng, (k + 1) % np.maximum(count, 1)]
        area = 0.5 * np.abs((p1[:, 0] - c[:, 0]) * (p2[:, 1] - c[:, 1])
                            - (p1[:, 1] - c[:, 1]) * (p2[:, 0] - c[:, 0]))
        area = np.where(use, area, 0.0)
        for (q1, q2), w in zip(_TRI_X, _TRI_W, strict=True):
            p = c + q1 * (p1 - c) + q2 * (p2 - c)
            Ns = bary(p, s0, SE, safe_sdet)
            Nm = bary(p, m0, ME, mdet)
            psi = 4.0 * Ns - 1.0
            acc_ok += (w * area)[:, None, None] * psi[:, :, None] * Nm[:, None, :]
    acc = np.zeros((i.size, 3, 3))
    acc[idx] = acc_ok
    # Undo the guard's vertex reversal: slave vertex order (2, 1, 0) back to (0, 1, 2).
    acc = np.where((s_perm == 1)[:, None, None], acc[:, ::-1], acc)
    keep = np.flatnonzero(ok & (np.abs(acc).sum(axis=(1, 2)) > 0.0))
    rows_ = np.repeat(slave[i[keep]], 3, axis=1).ravel()
    cols_ = np.tile(master[j[keep]], (1, 3)).ravel()
    vals_ = acc[keep].ravel()
    return rows_, cols_, vals_, keep.size


@dataclass
class Search:
    """The facet pairs of a slave and a master surface that the search kept.

    Attributes:
        slave, master: The facets (quadrilaterals in tensor order; for self-contact the
            slave facets of the pairs only).
        ns: The slave facets' outward unit normals.
        i, j: The slave and master facet of each pair.
        search_distance: The search distance used.
        zones: As :attr:`MortarCoupling.zones`.
    """

    slave: np.ndarray
    master: np.ndarray
    ns: np.ndarray
    i: np.ndarray
    j: np.ndarray
    search_distance: float
    zones: tuple[np.ndarray, np.ndarray] | None

    def coupling(self, nodes: np.ndarray, normals: np.ndarray, D: np.ndarray,
                 entries: tuple[np.ndarray, np.ndarray, np.ndarray], num_columns: int,
                 pairs: int) -> MortarCoupling:
        """The coupling from the entries (slave node, master node, value) of M."""
        r, c, v = entries
        M = sp.csr_matrix((v, (np.searchsorted(nodes, r), c)), shape=(nodes.size, num_columns))
        M.sum_duplicates()
        M.eliminate_zeros()
        coverage = np.asarray(M.sum(axis=1)).ravel() / D
        return MortarCoupling(slave_nodes=nodes, normals=normals, D=D, M=M, coverage=coverage,
                              search_distance=float(self.search_distance), pairs=int(pairs),
                              zones=self.zones)


def search(x: np.ndarray, cells: np.ndarray, slave: np.ndarray, master: np.ndarray,
           search_distance: float | None, cell_type: str | None, self_contact: bool) -> Search:
    """The contact search of :func:`mortar_coupling` (its arguments), for every facet kind."""
    slave = facets_in_cell_order(cells, slave, cell_type)
    master = facets_in_cell_order(cells, master, cell_type)
    ns, _ = facet_normals(x, cells, slave, cell_type)
    nm, _ = facet_normals(x, cells, master, cell_type)
    if search_distance is None:
        search_distance = default_search_distance(x, slave, master)
    i, j = candidate_pairs(x, slave, ns, master, nm, search_distance)
    zones = None
    if self_contact:
        i, j, _ = one_sided_pairs(x, slave, ns, i, j)
        # The slave side is its zones only: their nodes' normals and areas from their own
        # facets (a node at the zone's edge would otherwise average in the facets round a
        # corner of the body, which face elsewhere).
        used = np.unique(i)
        slave, ns, i = slave[used], ns[used], np.searchsorted(used, i)
        zones = (slave, np.unique(master[j], axis=0))
    return Search(slave, master, ns, i, j, float(search_distance), zones)


def mortar_coupling(x: np.ndarray, cells: np.ndarray, slave: np.ndarray, master: np.ndarray,
                    search_distance: float | None = None, cell_type: str | None = None,
                    self_contact: bool = False) -> MortarCoupling:
    """Search and integrate the mortar coupling of two surfaces of a mesh.

    Args:
        x: Node coordinates (N, gdim).
        cells: Cells (to orient the facets' outward normals).
        slave: Slave facets as node numbers: segments (2D), triangles or quadrilaterals (3D).
        master: Master facets, of the same kind.
        search_distance: How far apart (along the slave normal, either side) two facets may be
            and still be coupled; :func:`default_search_distance` when None.
        cell_type: The cells' type (simplices when None).
        self_contact: ``slave`` and ``master`` are one surface: its pairs with itself are
            kept once each, without a facet's own neighbourhood (:mod:`.self_contact`).

    Returns:
        The coupling (see :class:`MortarCoupling`).
    """
    found = search(x, cells, slave, master, search_distance, cell_type, self_contact)
    slave, ns, master, i, j = found.slave, found.ns, found.master, found.i, found.j
    nodes, normals, D = nodal_normals_and_areas(x, cells, slave, cell_type)
    entries, npairs, D = facet_integrals(x, slave, ns, master, i, j, nodes, D)
    return found.coupling(nodes, normals, D, entries, x.shape[0], npairs)


def facet_integrals(x: np.ndarray, slave: np.ndarray, ns: np.ndarray, master: np.ndarray,
                    i: np.ndarray, j: np.ndarray, nodes: np.ndarray, D: np.ndarray
                    ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], int, np.ndarray]:
    """The entries of M of the pairs (i, j), for first-order facets of any kind.

    Segments (2D), triangles and quadrilaterals (tensor order) on either side, a triangle
    against a quadrilateral included (bodies of different cell types). ``nodes`` and ``D``
    are the slave nodes and their lumped areas; on quadrilaterals D becomes ∫ N_j exactly.

    Returns:
        ``((slave node, master node, value), pairs with an overlap, D)``.
    """
    if x.shape[1] == 2:
        r, c, v, npairs = _segment_integrals(x, slave, master, i, j)
        return (r, c, v), npairs, D
    if slave.shape[1] == 3 and master.shape[1] == 3:
        r, c, v, npairs = _triangle_integrals(x, slave, ns, master, i, j)
        return (r, c, v), npairs, D
    if slave.shape[1] == 4:
        A, De = mortar_quad.dual_basis(x[slave])
        D = np.zeros(nodes.size)  # ∫ N_j exactly (the lumped area is exact on parallelograms)
        np.add.at(D, np.searchsorted(nodes, slave), De)
    else:  # a flat triangle's dual basis: ψ_j = 4 N_j − 1
        A = np.broadcast_to(4.0 * np.eye(3) - 1.0, (slave.shape[0], 3, 3))
    kinds = None if master.shape[1] == slave.shape[1] else tuple(
        mortar_quad.TRIANGLE if f.shape[1] == 3 else mortar_quad.QUADRILATERAL
        for f in (slave, master))
    r, c, v, npairs = mortar_quad.pair_integrals(x, slave, ns, A, master, i, j, kinds=kinds)
    return (r, c, v), npairs, D


def same_way_pairs(x: np.ndarray, cells: np.ndarray, slave: np.ndarray, master: np.ndarray,
                   search_distance: float, cell_type: str | None = None) -> int:
    """How many facet pairs would be coupled if the master surface faced the other way.

    A pair of surfaces that face the same way (the outward normals agree) has no pair that
    faces each other, so the search couples nothing; this count tells that case from two
    surfaces that are merely out of reach of each other.
    """
    slave = facets_in_cell_order(cells, slave, cell_type)
    master = facets_in_cell_order(cells, master, cell_type)
    ns, _ = facet_normals(x, cells, slave, cell_type)
    nm, _ = facet_normals(x, cells, master, cell_type)
    i, _ = candidate_pairs(x, slave, ns, master, -nm, search_distance)
    return int(i.size)


def penetration(p: np.ndarray, normals: np.ndarray, x: np.ndarray, cells: np.ndarray,
                facets: np.ndarray, depth: float, cell_type: str | None = None) -> np.ndarray:
    """How deep each point lies behind a surface (0 where it does not).

    A point counts as behind a facet when its foot along the facet's normal falls inside the
    facet, the point's own surface normal faces the facet, and it lies at most ``depth``
    behind it (a point far behind is on the other side of the body, not in it).

    Args:
        p: Points (n, gdim), e.g. the deformed nodes of one surface.
        normals: Outward unit normals of that surface at the points.
        x: Coordinates of the other surface's mesh (deformed).
        cells: Cells of that mesh (to orient its facets).
        facets: The other surface's facets.
        depth: The largest depth that counts.
        cell_type: The cells' type (simplices when None).
    """
    if p.shape[0] == 0:
        return np.zeros(0)
    nf, _ = facet_normals(x, cells, facets, cell_type)
    if facets.shape[1] == 4:  # a quadrilateral as two triangles (a check, not an integral)
        cyc = facets_in_cell_order(cells, facets, cell_type)[:, mortar_quad.CYCLIC]
        facets = np.concatenate([cyc[:, [0, 1, 2]], cyc[:, [0, 2, 3]]])
        nf = np.concatenate([nf, nf])
    centre = x[facets].mean(axis=1)
    k = min(16, facets.shape[0])
    _, cand = cKDTree(centre).query(p, k=k)
    cand = cand.reshape(p.shape[0], k)
    v = x[facets[cand]]  # (n, k, nv, gdim)
    n = nf[cand]  # (n, k, gdim)
    d = np.einsum("ikl,ikl->ik", p[:, None] - v[:, :, 0], n)  # signed distance, < 0 behind
    foot = p[:, None] - d[..., None] * n
    tol = 1e-8
    if x.shape[1] == 2:
        e = v[:, :, 1] - v[:, :, 0]
        xi = np.einsum("ikl,ikl->ik", foot - v[:, :, 0], e) / np.einsum("ikl,ikl->ik", e, e)
        inside = (xi >= -tol) & (xi <= 1.0 + tol)
    else:
        e1, e2, r = v[:, :, 1] - v[:, :, 0], v[:, :, 2] - v[:, :, 0], foot - v[:, :, 0]
        a11 = np.einsum("ikl,ikl->ik", e1, e1)
        a12 = np.einsum("ikl,ikl->ik", e1, e2)
        a22 = np.einsum("ikl,ikl->ik", e2, e2)
        b1, b2 = np.einsum("ikl,ikl->ik", r, e1), np.einsum("ikl,ikl->ik", r, e2)
        det = a11 * a22 - a12**2
        l1 = (b1 * a22 - b2 * a12) / det
        l2 = (a11 * b2 - a12 * b1) / det
        inside = (l1 >= -tol) & (l2 >= -tol) & (l1 + l2 <= 1.0 + tol)
    facing = np.einsum("il,ikl->ik", normals, n) < -FACING_MIN
    ok = inside & facing & (d >= -depth)
    dist = np.where(ok, np.abs(d), np.inf)
    best = np.argmin(dist, axis=1)
    rows = np.arange(p.shape[0])
    return np.where(ok[rows, best], np.maximum(-d[rows, best], 0.0), 0.0)
