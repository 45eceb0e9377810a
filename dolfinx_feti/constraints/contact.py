"""Non-penetration rows: node-to-node pairs between two bodies, and a body on a rigid obstacle."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from ..mesh.data import MeshData
from ..mesh.dofpoints import DofPoints, dof_points
from ..mesh.topology import surface_points
from ..problem.conditions import NodeToNode, RigidObstacle
from .rows import Kind, Rows


def surface(mesh: MeshData, group: str, points: DofPoints | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dof points, outward unit normals and lumped areas of a boundary group.

    The points are the vertices (degree 1, the default) or all dof points on the group's
    facets; the lumped area of a point is the integral of its basis function over the group.
    """
    points = dof_points(mesh, 1) if points is None else points
    try:
        facets = mesh.facets(group)
        return surface_points(mesh.x, mesh.cells, facets, points.facet_points(mesh, facets),
                              points.facet_weights, mesh.cell_type)
    except ValueError as e:
        raise InputError(f"boundary group {group!r}: {e} (is it a boundary of a body?)") from None


def _mean_edge(mesh: MeshData, group: str) -> float:
    f = mesh.facets(group)
    return float(np.mean(np.linalg.norm(mesh.x[f[:, 1]] - mesh.x[f[:, 0]], axis=1)))


def match_pairs(xs: np.ndarray, xm: np.ndarray, nm: np.ndarray, tol: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """For each slave point, the master point at the same place along the master surface.

    The distance that counts is the tangential one (the offset along the master normal is the
    gap). A planar master surface is matched exactly in its plane; a curved one among the
    nearest candidates.

    Returns:
        (index of the master point per slave point, tangential mismatch per slave point).
    """
    nbar = nm.mean(axis=0)
    nbar /= np.linalg.norm(nbar)
    if np.all(nm @ nbar > 1.0 - 1e-10):
        ys = xs - np.outer(xs @ nbar, nbar)
        ym = xm - np.outer(xm @ nbar, nbar)
        dist, j = cKDTree(ym).query(ys)
        return j, dist
    k = min(16, xm.shape[0])
    _, cand = cKDTree(xm).query(xs, k=k)
    cand = cand.reshape(xs.shape[0], k)
    d = xs[:, None, :] - xm[cand]
    dn = np.einsum("ijk,ijk->ij", d, nm[cand])
    tang = np.sqrt(np.maximum(np.einsum("ijk,ijk->ij", d, d) - dn**2, 0.0))
    best = np.argmin(tang, axis=1)
    return cand[np.arange(xs.shape[0]), best], tang[np.arange(xs.shape[0]), best]


def check_own_nodes(mesh: MeshData, name: str, s_nodes: np.ndarray, m_nodes: np.ndarray
                    ) -> None:
    """Refuse contact surfaces that share nodes: the bodies are glued there, not in contact."""
    shared = np.intersect1d(s_nodes, m_nodes)
    if shared.size:
        bodies = np.unique(mesh.cell_body[np.isin(mesh.cells, shared).any(axis=1)])
        raise InputError(f"{name}: the two surfaces share {shared.size} nodes (e.g. at "
                         f"{mesh.x[shared[0]].round(6).tolist()}), so bodies "
                         f"{[mesh.body_names[b] for b in bodies]} are glued there (one mesh, "
                         "common nodes), not in contact: bodies in contact need their own "
                         "nodes on the contact surfaces (mesh them apart, or do not fragment "
                         "them together)")


def node_to_node_rows(mesh: MeshData, spec: NodeToNode, index: int, node_ptr: np.ndarray,
                      node_subs: np.ndarray, bs: int, points: DofPoints | None = None,
                      all_components: bool = False) -> Rows:
    """Rows (u_m − u_s)·n <= gap for matched pairs of dof points, scaled to unit norm.

    ``all_components``: keep an entry for every component of both nodes, zero ones too
    (under large deformation the normal of the deformed master surface turns, and with it
    the row and its friction rows: drivers/current_rows.py); else the zero ones are left out.
    """
    points = dof_points(mesh, 1) if points is None else points
    s_nodes, s_normals, _ = surface(mesh, spec.slave, points)
    m_nodes, m_normals, _ = surface(mesh, spec.master, points)
    x = points.x
    name = f"contact pair {spec.slave!r} (slave) / {spec.master!r} (master)"
    check_own_nodes(mesh, name, s_nodes, m_nodes)
    s_body = set(np.unique(mesh.cell_body[np.isin(mesh.cells, s_nodes).any(axis=1)]))
    m_body = set(np.unique(mesh.cell_body[np.isin(mesh.cells, m_nodes).any(axis=1)]))
    if s_body & m_body:
        raise InputError(f"{name}: both surfaces belong to body "
                         f"{mesh.body_names[min(s_body & m_body)]!r}; node-to-node contact is "
                         "between two bodies")
    tol = spec.match_tol * _mean_edge(mesh, spec.slave)
    j, mismatch = match_pairs(x[s_nodes], x[m_nodes], m_normals, tol)
    bad = mismatch > tol
    if np.any(bad):
        raise InputError(f"{name}: {int(bad.sum())} of {s_nodes.size} slave nodes have no "
                         f"matching master node (largest mismatch {mismatch.max():.3g}, "
                         f"tolerance {tol:.3g}; e.g. slave node at "
                         f"{x[s_nodes[np.argmax(mismatch)]].round(6).tolist()}). "
                         "Node-to-node contact needs matching meshes on the two surfaces")
    if np.unique(j).size != j.size:
        raise InputError(f"{name}: several slave nodes match the same master node; the "
                         "surfaces' meshes do not match one to one")
    m = m_nodes[j]
    n = m_normals[j]
    if bs > 1:
        facing = np.einsum("ij,ij->i", s_normals, n)
        if np.any(facing > 0.0):
            raise InputError(f"{name}: inconsistent normals: at {int(np.sum(facing > 0))} pairs "
                             "the two surfaces face the same way (their outward normals agree); "
                             "contact surfaces must face each other")
        gap = np.einsum("ij,ij->i", x[s_nodes] - x[m], n)
        coef_s, coef_m = -n, n
    else:
        gap = np.zeros(s_nodes.size)
        coef_s, coef_m = np.ones((s_nodes.size, 1)), -np.ones((s_nodes.size, 1))
    if spec.gap is not None:
        gap = np.full(s_nodes.size, float(spec.gap))
    scale = 1.0 / np.sqrt(2.0)
    first = node_subs[node_ptr[:-1]]  # the smallest subdomain holding each node
    npair = s_nodes.size
    rows = np.arange(npair)
    e_row = np.concatenate([np.repeat(rows, bs), np.repeat(rows, bs)])
    e_sub = np.concatenate([np.repeat(first[s_nodes], bs), np.repeat(first[m], bs)])
    e_node = np.concatenate([np.repeat(s_nodes, bs), np.repeat(m, bs)])
    e_comp = np.tile(np.arange(bs), 2 * npair)
    e_coef = scale * np.concatenate([coef_s.ravel(), coef_m.ravel()])
    keep = (e_coef != 0.0) | (all_components and bs > 1)
    normal = n if bs > 1 else np.zeros((npair, mesh.gdim))
    return Rows(e_row=e_row[keep], e_sub=e_sub[keep].astype(np.int32), e_node=e_node[keep],
                e_comp=e_comp[keep].astype(np.int8), e_coef=e_coef[keep], rhs=scale * gap,
                kind=np.full(npair, Kind.CONTACT, dtype=np.int8), scale=np.full(npair, scale),
                node=s_nodes, partner=m, normal=normal,
                spec=np.full(npair, index, dtype=np.int32))


def obstacle_gaps(spec: RigidObstacle, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gaps φ/|∇φ| and the normals n = ∇φ/|∇φ| of an obstacle at the points ``x``, checked.

    Raises:
        InputError: Naming the condition, for a distance that fails, has the wrong shape, is
            not finite or has a zero gradient.
    """
    npts, gdim = x.shape
    try:
        phi, grad = spec.obstacle.distance(x)
        phi, grad = np.asarray(phi, dtype=float), np.asarray(grad, dtype=float)
    except InputError as e:
        raise InputError(f"obstacle on {spec.group!r}: {e}") from None
    except Exception as e:  # a user's signed distance: say which one failed
        raise InputError(f"obstacle on {spec.group!r}: its distance(x) raised "
                         f"{type(e).__name__}: {e}") from e
    if phi.shape != (npts,) or grad.shape != (npts, gdim):
        raise InputError(f"obstacle on {spec.group!r}: distance() must return arrays of shape "
                         f"({npts},) and ({npts}, {gdim}), got {phi.shape} and {grad.shape}")
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(grad))):
        raise InputError(f"obstacle on {spec.group!r}: the signed distance is not finite")
    g = np.linalg.norm(grad, axis=1)
    if np.any(g <= 0):
        raise InputError(f"obstacle on {spec.group!r}: zero distance gradient at some nodes")
    return phi / g, grad / g[:, None]


def obstacle_rows(mesh: MeshData, spec: RigidObstacle, index: int, node_ptr: np.ndarray,
                  node_subs: np.ndarray, points: DofPoints | None = None) -> Rows:
    """Rows −n·u <= φ/|∇φ| at the dof points of a boundary group, n = ∇φ/|∇φ|."""
    points = dof_points(mesh, 1) if points is None else points
    nodes, normals, _ = surface(mesh, spec.group, points)
    gap, n = obstacle_gaps(spec, points.x[nodes])
    away = np.einsum("ij,ij->i", normals, n) > 0.0
    if np.any(away):
        raise InputError(f"obstacle on {spec.group!r}: inconsistent normals: the surface faces "
                         f"away from the obstacle at {int(away.sum())} nodes (the body's "
                         "outward normal and the obstacle's outward normal agree)")
    first = node_subs[node_ptr[:-1]]
    gdim = mesh.gdim
    npn = nodes.size
    return Rows(e_row=np.repeat(np.arange(npn), gdim),
                e_sub=np.repeat(first[nodes], gdim).astype(np.int32),
                e_node=np.repeat(nodes, gdim), e_comp=np.tile(np.arange(gdim), npn).astype(np.int8),
                e_coef=-n.ravel(), rhs=gap, kind=np.full(npn, Kind.OBSTACLE, dtype=np.int8),
                scale=np.ones(npn), node=nodes, partner=np.full(npn, -1), normal=n,
                spec=np.full(npn, index, dtype=np.int32))
