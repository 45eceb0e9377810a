"""Hostile input and faults (issue 7): a clear error naming the fault, before any solve, on
every rank, and nothing written; a rank that fails while assembling or factoring stops the
whole job (no hang). Extends tests/robustness/test_errors.py (which this file does not repeat).

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
MESHES = Path(__file__).resolve().parents[2] / "meshes"


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


@pytest.mark.parametrize("make, words", [
    (lambda: df.Sphere((0.5, -1.0), np.nan), ("Sphere.radius", "finite", "nan")),
    (lambda: df.Sphere((np.inf, -1.0), 1.0), ("Sphere.center", "finite", "inf")),
    (lambda: df.Plane((0.0, np.inf), (0.0, 1.0)), ("Plane.point", "finite", "inf"))],
    ids=["radius nan", "centre inf", "plane point inf"])
def test_non_finite_obstacle_data(make, words):
    with refused(*words):
        make()


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_non_finite_signed_distance(block):
    obstacle = df.SignedDistance(lambda x: (np.where(x[:, 0] > 0.5, np.nan, x[:, 1]),
                                            np.tile([0.0, 1.0], (x.shape[0], 1))))
    with refused("'block_bottom'", "not finite"):
        df.solve(sc.block_on_plane(block, obstacles=[df.RigidObstacle("block_bottom", obstacle)]))


def test_inf_dirichlet_value(block):
    with refused("Dirichlet('block_sides').value", "finite", "(inf, 0.0)"):
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
                 *(["in factorization on rank 1"] if COMM.size == 2 else []),
                 error=df.SolveError):
        df.solve(pushed(membranes, forms), factor=factor)


class Boom(sc.ConstElasticity):
    def __call__(self, V, sub):
        if sub.body == "right":
            raise RuntimeError("boom: no forms for the right body")
        return super().__call__(V, sub)


def test_assembly_fault_on_one_rank(membranes):
    """A forms callback that raises for one body: every rank raises a SolveError that
    carries its message (no rank waits forever)."""
    with refused("RuntimeError: boom: no forms for the right body", error=df.SolveError):
        df.solve(pushed(membranes, Boom(1.0, 0.3)))


@pytest.mark.parametrize("factor", factor_params("cholmod", "mumps", "petsc"))
def test_fewer_subdomains_than_ranks(block, factor):
    """One subdomain: under mpirun a rank holds no subdomain and factors an empty matrix."""
    sol = df.solve(sc.block_on_plane(block, load=(0.0, -0.1)), factor=factor, rtol=1e-10)
    assert sol.report.converged and sol.report.sizes["subdomains"] == 1
    ref = sc.block_reference(block, load=(0.0, -0.1))
    assert sc.rel_diff(sol.nodal_values(), ref) < 1e-8


# ------------------------------------------------------------------------------------------
# Issue 13: silent wrong answers, now refused or fixed
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("options, words", [
    ({"rtol": np.inf}, ("solver option rtol", "< 1", "got inf")),
    ({"rtol": 1.5}, ("solver option rtol", "< 1", "got 1.5")),
    ({"eq_rtol": np.nan}, ("solver option eq_rtol", "got nan")),
    ({"norm_rtol": 0.0}, ("solver option norm_rtol", "> 0")),
])
def test_a_tolerance_that_cannot_mean_convergence(block, options, words):
    """rtol = inf was accepted and reported as converged after 0 iterations (23 % error)."""
    with refused(*words):
        df.solve(sc.block_on_plane(block, load=(0.0, -0.1)), **options)


def test_a_tolerance_from_the_options_database(block):
    from petsc4py import PETSc

    PETSc.Options().setValue("feti_rtol", "inf")
    try:
        with refused("solver option rtol", "got inf"):
            df.solve(sc.block_on_plane(block, load=(0.0, -0.1)))
    finally:
        PETSc.Options().delValue("feti_rtol")


@pytest.mark.parametrize("tol", [np.nan, 0.0, -1e-4, 1.0, np.inf])
def test_nan_match_tol(tol):
    """match_tol = nan disabled the pairing check (nodes a quarter of a cell apart paired)."""
    with refused("NodeToNode('a', 'b').match_tol", "> 0 and < 1"):
        df.NodeToNode("a", "b", match_tol=tol)


@pytest.mark.parametrize("obstacle, words", [
    (lambda: df.Plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)), ("Plane.point", "3 coordinates", "2D")),
    (lambda: df.Plane((0.0, 0.0), (0.0, 1.0, 5.0)), ("Plane.normal", "3 coordinates", "2D")),
    (lambda: df.Sphere((0.5,), 1.0), ("Sphere.center", "1 coordinates", "2D")),
    (lambda: df.Cylinder((0, 0, 0), (0, 0, 1), 1.0), ("Cylinder", "3D only")),
], ids=["plane point 3D", "plane normal 3D", "sphere centre 1D", "cylinder in 2D"])
def test_coordinates_that_do_not_fit_the_mesh(block, obstacle, words):
    """Were broadcast or cut to the mesh's dimension instead of refused."""
    with refused(*words):
        sc.block_on_plane(block, obstacles=[df.RigidObstacle("block_bottom", obstacle())])


