"""Two neo-Hookean blocks pressed together under Newton: mortar against node-to-node.

The two-block patch test of tests/drivers/test_newton_mortar.py (E = 10, ν = 0.3, blocks
[0, 2] × [0, 1] and [0, 2] × [1, 2] meshed apart, the top moved down by 2·strain, the bottom
on rollers, the left sides on a symmetry plane, one subdomain per body, FETI-DP):

1. the smallest eigenvalues of the tangent K_t of the two blocks at the exact homogeneous
   states, on the dofs their Dirichlet conditions leave free, and with the mortar rows held as
   equalities besides (is the increment's QP convex?);
2. the load path [0.2, 0.4] with mortar contact (7 × 4 and 5 × 3 cells: non-matching) and
   with node-to-node contact (5 × 3 cells each: matching): converged or not, Newton
   iterations and cut-backs per step, the error against the exact solution.

3. ``--curved``: curved mortar contact (the quarter disk pressed 0.1 and 0.2 into the block
   of tests/drivers/test_newton_mortar.py): Newton iterations, inner QPs and seconds with the
   rows' D, M, n frozen and with their derivatives (``newton_mortar_derivatives=True``,
   drivers/mortar_step.py), the increments' history and the difference of the solutions.
4. ``--flat``: the same two ways on the flat patch tests of tests/drivers/test_newton_mortar.py
   (the two blocks, path [0.2, 0.4]; the 3D boxes, path [0.2, 0.3] and [0.2, 0.3, 0.4]):
   converged or not, Newton iterations per step, inner QPs, the error against the exact
   homogeneous solution.

5. ``--spectrum``: on the two blocks at the states the frozen Newton path reaches (20, 30,
   35, 40 %), with G and H as dense matrices (drivers/mortar_linearization.py): the spectral
   radius of the plain inner fixed point of drivers/mortar_step.py (x ↦ Φ(x), all contact rows
   active), and the least real part of the eigenvalues of the consistent Jacobian K_t + H on
   the null space of the Dirichlet rows and G (below 0: the homogeneous state is unstable for
   the mortar rows' own forces).

Run (serial; small dense eigenproblems):

    OMP_NUM_THREADS=1 PYTHONPATH=$PWD python bench/newton_two_blocks.py \
        [--curved | --flat | --spectrum]
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.linalg as sl

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "support"))
sys.path.insert(0, str(ROOT / "tests" / "drivers"))

from hand_meshes import blocks  # noqa: E402
from test_newton import LX, neo_hookean_exact, nodal  # noqa: E402
from test_newton_mortar import TWO_BLOCKS, stack  # noqa: E402

import dolfinx_feti as df  # noqa: E402
from dolfinx_feti.constraints.rows import Kind  # noqa: E402
from dolfinx_feti.drivers.newton import NewtonSolver  # noqa: E402
from dolfinx_feti.errors import SolveError  # noqa: E402


def smallest_eigenvalues(mesh, strain: float, first: bool = False) -> tuple[float, float]:
    """min eig of K_t at the exact state: Dirichlet dofs held; and mortar rows held too.

    ``first``: at the first Newton iterate of the step from 20 % to ``strain`` instead.
    """
    problem = stack(mesh, strain, df.Mortar("upper_bottom", "lower_top"))
    run = NewtonSolver(problem, method="fetidp", rtol=1e-12)
    data = run.solver.data
    if first:
        run.step(stack(mesh, 0.2, df.Mortar("upper_bottom", "lower_top")))
        run.newton = replace(run.newton, max_it=1)
        run.step(problem)
    else:
        a, _ = neo_hookean_exact(strain)
        x = data.dof_x
        run.u.array[:] = np.where(data.dof_comp == 0, (a - 1) * x[:, 0], -strain * x[:, 1])
    current = run._at_state(problem)
    run.state.set(run.solver.data, run.u.array_r)
    rows0 = run.solver.rows_of(current)
    rows, _, _ = run.mortar.relayout(current, rows0, rows0.own.rhs.copy(), run.u)
    run.solver.update_stiffness(current, rows=rows)
    K = run.solver.data.K.toarray()
    own = rows.own
    B = np.zeros((own.size, K.shape[0]))
    np.add.at(B, (own.e_row, rows.cols), own.e_coef)
    out = []
    for C in (B[own.kind == Kind.DIRICHLET], B[own.kind != Kind.GLUE]):
        Z = sl.null_space(C)
        out.append(float(np.linalg.eigvalsh(Z.T @ K @ Z)[0]))
    run.destroy()
    return out[0], out[1]


def path(mesh, interface) -> list[str]:
    sols = df.solve_path(lambda t: stack(mesh, t, interface), [0.2, 0.4], rtol=1e-12,
                         newton_rtol=1e-10, method="fetidp", progress=False)
    out = []
    for sol, strain in zip(sols, (0.2, 0.4), strict=False):
        a, p22 = neo_hookean_exact(strain)
        X, U = nodal(sol)
        err = np.abs(U - np.c_[(a - 1) * X[:, 0], -strain * X[:, 1]]).max() / strain
        out.append(f"{strain:.0%}: {'converged' if sol.report.converged else 'FAILED'}, "
                   f"{sol.report.extra['newton_iterations']} iterations, "
                   f"{sol.report.extra['cutbacks']} cut-backs, error/strain {err:.1e}, "
                   f"force {sol.contact.force.sum() / (-p22 * LX):.12f} of the exact")
    return out


def curved() -> None:
    """The disk on the block, frozen rows against the rows' derivatives."""
    import time

    from test_newton_mortar import disk_block_mesh, disk_pressed
    mesh = disk_block_mesh()

    def problem(t):
        return disk_pressed(mesh, t)

    out = {}
    for derivs in (False, True):
        t0 = time.perf_counter()
        out[derivs] = df.solve_path(problem, [0.1, 0.2], rtol=1e-12, newton_rtol=1e-10,
                                    method="fetidp", newton_max_it=40, progress=False,
                                    newton_mortar_derivatives=derivs)
        print(f"derivatives={derivs}: {time.perf_counter() - t0:.1f} s")
        for sol in out[derivs]:
            hist = sol.report.extra["newton"]
            steps = " ".join(f"{h['du_rel']:.1e}" for h in hist)
            print(f"  converged {sol.report.converged}, {len(hist)} iterations, inner QPs "
                  f"{[h.get('inner_qps', 0) for h in hist]}, du/u {steps}")
    u0, u1 = out[False][-1].nodal_values(), out[True][-1].nodal_values()
    diff = np.abs(u1 - u0).max() / np.abs(u0).max()
    print(f"max |u_derivatives − u_frozen| / max |u| = {diff:.1e}")


