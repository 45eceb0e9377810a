"""Large-deformation mortar contact and ties under Newton (drivers/current_mortar.py).

The patch test of two blocks meshed independently (non-matching interface): a neo-Hookean
block [0, 2] × [1, 2] pressed onto a second one [0, 2] × [0, 1] of the same material, the top
moved down by 2·strain, the bottom on rollers, the left sides on a symmetry plane, laterally
free, frictionless. The exact solution is homogeneous, u = ((a − 1) x, −strain · y), with the
lateral stretch a from the scalar equation P₁₁(a) = 0 (``test_newton.neo_hookean_exact``); the
interface stays flat and both surfaces stretch by a, so the mortar rows of the deformed
surfaces hold it exactly (a linear field is in both spaces; dual mortar reproduces it).
"""

from __future__ import annotations

import numpy as np
import pytest
from hand_meshes import blocks
from scipy.optimize import brentq
from test_newton import LX, NU, E, neo_hookean_exact, nodal, residuals

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar import mortar_coupling
from dolfinx_feti.drivers.current_mortar import DeformedMortar
from dolfinx_feti.errors import SolveError, inject_fault
from dolfinx_feti.io.meshes_occ import disk_on_block, stacked_blocks

#: Both blocks' bottom/top/left; the upper block 5 cells across, the lower one 7: no node of
#: the interface matches but its two ends.
TWO_BLOCKS = [{"name": "lower", "n": (7, 4), "size": (LX, 1.0)},
              {"name": "upper", "n": (5, 3), "origin": (0.0, 1.0), "size": (LX, 1.0)}]


@pytest.fixture(scope="module")
def two_blocks():
    return blocks(TWO_BLOCKS)


def stack(mesh, strain: float, interface, decomposition=None) -> df.ContactProblem:
    kw = {"ties": [interface]} if isinstance(interface, df.Tie) else {"contact": [interface]}
    return df.ContactProblem(
        mesh, df.NeoHookean(E, NU),
        dirichlet=[df.Dirichlet("lower_bottom", 0.0, components=[1]),
                   df.Dirichlet("upper_top", -2 * strain, components=[1]),
                   df.Dirichlet("lower_left", 0.0, components=[0]),
                   df.Dirichlet("upper_left", 0.0, components=[0])],
        decomposition=decomposition or df.ByTags(), **kw)


def weighted_gaps(mesh, sol, slave: str, master: str) -> tuple[np.ndarray, np.ndarray]:
    """The coupled slave nodes and their weighted gaps n·(Σ_k w_jk y_k − y_j) on the deformed
    surfaces y = x + u of ``sol``, from its displacement alone."""
    y = mesh.x[:, :2] + sol.nodal_values()
    coupling = mortar_coupling(y, mesh.cells, mesh.facets(slave), mesh.facets(master), None,
                               mesh.cell_type)
    return coupling.slave_nodes[coupling.coupled], coupling.weighted_gap(y)


def test_two_blocks_mortar_patch_test(two_blocks):
    """20 % and 40 %: the exact homogeneous solution and contact force to 1e-8, quadratic
    convergence, and the weighted gaps of the deformed surfaces zero. (One subdomain per body:
    pieces of a body joined at one FETI-DP corner make K̃_t indefinite under compression, and
    a mortar row, coupling two subdomains, gets no augmentation: docs/large_deformation.md.)"""
    iface = df.Mortar("upper_bottom", "lower_top")
    sols = df.solve_path(lambda t: stack(two_blocks, t, iface), [0.2, 0.4], rtol=1e-12,
                         newton_rtol=1e-10, method="fetidp")
    assert [s.report.converged for s in sols] == [True, True], \
        [s.report.extra["newton"] for s in sols]
    for sol, strain in zip(sols, (0.2, 0.4), strict=True):
        a, p22 = neo_hookean_exact(strain)
        X, U = nodal(sol)
        assert np.abs(U - np.c_[(a - 1) * X[:, 0], -strain * X[:, 1]]).max() < 1e-8 * strain
        assert abs(sol.contact.force.sum() + p22 * LX) < 1e-8 * abs(p22) * LX
        assert np.all(sol.contact.force > 0)  # every slave node carries its share
        assert max(sol.report.kkt.values()) < 1e-9
        r = residuals(sol)
        assert len(r) <= 8
        # quadratic above the round-off floor (the last residual: 1e-15 … 1e-13 by version)
        for r0, r1 in zip(r, r[1:], strict=False):
            if r1 > 1e-12:
                assert r1 <= 10 * r0 ** 2, r
        # the converged rows are those of the deformed surfaces: weighted gaps of x + u zero
        nodes, gap = weighted_gaps(two_blocks, sol, "upper_bottom", "lower_top")
        assert nodes.size == sol.contact.force.size
        assert np.abs(gap).max() < 1e-10
        # the report's mortar summary is that of the deformed surfaces (total displacement)
        (summary,) = sol.report.extra["mortar"]
        assert summary["rows"] == summary["active_rows"] == nodes.size
        assert summary["max_penetration"] < 1e-10


