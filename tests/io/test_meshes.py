"""The benchmark geometries of dolfinx_feti.io.meshes and the committed .msh files in meshes/."""

import math
import subprocess
import sys
from pathlib import Path

import gmsh
import numpy as np
import pytest

from dolfinx_feti import compat
from dolfinx_feti.io import meshes

ROOT = Path(__file__).resolve().parents[2]
MESH_DIR = ROOT / "meshes"


@pytest.fixture
def session():
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    yield
    gmsh.finalize()


def nodes():
    """All nodes of the current model: (tag → row, coordinates)."""
    tags, x, _ = gmsh.model.mesh.getNodes()
    row = np.full(int(tags.max()) + 1, -1)
    row[tags.astype(int)] = np.arange(tags.size)
    return row, x.reshape(-1, 3)


def group_elements(groups, name):
    """The simplices of a physical group as node tags, one row each."""
    dim, tag = groups[name]
    blocks = []
    for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
        types, _, elem_nodes = gmsh.model.mesh.getElements(dim, entity)
        assert list(types) == [{1: 1, 2: 2, 3: 4}[dim]]  # first-order simplices only
        blocks.append(elem_nodes[0].astype(int).reshape(-1, dim + 1))
    return np.concatenate(blocks)


def group_nodes(groups, name):
    """Coordinates of the nodes of a physical group."""
    tags, x = gmsh.model.mesh.getNodesForPhysicalGroup(*groups[name])
    assert tags.size == np.unique(tags).size
    return x.reshape(-1, 3)


def signed_measure(x, cells):
    """Signed area (triangles in the xy plane) or volume (tetrahedra) of each cell."""
    v = x[cells[:, 1:]] - x[cells[:, :1]]
    if cells.shape[1] == 3:
        return 0.5 * (v[:, 0, 0] * v[:, 1, 1] - v[:, 0, 1] * v[:, 1, 0])
    return np.linalg.det(v) / 6


def assert_conforming(cells):
    """Every facet of the simplices belongs to one or two of them."""
    k = cells.shape[1]
    facets = np.concatenate([np.delete(cells, m, axis=1) for m in range(k)])
    _, counts = np.unique(np.sort(facets, axis=1), axis=0, return_counts=True)
    assert counts.max() <= 2


def assert_same_point_sets(a, b):
    assert a.shape == b.shape
    np.testing.assert_array_equal(a[np.lexsort(a.T[::-1])], b[np.lexsort(b.T[::-1])])


def assert_boundary_of(groups, body, facet_group):
    """The facets of a group are facets of the body's cells."""
    cells = group_elements(groups, body)
    k = cells.shape[1]
    faces = {tuple(sorted(f)) for m in range(k) for f in np.delete(cells, m, axis=1)}
    assert all(tuple(sorted(f)) in faces for f in group_elements(groups, facet_group))


@pytest.mark.serial
@pytest.mark.parametrize("n", [1, 3, 8])
def test_membranes(session, n):
    groups = meshes.membranes(n)
    assert groups == {
        "left": (2, 1),
        "right": (2, 2),
        "dirichlet": (1, 11),
        "contact_left": (1, 12),
        "contact_right": (1, 13),
    }
    row, x = nodes()
    assert x.shape[0] == 2 * (n + 1) ** 2
    h = 1 / n
    for body, x0 in (("left", 0.0), ("right", 1.0)):
        cells = row[group_elements(groups, body)]
        assert cells.shape[0] == 2 * n * n
        xb = x[np.unique(cells)]
        assert xb[:, 0].min() == x0 and xb[:, 0].max() == x0 + 1
        area = signed_measure(x, cells)
        np.testing.assert_allclose(area, h * h / 2, rtol=1e-12)  # all counter-clockwise
        # The diagonal of each square runs from its lower-left to its upper-right corner: the
        # longest edge of every triangle has direction (+h, +h).
        edges = x[np.roll(cells, -1, axis=1)] - x[cells]
        longest = edges[np.arange(cells.shape[0]), np.argmax(np.linalg.norm(edges, axis=2), 1)]
        np.testing.assert_allclose(np.abs(longest[:, :2]), h, rtol=1e-12)
        assert np.all(longest[:, 0] * longest[:, 1] > 0)
        assert_conforming(cells)
    left, right = (np.unique(group_elements(groups, b)) for b in ("left", "right"))
    assert np.intersect1d(left, right).size == 0  # two bodies, no shared node
    for name, body, xc in [
        ("dirichlet", "left", 0.0),
        ("contact_left", "left", 1.0),
        ("contact_right", "right", 1.0),
    ]:
        xg = group_nodes(groups, name)
        assert xg.shape[0] == n + 1 and np.all(xg[:, 0] == xc)
        assert group_elements(groups, name).shape[0] == n
        assert_boundary_of(groups, body, name)
    assert_same_point_sets(
        group_nodes(groups, "contact_left"), group_nodes(groups, "contact_right")
    )


