"""Hostile input and faults (issue 7): a clear error naming the fault, before any solve, on
every rank, and nothing written; a rank that fails while assembling or factoring stops the
whole job (no hang). Extends tests/test_errors.py (which this file does not repeat).

Meshes with faults are built as gmsh discrete models from arrays (``stress_cases.from_arrays``)
and read with ``read_gmsh``, the path a user's file takes.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

import gmsh
import numpy as np
import pytest
import stress_cases as sc
from mpi4py import MPI
from scratch import scratch_cwd_fixture
from stack import factor_params

import dolfinx_feti as df
from dolfinx_feti.cli import main

COMM = MPI.COMM_WORLD
MESHES = Path(__file__).resolve().parents[1] / "meshes"


scratch_cwd = scratch_cwd_fixture("feti-stress-input-")


@contextmanager
def refused(*words: str, error=df.InputError):
    """Expect ``error`` whose message has every one of ``words``; nothing written."""
    before = sorted(os.listdir(Path.cwd()))
    with pytest.raises(error) as info:
        yield info
    msg = str(info.value)
    missing = [w for w in words if w not in msg]
    assert not missing, f"message lacks {missing}: {msg}"
    assert sorted(os.listdir(Path.cwd())) == before, "files were written"


def read_arrays(x, cells, bodies=None, facets=None) -> df.MeshData:
    """read_gmsh of a discrete gmsh model holding exactly these cells (the checks included)."""
    bodies = {"plate": np.arange(len(cells))} if bodies is None else bodies
    return df.build_mesh(sc.from_arrays, np.asarray(x, dtype=float), np.asarray(cells),
                         bodies, facets or {})


def grid(nx=3, ny=3):
    x, cells = sc.grid_arrays(nx, ny)
    return x, cells


def node_at(x, p) -> int:
    return int(np.flatnonzero(np.all(np.isclose(x, p), axis=1))[0])


# ------------------------------------------------------------------------------------------
# Cells
# ------------------------------------------------------------------------------------------


def test_a_valid_grid_passes():
    x, cells = grid()
    mesh = read_arrays(x, cells)
    assert mesh.cells.shape == (18, 3)


def test_inverted_cell():
    """An interior node moved across the opposite edge of one of its triangles."""
    x, cells = grid()
    x[node_at(x, (1, 1))] = (2.3, 1.6)  # beyond the edge (2,1)-(2,2)
    with refused("inverted", "'plate'", "same side", "node"):
        read_arrays(x, cells)


def test_inverted_cell_at_the_boundary():
    """A boundary triangle whose free vertex crosses its boundary edge (one cell flips)."""
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    cells = np.array([[0, 1, 3], [0, 3, 2]])
    assert read_arrays(x, cells).num_nodes == 4
    x[1] = (1.2, 1.5)  # (0,1,3) turns clockwise: it folds over its neighbour (0,3,2)
    with refused("inverted", "'plate'"):
        read_arrays(x, cells)


@pytest.mark.parametrize("kind", ["flat", "repeated node"])
def test_degenerate_cell(kind):
    x = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    bad = [0, 1, 2] if kind == "flat" else [0, 1, 1]
    with refused("degenerate", "zero area", "'plate'", "[2.0, 0.0]" if kind == "flat" else ""):
        read_arrays(x, np.array([bad, [0, 1, 3]]))


def test_cells_overlapping_on_a_facet():
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0], [0.5, -1.0], [0.3, 2.0]])
    with refused("more than two cells", "overlap"):
        read_arrays(x, np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4]]))


def test_non_finite_coordinates():
    x, cells = grid()
    x[node_at(x, (1, 2))] = (np.nan, 2.0)
    with refused("non-finite", "NaN"):
        read_arrays(x, cells)


def test_empty_body_group():
    """A physical surface group with no cell (e.g. its surface was lost in a boolean)."""
    x, cells = grid()
    with refused("empty", "'ghost'", "'plate'"):
        read_arrays(x, cells, bodies={"plate": np.arange(len(cells)), "ghost": []})


def test_checks_of_a_hand_made_mesh_data():
    """MeshData built without read_gmsh is checked by ContactProblem."""
    x, cells = grid()
    mesh = df.MeshData(x=x, cells=cells, cell_type="triangle",
                       cell_body=np.zeros(len(cells), dtype=np.int32), body_names=("plate",),
                       facet_groups={"left": np.array([[0, 4], [4, 8]])},
                       node_tags=np.arange(1, x.shape[0] + 1))
    df.ContactProblem(mesh, df.Poisson(1.0), dirichlet=[df.Dirichlet("left")])
    x2 = x.copy()
    x2[node_at(x, (1, 1))] = (2.3, 1.6)
    bad = df.MeshData(**{**mesh.__dict__, "x": x2})
    with refused("inverted"):
        df.ContactProblem(bad, df.Poisson(1.0), dirichlet=[df.Dirichlet("left")])


def tets(x, cells) -> df.MeshData:
    x, cells = np.asarray(x, dtype=float), np.asarray(cells)
    return df.MeshData(x=x, cells=cells, cell_type="tetrahedron",
                       cell_body=np.zeros(len(cells), dtype=np.int32), body_names=("solid",),
                       facet_groups={}, node_tags=np.arange(1, len(x) + 1))


def test_inverted_and_flat_tetrahedra():
    from dolfinx_feti.mesh.checks import check_mesh

    x = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.3, 0.3, -1]]
    check_mesh(tets(x, [[0, 1, 2, 3], [0, 1, 2, 4]]))
    folded = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.3, 0.3, 0.5]]  # apex 4 moved up
    with refused("inverted", "'solid'"):
        check_mesh(tets(folded, [[0, 1, 2, 3], [0, 1, 2, 4]]))
    flat = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.3, 0.3, 0.0]]
    with refused("degenerate", "zero volume"):
        check_mesh(tets(flat, [[0, 1, 2, 3], [0, 1, 2, 4]]))


def test_unglued_blocks_in_one_body_3d():
    """The two stacked blocks of blocks3d put in one body: coincident nodes at z = 0.5."""
    mesh = df.read_gmsh(MESHES / "blocks3d.msh")
    one = df.MeshData(**{**mesh.__dict__, "cell_body": np.zeros_like(mesh.cell_body),
                         "body_names": ("both",)})
    with refused("not conforming", "'both'", "duplicate nodes"):
        df.ContactProblem(one, df.Elasticity(1.0, 0.3), dirichlet=[df.Dirichlet("bottom")])
    # two bodies in contact have their own nodes on the contact surfaces: accepted
    df.ContactProblem(mesh, df.Elasticity(1.0, 0.3), dirichlet=[df.Dirichlet("bottom")],
                      contact=[df.NodeToNode("contact_upper", "contact_lower")])


# ------------------------------------------------------------------------------------------
# Conformity: pieces of one body that should be glued
# ------------------------------------------------------------------------------------------


def plate_problem(mesh, **kwargs):
    return df.ContactProblem(mesh, sc.ConstElasticity(1.0, 0.3, tractions={"right": (0.1, 0.0)}),
                             dirichlet=[df.Dirichlet("left")], **kwargs)


def test_glued_squares_solve_as_one_plate():
    mesh = df.build_mesh(sc.two_squares_one_body, 4, True)
    sol = df.solve(plate_problem(mesh), rtol=1e-10)
    assert sol.report.converged and sol.report.sizes["subdomains"] == 1


def test_duplicate_nodes_on_an_interface_that_should_be_glued():
    """Two squares in one physical group, not fragmented: coincident nodes on x = 1."""
    mesh = df.build_mesh(sc.two_squares_one_body, 4, False)
    on_x1 = int(np.isclose(mesh.x[:, 0], 1.0).sum())  # each square has its own nodes there
    with refused("not conforming", "'plate'", f"{on_x1} boundary nodes", "coincides",
                 "fragment"):
        plate_problem(mesh)


def test_hanging_nodes_of_non_matching_pieces():
    """The same, meshed with 4 and 6 cells per unit: nodes of one side inside facets."""
    mesh = df.build_mesh(sc.two_squares_one_body, 4, False, 6)
    with refused("not conforming", "'plate'", "lies on the boundary facet"):
        plate_problem(mesh)


def test_squares_touching_at_a_corner_without_a_common_node():
    mesh = df.build_mesh(sc.corner_squares, 2, False)
    with refused("not conforming", "'body'", "[1.0, 1.0]"):
        df.ContactProblem(mesh, sc.ConstElasticity(1.0, 0.3), dirichlet=[df.Dirichlet("bottom_a")])


def test_contact_surface_inside_the_mesh():
    """A contact condition on the glued matrix/inclusion interface: no outward side."""
    mesh = df.build_mesh(sc.composite, 0.2, 1)
    with refused("contact surface 'interface'", "inside the mesh", "'inclusions'", "'matrix'"):
        df.ContactProblem(mesh, sc.ConstElasticity(1.0, 0.3), dirichlet=[df.Dirichlet("top")],
                          contact=[df.RigidObstacle("interface", df.Plane((0, 0), (0, 1)))])


def test_load_on_facets_inside_the_mesh():
    """A traction on the glued matrix/inclusion interface: ds there is not defined (the load
    would count only where a subdomain boundary passes: 0.99 with ByTags, 0.14 with a 2×2
    grid before this check)."""
    mesh = df.build_mesh(sc.composite, 0.2, 1)
    with refused("tractions on the group 'interface'", "inside the mesh", "decomposition"):
        df.ContactProblem(mesh, df.Elasticity(1.0, 0.3, tractions={"interface": (0.0, -1.0)}),
                          dirichlet=[df.Dirichlet("bottom")])


def test_user_ds_over_facets_inside_the_mesh():
    """The same through a forms callback's sub.ds: refused on every rank, before the QP."""
    mesh = df.build_mesh(sc.composite, 0.2, 1)
    inner = sc.ConstElasticity(1.0, 0.3, tractions={"interface": (0.0, -1.0)})

    def forms(V, sub):  # a plain callback: nothing to check up front
        return inner(V, sub)

    problem = df.ContactProblem(mesh, forms, value_size=2, dirichlet=[df.Dirichlet("bottom")],
                                decomposition=df.ByFunction(sc.grid_labels(0.5)))
    with refused("sub.ds", "'interface'", "inside the mesh", error=(df.InputError,
                                                                    df.SolveError)):
        df.solve(problem)


