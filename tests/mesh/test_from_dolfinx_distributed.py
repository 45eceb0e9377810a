"""from_dolfinx(..., distribute=True): a DOLFINx mesh spread over the ranks in blocks of cells.

The solve then runs the distributed set-up, and the output puts the solution on the user's own
mesh through directories of the input indices: the same Functions as the replicated input.
"""

from __future__ import annotations

import element_models as em
import numpy as np
import pytest
from dolfinx_models import gmsh_both
from mpi4py import MPI
from test_elements import uniaxial
from test_from_dolfinx import RTOL, hertz_problem

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.results.postprocess import output_functions

COMM = MPI.COMM_WORLD


@pytest.fixture(scope="module")
def hertz():
    """The Hertz half model (h = 0.2) as a DOLFINx mesh distributed by gmshio."""
    from dolfinx_feti.io import meshes

    return gmsh_both(meshes.hertz2d, h_contact=0.2, h_far=2.0, gdim=2)[1]


def assert_same_solution(a, b, msh):
    """Two solutions of one problem: the same iterations, multipliers and Functions."""
    assert a.report.converged and b.report.converged
    assert a.report.sizes == b.report.sizes
    assert a.report.hessian_mults == b.report.hessian_mults
    assert a.u.function_space.mesh is msh and b.u.function_space.mesh is msh
    assert compat.space_degree(a.u.function_space) == compat.space_degree(b.u.function_space)
    scale = np.abs(b.u.x.array).max()
    assert np.abs(a.u.x.array - b.u.x.array).max() <= 1e-10 * scale


def test_hertz_distributed_equals_replicated(hertz):
    """The blocks hold about 1/n of the cells each; the solution is the replicated one's."""
    msh, ct, ft, names = hertz
    whole = df.from_dolfinx(msh, ct, ft, names=names)
    dist = df.from_dolfinx(msh, ct, ft, names=names, distribute=True)
    part = dist.part
    assert part is not None and part.comm.size == COMM.size
    n = whole.cells.shape[0]
    counts = COMM.allgather(dist.cells.shape[0])
    assert sum(counts) == n and max(counts) <= n // COMM.size + 1
    assert dist.num_cells == n and dist.num_nodes == whole.num_nodes
    # each block: the replicated mesh's cells and vertices of its global numbers
    np.testing.assert_array_equal(part.vertex_ids[dist.cells], whole.cells[part.cell_ids])
    np.testing.assert_array_equal(dist.x, whole.x[part.vertex_ids])
    np.testing.assert_array_equal(dist.node_tags, whole.node_tags[part.vertex_ids])
    a = df.solve(hertz_problem(dist), rtol=RTOL)
    b = df.solve(hertz_problem(whole), rtol=RTOL)
    assert_same_solution(a, b, msh)
    c = b.contact.pressure.max()
    np.testing.assert_allclose(a.multipliers(), b.multipliers(), rtol=0, atol=1e-10 * c)
    np.testing.assert_allclose(a.pressure_function().x.array, b.pressure_function().x.array,
                               rtol=0, atol=1e-10 * c)
    # the cell-wise fields go to the user's cells through the directory of input cells:
    # the same decomposition (the subdomain of each cell) and von Mises stress
    (sa, *_, va), (sb, *_, vb) = output_functions(a), output_functions(b)
    assert sa.name == "subdomain" and sa.function_space.mesh is msh
    np.testing.assert_array_equal(sa.x.array, sb.x.array)
    assert va.name == "von_mises" and va.function_space.mesh is msh
    np.testing.assert_allclose(va.x.array, vb.x.array, rtol=0,
                               atol=1e-9 * np.abs(vb.x.array).max())


def test_hertz_degree2_distributed(hertz):
    """A P2 space on the distributed DOLFINx mesh: the replicated input's P2 Function."""
    msh, ct, ft, names = hertz
    a = df.solve(hertz_problem(df.from_dolfinx(msh, ct, ft, names=names, distribute=True),
                               degree=2), rtol=RTOL)
    b = df.solve(hertz_problem(df.from_dolfinx(msh, ct, ft, names=names), degree=2),
                 rtol=RTOL)
    assert compat.space_degree(a.u.function_space) == 2
    assert_same_solution(a, b, msh)


@pytest.mark.parametrize("cell", ["quadrilateral", "hexahedron"])
def test_quadrilaterals_and_hexahedra_distributed_xdmf(cell, tmp_path_factory):
    """Quadrilaterals or hexahedra with contact: the replicated solution, written to XDMF."""
    _, (msh, ct, ft, names) = gmsh_both(em.rectangle, quads=True, gdim=2) \
        if cell == "quadrilateral" else gmsh_both(em.box, hexes=True, gdim=3)
    dist = df.from_dolfinx(msh, ct, ft, names=names, distribute=True)
    assert dist.cell_type == cell and dist.part is not None
    a = df.solve(uniaxial(dist, 1, contact=True), rtol=RTOL)
    b = df.solve(uniaxial(df.from_dolfinx(msh, ct, ft, names=names), 1, contact=True),
                 rtol=RTOL)
    assert_same_solution(a, b, msh)
    folder = COMM.bcast(str(tmp_path_factory.mktemp("dxd")) if COMM.rank == 0 else None)
    a.write_xdmf(f"{folder}/{cell}.xdmf")
    if COMM.rank == 0:
        text = open(f"{folder}/{cell}.xdmf").read()
        assert all(f'Name="{n}"' in text for n in ("displacement", "subdomain", "von_mises"))


def test_refused_arguments(hertz):
    """distribute=True with replicate=False, or with a curved mesh, is refused by name."""
    msh, ct, ft, names = hertz
    with pytest.raises(df.InputError, match="distribute=True.*replicate=False"):
        df.from_dolfinx(msh, ct, ft, names=names, replicate=False, distribute=True)
    # rank 0's checks of the whole mesh end every rank with their message
    with pytest.raises(df.InputError, match="names.*no such tag"):
        df.from_dolfinx(msh, ct, ft, names={"nothing": 99}, distribute=True)
    _, (curved, cct, cft, cnames) = gmsh_both(em.plate_with_hole, gdim=2)
    with pytest.raises(df.InputError, match="curved.*distribute=False"):
        df.from_dolfinx(curved, cct, cft, names=cnames, distribute=True)