def shifted(mesh, body: str, dx: float) -> df.MeshData:
    x = mesh.x.copy()
    nodes = np.unique(mesh.cells[mesh.cell_body == mesh.body_index(body)])
    x[nodes, 0] += dx
    return df.MeshData(**{**mesh.__dict__, "x": x})


def test_bodies_that_overlap_in_space(membranes):
    """Two bodies with their own nodes, one pushed 0.3 (2.4 cells) into the other: solved as if
    apart before, although the docs said overlapping bodies are refused."""
    with refused("bodies overlap in space", "'left' and 'right'", "move them apart"):
        df.ContactProblem(shifted(membranes, "right", -0.3), sc.ConstElasticity(1.0, 0.3),
                          dirichlet=[df.Dirichlet("dirichlet")])
    # an initial penetration shallower than a third of a cell (h = 0.125) is accepted
    df.ContactProblem(shifted(membranes, "right", -0.03), sc.ConstElasticity(1.0, 0.3),
                      dirichlet=[df.Dirichlet("dirichlet")])


def test_a_body_inside_another():
    """A small square with its own nodes inside a large one (no shared node at all)."""
    x, cells = sc.grid_arrays(4, 4)
    xi, ci = sc.grid_arrays(2, 2, x0=1.3, y0=1.3, h=0.6)
    both = np.concatenate([cells, ci + x.shape[0]])
    with refused("bodies overlap in space", "'inner'", "'outer'"):
        read_arrays(np.concatenate([x, xi]), both,
                    bodies={"outer": np.arange(len(cells)),
                            "inner": len(cells) + np.arange(len(ci))})


def _write_msh(text: str, name: str = "m.msh") -> Path:
    path = Path.cwd() / name
    path.write_text(text)
    return path


def _msh22(nodes, elements) -> str:
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", "1",
             '2 1 "plate"', "$EndPhysicalNames", "$Nodes", str(len(nodes))]
    lines += [f"{t} {x} {y} 0" for t, x, y in nodes]
    lines += ["$EndNodes", "$Elements", str(len(elements))]
    lines += [f"{t} 2 2 1 1 {a} {b} {c}" for t, a, b, c in elements]
    lines += ["$EndElements", ""]
    return "\n".join(lines)


NODES = [(1, 0, 0), (2, 1, 0), (3, 1, 1), (4, 0, 1)]
ELEMENTS = [(1, 1, 2, 3), (2, 1, 3, 4)]


