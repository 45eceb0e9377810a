"""A C-shaped 2D strip (a split ring) for self-contact tests, meshed by gmsh.

The ring R1 <= r <= R2 with a slit |y| < gap/2 on its right (x > 0): its two ends face each
other across the slit. The upper half (y >= 0) is meshed by gmsh and mirrored, so the mesh is
symmetric about y = 0 (the ends' meshes match) — or, with ``h_lower``, the lower half is
meshed on its own with another size (the ends' meshes do not match; the halves still share
the nodes of the back, where the mesh size is ``h``).

Groups: ``skin`` (the whole boundary), ``end_upper`` / ``end_lower`` (the ends, y = ±gap/2),
``load_upper`` / ``load_lower`` (the outer rim between 20° and 50° from the slit, each half),
``back`` (the outer rim within 12° of the leftmost point). Bodies: one, ``clip``, or with
``two_bodies`` the halves ``upper`` and ``lower`` (the same mesh, glued at y = 0).
"""

from __future__ import annotations

import gmsh
import numpy as np
from mpi4py import MPI

import dolfinx_feti as df

R1, R2 = 0.8, 1.0


def _half(h: float, gap: float, h_back: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (n, 2) and triangles of the upper half, meshed by gmsh (size h, h_back at y=0)."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        occ = gmsh.model.occ
        ring = occ.cut([(2, occ.addDisk(0, 0, 0, R2, R2))], [(2, occ.addDisk(0, 0, 0, R1, R1))])[0]
        half = occ.intersect(ring, [(2, occ.addRectangle(-R2, 0, 0, 2 * R2, R2))])[0]
        occ.cut(half, [(2, occ.addRectangle(0, -gap, 0, R2, 1.5 * gap))])
        occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 1)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
        for _, tag in gmsh.model.getEntities(0):
            y = gmsh.model.getValue(0, tag, [])[1]
            gmsh.model.mesh.setSize([(0, tag)], h_back if abs(y) < 1e-9 else h)
        gmsh.model.mesh.generate(2)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        x = np.zeros((int(tags.max()) + 1, 2))
        x[tags.astype(np.int64)] = xyz.reshape(-1, 3)[:, :2]
        _, _, conn = gmsh.model.mesh.getElements(2)
        tri = conn[0].astype(np.int64).reshape(-1, 3)
    finally:
        gmsh.finalize()
    used, tri = np.unique(tri, return_inverse=True)
    return x[used], tri.reshape(-1, 3)


def _merge(xu, tu, xl, tl, cut: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two halves as one mesh; nodes of the back (y = 0) shared unless ``cut``. Also the
    half of each cell."""
    back_u = np.flatnonzero(np.abs(xu[:, 1]) < 1e-12)
    back_l = np.flatnonzero(np.abs(xl[:, 1]) < 1e-12)
    ou, ol = np.argsort(xu[back_u, 0]), np.argsort(xl[back_l, 0])
    assert np.allclose(xu[back_u[ou]], xl[back_l[ol]], atol=1e-12), "the back must match"
    new = np.full(len(xl), -1)
    if not cut:
        new[back_l[ol]] = back_u[ou]
    rest = np.flatnonzero(new < 0)
    new[rest] = len(xu) + np.arange(rest.size)
    x = np.vstack([xu, xl[rest]])
    cells = np.vstack([tu, new[tl]])
    half = np.r_[np.zeros(len(tu), dtype=np.int64), np.ones(len(tl), dtype=np.int64)]
    return x, cells, half


def _boundary(cells: np.ndarray) -> np.ndarray:
    edges = np.sort(np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    return uniq[count == 1]


def c_strip_arrays(h: float = 0.04, gap: float = 0.02, h_lower: float | None = None,
                   cut: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes, triangles (counter-clockwise) and the half (0 upper, 1 lower) of each cell."""
    xu, tu = _half(h, gap, h)
    if h_lower is None:
        xl, tl = xu * np.array([1.0, -1.0]), tu[:, ::-1]  # mirrored (orientation kept)
    else:
        xl, tl = _half(h_lower, gap, h)
        xl, tl = xl * np.array([1.0, -1.0]), tl[:, ::-1]
    x, cells, half = _merge(xu, tu, xl, tl, cut)
    e1, e2 = x[cells[:, 1]] - x[cells[:, 0]], x[cells[:, 2]] - x[cells[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    cells[cw] = cells[cw][:, ::-1]
    return x, cells, half


def c_strip(h: float = 0.04, gap: float = 0.02, h_lower: float | None = None,
            two_bodies: bool = False, cut: bool = False,
            comm: MPI.Comm = MPI.COMM_WORLD) -> df.MeshData:
    """The C-shaped strip as :class:`~dolfinx_feti.MeshData` (built on rank 0, broadcast).

    ``cut``: the back cut through at y = 0 (each half its own nodes there), with the groups
    ``cut_upper`` and ``cut_lower`` on the two faces of the cut, which ``skin`` leaves out;
    the halves are then the bodies ``upper`` and ``lower``.
    """
    data = None
    if comm.rank == 0:
        x, cells, half = c_strip_arrays(h, gap, h_lower, cut)
        skin = _boundary(cells)
        m = x[skin].mean(axis=1)
        r = np.linalg.norm(m, axis=1)
        ang = np.degrees(np.arctan2(np.abs(m[:, 1]), m[:, 0]))  # 0 at the slit, 180 at the back
        flat = np.abs(x[skin[:, 0], 1] - x[skin[:, 1], 1]) < 1e-12
        end = flat & (np.abs(np.abs(m[:, 1]) - gap / 2) < 1e-9) & (m[:, 0] > 0)
        outer = r > 0.5 * (R1 + R2)
        load = outer & (ang > 20.0) & (ang < 50.0)
        groups = {"skin": skin, "end_upper": skin[end & (m[:, 1] > 0)],
                  "end_lower": skin[end & (m[:, 1] < 0)],
                  "load_upper": skin[load & (m[:, 1] > 0)],
                  "load_lower": skin[load & (m[:, 1] < 0)],
                  "back": skin[outer & (ang > 168.0)]}
        if cut:
            on_cut = np.abs(x[skin, 1]).max(axis=1) < 1e-12
            upper_nodes = np.unique(cells[half == 0])
            in_upper = np.isin(skin, upper_nodes).all(axis=1)
            groups["cut_upper"] = skin[on_cut & in_upper]
            groups["cut_lower"] = skin[on_cut & ~in_upper]
            groups["skin"] = skin[~on_cut]  # the faces of the cut are clamped, not in contact
        two = two_bodies or cut  # a body is one piece: the cut halves are two
        bodies = ("upper", "lower") if two else ("clip",)
        body = half if two else np.zeros(len(cells), dtype=np.int64)
        tags = {name: k + 1 for k, name in enumerate([*bodies, *groups])}
        data = df.MeshData(x=x, cells=cells, cell_type="triangle", cell_body=body,
                           body_names=bodies, facet_groups=groups,
                           node_tags=np.arange(1, len(x) + 1), group_tags=tags)
    return comm.bcast(data, root=0)