@pytest.mark.serial
@pytest.mark.parametrize(
    "kwargs",
    [{}, {"h_contact": 0.1, "h_far": 2.0, "R": 5.0, "contact_width": 1.25}],
    ids=["default", "coarse"],
)
def test_hertz2d(session, kwargs):
    p = {"h_contact": 0.05, "h_far": 1.0, "R": 8.0, "width": 20.0, "height": 20.0}
    p |= {"contact_width": 2.5} | kwargs
    groups = meshes.hertz2d(**kwargs)
    assert groups == {
        "disk": (2, 1),
        "block": (2, 2),
        "disk_contact": (1, 11),
        "block_contact": (1, 12),
        "load": (1, 13),
        "symmetry": (1, 14),
        "bottom": (1, 15),
    }
    R, h, cw = p["R"], p["h_contact"], p["contact_width"]
    row, x = nodes()
    disk, block = (row[group_elements(groups, b)] for b in ("disk", "block"))
    assert np.intersect1d(disk, block).size == 0
    for cells in (disk, block):
        assert np.all(signed_measure(x, cells) > 0)
        assert_conforming(cells)
    assert signed_measure(x, block).sum() == pytest.approx(p["width"] / 2 * p["height"])
    # The arc is a polygon: chords of length <= h_far cut at most (arc length) h_far² / (12 R).
    chord_loss = math.pi * p["h_far"] ** 2 / 24
    assert 0 < math.pi * R * R / 4 - signed_measure(x, disk).sum() < chord_loss

    # Matching contact nodes: x_k = k h on both sides, on the circle and on y = 0.
    xd = group_nodes(groups, "disk_contact")
    xb = group_nodes(groups, "block_contact")
    xd, xb = xd[np.argsort(xd[:, 0])], xb[np.argsort(xb[:, 0])]
    np.testing.assert_array_equal(xd[:, 0], xb[:, 0])
    # x_k = k h up to the contact width, which ends the zone (with a shorter last segment if
    # it is not a multiple of h).
    expected = h * np.arange(math.floor(cw / h + 1e-9) + 1)
    if not math.isclose(expected[-1], cw):
        expected = np.append(expected, cw)
    k = expected.size - 1
    np.testing.assert_allclose(xb[:, 0], expected, rtol=0, atol=1e-12)
    assert xb[-1, 0] == cw
    assert np.all(xb[:, 1] == 0)
    np.testing.assert_allclose(xd[:, 1], R - np.sqrt(R * R - xd[:, 0] ** 2), rtol=0, atol=1e-14)
    assert group_elements(groups, "disk_contact").shape[0] == k
    assert group_elements(groups, "block_contact").shape[0] == k
    assert_boundary_of(groups, "disk", "disk_contact")
    assert_boundary_of(groups, "block", "block_contact")

    # The element size near the origin is about h on both bodies.
    origin = np.flatnonzero(np.linalg.norm(x, axis=1) < 1e-14)
    assert origin.size == 2
    for cells in (disk, block):
        touching = cells[np.isin(cells, origin).any(axis=1)]
        edges = np.linalg.norm(x[np.roll(touching, 1, axis=1)] - x[touching], axis=2)
        assert 0.5 * h < edges.min() and edges.max() < 2 * h
    # Beyond the contact zone the boundaries are coarser.
    assert np.max(np.linalg.norm(x[block[:, 1]] - x[block[:, 0]], axis=1)) > 0.5 * p["h_far"]

    xl = group_nodes(groups, "load")
    assert np.all(xl[:, 1] == R) and xl[:, 0].min() == 0 and xl[:, 0].max() == R
    xs = group_nodes(groups, "symmetry")
    assert np.all(xs[:, 0] == 0) and xs[:, 1].min() == -p["height"] and xs[:, 1].max() == R
    assert np.sum(np.all(xs == 0, axis=1)) == 2  # the origin of each body
    assert_boundary_of(groups, "disk", "load")
    assert np.all(group_nodes(groups, "bottom")[:, 1] == -p["height"])