@pytest.mark.serial  # each rank would write the file in its own scratch folder
@pytest.mark.parametrize("nodes, elements, words", [
    (NODES + [(4, 0.2, 0.9)], ELEMENTS, ("malformed mesh data", "duplicate node 4")),
    (NODES, ELEMENTS + [(2, 2, 3, 4)], ("malformed mesh data", "3 elements", "2")),
], ids=["repeated node tag", "repeated element tag"])
def test_malformed_msh_data(nodes, elements, words):
    """gmsh keeps one of two nodes (with a warning) or elements (silently) of the same tag."""
    assert df.read_gmsh(_write_msh(_msh22(NODES, ELEMENTS))).cells.shape == (2, 3)
    bad = _write_msh(_msh22(nodes, elements), "bad.msh")
    with refused(*words):
        df.read_gmsh(bad)


@pytest.mark.serial
@pytest.mark.parametrize("name", ["model.geo", "model.msh"])
def test_a_gmsh_script_is_never_run(name):
    """A .geo script runs its System commands when gmsh opens it, even under --check."""
    marker = Path.cwd() / "ran"
    script = _write_msh(f'System "touch {marker}";\nPoint(1) = {{0, 0, 0}};\n', name)
    with refused("not a gmsh mesh file"):
        df.read_gmsh(script)
    assert not marker.exists()
    toml = Path.cwd() / "p.toml"
    toml.write_text(f'mesh = "{name}"\n[model]\ntype = "poisson"\n')
    assert main([str(toml), "--check", "-q"]) == 2
    assert not marker.exists()


def with_edge(mesh: df.MeshData, name: str, x0: float) -> df.MeshData:
    """The mesh with a new boundary group: the boundary edges on the line x = x0."""
    tri = mesh.cells
    edges = np.concatenate([tri[:, [1, 2]], tri[:, [0, 2]], tri[:, [0, 1]]])
    key, count = np.unique(np.sort(edges, axis=1), axis=0, return_counts=True)
    bnd = key[count == 1]
    group = bnd[np.all(np.isclose(mesh.x[bnd][..., 0], x0), axis=1)]
    return df.MeshData(**{**mesh.__dict__, "facet_groups": {**mesh.facet_groups, name: group}})


def _free_square_problem(decomposition):
    """membranes' left square alone (the right one unloaded, both free), pulled apart by equal
    and opposite tractions on x = 0 and x = 1: a self-equilibrated load."""
    mesh = with_edge(df.read_gmsh(MESHES / "membranes_8.msh"), "start", 0.0)
    return df.ContactProblem(mesh, sc.ConstElasticity(1.0, 0.3, tractions={
        "start": (-0.1, 0.0), "contact_left": (0.1, 0.0)}), decomposition=decomposition)


def _rigid_means(mesh, u, body):
    """The nodal means of u along the three rigid motions of a body (translations, rotation)."""
    nodes = np.unique(mesh.cells[mesh.cell_body == mesh.body_index(body)])
    xc = mesh.x[nodes] - mesh.x[nodes].mean(axis=0)
    v = u[nodes]
    return np.array([v[:, 0].mean(), v[:, 1].mean(), (xc[:, 0] * v[:, 1] - xc[:, 1] * v[:, 0])
                     .mean()])


def test_self_equilibrated_load_on_a_free_body():
    """Refused before as 'cannot be balanced (relative size 1.00e+00)': the test was relative
    to the load's rigid part, which is round-off here. Solved now, the same for any
    decomposition, orthogonal to the free motions."""
    sols = [df.solve(_free_square_problem(d), rtol=1e-10) for d in (df.ByTags(), df.Parts(3))]
    u = [s.nodal_values() for s in sols]
    mesh = sols[0].problem.mesh
    assert all(s.report.converged for s in sols)
    assert any("orthogonal to them" in w for w in sols[0].report.warnings)
    assert sc.rel_diff(u[1], u[0]) < 1e-8
    assert np.abs(_rigid_means(mesh, u[0], "left")).max() < 1e-10 * np.abs(u[0]).max()
    # the stretch: u_x(1) − u_x(0) = σ/E' L with plane strain E' = E/(1 − ν²), σ = 0.1
    left = np.unique(mesh.cells[mesh.cell_body == mesh.body_index("left")])
    ux, xl = u[0][left, 0], mesh.x[left, 0]
    stretch = ux[np.isclose(xl, 1.0)].mean() - ux[np.isclose(xl, 0.0)].mean()
    assert abs(stretch - 0.1 * (1 - 0.3**2)) < 1e-8