def uniaxial_3d(mu: float, lmbda: float, s: float) -> tuple[float, float]:
    """Lateral stretch a and the traction P₃₃ of uniaxial stress at axial stretch s (3D)."""
    a = brentq(lambda a: mu * (a - 1 / a) + lmbda * np.log(a * a * s) / a, 0.5, 3.0,
               xtol=1e-15)
    return a, mu * (s - 1 / s) + lmbda * np.log(a * a * s) / s


def boxes(mesh, strain: float) -> df.ContactProblem:
    """The two boxes of ``stacked_blocks`` (3D), the top moved down by 2·strain, the bottom
    and two sides on symmetry planes, mortar contact."""
    return df.ContactProblem(
        mesh, df.NeoHookean(E, NU),
        dirichlet=[df.Dirichlet("bottom", 0.0, [2]), df.Dirichlet("top", -2 * strain, [2]),
                   df.Dirichlet("sym0", 0.0, [0]), df.Dirichlet("sym1", 0.0, [1])],
        contact=[df.Mortar("upper_bottom", "lower_top")], decomposition=df.ByTags())


def test_two_boxes_mortar_patch_test_3d():
    """3D: two unit boxes meshed apart (tetrahedra of 0.3 and 0.45), pressed 20 % and 30 %,
    laterally free: the homogeneous state u = ((a − 1) x, (a − 1) y, −strain · z) with
    P₁₁(a) = μ(a − 1/a) + λ ln(a² s)/a = 0, and the force P₃₃ (unit area), to 1e-8. (At 40 %
    Newton with the frozen D, M, n does not converge on this mesh: docs/large_deformation.md.)"""
    mesh = df.build_mesh(stacked_blocks, dim=3, h_lower=0.3, h_upper=0.45)
    mu, lmbda = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    sols = df.solve_path(lambda t: boxes(mesh, t), [0.2, 0.3], rtol=1e-12, newton_rtol=1e-10,
                         method="fetidp")
    for sol, strain in zip(sols, (0.2, 0.3), strict=True):
        assert sol.report.converged, sol.report.extra["newton"]
        a, p33 = uniaxial_3d(mu, lmbda, 1.0 - strain)
        X, U = mesh.x, sol.nodal_values()
        exact = np.c_[(a - 1) * X[:, 0], (a - 1) * X[:, 1], -strain * X[:, 2]]
        assert np.abs(U - exact).max() < 1e-8 * strain
        assert abs(sol.contact.force.sum() + p33) < 1e-8 * abs(p33)
        assert len(residuals(sol)) <= 8


def test_two_blocks_tied_patch_test(two_blocks):
    """A mortar tie under Newton glues material points (its rows of the reference surfaces,
    on total displacements): the homogeneous solution at 40 % to 1e-8."""
    iface = df.Tie("upper_bottom", "lower_top")
    sol = df.solve(stack(two_blocks, 0.4, iface), rtol=1e-12, newton_rtol=1e-10,
                   method="fetidp")
    assert sol.report.converged, sol.report.extra["newton"]
    a, _ = neo_hookean_exact(0.4)
    X, U = nodal(sol)
    assert np.abs(U - np.c_[(a - 1) * X[:, 0], -0.4 * X[:, 1]]).max() < 1e-8 * 0.4


