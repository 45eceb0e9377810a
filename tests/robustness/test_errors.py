"""Bad input: a clear InputError that names the fault, on every rank.

Never a hang, a NaN reported as converged, or a bare PETSc/NumPy/UFL traceback. Every test
runs in an empty scratch directory of its own, and the error checks also assert that nothing
was written there. A watchdog dumps the stacks and ends the process if a test hangs.
"""

from __future__ import annotations

import dataclasses
import math
import os
from contextlib import contextmanager
from pathlib import Path

import gmsh
import numpy as np
import pytest
import ufl
from mpi4py import MPI
from scratch import scratch_cwd_fixture

import dolfinx_feti as df

MESHES = Path(__file__).resolve().parents[2] / "meshes"

# ------------------------------------------------------------------------------------------
# Helpers
# ------------------------------------------------------------------------------------------


scratch_cwd = scratch_cwd_fixture("feti-errors-")


@contextmanager
def input_error(*words: str):
    """Expect an InputError whose message contains every one of ``words``; nothing written."""
    cwd = Path.cwd()
    before = sorted(os.listdir(cwd))
    with pytest.raises(df.InputError) as info:
        yield info
    msg = str(info.value)
    missing = [w for w in words if w not in msg]
    assert not missing, f"message lacks {missing}: {msg}"
    assert sorted(os.listdir(cwd)) == before, "files were written"


def quoted(*names: str) -> tuple[str, ...]:
    return tuple(repr(n) for n in names)


B1_GROUPS = quoted("contact_left", "contact_right", "dirichlet")


@pytest.fixture(scope="module")
def membranes() -> df.MeshData:
    return df.read_gmsh(MESHES / "membranes_8.msh")


def b1_source(right: float = -1.0):
    """f of benchmark B1, with f = ``right`` on (1,2)×[0,0.25) (B1 has right = −1)."""

    def f(x):
        return ufl.conditional(ufl.lt(x[0], 1.0),
                               ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0),
                               ufl.conditional(ufl.lt(x[1], 0.25), right, 0.0))

    return f


def b1(mesh, *, source=None, dirichlet=None, contact=None, **kwargs) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.Poisson(source=b1_source() if source is None else source),
        dirichlet=[df.Dirichlet("dirichlet")] if dirichlet is None else dirichlet,
        contact=[df.NodeToNode("contact_left", "contact_right")] if contact is None else contact,
        **kwargs)


def elastic(mesh, *, contact=None, dirichlet=None, **material) -> df.ContactProblem:
    """The B1 geometry as a plane-strain body pair: left clamped, right pressed on it."""
    args = {"E": 1.0, "nu": 0.3, **material}
    return df.ContactProblem(
        mesh, df.Elasticity(**args),
        dirichlet=[df.Dirichlet("dirichlet")] if dirichlet is None else dirichlet,
        contact=[df.NodeToNode("contact_right", "contact_left")] if contact is None else contact)


def boundary_facets(mesh: df.MeshData, where) -> np.ndarray:
    """Boundary facets (node pairs) whose nodes all satisfy ``where(x) -> bool``."""
    tri = mesh.cells
    edges = np.concatenate([tri[:, [1, 2]], tri[:, [0, 2]], tri[:, [0, 1]]])
    key, count = np.unique(np.sort(edges, axis=1), axis=0, return_counts=True)
    bnd = key[count == 1]
    return bnd[np.all(where(mesh.x[bnd]), axis=1)]


def with_group(mesh: df.MeshData, name: str, facets: np.ndarray) -> df.MeshData:
    return dataclasses.replace(mesh, facet_groups={**mesh.facet_groups, name: facets})


