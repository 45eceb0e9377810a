"""Bodies of different cell types from DOLFINx meshes: one mesh per type (MixedMesh.of)."""

from __future__ import annotations

import gmsh
import numpy as np
import pytest
from dolfinx_models import gmsh_both

import dolfinx_feti as df

P, E, NU = 1.0, 1.0, 0.3


def _box(y0: float, body: str, bottom: str, top: str, h: float, quads: bool) -> None:
    """The unit square [0, 1] x [y0, y0 + 1] alone, of quadrilaterals or triangles."""
    gmsh.model.add(body)
    occ = gmsh.model.occ
    s = occ.addRectangle(0.0, y0, 0.0, 1.0, 1.0)
    occ.synchronize()
    gmsh.model.mesh.setSize(gmsh.model.getBoundary([(2, s)], recursive=True), h)
    if quads:
        for c in gmsh.model.getEntities(1):
            gmsh.model.mesh.setTransfiniteCurve(c[1], int(round(1 / h)) + 1)
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
    gmsh.model.addPhysicalGroup(2, [s], 1)
    gmsh.model.setPhysicalName(2, 1, body)

    def curves(x0, y0_, x1, y1):
        e = 1e-7
        return [t for _, t in gmsh.model.getEntitiesInBoundingBox(x0 - e, y0_ - e, -e,
                                                                   x1 + e, y1 + e, e, 1)]

    for tag, (name, box) in enumerate([(bottom, (0, y0, 1, y0)), (top, (0, y0 + 1, 1, y0 + 1)),
                                       ("left", (0, y0, 0, y0 + 1))], start=11):
        gmsh.model.addPhysicalGroup(1, curves(*box), tag)
        gmsh.model.setPhysicalName(1, tag, name)
    gmsh.model.mesh.generate(2)
    return {body: (2, 1), bottom: (1, 11), top: (1, 12), "left": (1, 13)}


def _dolfinx_meshes():
    """A quadrilateral block under a triangle block: two DOLFINx meshes (gmshio)."""
    out = []
    for args in ((0.0, "lower", "bottom", "lower_top", 0.25, True),
                 (1.0, "upper", "upper_bottom", "top", 0.4, False)):
        _, (msh, ct, ft, names) = gmsh_both(_box, *args, gdim=2)
        out.append((msh, df.from_dolfinx(msh, ct, ft, names=names)))
    return out


def test_tie_patch_test_on_two_dolfinx_meshes():
    """The tie patch test through MixedMesh.of; the solution is on the user's meshes."""
    meshes = _dolfinx_meshes()
    mesh = df.MixedMesh.of([m for _, m in meshes])
    assert mesh.cell_types == ("quadrilateral", "triangle")
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"top": (0.0, -P)}),
        dirichlet=[df.Dirichlet("bottom", 0.0, components=(1,)),
                   df.Dirichlet("left", 0.0, components=(0,))],
        ties=[df.Tie("upper_bottom", "lower_top")])
    sol = df.solve(problem, method="tfeti", rtol=1e-12)
    assert sol.report.converged
    for k, (msh, _) in enumerate(meshes):
        u = sol.function(k)
        assert u.function_space.mesh is msh  # the user's own mesh
        V = u.function_space
        n = V.dofmap.index_map.size_local
        x = V.tabulate_dof_coordinates()[:n, :2]
        exact = np.stack([NU * (1 + NU) * P / E * x[:, 0], -(1 - NU**2) * P / E * x[:, 1]], 1)
        assert np.abs(u.x.array.reshape(-1, 2)[:n] - exact).max() < 1e-10


def test_mixed_mesh_of_refuses_by_name():
    meshes = _dolfinx_meshes()
    with pytest.raises(df.InputError, match="two or more MeshData"):
        df.MixedMesh.of([meshes[0][1]])
    with pytest.raises(df.InputError, match="a body name is used in two meshes"):
        df.MixedMesh.of([meshes[0][1], meshes[0][1]])
