"""The solver object: set up once, solve many.

A solve after ``FetiSolver.update`` equals a cold ``df.solve`` of the new problem (to solver
tolerance), for every method, for new tractions, Dirichlet values and obstacle positions (a
plane that moves keeps B; a circle that moves sideways changes its normals, so B); the update
rebuilds neither the factorizations nor the coarse problem; a warm start needs fewer
F-multiplications than a cold one; a change the set-up cannot reuse is refused by name.
"""

from __future__ import annotations

import gc

import numpy as np
import pytest
import reference as ref
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.feti.system import BlockSystem

RTOL = 1e-10
TOL = 1e-6
METHODS = ("tfeti", "feti1", "fetidp")
#: The set-up's phases an update must not repeat.
SETUP_ONLY = ("decomposition", "distribution", "factorization", "coarse problem",
              "preconditioner")


@pytest.fixture(scope="module")
def hertz_mesh(root):
    return df.read_gmsh(root / "meshes/hertz2d.msh")


@pytest.fixture(scope="module")
def blocks_mesh(root):
    return df.read_gmsh(root / "meshes/stacked_blocks2d.msh")


def hertz(mesh, load: float = 10.0, E: float = 200.0, parts=2, contact=None):
    """The 2D Hertz half model; ``contact`` replaces the node-to-node pair."""
    return df.ContactProblem(
        mesh, df.Elasticity(E, 0.3, tractions={"load": (0.0, -load / 2 / 8.0)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=contact or [df.NodeToNode(slave="disk_contact", master="block_contact")],
        decomposition=df.Parts(parts))


def pressed(mesh, shift: float, parts: int = 2):
    """Two tied blocks, the top pressed down by a prescribed displacement (Dirichlet only)."""
    return df.ContactProblem(
        mesh, df.Elasticity(100.0, 0.3),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sym0", components=[0]),
                   df.Dirichlet("top", value=(0.0, -shift))],
        ties=[df.Tie(slave="upper_bottom", master="lower_top")], decomposition=df.Parts(parts))


def on_obstacle(mesh, obstacle):
    """The disk of the Hertz mesh on a rigid obstacle (the block held in place)."""
    return hertz(mesh, contact=[df.RigidObstacle("disk_contact", obstacle)])


def assert_same(a: df.Solution, b: df.Solution, tol: float = TOL) -> None:
    assert ref.rel_max_diff(a.nodal_values(), b.nodal_values()) <= tol
    if b.contact.force.size:
        scale = np.abs(b.contact.force).max()
        assert np.abs(a.contact.force - b.contact.force).max() <= tol * max(scale, 1e-300)


def assert_no_setup(sol: df.Solution) -> None:
    assert not set(SETUP_ONLY) & set(sol.report.timings), sol.report.timings


@pytest.mark.parametrize("method", METHODS)
def test_new_traction_equals_cold_solve(hertz_mesh, method):
    solver = df.FetiSolver(hertz(hertz_mesh), rtol=RTOL, method=method)
    first = solver.solve()
    assert first.report.converged
    assert "factorization" in first.report.timings  # the set-up is the first solve's
    solver.update(hertz(hertz_mesh, load=11.0))
    warm = solver.solve()
    cold = df.solve(hertz(hertz_mesh, load=11.0), rtol=RTOL, method=method)
    assert warm.report.converged and cold.report.converged
    assert_same(warm, cold)
    assert_no_setup(warm)
    assert warm.report.hessian_mults < cold.report.hessian_mults
    # the load is linear in the data: 11/10 of the first contact force in total
    assert np.isclose(warm.total_contact_force[1], 1.1 * first.total_contact_force[1],
                      rtol=1e-3)


@pytest.mark.parametrize("method", ("tfeti", "fetidp"))
def test_secant_predictor_on_a_load_path(hertz_mesh, method):
    """From the third load case on, the start extrapolates the last two cases' multipliers.

    The step ω is measured on d (affine in the load here: f ∝ load, the gaps fixed), so loads
    10, 11, 13 give ω = 2 whatever the parameter of the path; the solution is a cold solve's.
    """
    solver = df.FetiSolver(hertz(hertz_mesh, load=10.0), rtol=RTOL, method=method)
    first = solver.solve()
    assert first.report.extra["warm_start_secant"] is None
    solver.update(hertz(hertz_mesh, load=11.0))
    second = solver.solve()
    assert second.report.extra["warm_start_secant"] is None  # one case before: scaled
    again = solver.solve()  # the same case again: the case before stays the load 10 one
    assert again.report.extra["warm_start_secant"] is None
    solver.update(hertz(hertz_mesh, load=13.0))
    third = solver.solve()
    assert third.report.extra["warm_start_secant"] == pytest.approx(2.0, rel=1e-8)
    assert_same(third, df.solve(hertz(hertz_mesh, load=13.0), rtol=RTOL, method=method))
    solver.update(hertz(hertz_mesh, load=13.0))  # the same load twice: a step of zero
    fourth = solver.solve()
    assert fourth.report.extra["warm_start_secant"] == pytest.approx(0.0, abs=1e-8)
    assert_same(fourth, third)
    solver.update(hertz(hertz_mesh, load=14.0))  # the last step was zero: no secant
    assert solver.solve().report.extra["warm_start_secant"] is None
    solver.destroy()


def test_cold_start_repeats_the_first_solve(hertz_mesh):
    solver = df.FetiSolver(hertz(hertz_mesh), rtol=RTOL)
    first = solver.solve()
    again = solver.solve(x0="cold")
    assert again.report.hessian_mults == first.report.hessian_mults
    assert np.array_equal(again.nodal_values(), first.nodal_values())
    warm = solver.solve()  # from the solution itself: nothing to do
    assert warm.report.hessian_mults < first.report.hessian_mults // 2
    assert_same(warm, first)
    from_sol = solver.solve(x0=first)  # λ only: SMALBE's multiplier starts from zero
    assert from_sol.report.hessian_mults < first.report.hessian_mults
    assert_same(from_sol, first)
    with pytest.raises(df.InputError, match="x0"):
        solver.solve(x0="hot")


@pytest.mark.parametrize("method", METHODS)
def test_new_dirichlet_values_equal_cold_solve(blocks_mesh, method):
    solver = df.FetiSolver(pressed(blocks_mesh, 0.01), rtol=RTOL, method=method)
    a = solver.solve()
    solver.update(pressed(blocks_mesh, 0.03))
    b = solver.solve()
    cold = df.solve(pressed(blocks_mesh, 0.03), rtol=RTOL, method=method)
    assert_same(b, cold)
    assert_no_setup(b)
    # linear in the prescribed displacement
    assert ref.rel_max_diff(b.nodal_values(), 3.0 * a.nodal_values()) <= TOL


@pytest.mark.parametrize("method", ("tfeti", "fetidp"))
def test_moving_plane_keeps_B(hertz_mesh, method):
    plane = df.Plane((0.0, 0.0), (0.0, 1.0))
    solver = df.FetiSolver(on_obstacle(hertz_mesh, plane), rtol=RTOL, method=method)
    solver.solve()
    moved = on_obstacle(hertz_mesh, df.Plane((0.0, 0.002), (0.0, 1.0)))
    solver.update(moved)
    b = solver.solve()
    assert_same(b, df.solve(on_obstacle(hertz_mesh, df.Plane((0.0, 0.002), (0.0, 1.0))),
                            rtol=RTOL, method=method))
    assert_no_setup(b)
    assert np.min(b.contact.gap) >= -1e-8  # no penetration of the moved plane


@pytest.mark.parametrize("method", METHODS)
def test_moving_circle_updates_rows(hertz_mesh, method, monkeypatch):
    def circle(dx, dy):
        return df.Sphere((dx, -40.0 + dy), 40.0)

    solver = df.FetiSolver(on_obstacle(hertz_mesh, circle(0.0, 0.0)), rtol=RTOL, method=method)
    solver.solve()
    kplus = [0]
    apply_kplus = BlockSystem.apply_kplus

    def counted(system, x, y):
        kplus[0] += 1
        apply_kplus(system, x, y)

    monkeypatch.setattr(BlockSystem, "apply_kplus", counted)
    solver.update(on_obstacle(hertz_mesh, circle(0.3, 0.001)))
    monkeypatch.undo()
    if method != "fetidp":  # (FETI-DP's K⁺ is its corner system's)
        # the load is the same: K⁺f is kept; K⁺ only in ‖PFP‖'s estimate and in b
        assert kplus[0] == solver.qp.proj.norm_mults + 1
    b = solver.solve()
    fresh = df.FetiSolver(on_obstacle(hertz_mesh, circle(0.3, 0.001)), rtol=RTOL, method=method)
    cold = fresh.solve()
    assert_same(b, cold)
    assert np.allclose(b.contact.normal, cold.contact.normal, atol=1e-14)
    assert "factorization" not in b.report.timings  # B changed, the subdomain factors did not
    # ‖P F P‖ from the last Ritz vector: the fresh set-up's estimate, in fewer F-multiplications
    assert solver.qp.norm_A == pytest.approx(fresh.qp.norm_A, rel=3e-4)
    assert solver.qp.proj.norm_mults <= fresh.qp.proj.norm_mults - (method != "fetidp")
    # another G̃: SMALBE's multiplier is the one the start implies, not the last one's
    assert b.report.extra["warm_start_multiplier"] == \
        ("estimate" if solver.qp.constraint.m else None)
    assert b.report.hessian_mults < cold.report.hessian_mults
    fresh.destroy()


def test_old_solution_survives_update(hertz_mesh):
    solver = df.FetiSolver(hertz(hertz_mesh), rtol=RTOL)
    a = solver.solve()
    energy, u = a.energy, a.nodal_values().copy()
    solver.update(hertz(hertz_mesh, load=20.0))
    solver.solve()
    assert a.energy == energy
    assert np.array_equal(a.nodal_values(), u)


def test_update_refuses_what_it_cannot_reuse(hertz_mesh, root):
    solver = df.FetiSolver(hertz(hertz_mesh), rtol=1e-6)
    with pytest.raises(df.InputError, match="differs in forms.*update_stiffness"):
        solver.update(hertz(hertz_mesh, E=300.0))
    with pytest.raises(df.InputError, match="differs in decomposition"):
        solver.update(hertz(hertz_mesh, parts=3))
    with pytest.raises(df.InputError, match="differs in mesh"):
        solver.update(hertz(df.read_gmsh(root / "meshes/hertz2d.msh")))
    with pytest.raises(df.InputError, match="differs in contact"):
        solver.update(on_obstacle(hertz_mesh, df.Plane((0.0, 0.0), (0.0, 1.0))))
    p = hertz(hertz_mesh)
    p.dirichlet = [df.Dirichlet("bottom")]
    with pytest.raises(df.InputError, match="differs in dirichlet"):
        solver.update(p)
    assert solver.solve().report.converged  # still usable


def test_update_stiffness_equals_cold_solve(hertz_mesh):
    solver = df.FetiSolver(hertz(hertz_mesh), rtol=RTOL)
    solver.solve()
    solver.update_stiffness(hertz(hertz_mesh, E=300.0))
    b = solver.solve()
    assert_same(b, df.solve(hertz(hertz_mesh, E=300.0), rtol=RTOL))


def test_plain_forms_need_the_stiffness_check(hertz_mesh):
    def forms_of(load):
        el = df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -load)})
        el.check(hertz_mesh)
        return lambda V, sub: el(V, sub)

    def problem(forms):
        return df.ContactProblem(
            hertz_mesh, forms, value_size=2,
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
            contact=[df.NodeToNode(slave="disk_contact", master="block_contact")],
            decomposition=df.Parts(2))

    solver = df.FetiSolver(problem(forms_of(0.6)), rtol=RTOL)
    solver.solve()
    with pytest.raises(df.InputError, match="forms"):
        solver.update(problem(forms_of(0.7)))
    solver.update(problem(forms_of(0.7)), check_stiffness=True)
    assert_same(solver.solve(), df.solve(problem(forms_of(0.7)), rtol=RTOL))