def _history(sols, times, error) -> None:
    for sol, t in zip(sols, times, strict=False):
        hist = sol.report.extra["newton"]
        print(f"  {t:.0%}: {'converged' if sol.report.converged else 'FAILED'}, "
              f"{len(hist)} iterations, {sol.report.extra['cutbacks']} cut-backs, inner QPs "
              f"{[h.get('inner_qps', 0) for h in hist]}, error/strain {error(sol, t):.1e}")


def flat() -> None:
    """The flat patch tests (2D blocks, 3D boxes), frozen rows against the derivatives."""
    import time

    from test_newton_mortar import boxes, uniaxial_3d

    from dolfinx_feti.io.meshes_occ import stacked_blocks
    mesh2 = blocks(TWO_BLOCKS)
    iface = df.Mortar("upper_bottom", "lower_top")

    def error2(sol, t):
        a, _ = neo_hookean_exact(t)
        X, U = nodal(sol)
        return np.abs(U - np.c_[(a - 1) * X[:, 0], -t * X[:, 1]]).max() / t

    mesh3 = df.build_mesh(stacked_blocks, dim=3, h_lower=0.3, h_upper=0.45)
    E, NU = 10.0, 0.3
    mu, lmbda = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))

    def box(t):
        return boxes(mesh3, t)

    def error3(sol, t):
        a, _ = uniaxial_3d(mu, lmbda, 1.0 - t)
        X, U = mesh3.x, sol.nodal_values()
        return np.abs(U - np.c_[(a - 1) * X[:, 0], (a - 1) * X[:, 1], -t * X[:, 2]]).max() / t

    cases = [("2D blocks", lambda t: stack(mesh2, t, iface), [0.2, 0.4], error2),
             ("3D boxes", box, [0.2, 0.3], error3),
             ("3D boxes", box, [0.2, 0.3, 0.4], error3)]
    for name, problem, times, error in cases:
        for derivs in (False, True):
            t0 = time.perf_counter()
            try:
                sols = df.solve_path(problem, times, rtol=1e-12, newton_rtol=1e-10,
                                     method="fetidp", progress=False,
                                     newton_mortar_derivatives=derivs)
            except SolveError as e:  # a tangent that cannot be factored after the cut-backs
                print(f"{name} {times}, derivatives={derivs}: FAILED: {e}")
                continue
            print(f"{name} {times}, derivatives={derivs}: {time.perf_counter() - t0:.1f} s")
            _history(sols, times, error)