@pytest.mark.serial
@pytest.mark.parametrize(
    "n, top, bottom",
    [(4, (1.0, 1.0, 0.5), (1.0, 1.0, 0.5)), (3, (2.0, 1.0, 1.0), (2.0, 1.0, 0.5))],
)
def test_blocks3d(session, n, top, bottom):
    groups = meshes.blocks3d(n, top, bottom)
    assert groups == {
        "lower": (3, 1),
        "upper": (3, 2),
        "bottom": (2, 11),
        "top": (2, 12),
        "contact_lower": (2, 13),
        "contact_upper": (2, 14),
        "sides_upper": (2, 15),
        "sides_lower": (2, 16),
    }
    lx, ly, hb = bottom
    ht = top[2]
    nx, ny, nzb, nzt = (max(1, round(n * s)) for s in (lx, ly, hb, ht))
    row, x = nodes()
    assert x.shape[0] == (nx + 1) * (ny + 1) * (nzb + nzt + 2)
    lower, upper = (row[group_elements(groups, b)] for b in ("lower", "upper"))
    assert np.intersect1d(lower, upper).size == 0
    for cells, nz, z0, height in ((lower, nzb, 0, hb), (upper, nzt, hb, ht)):
        assert cells.shape[0] == 6 * nx * ny * nz
        vol = signed_measure(x, cells)
        assert np.all(vol > 0)
        assert vol.sum() == pytest.approx(lx * ly * height)
        assert x[cells, 2].min() == z0 and x[cells, 2].max() == z0 + height
        assert_conforming(cells)
    # Identical triangulations of the two contact faces, on separate nodes.
    faces = {}
    for name, body, z in [
        ("contact_lower", "lower", hb),
        ("contact_upper", "upper", hb),
        ("bottom", "lower", 0.0),
        ("top", "upper", hb + ht),
    ]:
        tri = row[group_elements(groups, name)]
        assert tri.shape[0] == 2 * nx * ny
        assert np.all(x[tri, 2] == z)
        assert_boundary_of(groups, body, name)
        faces[name] = {tuple(sorted(map(tuple, x[t]))) for t in tri}
    assert faces["contact_lower"] == faces["contact_upper"]
    assert_same_point_sets(
        group_nodes(groups, "contact_lower"), group_nodes(groups, "contact_upper")
    )
    for name, body, nz in (("sides_lower", "lower", nzb), ("sides_upper", "upper", nzt)):
        tri = row[group_elements(groups, name)]
        assert tri.shape[0] == 4 * (nx + ny) * nz
        planes = [x[tri, 0] == 0, x[tri, 0] == lx, x[tri, 1] == 0, x[tri, 1] == ly]
        assert np.all(np.any([p.all(axis=1) for p in planes], axis=0))
        assert_boundary_of(groups, body, name)


@pytest.mark.serial
def test_blocks3d_rejects_different_footprints(session):
    with pytest.raises(ValueError, match="footprint"):
        meshes.blocks3d(2, (0.5, 1.0, 0.5), (1.0, 1.0, 0.5))


