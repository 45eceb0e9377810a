"""A user's own DOLFINx mesh: a box from ``dolfinx.mesh.create_box`` graded toward a contact.

The unit cube [0, 1]³ of n × n × n/2·2 tetrahedra, its vertices pulled toward the corner
(0, 0, 1) (x → x^1.6, y → y^1.6, z → 1 − (1 − z)^1.6: cells shrink toward the contact), a rigid
sphere of radius 0.5 pressed 0.02 into the top at the corner (a quarter model: symmetry on
x = 0 and y = 0, the bottom clamped), E = 10, ν = 0.3. Built as a new user builds it:
``create_box``, MeshTags from ``locate_entities_boundary``, ``df.from_dolfinx``.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti import compat

GRADING = 1.6
RADIUS, DEPTH = 0.5, 0.02


def box_mesh(n: int, comm: MPI.Comm = MPI.COMM_WORLD):
    """The graded DOLFINx box and its tags: ``(msh, cell_tags, facet_tags, names)``."""
    import dolfinx.mesh as dm

    msh = dm.create_box(comm, [np.zeros(3), np.ones(3)], [n, n, n],
                        dm.CellType.tetrahedron)
    x = msh.geometry.x
    x[:, 0] = x[:, 0] ** GRADING
    x[:, 1] = x[:, 1] ** GRADING
    x[:, 2] = 1.0 - (1.0 - x[:, 2]) ** GRADING
    tdim = msh.topology.dim
    groups = {"bottom": (1, lambda p: np.isclose(p[2], 0.0)),
              "symmetry_x": (2, lambda p: np.isclose(p[0], 0.0)),
              "symmetry_y": (3, lambda p: np.isclose(p[1], 0.0)),
              "top": (4, lambda p: np.isclose(p[2], 1.0))}
    facets, values = [], []
    for tag, where in groups.values():
        f = dm.locate_entities_boundary(msh, tdim - 1, where)
        facets.append(f)
        values.append(np.full(f.size, tag, dtype=np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    facets, first = np.unique(facets, return_index=True)  # an edge facet keeps its first group
    ft = dm.meshtags(msh, tdim - 1, facets.astype(np.int32), values[first])
    ncell = compat.cell_counts(msh)[0]
    ct = compat.cell_tags(msh, np.arange(ncell, dtype=np.int32), np.ones(ncell, np.int32))
    names = {"block": (tdim, 1), **{k: (tdim - 1, v[0]) for k, v in groups.items()}}
    return msh, ct, ft, names


def box_problem(n: int, decomposition=None, comm: MPI.Comm = MPI.COMM_WORLD
                ) -> df.ContactProblem:
    """The contact problem of the graded box (the library's default decomposition if None)."""
    msh, ct, ft, names = box_mesh(n, comm)
    mesh = df.from_dolfinx(msh, ct, ft, names=names)
    sphere = df.Sphere(center=(0.0, 0.0, 1.0 + RADIUS - DEPTH), radius=RADIUS)
    kw = {} if decomposition is None else {"decomposition": decomposition}
    return df.ContactProblem(
        mesh, df.Elasticity(10.0, 0.3),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry_x", components=[0]),
                   df.Dirichlet("symmetry_y", components=[1])],
        contact=[df.RigidObstacle("top", sphere)], **kw)