def test_several_load_cases_on_one_setup(hertz_mesh):
    solver = df.FetiSolver(hertz(hertz_mesh), rtol=RTOL, keep_meshes=False)
    for load in (5.0, 15.0, 10.0):
        solver.update(hertz(hertz_mesh, load=load))
        assert_same(solver.solve(), df.solve(hertz(hertz_mesh, load=load), rtol=RTOL))
    assert solver.solves == 3


def test_update_on_a_distributed_mesh(root):
    mesh = df.read_gmsh(root / "meshes/hertz2d.msh", distribute=True)
    whole = df.read_gmsh(root / "meshes/hertz2d.msh")
    plane = df.Plane((0.0, 0.001), (0.0, 1.0))
    solver = df.FetiSolver(on_obstacle(mesh, df.Plane((0.0, 0.0), (0.0, 1.0))), rtol=RTOL,
                           method="tfeti")
    solver.solve()
    problem = on_obstacle(mesh, plane)
    problem.dirichlet = [df.Dirichlet("bottom", value=(0.0, -0.001)),
                         df.Dirichlet("symmetry", components=[0])]
    solver.update(problem)
    b = solver.solve()
    cold = on_obstacle(whole, plane)
    cold.dirichlet = problem.dirichlet
    assert_same(b, df.solve(cold, rtol=RTOL, method="tfeti"))
    assert MPI.COMM_WORLD.allreduce(1) == MPI.COMM_WORLD.size


