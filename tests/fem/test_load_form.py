"""A new load case of the same shape reuses the subdomains' compiled linear forms.

The load vector assembled from the kept form with new constants equals the one of a fresh
set-up of the new problem to round-off; a load given as a function of x is kept by its
structure (its numbers are constants); one of another shape is built again; Poisson's fluxes
and zero source go the same way.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx_feti as df


@pytest.fixture(scope="module")
def hertz_mesh(root):
    return df.read_gmsh(root / "meshes/hertz2d.msh")


def _problem(mesh, forms) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, forms, dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry",
                                                                     components=[0])],
        contact=[df.NodeToNode(slave="disk_contact", master="block_contact")],
        decomposition=df.Parts(3))


def _elastic(load: float, gravity: float, factor: float = 1.0, **kw) -> df.Elasticity:
    return df.Elasticity(200.0, 0.3, tractions={"load": (0.1 * load, -load)},
                         body_force=kw.get("body_force", (0.0, -gravity)), load_factor=factor)


def _kept(solver: df.FetiSolver) -> list:
    return [sub._kept_load for sub in solver._data.assemblers]


def _assert_load_of_fresh_setup(solver: df.FetiSolver, problem: df.ContactProblem) -> None:
    fresh = df.FetiSolver(problem)
    try:
        comm = MPI.COMM_WORLD  # a rank's subdomains may carry no load
        scale = comm.allreduce(np.max(np.abs(fresh._data.f), initial=0.0), op=MPI.MAX)
        diff = comm.allreduce(np.max(np.abs(solver._data.f - fresh._data.f), initial=0.0),
                              op=MPI.MAX)
        assert scale > 0
        assert diff <= 1e-13 * scale
    finally:
        fresh.destroy()


def test_new_values_reuse_the_compiled_form(hertz_mesh):
    solver = df.FetiSolver(_problem(hertz_mesh, _elastic(1.0, 0.5)))
    try:
        kept = _kept(solver)
        assert all(k is not None for k in kept)  # unloaded subdomains keep "zero"
        new = _problem(hertz_mesh, _elastic(3.0, -2.0, factor=0.7))
        solver.update(new)
        assert all(a is b for a, b in zip(kept, _kept(solver), strict=True))  # nothing built again
        _assert_load_of_fresh_setup(solver, new)
    finally:
        solver.destroy()


def test_another_shape_builds_the_form_again(hertz_mesh):
    solver = df.FetiSolver(_problem(hertz_mesh, _elastic(1.0, 0.5)))
    try:
        kept = _kept(solver)
        new = _problem(hertz_mesh, df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -2.0)}))
        solver.update(new)  # no body force now: a form of another shape
        now = _kept(solver)
        assert all(a is not b for a, b in zip(kept, now, strict=True) if a.compiled is not None)
        _assert_load_of_fresh_setup(solver, new)
    finally:
        solver.destroy()


def test_a_function_of_x_sets_its_numbers(hertz_mesh):
    """A load given as a function of x is kept by its structure; its numbers are constants.

    New numbers (the state it reads) reuse the compiled form; another expression (x[1] for
    x[0]) builds it again; both give the load of a fresh set-up.
    """
    state = {"g": 1.0, "axis": 0}

    def gravity(x):
        return ufl.as_vector((0.0, -state["g"] * (1.0 + 0.5 * x[state["axis"]])))

    solver = df.FetiSolver(_problem(hertz_mesh, _elastic(1.0, 0.0, body_force=gravity)))
    try:
        kept = _kept(solver)
        assert all(k is not None and k.compiled is not None for k in kept)
        state["g"] = 4.0
        new = _problem(hertz_mesh, _elastic(1.0, 0.0, body_force=gravity))
        solver.update(new)
        assert all(a is b for a, b in zip(kept, _kept(solver), strict=True))
        _assert_load_of_fresh_setup(solver, new)
        state["axis"] = 1
        other = _problem(hertz_mesh, _elastic(1.0, 0.0, body_force=gravity))
        solver.update(other)
        assert all(a is not b for a, b in zip(kept, _kept(solver), strict=True))
        _assert_load_of_fresh_setup(solver, other)
    finally:
        solver.destroy()


def test_poisson_fluxes_and_a_zero_source(root):
    mesh = df.read_gmsh(root / "meshes/stacked_blocks2d.msh")

    def problem(flux: float, source: float) -> df.ContactProblem:
        return df.ContactProblem(
            mesh, df.Poisson(source, flux={"top": flux}),
            dirichlet=[df.Dirichlet("bottom")],
            ties=[df.Tie(slave="upper_bottom", master="lower_top")],
            decomposition=df.Parts(2))

    solver = df.FetiSolver(problem(1.0, 0.0))
    try:
        kept = _kept(solver)
        new = problem(-2.5, 0.0)
        solver.update(new)
        assert all(k is not None for k in kept)
        assert all(a is b for a, b in zip(kept, _kept(solver), strict=True))
        _assert_load_of_fresh_setup(solver, new)
        other = problem(-2.5, 3.0)  # a source appears: another shape
        solver.update(other)
        _assert_load_of_fresh_setup(solver, other)
    finally:
        solver.destroy()