def spectrum(mesh, strain: float) -> tuple[float, float]:
    """(ρ of the plain inner fixed point, least real eigenvalue of K_t + H on null(B_D; G))."""
    iface = df.Mortar("upper_bottom", "lower_top")
    run = NewtonSolver(stack(mesh, 0.2, iface), method="fetidp", rtol=1e-12)
    for t in sorted({0.2, strain}):
        run.step(stack(mesh, t, iface))
    current = run._at_state(stack(mesh, strain, iface))
    solver, mortar = run.solver, run.mortar
    at = mortar.rows_at_iterate(current, run.u, solver.qp.rows, run._lam)
    d = at.dense(mortar.surface_dofs(current))
    run.state.set(solver.data, run.u.array_r)
    rows0 = solver.rows_of(current)
    rows, _, _ = mortar.relayout(current, rows0, rows0.own.rhs.copy(), run.u)
    solver.update_stiffness(current, rows=rows)
    K = solver.data.K.toarray()
    n = K.shape[0]
    col = mortar._col.ravel()
    P = np.zeros((col.size, n))
    P[np.flatnonzero(col >= 0), col[col >= 0]] = 1.0
    own = rows.own
    B = np.zeros((own.size, n))
    np.add.at(B, (own.e_row, rows.cols), own.e_coef / own.scale[own.e_row])
    BD, Bm, G, H = B[own.kind == Kind.DIRICHLET], d.B @ P, d.G @ P, P.T @ d.H @ P
    C = np.vstack([BD, Bm])
    A0 = np.block([[K, C.T], [C, np.zeros((C.shape[0], C.shape[0]))]])
    N = np.zeros_like(A0)
    N[:n, :n] = H
    N[n + BD.shape[0]:, :n] = G - Bm
    rho = float(np.abs(np.linalg.eigvals(-np.linalg.solve(A0, N)[:n, :n])).max())
    Z = sl.null_space(np.vstack([BD, G]))
    least = float(np.linalg.eigvals(Z.T @ (K + H) @ Z).real.min())
    run.destroy()
    return rho, least


if __name__ == "__main__":
    if "--spectrum" in sys.argv:
        mesh = blocks(TWO_BLOCKS)
        print("strain | ρ(plain inner fixed point) | least Re λ(K_t + H on null(B_D; G))")
        for strain in (0.2, 0.3, 0.35, 0.4):
            rho, least = spectrum(mesh, strain)
            print(f"{strain:.2f} | {rho:.3g} | {least:.3g}")
        lo, hi = smallest_eigenvalues(mesh, 0.4, first=True)
        print(f"min eig K_t at the first iterate of the step 20 % -> 40 %: {lo:.3g} (Dirichlet "
              f"dofs held), {hi:.3g} (and the mortar rows)")
        sys.exit()
    if "--curved" in sys.argv:
        curved()
        sys.exit()
    if "--flat" in sys.argv:
        flat()
        sys.exit()
    nonmatching = blocks(TWO_BLOCKS)
    print("strain | min eig K_t (Dirichlet held) | with the mortar rows held")
    for strain in (0.1, 0.2, 0.3, 0.35, 0.4):
        lo, hi = smallest_eigenvalues(nonmatching, strain)
        print(f"{strain:.2f} | {lo:.3g} | {hi:.3g}")
    print("mortar (non-matching):", *path(nonmatching, df.Mortar("upper_bottom", "lower_top")),
          sep="\n  ")
    matching = blocks([{**TWO_BLOCKS[0], "n": (5, 3)}, TWO_BLOCKS[1]])
    print("node-to-node (matching):",
          *path(matching, df.NodeToNode("upper_bottom", "lower_top")), sep="\n  ")
