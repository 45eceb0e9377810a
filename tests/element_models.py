"""Small meshes of every supported cell type for the element tests (gmsh on rank 0, or NumPy)."""

from __future__ import annotations

import gmsh
import numpy as np

import dolfinx_feti as df
from dolfinx_feti.meshes import physical_groups


def _group(dim, ents, tag, name):
    gmsh.model.addPhysicalGroup(dim, ents, tag)
    gmsh.model.setPhysicalName(dim, tag, name)


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
        for _, c in gmsh.model.getEntities(1):
            gmsh.model.mesh.setTransfiniteCurve(c, n + 1)
        for _, s in gmsh.model.getEntities(2):
            gmsh.model.mesh.setTransfiniteSurface(s)
            gmsh.model.mesh.setRecombine(2, s)
        gmsh.model.mesh.setTransfiniteVolume(v)
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