def disk_block_mesh():
    """A quarter disk (R = 1) on a block, meshed apart (finer on the disk)."""
    return df.build_mesh(disk_on_block, h_contact_disk=0.06, h_contact_block=0.1, h_far=0.5,
                         R=1.0, width=3.0, height=1.5, refine=0.6, gdim=2)


def disk_pressed(mesh, t: float) -> df.ContactProblem:
    """The neo-Hookean disk pressed t into the neo-Hookean block, mortar contact."""
    return df.ContactProblem(
        mesh, df.NeoHookean(1.0, 0.3),
        dirichlet=[df.Dirichlet("load", -t, components=[1]),
                   df.Dirichlet("symmetry", 0.0, components=[0]), df.Dirichlet("bottom")],
        contact=[df.Mortar("disk_contact", "block_contact")])


@pytest.fixture(scope="module")
def disk_block():
    return disk_block_mesh()


def test_rows_change_with_the_deformed_surfaces(disk_block):
    """A neo-Hookean quarter disk (R = 1) pressed 0.2 into a neo-Hookean block, mortar contact
    on the deformed surfaces: the set of coupled slave nodes grows with the flattening disk (the
    rows' layout changes between iterates); the result does not depend on the load steps
    taken, and its weighted gaps recomputed from the displacement alone are >= 0, zero where a
    row carries force."""
    def problem(t):
        return disk_pressed(disk_block, t)

    opts = {"rtol": 1e-12, "newton_rtol": 1e-10, "method": "fetidp", "newton_max_it": 40}
    path = df.solve_path(problem, [0.1, 0.2], **opts)
    single = df.solve(problem(0.2), **opts)
    assert all(s.report.converged for s in [*path, single])
    first, last = path
    assert first.contact.force.size != last.contact.force.size  # another layout of the rows
    u_path, u_single = last.nodal_values(), single.nodal_values()
    assert np.abs(u_path - u_single).max() < 1e-8 * np.abs(u_single).max()
    nodes, gap = weighted_gaps(disk_block, last, "disk_contact", "block_contact")
    c = last.contact
    assert np.array_equal(np.sort(nodes), np.sort(c.node))
    force = c.force[np.argsort(c.node)][np.argsort(np.argsort(nodes))]
    assert gap.min() > -1e-9 and force.min() > -1e-9 * force.max()
    assert np.abs(force * gap).max() < 1e-9 * force.max()
    assert (force > 1e-6 * force.max()).sum() >= 4


SHIFTED = [{"name": "lower", "n": (7, 4), "size": (LX, 1.0)},
           {"name": "upper", "n": (5, 3), "origin": (0.0, 1.0), "size": (LX, 1.0)}]


def linear_blocks(mesh) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU),
        dirichlet=[df.Dirichlet("lower_bottom"), df.Dirichlet("upper_left", 0.0, [0]),
                   df.Dirichlet("upper_top", -0.01, [1])],
        contact=[df.Mortar("upper_bottom", "lower_top")], decomposition=df.ByTags())


def moved_rows(solver):
    """The solver's rows with the mortar rows of the upper block moved 0.5 to the right
    (its slave nodes beyond the lower block's edge lose their rows: another layout)."""
    shift = solver.qp.system.B.createVecRight()
    data = solver.data
    upper = data.local_subs[np.array([b == "upper" for b in data.bodies], dtype=bool)]
    shift.array[:] = np.where((data.dof_comp == 0) & np.isin(data.dof_sub, upper), 0.5, 0.0)
    mortar = DeformedMortar(solver, solver.problem, solver.comm)
    rows, _, _ = mortar.relayout(solver.problem, solver.qp.rows, solver.qp.rows.own.rhs, shift)
    shift.destroy()
    return rows