@contextmanager
def gmsh_model(name: str):
    """A new model in the gmsh session (built on rank 0 by the caller); options restored."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    saved = {k: gmsh.option.getNumber(k) for k in ("Mesh.RecombineAll", "Mesh.MeshSizeMax")}
    gmsh.model.add(name)
    try:
        yield MPI.COMM_WORLD.rank == 0
    finally:
        gmsh.model.remove()
        for k, v in saved.items():
            gmsh.option.setNumber(k, v)


def square_model(*, groups: bool = True, quads: bool = False, empty_group: bool = False,
                 order: int = 1, incomplete: bool = False):
    """A meshed unit square on rank 0: body "plate", boundary group "edge" (x = 0)."""
    s = gmsh.model.occ.addRectangle(0.0, 0.0, 0.0, 1.0, 1.0)
    gmsh.model.occ.synchronize()
    if groups:
        gmsh.model.addPhysicalGroup(2, [s], 1)
        gmsh.model.setPhysicalName(2, 1, "plate")
        left = [c for _, c in gmsh.model.getEntitiesInBoundingBox(-0.1, -0.1, -0.1, 0.1, 1.1,
                                                                    0.1, 1)]
        gmsh.model.addPhysicalGroup(1, left, 11)
        gmsh.model.setPhysicalName(1, 11, "edge")
    if empty_group:
        c = gmsh.model.addDiscreteEntity(1)  # a curve with no mesh element
        gmsh.model.addPhysicalGroup(1, [c], 12)
        gmsh.model.setPhysicalName(1, 12, "nothing")
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
    gmsh.option.setNumber("Mesh.RecombineAll", 1 if quads else 0)
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 1 if incomplete else 0)
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.setOrder(order)


def assert_honest_failure(sol: df.Solution) -> None:
    """A returned solve that did not converge says so, with finite numbers and a warning."""
    rep = sol.report
    assert rep.converged is False
    assert rep.reason and rep.reason != "converged"
    assert rep.warnings
    assert "NOT CONVERGED" in rep.summary()
    assert all(math.isfinite(v) for v in (rep.gP_rel, rep.G_lambda, rep.norm_F))
    assert all(math.isfinite(v) for v in rep.kkt.values())


# ------------------------------------------------------------------------------------------
# Mesh input
# ------------------------------------------------------------------------------------------


def test_missing_file():
    with input_error("not found", "no_such_mesh.msh"):
        df.read_gmsh("no_such_mesh.msh")


@pytest.fixture
def gmsh_reset():
    """Restart this process's gmsh session after the test (a failed gmsh.open leaves gmsh 4.8
    locked: every later gmsh.open or mesh generation only says "I'm busy")."""
    yield
    try:  # a rank that never used gmsh in this process has nothing to finalize (gmsh ≥ 4.9)
        gmsh.finalize()
    except Exception:
        pass
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)


def _garbage_file() -> str:
    """A file that is no mesh, on rank 0 (the only rank that reads)."""
    bad = Path.cwd() / "garbage.msh"
    if MPI.COMM_WORLD.rank == 0:
        bad.write_text("this is no mesh\n")
    return str(bad)


def test_unreadable_file(gmsh_reset):
    bad = _garbage_file()
    with pytest.raises(df.InputError, match="garbage.msh: not a gmsh mesh file"):
        df.read_gmsh(bad)
    assert os.listdir(Path.cwd()) == (["garbage.msh"] if MPI.COMM_WORLD.rank == 0 else [])


def test_read_after_an_unreadable_file(gmsh_reset):
    with pytest.raises(df.InputError):
        df.read_gmsh(_garbage_file())
    mesh = df.read_gmsh(MESHES / "membranes_8.msh")
    assert mesh.body_names == ("left", "right")


def test_no_physical_groups():
    with gmsh_model("no-groups") as root:
        if root:
            square_model(groups=False)
        with input_error("no physical groups"):
            df.read_gmsh(None)


def test_quadrilateral_cells_are_read_serendipity_refused():
    with gmsh_model("quads") as root:
        if root:
            square_model(quads=True)
        mesh = df.read_gmsh(None)
    assert mesh.cell_type == "quadrilateral" and mesh.tdim == 2
    with gmsh_model("quads2") as root:
        if root:
            square_model(quads=True, order=2)
        mesh = df.read_gmsh(None)
    assert mesh.cell_type == "quadrilateral" and mesh.geometry_degree == 2
    with gmsh_model("quads8") as root:
        if root:
            square_model(quads=True, order=2, incomplete=True)
        with input_error("'plate'", "8-node (serendipity) quadrangle", "order 1 or 2"):
            df.read_gmsh(None)


def test_empty_physical_group():
    with gmsh_model("empty-group") as root:
        if root:
            square_model(empty_group=True)
        mesh = df.read_gmsh(None)
    assert mesh.facet_groups["nothing"].shape[0] == 0
    with input_error("'nothing'", "empty"):
        df.ContactProblem(mesh, df.Poisson(1.0), dirichlet=[df.Dirichlet("nothing")])
    with input_error("'nothing'", "empty"):
        df.ContactProblem(mesh, df.Elasticity(1.0, 0.3), dirichlet=[df.Dirichlet("edge")],
                          contact=[df.RigidObstacle("nothing", df.Plane((0, 2), (0, -1)))])


# ------------------------------------------------------------------------------------------
# Names of groups and bodies
# ------------------------------------------------------------------------------------------


def test_misspelled_dirichlet_tag(membranes):
    with input_error("'dirichlett'", *B1_GROUPS):
        b1(membranes, dirichlet=[df.Dirichlet("dirichlett")])


@pytest.mark.parametrize("slave, master, bad", [("contact_lft", "contact_right", "contact_lft"),
                                                ("contact_left", "Contact_right",
                                                 "Contact_right")])
def test_misspelled_contact_tag(membranes, slave, master, bad):
    with input_error(repr(bad), *B1_GROUPS):
        b1(membranes, contact=[df.NodeToNode(slave, master)])


def test_misspelled_traction_and_flux_tags(membranes):
    with input_error("'contact_rigth'", *B1_GROUPS):
        df.ContactProblem(membranes, df.Elasticity(1.0, 0.3,
                                                   tractions={"contact_rigth": (0.0, -1.0)}),
                          dirichlet=[df.Dirichlet("dirichlet")])
    with input_error("'dirichle'", *B1_GROUPS):
        df.ContactProblem(membranes, df.Poisson(1.0, flux={"dirichle": 1.0}),
                          dirichlet=[df.Dirichlet("dirichlet")])


def test_misspelled_obstacle_tag(membranes):
    with input_error("'contact'", *B1_GROUPS):
        elastic(membranes, contact=[df.RigidObstacle("contact", df.Plane((3, 0), (-1, 0)))])


def test_body_name_as_boundary_group(membranes):
    with input_error("'left'", *B1_GROUPS):
        b1(membranes, dirichlet=[df.Dirichlet("left")])


def test_unknown_body_in_material_map(membranes):
    with input_error("'middle'", "'left'", "'right'"):
        elastic(membranes, E={"left": 1.0, "right": 1.0, "middle": 2.0})
    with input_error("'right'"):
        elastic(membranes, E={"left": 1.0})


# ------------------------------------------------------------------------------------------
# Contact pairs
# ------------------------------------------------------------------------------------------


def test_contact_pair_with_itself(membranes):
    with input_error("'contact_left'", "itself"):
        b1(membranes, contact=[df.NodeToNode("contact_left", "contact_left")])


def test_contact_surfaces_of_one_body(membranes):
    with input_error("'contact_left'", "'dirichlet'", "'left'", "two bodies"):
        df.solve(b1(membranes, contact=[df.NodeToNode("contact_left", "dirichlet")]))


def test_contact_surfaces_without_matching_nodes(membranes):
    x = membranes.x.copy()
    right = np.unique(membranes.cells[membranes.cell_body == membranes.body_index("right")])
    x[right, 1] += 0.5 / 8  # half a cell along the contact line
    shifted = dataclasses.replace(membranes, x=x)
    with input_error("'contact_left'", "'contact_right'", "no matching master node"):
        df.solve(b1(shifted))


def test_node_to_node_surfaces_facing_the_same_way(membranes):
    # "right_end" (x = 2) faces +x like "contact_left" (x = 1): they cannot touch
    mesh = with_group(membranes, "right_end",
                      boundary_facets(membranes, lambda p: np.isclose(p[..., 0], 2.0)))
    with input_error("'contact_left'", "'right_end'", "inconsistent normals"):
        df.solve(elastic(mesh, contact=[df.NodeToNode("contact_left", "right_end")]))


def test_obstacle_normal_pointing_the_wrong_way(membranes):
    # the obstacle {x <= -0.1} has outward normal +x; −x is the body's own outward side
    wrong = df.Plane(point=(-0.1, 0.0), normal=(-1.0, 0.0))
    with input_error("'dirichlet'", "inconsistent normals"):
        df.solve(elastic(membranes, dirichlet=[df.Dirichlet("contact_left")],
                         contact=[df.RigidObstacle("dirichlet", wrong)]))


def test_obstacle_with_a_degenerate_normal(membranes):
    with input_error("Plane.normal", "not all zero", "(0, 0)"):
        df.solve(elastic(membranes, dirichlet=[df.Dirichlet("contact_left")],
                         contact=[df.RigidObstacle("dirichlet", df.Plane((-1, 0), (0, 0)))]))


def test_obstacle_on_a_scalar_problem(membranes):
    with input_error("vector"):
        b1(membranes, contact=[df.RigidObstacle("contact_right", df.Plane((3, 0), (-1, 0)))])


# ------------------------------------------------------------------------------------------
# Material and data values
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("E, nu, words", [
    (1.0, 0.5, ("Poisson's ratio", "'left'", "nu = 0.5", "incompressible")),
    (1.0, 0.7, ("Poisson's ratio", "'left'", "nu = 0.7")),
    (1.0, -1.0, ("Poisson's ratio", "nu = -1.0")),
    (1.0, math.nan, ("Poisson's ratio", "nu = nan")),
    (0.0, 0.3, ("Young's modulus", "'left'", "E = 0.0")),
    (-1.0, 0.3, ("Young's modulus", "E = -1.0")),
    (math.nan, 0.3, ("Young's modulus", "E = nan")),
    (math.inf, 0.3, ("Young's modulus", "E = inf")),
    ({"left": 1.0, "right": -2.0}, 0.3, ("Young's modulus", "'right'", "E = -2.0")),
])
def test_bad_material(membranes, E, nu, words):
    with input_error(*words):
        elastic(membranes, E=E, nu=nu)


def test_bad_conductivity(membranes):
    with input_error("conductivity", "'right'"):
        df.ContactProblem(membranes, df.Poisson(1.0, k={"left": 1.0, "right": 0.0}),
                          dirichlet=[df.Dirichlet("dirichlet")])


def test_nan_traction_body_force_flux_source(membranes):
    with input_error("Elasticity.tractions", "'contact_right': (0.0, nan)"):
        df.ContactProblem(membranes, df.Elasticity(1.0, 0.3,
                                                   tractions={"contact_right": (0.0, math.nan)}),
                          dirichlet=[df.Dirichlet("dirichlet")])
    with input_error("Elasticity.body_force", "(inf, 0.0)"):
        df.ContactProblem(membranes, df.Elasticity(1.0, 0.3, body_force=(math.inf, 0.0)),
                          dirichlet=[df.Dirichlet("dirichlet")])
    with input_error("flux", "'contact_right'", "not finite"):
        df.ContactProblem(membranes, df.Poisson(0.0, flux={"contact_right": math.nan}),
                          dirichlet=[df.Dirichlet("dirichlet")])
    with input_error("source", "not finite"):
        b1(membranes, source=math.nan)


@pytest.mark.parametrize("value", [math.nan, lambda x: np.where(x[:, 1] > 0.5, np.nan, 0.0)],
                         ids=["number", "function"])
def test_nan_dirichlet_value(membranes, value):
    with input_error("Dirichlet", "'dirichlet'", "finite"):
        df.solve(b1(membranes, dirichlet=[df.Dirichlet("dirichlet", value=value)]))


@pytest.mark.parametrize("gap", [math.nan, math.inf])
def test_non_finite_gap(membranes, gap):
    with input_error("NodeToNode('contact_left', 'contact_right').gap", "finite",
                     repr(gap)):
        b1(membranes, contact=[df.NodeToNode("contact_left", "contact_right", gap=gap)])


def test_dirichlet_component_out_of_range(membranes):
    with input_error("'dirichlet'", "components", "[2]"):
        elastic(membranes, dirichlet=[df.Dirichlet("dirichlet", components=(2,))])


def test_dirichlet_value_with_wrong_length(membranes):
    with input_error("'dirichlet'", "3 numbers", "2 constrained component"):
        df.solve(elastic(membranes, dirichlet=[df.Dirichlet("dirichlet", value=(1.0, 2.0, 3.0))]))


@pytest.mark.parametrize("kind", ["traction", "body_force"])
def test_load_vector_with_wrong_length(membranes, kind):
    load = (0.0, -1.0, 0.0)
    material = ({"tractions": {"contact_right": load}} if kind == "traction"
                else {"body_force": load})
    with input_error("'contact_right'" if kind == "traction" else "body force", "2"):
        df.solve(elastic(membranes, **material))


# Serial: under mpirun the ranks compile the same (failing) form, and the rank that does not hold
# the FFCx cache lock waits for its 10 s timeout.
@pytest.mark.serial
def test_nan_inside_a_ufl_source(membranes):
    with input_error("not finite"):
        df.solve(b1(membranes, source=lambda x: math.nan * x[0]))


# ------------------------------------------------------------------------------------------
# Solver options and decomposition
# ------------------------------------------------------------------------------------------


def test_unknown_solver_option(membranes):
    with input_error("'rtool'", "'rtol'"):
        df.solve(b1(membranes), rtool=1e-8)


@pytest.mark.parametrize("rtol", [0.0, -1e-6, math.nan])
def test_non_positive_rtol(membranes, rtol):
    with input_error("rtol"):
        df.solve(b1(membranes), rtol=rtol)


def test_unknown_decomposition(membranes):
    with input_error("ContactProblem.decomposition", "'grid'"):
        df.solve(b1(membranes, decomposition="grid"))


@pytest.mark.parametrize("args, words", [
    ((0,), ("Parts.n", ">= 1", "got 0")),
    ((-3,), ("Parts.n", ">= 1", "got -3")),
    (({"left": 2, "right": 0},), ("Parts.n", "'right': 0")),
    (({"lft": 2},), ("Parts", "'lft'", "'left'")),
    ((2, "metis"), ("Parts.method", "'metis'")),
    ((10**12,), ("Parts.n", "<= 2147483647")),
    ((1000,), ("Parts", "1000 parts", "'left'", "128 cells")),
])
def test_bad_parts(membranes, args, words):
    with input_error(*words):
        df.solve(b1(membranes, decomposition=df.Parts(*args)))


@pytest.mark.parametrize("n", [2.5, math.nan, "2", None, True])
def test_non_integer_parts(membranes, n):
    with input_error("Parts.n", "an integer"):
        df.solve(b1(membranes, decomposition=df.Parts(n)))


def test_unknown_contact_condition(membranes):
    with input_error("unknown contact condition", "Dirichlet"):
        b1(membranes, contact=[df.Dirichlet("contact_left")])


def test_bad_gluing_and_value_size(membranes):
    with input_error("gluing", "'full'"):
        b1(membranes, gluing="full")
    with input_error("value_size"):
        df.ContactProblem(membranes, lambda V, sub: None)
    with input_error("value_size", "3"):
        df.ContactProblem(membranes, lambda V, sub: None, value_size=3)


# ------------------------------------------------------------------------------------------
# Ill-posed problems
# ------------------------------------------------------------------------------------------


def test_floating_body_without_contact(membranes):
    """B1 without the contact: Ω2 floats with net load −0.25."""
    with input_error("cannot be balanced", "'right'"):
        df.solve(b1(membranes, contact=[]))


def test_floating_body_pulled_off_the_contact(membranes):
    """B1 with +1 on Ω2: the load pulls Ω2 away from Ω1; u_1 <= u_2 cannot hold it.

    The QP is unbounded (e is in Im G but needs a negative contact force). The solver must not
    report convergence: an InputError or a returned, honestly failed solve.
    """
    try:
        sol = df.solve(b1(membranes, source=b1_source(right=+1.0)), rtol=1e-8)
    except df.InputError as e:
        assert "'right'" in str(e)
        return
    assert_honest_failure(sol)


def test_tangential_load_on_frictionless_contact(membranes):
    """Ω2 pressed on nothing, loaded along the contact line only: it slides away."""

    def down_on_right(x):
        return ufl.as_vector([0.0, ufl.conditional(ufl.gt(x[0], 1.0), -1.0, 0.0)])

    with input_error("cannot be balanced", "'right'"):
        df.solve(elastic(membranes, body_force=down_on_right))


def test_tangential_traction_on_the_contact_surface(membranes):
    with input_error("cannot be balanced", "'right'"):
        df.solve(elastic(membranes, tractions={"contact_right": (0.0, -1.0)}))


def test_unloaded_floating_body_is_only_a_warning(membranes):
    """No load on a floating body: solvable, with a warning about the free rigid motion."""
    sol = df.solve(b1(membranes, source=lambda x: ufl.conditional(ufl.lt(x[0], 1.0), -1.0, 0.0),
                      contact=[]), rtol=1e-10)
    assert sol.report.converged
    assert any("'right'" in w and "not fixed" in w for w in sol.report.warnings)


def test_zero_source_with_prescribed_values(membranes):
    """Only Dirichlet data drives the problem: not an error."""
    sol = df.solve(b1(membranes, source=0.0, contact=[],
                      dirichlet=[df.Dirichlet("dirichlet", 1.0)]
                      ), rtol=1e-10)
    assert sol.report.converged


def test_non_converging_solve_returns(membranes):
    sol = df.solve(b1(membranes), max_it=3)
    assert_honest_failure(sol)
    assert sol.report.reason == "max_it"
    assert sol.report.iterations <= 3
    assert any("did not converge" in w for w in sol.report.warnings)
    assert np.all(np.isfinite(sol.nodal_values()))
    assert os.listdir(Path.cwd()) == []


# ------------------------------------------------------------------------------------------
# Reports that must not mislead
# ------------------------------------------------------------------------------------------


def test_push_on_an_unloaded_floating_body_does_not_penetrate(membranes):
    """Ω1 pushed by 0.1 into the unloaded, free Ω2: Ω2 must move along (not unique, solvable)."""
    sol = df.solve(elastic(membranes, dirichlet=[df.Dirichlet("dirichlet", (0.1, 0.0))]),
                   rtol=1e-10)
    rep = sol.report
    if not rep.converged:
        assert_honest_failure(sol)
        return
    assert rep.max_penetration <= 1e-6
    assert rep.kkt["primal_feasibility"] <= 1e-6
    assert sol.contact.gap.min() >= -1e-6


def test_equilibrium_residual_of_an_exact_rigid_translation(membranes):
    prob = elastic(membranes, contact=[], dirichlet=[df.Dirichlet("dirichlet", (0.1, 0.0)),
                                                     df.Dirichlet("contact_right")])
    sol = df.solve(prob, rtol=1e-10)
    assert sol.report.converged
    u = sol.nodal_values()
    left = membranes.x[:, 0] < 1.0 - 1e-9
    np.testing.assert_allclose(u[left], np.tile([0.1, 0.0], (left.sum(), 1)), atol=1e-12)
    np.testing.assert_allclose(u[~left & (membranes.x[:, 0] > 1.0 + 1e-9)], 0.0, atol=1e-12)
    assert sol.report.kkt["equilibrium"] < 1e-6
