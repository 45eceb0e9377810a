"""Small 2D meshes made by hand as MeshData (no gmsh): blocks of Kuhn triangles with groups.

For the checks of interface pairs and the property-based suite: any size, position and
spacing in microseconds, with every boundary side of every block a named group.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

import dolfinx_feti as df

SIDES = ("bottom", "right", "top", "left")


def block(nx: int, ny: int, origin: Sequence[float] = (0.0, 0.0),
          size: Sequence[float] = (1.0, 1.0)) -> tuple[np.ndarray, np.ndarray, dict]:
    """Nodes, Kuhn triangles and the boundary sides (node pairs) of an nx × ny grid."""
    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="xy")
    x = np.stack([origin[0] + size[0] * i.ravel() / nx,
                  origin[1] + size[1] * j.ravel() / ny], axis=1)
    v = (np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)[None, :]).ravel()
    cells = np.concatenate([np.stack([v, v + 1, v + nx + 2], axis=1),
                            np.stack([v, v + nx + 2, v + nx + 1], axis=1)])
    node = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)

    def chain(a):
        return np.stack([a[:-1], a[1:]], axis=1)

    sides = {"bottom": chain(node[0]), "right": chain(node[:, -1]),
             "top": chain(node[-1]), "left": chain(node[:, 0])}
    return x, cells, sides


def blocks(specs: Sequence[dict]) -> df.MeshData:
    """Several blocks, each a body with its own nodes; groups ``<body>_<side>``.

    Each spec: ``name``, ``n`` (nx, ny), ``origin``, ``size``.
    """
    xs, cells, body, groups, offset = [], [], [], {}, 0
    for b, spec in enumerate(specs):
        x, c, sides = block(*spec["n"], spec.get("origin", (0.0, 0.0)),
                            spec.get("size", (1.0, 1.0)))
        xs.append(x)
        cells.append(c + offset)
        body.append(np.full(c.shape[0], b, dtype=np.int32))
        for side, f in sides.items():
            groups[f"{spec['name']}_{side}"] = f + offset
        offset += x.shape[0]
    x = np.concatenate(xs)
    names = tuple(s["name"] for s in specs)
    tags = {n: i + 1 for i, n in enumerate(names)}
    tags.update({g: 100 + i for i, g in enumerate(groups)})
    return df.MeshData(x=x, cells=np.concatenate(cells).astype(np.int64), cell_type="triangle",
                       cell_body=np.concatenate(body), body_names=names, facet_groups=groups,
                       node_tags=np.arange(1, x.shape[0] + 1), group_tags=tags)


def stacked(n_lower: int = 4, n_upper: int = 3, gap: float = 0.0, shift: float = 0.0,
            height: float = 0.5) -> df.MeshData:
    """Body "lower" on [0, 1] × [0, height], body "upper" above it, ``gap`` apart.

    The two meshes do not match (n_lower and n_upper cells across); ``shift`` moves the upper
    block along x.
    """
    return blocks([
        {"name": "lower", "n": (n_lower, max(1, n_lower // 2)), "size": (1.0, height)},
        {"name": "upper", "n": (n_upper, max(1, n_upper // 2)),
         "origin": (shift, height + gap), "size": (1.0, height)},
    ])


def transformed(mesh: df.MeshData, scale: float = 1.0, shift: Sequence[float] = (0.0, 0.0)
                ) -> df.MeshData:
    """The same mesh with its coordinates scaled, then shifted."""
    import dataclasses
    return dataclasses.replace(mesh, x=mesh.x * scale + np.asarray(shift, dtype=float))