@pytest.mark.serial
def test_rigid_sphere_cube(session):
    h = 0.05
    groups = meshes.rigid_sphere_cube(h)
    assert groups == {
        "cube": (3, 1),
        "bottom": (2, 11),
        "symmetry_x": (2, 12),
        "symmetry_y": (2, 13),
        "top": (2, 14),
    }
    row, x = nodes()
    cells = row[group_elements(groups, "cube")]
    assert np.abs(signed_measure(x, cells)).sum() == pytest.approx(1.0)
    assert_conforming(cells)
    for name, axis, value in [
        ("bottom", 2, -1.0),
        ("symmetry_x", 0, 0.0),
        ("symmetry_y", 1, 0.0),
        ("top", 2, 0.0),
    ]:
        assert np.allclose(group_nodes(groups, name)[:, axis], value, rtol=0, atol=1e-14)
        assert_boundary_of(groups, "cube", name)
    origin = np.flatnonzero(np.linalg.norm(x, axis=1) < 1e-14)
    touching = cells[np.isin(cells, origin).any(axis=1)]
    edges = np.linalg.norm(x[np.roll(touching, 1, axis=1)] - x[touching], axis=2)
    assert edges.max() < 2 * h
    assert np.linalg.norm(x[cells[:, 1]] - x[cells[:, 0]], axis=1).max() > 3 * h


#: The gmsh that wrote the committed meshes (Debian 12's, beside DOLFINx 0.5.2), and the meshes
#: built node by node (structured: byte for byte the same with any gmsh). The others are meshed
#: by gmsh's algorithms, which change between versions (gmsh 4.15 of the DOLFINx 0.11
#: environment moves a few nodes of the Hertz disk).
COMMITTED_BY_GMSH = "4.8"
STRUCTURED = {"blocks3d.msh", "membranes_16.msh", "membranes_8.msh"}
COMMITTED = ["blocks3d.msh", "disk_on_block.msh", "disk_on_block_17.msh", "hertz2d.msh",
             "membranes_16.msh", "membranes_8.msh", "rubber_quarter_disk.msh",
             "slab_with_inclusions.msh", "sphere_on_block.msh", "stacked_blocks2d.msh"]


@pytest.mark.serial
@pytest.mark.parametrize("name", COMMITTED)
def test_committed_meshes_are_up_to_date(name, written_meshes):
    """meshes/generate.py writes the same meshes as those committed in meshes/."""
    assert sorted(p.name for p in written_meshes.glob("*.msh")) == COMMITTED
    committed = MESH_DIR / name
    assert committed.stat().st_size < 1_000_000
    same = committed.read_bytes() == (written_meshes / name).read_bytes()
    if not same and name not in STRUCTURED \
            and not gmsh.__version__.startswith(COMMITTED_BY_GMSH + "."):
        pytest.skip(f"{name} was written by gmsh {COMMITTED_BY_GMSH} (with DOLFINx 0.5.2); "
                    f"gmsh {gmsh.__version__} (with DOLFINx {compat.DOLFINX_VERSION}) meshes "
                    "it differently")
    assert same, name


@pytest.fixture(scope="module")
def written_meshes(tmp_path_factory):
    out = tmp_path_factory.mktemp("meshes")
    subprocess.run([sys.executable, str(MESH_DIR / "generate.py"), "--out", str(out)],
                   check=True, capture_output=True)
    return out


def test_membranes_msh_in_dolfinx():
    """The committed membranes mesh reads into DOLFINx on all ranks with its tags."""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    # gmshio.read_from_msh of DOLFINx 0.5.2 is broken on the reading rank: use model_to_mesh.
    if comm.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(MESH_DIR / "membranes_8.msh"))
    try:
        mesh, cell_tags, facet_tags = compat.gmsh_model_to_mesh(gmsh.model, comm, 0, gdim=2)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    imap = mesh.topology.index_map(2)
    assert imap.size_global == 2 * 2 * 8 * 8
    assert mesh.geometry.index_map().size_global == 2 * 9 * 9
    local_cells = cell_tags.indices[cell_tags.indices < imap.size_local]
    values = cell_tags.values[cell_tags.indices < imap.size_local]
    assert comm.allreduce(local_cells.size) == 256
    assert comm.allreduce(np.count_nonzero(values == 1)) == 128
    assert set(np.concatenate(comm.allgather(facet_tags.values))) == {11, 12, 13}