def test_the_free_sliding_motion_does_not_depend_on_the_decomposition(membranes):
    """The right square pressed on the clamped left one along x can slide along y (frictionless):
    u_y on it differed by 9 % of max |u| between ByTags and Parts(3) before."""
    mesh = with_edge(membranes, "end", 2.0)
    u = []
    for dec in (df.ByTags(), df.Parts(4), df.Parts(3)):
        sol = df.solve(df.ContactProblem(
            mesh, sc.ConstElasticity(1.0, 0.3, tractions={"end": (-0.1, 0.0)}),
            dirichlet=[df.Dirichlet("dirichlet")],
            contact=[df.NodeToNode("contact_right", "contact_left")], decomposition=dec),
            rtol=1e-10)
        assert sol.report.converged
        u.append(sol.nodal_values())
    assert max(sc.rel_diff(v, u[0]) for v in u[1:]) < 1e-8
    right = np.unique(mesh.cells[mesh.cell_body == mesh.body_index("right")])
    assert abs(u[0][right, 1].mean()) < 1e-10 * np.abs(u[0]).max()


# ------------------------------------------------------------------------------------------
# Issue 13: every argument checked by name, before heavy work
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("make, words", [
    (lambda: df.Elasticity("200", 0.3), ("Elasticity.E", "'200'")),
    (lambda: df.Elasticity(None, 0.3), ("Elasticity.E", "None")),
    (lambda: df.Elasticity(1.0, [0.3]), ("Elasticity.nu", "[0.3]")),
    (lambda: df.Elasticity(1.0, 0.3, tractions={"top": "down"}), ("Elasticity.tractions",)),
    (lambda: df.Poisson(k=True), ("Poisson.k", "True")),
    (lambda: df.Dirichlet("top", "x"), ("Dirichlet('top').value", "'x'")),
    (lambda: df.Dirichlet("top", components=(0, 0)), ("Dirichlet('top').components",
                                                       "distinct")),
    (lambda: df.Dirichlet("top", components=(-1,)), ("Dirichlet('top').components", ">= 0")),
    (lambda: df.Dirichlet(None), ("Dirichlet.group", "None")),
    (lambda: df.NodeToNode("a", "b", gap="0"), ("NodeToNode('a', 'b').gap", "'0'")),
    (lambda: df.NodeToNode("a", 7), ("NodeToNode.master", "7")),
    (lambda: df.Tresca(np.nan), ("Tresca.bound", "nan")),
    (lambda: df.Coulomb(0.3, max_steps=np.nan), ("Coulomb.max_steps", "nan")),
    (lambda: df.Coulomb(0.3, rtol=2.0), ("Coulomb.rtol", "< 1")),
    (lambda: df.Sphere((0, 0), "1"), ("Sphere.radius", "'1'")),
    (lambda: df.RigidObstacle("a", (0, 1)), ("RigidObstacle('a').obstacle", "(0, 1)")),
    (lambda: df.ByFunction(3), ("ByFunction.fn", "3")),
    (lambda: df.Parts(10**12), ("Parts.n", "<= 2147483647")),
], ids=lambda v: v[0] if isinstance(v, tuple) else None)
def test_bad_arguments_are_refused_by_name(make, words):
    with refused(*words):
        make()