# ------------------------------------------------------------------------------------------
# Obstacles: wrong normals, non-finite data
# ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def block():
    return df.build_mesh(sc.rectangle, 1.0, 1.0, 4)


def test_body_inside_a_sphere_needs_a_cavity(block):
    """A Sphere is a solid ball: a body inside it faces away from it (refused); the cavity is
    a SignedDistance with φ = R − |x − c| (solved)."""
    c, R = np.array([0.5, 0.5]), 1.0
    with refused("'block_bottom'", "inconsistent normals"):
        df.solve(sc.block_on_plane(block, obstacles=[
            df.RigidObstacle("block_bottom", df.Sphere(tuple(c), R))]))

    def cavity(x):
        d = x - c
        r = np.linalg.norm(d, axis=1)
        return R - r, -d / r[:, None]

    sol = df.solve(sc.block_on_plane(block, load=(0.0, -0.1), obstacles=[
        df.RigidObstacle("block_bottom", df.SignedDistance(cavity))]), rtol=1e-10)
    assert sol.report.converged
    assert sol.contact.force.sum() > 0


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize("obstacle", [
    df.Sphere((0.5, -1.0), np.nan), df.Sphere((np.inf, -1.0), 1.0),
    df.Plane((0.0, np.inf), (0.0, 1.0)),
    df.SignedDistance(lambda x: (np.where(x[:, 0] > 0.5, np.nan, x[:, 1]),
                                 np.tile([0.0, 1.0], (x.shape[0], 1))))],
    ids=["radius nan", "centre inf", "plane point inf", "distance nan"])
