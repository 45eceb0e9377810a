"""A gmsh model whose bodies are of different cell types: one mesh per type (mesh/mixed.py)."""

from __future__ import annotations

import gmsh
import numpy as np
import pytest
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes_occ import stacked_blocks
from dolfinx_feti.mesh.topology import cell_volumes


def _second_order(*args, **kwargs):
    stacked_blocks(*args, **kwargs)
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 0)
    gmsh.model.mesh.setOrder(2)


def _gmsh_counts(dim: int, recombined: str, h=(0.25, 0.4)) -> dict:
    """What gmsh itself holds of the model: elements per body, facets per group."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        stacked_blocks(dim, *h, recombine=recombined)
        out = {}
        for d, tag in gmsh.model.getPhysicalGroups():
            name = gmsh.model.getPhysicalName(d, tag)
            n = 0
            for ent in gmsh.model.getEntitiesForPhysicalGroup(d, tag):
                n += sum(e.size for e in gmsh.model.mesh.getElements(d, ent)[1])
            out[name] = n
        return out
    finally:
        gmsh.finalize()


@pytest.mark.parametrize("dim, types", [(2, ("quadrilateral", "triangle")),
                                        (3, ("hexahedron", "tetrahedron"))])
def test_one_mesh_per_cell_type(dim, types):
    """Each body in the mesh of its type, the groups split between them, nothing lost."""
    mesh = df.build_mesh(stacked_blocks, dim, 0.25, 0.4, recombine="lower")
    assert isinstance(mesh, df.MixedMesh)
    assert mesh.cell_types == types and mesh.body_names == ("lower", "upper")
    assert mesh.gdim == dim and mesh.tdim == dim
    lower, upper = mesh.parts
    assert lower.body_names == ("lower",) and upper.body_names == ("upper",)
    assert mesh.part_of_body("upper") == 1
    # the two boxes fill [0, 1]^dim and [0, 1]^(dim-1) x [1, 2]
    for part, z in ((lower, 0.0), (upper, 1.0)):
        assert np.isclose(np.abs(cell_volumes(part.x, part.cells, part.cell_type)).sum(), 1.0,
                          rtol=1e-12)
        assert np.isclose(part.x[:, -1].min(), z) and np.isclose(part.x[:, -1].max(), z + 1)
    counts = mesh.parts[0].cells.shape[0], mesh.parts[1].cells.shape[0]
    if MPI.COMM_WORLD.rank == 0:
        gm = _gmsh_counts(dim, "lower")
        assert counts == (gm["lower"], gm["upper"])
        assert sum(p.facet_groups["sym0"].shape[0] for p in mesh.parts) == gm["sym0"]
    assert mesh.parts_of_group("sym0") == (0, 1)
    assert mesh.parts_of_group("top") == (1,) and mesh.parts_of_group("bottom") == (0,)
    assert "top" not in lower.facet_groups
    # the parts share no node
    assert np.intersect1d(lower.node_tags, upper.node_tags).size == 0
    # every rank holds the same meshes
    comm = MPI.COMM_WORLD
    sig = [(p.x.sum(), p.cells.sum(), p.cell_type) for p in mesh.parts]
    assert all(s == sig for s in comm.allgather(sig))


def test_second_order_parts():
    """A second-order model: Q2 hexahedra and P2 tetrahedra, each part with its nodes."""
    mesh = df.build_mesh(_second_order, 3, 0.5, 0.5, recombine="upper")
    assert mesh.cell_types == ("tetrahedron", "hexahedron")
    for part in mesh.parts:
        assert part.geometry_degree == 2
        ent, pos = part.high_order[1]  # edge nodes: the edges' midpoints on straight edges
        assert np.allclose(part.x[ent].mean(axis=1), pos, atol=1e-12)


def test_single_type_still_one_mesh():
    mesh = df.build_mesh(stacked_blocks, 3, 0.5, 0.5, recombine=True)
    assert isinstance(mesh, df.MeshData) and mesh.cell_type == "hexahedron"


def _body_of_two_types():
    stacked_blocks(3, 0.5, 0.5, recombine="lower")
    gmsh.model.removePhysicalGroups([(3, 1), (3, 2)])
    gmsh.model.addPhysicalGroup(3, [1, 2], 1)
    gmsh.model.setPhysicalName(3, 1, "both")


def test_body_of_two_types_refused():
    with pytest.raises(df.InputError, match="body 'both' mixes hexahedron cells of order 1 "
                       "and tetrahedron cells of order 1"):
        df.build_mesh(_body_of_two_types)


def _conforming_2d():
    """Two rectangles fragmented (a common edge, shared nodes): quadrilaterals and triangles."""
    gmsh.model.add("conforming")
    occ = gmsh.model.occ
    a, b = occ.addRectangle(0, 0, 0, 1, 1), occ.addRectangle(0, 1, 0, 1, 1)
    occ.fragment([(2, a)], [(2, b)])
    occ.synchronize()
    gmsh.model.mesh.setRecombine(2, a)
    gmsh.model.addPhysicalGroup(2, [a], 1)
    gmsh.model.setPhysicalName(2, 1, "quads")
    gmsh.model.addPhysicalGroup(2, [b], 2)
    gmsh.model.setPhysicalName(2, 2, "triangles")
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
    gmsh.model.mesh.generate(2)


def test_shared_nodes_refused():
    with pytest.raises(df.InputError, match=r"the quadrilateral bodies \['quads'\] and the "
                       r"triangle bodies \['triangles'\] share \d+ nodes"):
        df.build_mesh(_conforming_2d)


def test_distributed_refused():
    with pytest.raises(df.InputError, match=r"several cell types .* \(replicate=True, "
                       r"distribute=False\)"):
        df.build_mesh(stacked_blocks, 2, 0.5, 0.5, recombine="lower", distribute=True)
