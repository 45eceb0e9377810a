"""Small meshes of every supported cell type for the element tests (gmsh on rank 0, or NumPy)."""

from __future__ import annotations

import gmsh
import numpy as np

import dolfinx_feti as df
from dolfinx_feti.io.meshes import physical_groups


def _group(dim, ents, tag, name):
    gmsh.model.addPhysicalGroup(dim, ents, tag)
    gmsh.model.setPhysicalName(dim, tag, name)


def _structured_hexahedra(volume: int, n: int) -> None:
    """Ask gmsh for n³ hexahedra in a box-shaped volume (transfinite and recombined)."""
    for _, c in gmsh.model.getEntities(1):
        gmsh.model.mesh.setTransfiniteCurve(c, n + 1)
    for _, s in gmsh.model.getEntities(2):
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
    gmsh.model.mesh.setTransfiniteVolume(volume)


def rectangle(quads: bool = False, h: float = 0.35, lx: float = 2.0, ly: float = 1.0):
    """[0, lx] × [0, ly], unstructured triangles or recombined (general) quadrilaterals.

    Groups: "body"; "left", "right", "bottom", "top".
    """
    s = gmsh.model.occ.addRectangle(0, 0, 0, lx, ly)
    gmsh.model.occ.synchronize()
    _group(2, [s], 1, "body")
    eps = 1e-6
    sides = {"left": (-eps, -eps, eps, ly + eps), "right": (lx - eps, -eps, lx + eps, ly + eps),
             "bottom": (-eps, -eps, lx + eps, eps), "top": (-eps, ly - eps, lx + eps, ly + eps)}
    for k, (name, (a, b, c, d)) in enumerate(sides.items()):
        ents = [e for _, e in gmsh.model.getEntitiesInBoundingBox(a, b, -eps, c, d, eps, 1)]
        _group(1, ents, 11 + k, name)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.RecombineAll", 1 if quads else 0)
    gmsh.model.mesh.generate(2)
    return physical_groups()


def box(hexes: bool = False, n: int = 3, h: float = 0.4):
    """The unit cube, unstructured tetrahedra or n³ structured hexahedra.

    Groups: "body"; the faces "x0", "x1", "y0", "y1", "z0", "z1".
    """
    v = gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
    gmsh.model.occ.synchronize()
    _group(3, [v], 1, "body")
    eps = 1e-6
    for k, (axis, side) in enumerate([(a, s) for a in range(3) for s in (0, 1)]):
        lo, hi = [-eps] * 3, [1 + eps] * 3
        lo[axis], hi[axis] = side - eps, side + eps
        ents = [e for _, e in gmsh.model.getEntitiesInBoundingBox(*lo, *hi, 2)]
        _group(2, ents, 11 + k, "xyz"[axis] + str(side))
    if hexes:
        _structured_hexahedra(v, n)
    else:
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.model.mesh.generate(3)
    return physical_groups()


def distorted_hexahedra(n: int = 3, shake: float = 0.2, seed: int = 0) -> df.MeshData:
    """The unit cube in n³ hexahedra with the interior nodes moved at random (non-planar faces).

    Built as MeshData directly (vertices in DOLFINx's tensor order); the same groups as
    :func:`box`.
    """
    k = np.arange(n + 1)
    idx = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)[:, ::-1]
    x = idx / n  # x fastest
    inner = np.all((idx > 0) & (idx < n), axis=1)
    x[inner] += shake / n * np.random.default_rng(seed).uniform(-1, 1, (int(inner.sum()), 3))

    def node(i, j, m):
        return i + (n + 1) * (j + (n + 1) * m)

    c = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"),
                 axis=-1).reshape(-1, 3)
    cells = np.stack([node(c[:, 2] + a, c[:, 1] + b, c[:, 0] + d)
                      for d in (0, 1) for b in (0, 1) for a in (0, 1)], axis=1)
    groups = {}
    for axis in range(3):
        for side in (0, 1):
            on = np.isclose(x[cells], side)[:, :, axis]
            local = [v for v in range(8) if (v >> axis) & 1 == side]
            mine = on[:, local].all(axis=1)
            groups["xyz"[axis] + str(side)] = cells[mine][:, local]
    return df.MeshData(x=x, cells=cells, cell_type="hexahedron",
                       cell_body=np.zeros(cells.shape[0], dtype=np.int32), body_names=("body",),
                       facet_groups=groups, node_tags=np.arange(x.shape[0]))