def test_non_finite_obstacle(block, obstacle):
    with refused("'block_bottom'", "not finite"):
        df.solve(sc.block_on_plane(block, obstacles=[df.RigidObstacle("block_bottom", obstacle)]))


def test_inf_dirichlet_value(block):
    with refused("Dirichlet", "'block_sides'", "not finite"):
        df.solve(df.ContactProblem(block, sc.ConstElasticity(1.0, 0.3),
                                   dirichlet=[df.Dirichlet("block_sides", (np.inf, 0.0))]))


# ------------------------------------------------------------------------------------------
# The command: a broken mesh file is refused before anything is written
# ------------------------------------------------------------------------------------------


def test_command_refuses_an_inverted_mesh():
    folder = COMM.bcast(Path(tempfile.mkdtemp(prefix="feti-stress-cli-")) if COMM.rank == 0
                        else None, root=0)
    try:
        x, cells = grid()
        x[node_at(x, (1, 1))] = (2.3, 1.6)
        if COMM.rank == 0:
            gmsh.initialize()
            gmsh.option.setNumber("General.Terminal", 0)
            sc.from_arrays(x, cells, {"plate": np.arange(len(cells))},
                           {"left": np.array([[0, 4], [4, 8]])})
            gmsh.write(str(folder / "bad.msh"))
            gmsh.finalize()
            (folder / "bad.toml").write_text(
                'mesh = "bad.msh"\n[model]\ntype = "poisson"\nsource = 1.0\n'
                '[[dirichlet]]\ngroup = "left"\n[output]\ndirectory = "out"\n')
        COMM.barrier()
        assert main([str(folder / "bad.toml"), "-q"]) == 2
        assert sorted(p.name for p in folder.iterdir()) == ["bad.msh", "bad.toml"]
    finally:
        COMM.barrier()
        if COMM.rank == 0:
            shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------------------------------
