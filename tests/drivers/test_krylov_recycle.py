"""Krylov recycling on FetiSolver (qp/recycle.py): warm solves equal cold ones.

After an update of the loads (the operator unchanged) a warm solve with the last solve's CG
directions equals a cold solve of the new problem without them (to solver tolerance), in
fewer F-multiplications than the same warm solve without them; a row update (a moved curved
obstacle: another F) forgets the directions; ``x0="cold"`` repeats the first solve.
"""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref

import dolfinx_feti as df

RTOL = 1e-8
TOL = 1e-5
METHODS = ("tfeti", "feti1", "fetidp")


@pytest.fixture(scope="module")
def hertz_mesh(root):
    return df.read_gmsh(root / "meshes/hertz2d.msh")


def hertz(mesh, load: float = 10.0, contact=None):
    return df.ContactProblem(
        mesh, df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -load / 2 / 8.0)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=contact or [df.NodeToNode(slave="disk_contact", master="block_contact")],
        decomposition=df.Parts(2))


def assert_same(a: df.Solution, b: df.Solution, tol: float = TOL) -> None:
    assert ref.rel_max_diff(a.nodal_values(), b.nodal_values()) <= tol
    scale = np.abs(b.contact.force).max()
    assert np.abs(a.contact.force - b.contact.force).max() <= tol * scale


def warm_after_update(mesh, method: str, reuse: int) -> tuple[df.FetiSolver, df.Solution]:
    solver = df.FetiSolver(hertz(mesh), rtol=RTOL, method=method, mprgp_reuse=reuse)
    assert solver.solve().report.converged
    solver.update(hertz(mesh, load=11.0))
    return solver, solver.solve()


@pytest.mark.parametrize("method", METHODS)
def test_warm_solve_with_recycling_equals_cold(hertz_mesh, method):
    solver, warm = warm_after_update(hertz_mesh, method, 80)
    assert len(solver.recycle) > 0
    plain_solver, plain = warm_after_update(hertz_mesh, method, 0)
    assert plain_solver.recycle is None
    cold = df.solve(hertz(hertz_mesh, load=11.0), rtol=RTOL, method=method, mprgp_reuse=0)
    assert warm.report.converged and plain.report.converged and cold.report.converged
    assert_same(warm, cold)
    assert_same(plain, cold)
    # the directions of the first solve shorten the second
    assert warm.report.hessian_mults < plain.report.hessian_mults, \
        (warm.report.hessian_mults, plain.report.hessian_mults)
    # and a cold solve recycles within itself (SMALBE's outer iterations, the faces)
    cold_recycled = df.solve(hertz(hertz_mesh, load=11.0), rtol=RTOL, method=method)
    assert_same(cold_recycled, cold)
    solver.destroy()
    plain_solver.destroy()


def test_row_update_forgets_the_directions(hertz_mesh):
    """A circle moved sideways turns its normals: B and F change, nothing is recycled."""
    def on_circle(dx):
        return hertz(hertz_mesh, contact=[df.RigidObstacle(
            "disk_contact", df.Sphere((dx, -40.0), 40.0))])

    solver = df.FetiSolver(on_circle(0.0), rtol=RTOL, method="tfeti")
    solver.solve()
    assert len(solver.recycle) > 0
    solver.update(on_circle(0.3))
    assert len(solver.recycle) == 0
    warm = solver.solve()
    cold = df.solve(on_circle(0.3), rtol=RTOL, method="tfeti", mprgp_reuse=0)
    assert_same(warm, cold)
    solver.destroy()


def test_cold_start_forgets_the_directions(hertz_mesh):
    solver = df.FetiSolver(hertz(hertz_mesh), rtol=RTOL, method="feti1")
    first = solver.solve()
    again = solver.solve(x0="cold")
    assert again.report.hessian_mults == first.report.hessian_mults
    assert_same(again, first)
    solver.destroy()


def test_reuse_option_from_the_database(hertz_mesh):
    opts = df.SolverOptions.create(argv=["-feti_mprgp_reuse", "12", "-feti_mprgp_deflate",
                                         "false"])
    assert (opts.mprgp_reuse, opts.mprgp_deflate) == (12, False)
    solver = df.FetiSolver(hertz(hertz_mesh), options=opts, method="fetidp")
    assert solver.recycle.k == 12 and not solver.recycle.deflate
    solver.destroy()
    with pytest.raises(df.InputError, match="reuse"):
        df.SolverOptions(mprgp_reuse=-1)
