"""A 2D triangle mesh extruded into tetrahedra (a prism per triangle and layer, 3 tetrahedra).

Each prism (v0, v1, v2) × (k, k + 1) with v0 < v1 < v2 is cut into (v0, v1, v2, v0'),
(v1, v2, v0', v1'), (v2, v0', v1', v2') (primes: the upper layer): every quadrilateral side is
cut along the diagonal from its larger lower vertex to its smaller upper one, from whichever
prism it is seen, so the tetrahedra are conforming. A 2D boundary group (edges) becomes the
triangles of its extruded walls, cut the same way; the caps z = 0 and z = depth are the group
``caps`` and are added to a group named in ``with_caps``.
"""

from __future__ import annotations

import numpy as np

import dolfinx_feti as df


def extrude(mesh2d: df.MeshData, depth: float, layers: int,
            with_caps: tuple[str, ...] = ()) -> df.MeshData:
    """The extruded mesh (see the module's text); bodies and groups keep their names."""
    n = mesh2d.x.shape[0]
    z = np.linspace(0.0, depth, layers + 1)
    x = np.column_stack([np.tile(mesh2d.x, (layers + 1, 1)), np.repeat(z, n)])
    tri = np.sort(mesh2d.cells, axis=1)
    k = np.arange(layers)[:, None, None] * n
    lo, up = tri[None] + k, tri[None] + k + n  # (layers, C, 3)
    tets = np.concatenate([np.stack([lo[..., 0], lo[..., 1], lo[..., 2], up[..., 0]], -1),
                           np.stack([lo[..., 1], lo[..., 2], up[..., 0], up[..., 1]], -1),
                           np.stack([lo[..., 2], up[..., 0], up[..., 1], up[..., 2]], -1)])
    body = np.tile(mesh2d.cell_body, 3 * layers)

    def walls(edges):
        e = np.sort(edges, axis=1)[None] + k[:, :, :1]  # (layers, E, 2)
        a, b = e[..., 0], e[..., 1]
        return np.concatenate([np.stack([a, b, a + n], -1).reshape(-1, 3),
                               np.stack([b, a + n, b + n], -1).reshape(-1, 3)])

    groups = {name: walls(f) for name, f in mesh2d.facet_groups.items()}
    caps = np.concatenate([tri, tri + layers * n])
    groups["caps"] = caps
    for name in with_caps:
        groups[name] = np.concatenate([groups[name], caps])
    tags = {name: t + 1 for t, name in enumerate([*mesh2d.body_names, *groups])}
    return df.MeshData(x=x, cells=tets.reshape(-1, 4), cell_type="tetrahedron",
                       cell_body=body, body_names=mesh2d.body_names, facet_groups=groups,
                       node_tags=np.arange(1, x.shape[0] + 1), group_tags=tags)