# Faults in one rank's assembly or factorization (run with 2 ranks: each body on its own rank)
# ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def membranes():
    return df.read_gmsh(MESHES / "membranes_8.msh")


def pushed(mesh, forms):
    """B1's squares as plane-strain bodies: left clamped, right pushed onto it along x."""
    return df.ContactProblem(mesh, forms, dirichlet=[df.Dirichlet("dirichlet")],
                             contact=[df.NodeToNode("contact_right", "contact_left")])


@pytest.mark.parametrize("factor", factor_params("cholmod", "mumps", "petsc"))
def test_factorization_fault_on_one_rank(membranes, factor):
    """E = 0 in the right body (a forms callback that returns a zero matrix): its
    factorization fails; every rank raises, naming the subdomain and the body."""
    forms = sc.ConstElasticity(1.0, 0.3, zero_E=("right",))
    with refused("'right'", "material constant",
                 *(["raised on rank 1"] if COMM.size == 2 and COMM.rank == 0 else []),
                 error=df.SolveError):
        df.solve(pushed(membranes, forms), factor=factor)


class Boom(sc.ConstElasticity):
    def __call__(self, V, sub):
        if sub.body == "right":
            raise RuntimeError("boom: no forms for the right body")
        return super().__call__(V, sub)


def test_assembly_fault_on_one_rank(membranes):
    """A forms callback that raises for one body: the owner raises it, the others a
    SolveError that carries its message (no rank waits forever)."""
    owner = COMM.size == 1 or COMM.rank == 1
    error = RuntimeError if owner else df.SolveError
    with refused("boom: no forms for the right body", error=error):
        df.solve(pushed(membranes, Boom(1.0, 0.3)))


@pytest.mark.parametrize("factor", factor_params("cholmod", "mumps", "petsc"))
def test_fewer_subdomains_than_ranks(block, factor):
    """One subdomain: under mpirun a rank holds no subdomain and factors an empty matrix."""
    sol = df.solve(sc.block_on_plane(block, load=(0.0, -0.1)), factor=factor, rtol=1e-10)
    assert sol.report.converged and sol.report.sizes["subdomains"] == 1
    ref = sc.block_reference(block, load=(0.0, -0.1))
    assert sc.rel_diff(sol.nodal_values(), ref) < 1e-8
