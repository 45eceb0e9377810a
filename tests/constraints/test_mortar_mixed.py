"""Mortar coupling between meshes of different cell types (constraints/mortar_mixed.py)."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar_mixed import mortar_coupling_between
from dolfinx_feti.io.meshes_occ import stacked_blocks


def _meshes(dim, recombined, gap=0.0, h=(0.25, 0.4)):
    mesh = df.build_mesh(stacked_blocks, dim, *h, gap=gap, recombine=recombined)
    lower = mesh.parts[mesh.part_of_body("lower")]
    upper = mesh.parts[mesh.part_of_body("upper")]
    return lower, upper


def _coupling(lower, upper, slave_is_upper):
    if slave_is_upper:
        return upper, lower, mortar_coupling_between(
            upper, upper.facets("upper_bottom"), lower, lower.facets("lower_top"))
    return lower, upper, mortar_coupling_between(
        lower, lower.facets("lower_top"), upper, upper.facets("upper_bottom"))


CASES = [(3, "lower", True), (3, "lower", False), (3, "upper", True), (3, "upper", False),
         (2, "lower", True), (2, "upper", False)]


@pytest.mark.parametrize("dim, recombined, slave_is_upper", CASES)
def test_linear_fields_reproduced(dim, recombined, slave_is_upper):
    """On two coincident planes: full coverage, Σ_k M_jk = D_j and M x_m = D_j x_j.

    ∫ ψ_j (Σ_k N_k^m x_k) = ∫ ψ_j x = D_j x_j for a linear field x (biorthogonality), what
    ever the master facets are: a property of the exact integrals, not of the code.
    """
    lower, upper = _meshes(dim, recombined)
    s_mesh, m_mesh, c = _coupling(lower, upper, slave_is_upper)
    assert {s_mesh.cell_type, m_mesh.cell_type} == (
        {"hexahedron", "tetrahedron"} if dim == 3 else {"quadrilateral", "triangle"})
    assert c.slave_nodes.size == np.unique(s_mesh.facets(
        "upper_bottom" if slave_is_upper else "lower_top")).size
    assert np.allclose(c.coverage, 1.0, rtol=0, atol=1e-12)
    assert np.isclose(c.D.sum(), 1.0, rtol=1e-12)  # the interface's area (length in 2D)
    Mx = c.M @ m_mesh.x
    exact = c.D[:, None] * s_mesh.x[c.slave_nodes]
    assert np.abs(Mx - exact).max() < 1e-12
    # every rank computes the same coupling
    comm = MPI.COMM_WORLD
    assert all(np.array_equal(v, c.M.data) for v in comm.allgather(c.M.data))


@pytest.mark.parametrize("dim, recombined, slave_is_upper",
                         [(3, "lower", True), (3, "upper", True), (2, "lower", False)])
def test_weighted_gap(dim, recombined, slave_is_upper):
    """Bodies 0.01 apart: the weighted gap of every slave node is 0.01."""
    lower, upper = _meshes(dim, recombined, gap=0.01)
    s_mesh, m_mesh, c = _coupling(lower, upper, slave_is_upper)
    assert np.all(c.coupled)
    g = np.einsum("ij,ij->i", c.normals, c.weights() @ m_mesh.x - s_mesh.x[c.slave_nodes])
    assert np.abs(g - 0.01).max() < 1e-13


def _subtriangle_points(m):
    """Centroids of the m² subtriangles of the reference triangle (equal weights)."""
    pts = []
    for a in range(m):
        for b in range(m - a):
            pts.append(((a + 1 / 3) / m, (b + 1 / 3) / m))
            if a + b < m - 1:
                pts.append(((a + 2 / 3) / m, (b + 2 / 3) / m))
    return np.array(pts)


def _locate(p, x, facets):
    """Master facet and its functions at points p (n, 2) of the plane (x, y)."""
    P = x[facets][:, :, :2]
    if facets.shape[1] == 4:  # axis-parallel squares (a transfinite grid), tensor order
        lo, hi = P.min(axis=1), P.max(axis=1)
        inside = np.all((p[:, None] >= lo - 1e-14) & (p[:, None] <= hi + 1e-14), axis=2)
        f = np.argmax(inside, axis=1)
        s = (p - lo[f]) / (hi[f] - lo[f])
        N = np.stack([(1 - s[:, 0]) * (1 - s[:, 1]), s[:, 0] * (1 - s[:, 1]),
                      (1 - s[:, 0]) * s[:, 1], s[:, 0] * s[:, 1]], axis=1)
        # tensor order by position: the vertex at (lo, lo), (hi, lo), (lo, hi), (hi, hi)
        order = np.argsort(np.round((P[f] - lo[f][:, None]) / (hi[f] - lo[f])[:, None], 6)
                           @ np.array([1.0, 2.0]), axis=1)
        return facets[f][np.arange(f.size)[:, None], order], N
    T = P
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    d = p[:, None] - T[None, :, 0]
    l1 = (d[..., 0] * e2[None, :, 1] - d[..., 1] * e2[None, :, 0]) / det
    l2 = (e1[None, :, 0] * d[..., 1] - e1[None, :, 1] * d[..., 0]) / det
    inside = (l1 >= -1e-12) & (l2 >= -1e-12) & (l1 + l2 <= 1 + 1e-12)
    f = np.argmax(inside, axis=1)
    r = np.arange(p.shape[0])
    return facets[f], np.stack([1 - l1[r, f] - l2[r, f], l1[r, f], l2[r, f]], axis=1)


@pytest.mark.parametrize("recombined", ["lower", "upper"])
def test_M_against_sampling(recombined):
    """M of a triangle slave on quadrilaterals (and the reverse) against midpoint sampling.

    The slave facets are sampled on fine grids (the dual basis 4λ − 1 on triangles, the
    tensor product of (2 − 3s, 3s − 1) on the squares of a transfinite grid), the master
    functions located by point search: an integration independent of the clipping.
    """
    lower, upper = _meshes(3, recombined)
    s_mesh, m_mesh, c = _coupling(lower, upper, slave_is_upper=True)
    slave = s_mesh.facets("upper_bottom")
    master = m_mesh.facets("lower_top")
    rows, cols, vals = [], [], []
    if slave.shape[1] == 3:
        ref = _subtriangle_points(48)
        for f in slave:
            P = s_mesh.x[f]
            lam = np.stack([1 - ref[:, 0] - ref[:, 1], ref[:, 0], ref[:, 1]], axis=1)
            p = lam @ P
            area = 0.5 * np.linalg.norm(np.cross(P[1] - P[0], P[2] - P[0]))
            psi, w = 4 * lam - 1, area / ref.shape[0]
            mf, N = _locate(p[:, :2], m_mesh.x, master)
            for a in range(3):
                rows.append(np.full(mf.size, f[a]))
                cols.append(mf.ravel())
                vals.append((w * psi[:, a, None] * N).ravel())
    else:
        g = (np.arange(96) + 0.5) / 96
        s, t = [v.ravel() for v in np.meshgrid(g, g, indexing="ij")]
        d1 = np.stack([2 - 3 * s, 3 * s - 1]), np.stack([2 - 3 * t, 3 * t - 1])
        psi = np.stack([d1[0][0] * d1[1][0], d1[0][1] * d1[1][0], d1[0][0] * d1[1][1],
                        d1[0][1] * d1[1][1]], axis=1)
        from dolfinx_feti.mesh.topology import facets_in_cell_order
        for f in facets_in_cell_order(s_mesh.cells, slave, s_mesh.cell_type):
            P = s_mesh.x[f]
            p = P[0] + s[:, None] * (P[1] - P[0]) + t[:, None] * (P[2] - P[0])
            w = np.linalg.norm(np.cross(P[1] - P[0], P[2] - P[0])) / s.size
            mf, N = _locate(p[:, :2], m_mesh.x, master)
            for a in range(4):
                rows.append(np.full(mf.size, f[a]))
                cols.append(mf.ravel())
                vals.append((w * psi[:, a, None] * N).ravel())
    import scipy.sparse as sp
    r = np.searchsorted(c.slave_nodes, np.concatenate(rows))
    sampled = sp.csr_matrix((np.concatenate(vals), (r, np.concatenate(cols))),
                            shape=c.M.shape).toarray()
    err = np.abs(sampled - c.M.toarray()).max() / np.abs(c.M.toarray()).max()
    assert err < 1e-3, err  # measured 1.5e-4 and 8.8e-5