@pytest.mark.parametrize("kwargs, words", [
    ({"value_size": 2.5}, ("ContactProblem.value_size", "2.5")),
    ({"dirichlet": df.Dirichlet("top")}, ("ContactProblem.dirichlet", "list of Dirichlet")),
    ({"contact": "block_bottom"}, ("ContactProblem.contact", "list")),
    ({"decomposition": df.Parts}, ("ContactProblem.decomposition",)),
    ({"forms": None}, ("ContactProblem.forms", "None")),
    ({"mesh": "block.msh"}, ("ContactProblem.mesh", "MeshData")),
])
def test_bad_problem_arguments(block, kwargs, words):
    args = {"mesh": block, "forms": sc.ConstElasticity(1.0, 0.3), **kwargs}
    with refused(*words):
        df.ContactProblem(**args)


@pytest.mark.parametrize("options, words", [
    ({"smalbe_rho": -1.0}, ("solver option smalbe_rho", "> 0", "-1.0")),
    ({"max_it": np.nan}, ("solver option max_it", "an integer", "nan")),
    ({"max_it": 2.5}, ("solver option max_it", "2.5")),
    ({"max_it": 10**12}, ("solver option max_it", "<= 1000000000")),
    ({"max_outer": 0}, ("solver option max_outer", ">= 1")),
    ({"verbose": 5}, ("solver option verbose", "<= 2")),
    ({"factor": 3}, ("solver option factor", "'cholmod'")),
    ({"smalbe_M": np.inf}, ("solver option smalbe_M", "inf")),
    ({"penalty_rho": "big"}, ("solver option penalty_rho", "'big'")),
])
def test_bad_solver_options_before_assembly(block, options, words):
    with refused(*words):
        df.solve(sc.block_on_plane(block, load=(0.0, -0.1)), **options)


def test_an_integral_float_is_an_integer():
    """Accepted rather than refused: max_it=1e4 is the integer it denotes."""
    opts = df.SolverOptions.create(max_it=1e4)
    assert opts.max_it == 10000 and isinstance(opts.max_it, int)


@pytest.mark.parametrize("E", [1e200, 1e-200])
def test_material_constants_that_overflow(membranes, E):
    """Blamed on 'a larger null space than the rigid-body modes' after assembly before."""
    with refused("Lamé constants", "'left'", "double precision", "units"):
        df.ContactProblem(membranes, df.Elasticity(E, 0.3), dirichlet=[df.Dirichlet("dirichlet")])


def test_contact_between_bodies_that_share_nodes():
    """Glued bodies (common nodes) were reported as 'both surfaces belong to body X'."""
    x, cells = sc.grid_arrays(4, 2)
    left = np.flatnonzero(x[cells].mean(axis=1)[:, 0] < 2.0)
    right = np.setdiff1d(np.arange(len(cells)), left)
    top = np.array([[i, i + 1] for i in range(10, 14)])  # y = 2, x from 0 to 4
    mesh = read_arrays(x, cells, bodies={"a": left, "b": right},
                       facets={"a_top": top[:2], "b_top": top[2:], "bottom": [[0, 1]]})
    with refused("share 1 nodes", "glued", "'a'", "'b'"):
        df.solve(df.ContactProblem(mesh, sc.ConstElasticity(1.0, 0.3),
                                   dirichlet=[df.Dirichlet("bottom")],
                                   contact=[df.NodeToNode("a_top", "b_top")]))


@pytest.mark.parametrize("value, words", [
    (lambda x: np.zeros(3), ("Dirichlet('top').value(x)", "shape")),
    (lambda x: np.zeros((x.shape[0], 3)), ("Dirichlet('top').value(x)", "shape")),
    (lambda x: 1 / 0, ("Dirichlet('top').value(x) raised ZeroDivisionError",)),
])
def test_dirichlet_functions_checked(block, value, words):
    with refused(*words):
        df.solve(df.ContactProblem(block, sc.ConstElasticity(1.0, 0.3),
                                   dirichlet=[df.Dirichlet("top", value)]))