def test_byfunction_may_be_a_new_closure(hertz_mesh):
    def grid(h):
        return df.ByFunction(lambda m: np.floor(m[:, 0] / h).astype(np.int64))

    def problem(load, h):
        p = hertz(hertz_mesh, load=load)
        p.decomposition = grid(h)
        return p

    solver = df.FetiSolver(problem(10.0, 4.0), rtol=RTOL)
    solver.solve()
    solver.update(problem(11.0, 4.0))  # another closure, the same labels
    assert_same(solver.solve(), df.solve(problem(11.0, 4.0), rtol=RTOL))
    with pytest.raises(df.InputError, match="cuts a subdomain"):
        solver.update(problem(11.0, 1.0))


def _garbage(capfd) -> int:
    """Entries of PETSc's queue of collected, not yet destroyed objects, all ranks together."""
    from petsc4py import PETSc

    capfd.readouterr()
    PETSc.garbage_view(MPI.COMM_WORLD)  # rank 0 prints every rank's count
    out = capfd.readouterr().out
    total = sum(int(line.split("Total entries:")[1]) for line in out.splitlines()
                if "Total entries:" in line)
    return MPI.COMM_WORLD.bcast(total, root=0)


def test_solves_leave_no_petsc_garbage(hertz_mesh, capfd):
    """Since petsc4py 3.18 collected parallel objects wait in a queue until a collective
    cleanup: every solve and update empties it, so memory stays flat over many solves
    (without the cleanup, about 70 objects a cycle pile up here).

    Counted from what the earlier tests left: an object whose wrapper one rank's cyclic
    collector freed while the other rank's twin still waits in a cycle stays queued (the
    cleanup destroys only what every rank queued), so the queue is first emptied at a point
    where every rank has collected."""
    gc.collect()
    compat.garbage_cleanup(MPI.COMM_WORLD)
    before = _garbage(capfd)
    solver = df.FetiSolver(hertz(hertz_mesh), rtol=1e-6)
    queued = []
    for load in (10.0, 11.0, 12.0, 13.0):
        sol = solver.solve()
        del sol  # its vectors are queued, and freed at the next update
        solver.update(hertz(hertz_mesh, load=load))
        queued.append(_garbage(capfd))
    # what Python's cyclic collector frees late may wait a cycle; nothing accumulates
    bound = before + 10 * MPI.COMM_WORLD.size
    assert queued[-1] <= queued[0] + 2 and max(queued) <= bound, (before, queued)
    solver.destroy()
    kept = df.solve(hertz(hertz_mesh), rtol=1e-6)  # its set-up freed, its result kept
    assert _garbage(capfd) <= bound and kept.report.converged


def test_new_friction_values_beside_a_frictionless_condition(hertz_mesh):
    """A new Tresca bound on one pair while another condition has no friction."""

    def problem(bound):
        far = df.RigidObstacle("load", df.Plane((0.0, 100.0), (0.0, -1.0)))  # never touched
        return hertz(hertz_mesh, contact=[
            df.NodeToNode(slave="disk_contact", master="block_contact",
                          friction=df.Tresca(bound)), far])

    solver = df.FetiSolver(problem(0.5), rtol=RTOL)
    try:
        solver.solve()
        solver.update(problem(0.8))
        assert_same(solver.solve(), df.solve(problem(0.8), rtol=RTOL))
    finally:
        solver.destroy()