def plate_with_hole(quads: bool = False, h: float = 0.3, order: int = 2):
    """[0, 2] × [0, 1] with a hole of radius 0.25 at (1, 0.5), meshed with curved cells.

    Groups: "body"; "outer" (the rectangle's sides), "hole".
    """
    occ = gmsh.model.occ
    r = occ.addRectangle(0, 0, 0, 2, 1)
    d = occ.addDisk(1, 0.5, 0, 0.25, 0.25)
    occ.cut([(2, r)], [(2, d)])
    occ.synchronize()
    s = [e for _, e in gmsh.model.getEntities(2)]
    _group(2, s, 1, "body")
    curves = gmsh.model.getBoundary([(2, e) for e in s], oriented=False)
    hole = [c for _, c in curves if np.isclose(gmsh.model.occ.getCenterOfMass(1, c)[0], 1.0)
            and np.isclose(gmsh.model.occ.getCenterOfMass(1, c)[1], 0.5, atol=0.1)]
    _group(1, [c for _, c in curves if c not in hole], 11, "outer")
    _group(1, hole, 12, "hole")
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.RecombineAll", 1 if quads else 0)
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.setOrder(order)
    return physical_groups()


def box_with_hole(hexes: bool = False, h: float = 0.35, order: int = 2, n: int = 2):
    """Second-order 3D meshes: tetrahedra of a unit cube with a cylindrical hole (curved), or
    n³ structured hexahedra of the unit cube (27-node, straight).

    Groups: "body"; "outer" (the cube's faces), and "hole" for the tetrahedra.
    """
    occ = gmsh.model.occ
    b = occ.addBox(0, 0, 0, 1, 1, 1)
    if not hexes:
        c = occ.addCylinder(0.5, 0.5, -0.1, 0, 0, 1.2, 0.2)
        occ.cut([(3, b)], [(3, c)])
    occ.synchronize()
    vols = [e for _, e in gmsh.model.getEntities(3)]
    _group(3, vols, 1, "body")
    faces = [f for _, f in gmsh.model.getBoundary([(3, v) for v in vols], oriented=False)]
    hole = [f for f in faces
            if np.hypot(*(np.array(occ.getCenterOfMass(2, f))[:2] - 0.5)) < 0.3
            and 0.1 < occ.getCenterOfMass(2, f)[2] < 0.9]
    _group(2, [f for f in faces if f not in hole], 11, "outer")
    if hole:
        _group(2, hole, 12, "hole")
    if hexes:
        _structured_hexahedra(vols[0], n)
    else:
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.setOrder(order)
    return physical_groups()


def stacked_blocks(n: int = 6, lx: float = 2.0):
    """Two blocks [0, lx] × [0, 1] ("lower") and [0, lx] × [1, 2] ("upper"), meshed apart with
    the same structured triangles: matching nodes on their common side, each its own.

    Groups: "lower", "upper"; "bottom" (y = 0), "top" (y = 2), "left" (x = 0, both blocks),
    "lower_top", "upper_bottom".
    """
    a = gmsh.model.occ.addRectangle(0, 0, 0, lx, 1)
    b = gmsh.model.occ.addRectangle(0, 1, 0, lx, 1)
    gmsh.model.occ.synchronize()
    _group(2, [a], 1, "lower")
    _group(2, [b], 2, "upper")
    eps = 1e-6
    lines = {"bottom": [], "top": [], "left": [], "lower_top": [], "upper_bottom": []}
    for surf, (y0, y1) in ((a, (0, 1)), (b, (1, 2))):
        for _, c in gmsh.model.getBoundary([(2, surf)], oriented=False):
            x, y, _ = gmsh.model.occ.getCenterOfMass(1, c)
            gmsh.model.mesh.setTransfiniteCurve(c, 2 * n + 1 if abs(x - lx / 2) < eps else n + 1)
            if abs(x) < eps:
                lines["left"].append(c)
            elif abs(y - y0) < eps:
                lines["bottom" if surf == a else "upper_bottom"].append(c)
            elif abs(y - y1) < eps:
                lines["lower_top" if surf == a else "top"].append(c)
        gmsh.model.mesh.setTransfiniteSurface(surf)
    for k, (name, ents) in enumerate(lines.items()):
        _group(1, ents, 11 + k, name)
    gmsh.model.mesh.generate(2)
    return physical_groups()