def test_update_rows_takes_rows_of_another_number():
    """FetiSolver.update_rows with mortar rows of another number of slave nodes: the rows of
    the upper block moved 0.5 to the right give the linear solve of the mesh built with the
    upper block there."""
    moved = blocks([SHIFTED[0], {**SHIFTED[1], "origin": (0.5, 1.0)}])
    solver = df.FetiSolver(linear_blocks(blocks(SHIFTED)), method="fetidp", rtol=1e-12)
    solver.solve()
    rows = moved_rows(solver)
    before = solver.comm.allreduce(int(solver.qp.rows.own.size))
    solver.update_rows(rows)
    assert solver.comm.allreduce(int(solver.qp.rows.own.size)) < before
    sol = solver.solve()
    ref = df.solve(linear_blocks(moved), method="fetidp", rtol=1e-12)
    assert sol.report.converged and ref.report.converged
    u, r = sol.nodal_values(), ref.nodal_values()
    assert np.abs(u - r).max() < 1e-8 * np.abs(r).max()
    assert sol.contact.force.size == ref.contact.force.size
    solver.destroy()


def test_failed_update_stiffness_keeps_the_rows_of_its_b():
    """An update_stiffness with rows of a mortar relayout that fails (the factorization:
    a Newton tangent that cannot be factored) leaves the solver as it was: rows_of gives
    rows of the layout of its B (not the failed update's, of another number), the solve is
    the one before; the same update then succeeds and solves the moved blocks."""
    problem = linear_blocks(blocks(SHIFTED))
    solver = df.FetiSolver(problem, method="fetidp", rtol=1e-12)
    first = solver.solve()
    rows = moved_rows(solver)
    comm = solver.comm
    size = comm.allreduce(int(solver.qp.rows.own.size))
    assert comm.allreduce(int(rows.own.size)) < size
    with inject_fault("factorization", 0), pytest.raises(SolveError):
        solver.update_stiffness(rows=rows)
    assert comm.allreduce(int(solver.rows_of(problem).own.size)) == size
    assert solver.rows_of(problem).own.size == solver.qp.system.B.getLocalSize()[0]
    again = solver.solve()
    assert np.abs(again.nodal_values() - first.nodal_values()).max() < \
        1e-8 * np.abs(first.nodal_values()).max()
    solver.update_stiffness(rows=rows)
    assert comm.allreduce(int(solver.rows_of(problem).own.size)) < size
    sol = solver.solve()
    moved = blocks([SHIFTED[0], {**SHIFTED[1], "origin": (0.5, 1.0)}])
    ref = df.solve(linear_blocks(moved), method="fetidp", rtol=1e-12)
    assert np.abs(sol.nodal_values() - ref.nodal_values()).max() < \
        1e-8 * np.abs(ref.nodal_values()).max()
    solver.destroy()


def test_curved_mortar_converges_quadratically(disk_block):
    """With the rows' derivatives (newton_mortar_derivatives, drivers/mortar_step.py) the disk
    pressed into the block converges quadratically, ≤ 8 Newton iterations a step (frozen
    D, M, n: 13 and 18, linearly), to the solution of the frozen rows (the same KKT
    conditions) within 1e-8."""
    def problem(t):
        return disk_pressed(disk_block, t)

    opts = {"rtol": 1e-12, "newton_rtol": 1e-10, "method": "fetidp", "newton_max_it": 40}
    frozen = df.solve_path(problem, [0.1, 0.2], **opts)
    exact = df.solve_path(problem, [0.1, 0.2], newton_mortar_derivatives=True, **opts)
    assert all(s.report.converged for s in [*frozen, *exact])
    for f, e in zip(frozen, exact, strict=True):
        steps = [h["du_rel"] for h in e.report.extra["newton"]]
        assert len(steps) <= 8 < len(f.report.extra["newton"]), steps
        assert sum(h.get("inner_qps", 0) for h in e.report.extra["newton"]) > len(steps)
        # the last three increments: each within a constant of the one before squared
        for d0, d1 in zip(steps[-4:], steps[-3:], strict=False):
            assert d1 <= 1e3 * d0 ** 2, steps
        u_f, u_e = f.nodal_values(), e.nodal_values()
        assert np.abs(u_e - u_f).max() < 1e-8 * np.abs(u_f).max()
