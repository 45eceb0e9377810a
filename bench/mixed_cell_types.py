"""Bodies of different cell types in one problem: the patch tests and Hertz, measured.

Prints two tables (the figures of docs/index.md, *Bodies of different cell types*):

1. the patch tests through a non-matching interface of a quadrilateral/hexahedral block and a
   triangle/tetrahedral one (stacked unit boxes, h 0.25 / 0.4; E 1000, ν 0.3, uniform
   pressure p = 1 on the top): ‖u − u_exact‖∞ / ‖u_exact‖∞ over both meshes, max |p − 1|
   at the slave nodes (tie: the traction against (0, …, −1)), F-multiplications;
2. Hertz in plane strain (the quarter disk of triangles on a block of quadrilaterals,
   ``disk_on_block(recombine="block")``, R 8, E 200, ν 0.3, load 10): the peak pressure against
   Hertz's p0, the half-width of the contact zone against a, and the block's element size
   there;
3. Hertz in 3D (the quarter hemisphere of tetrahedra on a graded block of hexahedra,
   ``sphere_on_block(recombine="block")``, R 8, E 200, ν 0.3, force 20 on the whole sphere):
   the same figures, the contact radius against a.

Run: ``PYTHONPATH=$PWD python bench/mixed_cell_types.py`` (about 1 min); under ``mpirun -n 2``
the same figures (the F-multiplications of 3D Hertz may differ: reductions round off otherwise).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "support"))
import hertz_cases as hertz  # noqa: E402

import dolfinx_feti as df  # noqa: E402
from dolfinx_feti.io.meshes_occ import disk_on_block, sphere_on_block, stacked_blocks  # noqa: E402


def patch(dim: int, recombined: str, tie: bool) -> tuple[float, float, int]:
    """One patch test: (displacement error, traction error, F-multiplications)."""
    E, nu = 1000.0, 0.3
    mesh = df.build_mesh(stacked_blocks, dim, 0.25, 0.4, recombine=recombined)
    bcs = [df.Dirichlet("bottom", 0.0, components=(dim - 1,)),
           df.Dirichlet("sym0", 0.0, components=(0,))]
    if dim == 3:
        bcs.append(df.Dirichlet("sym1", 0.0, components=(1,)))
    cond = (df.Tie if tie else df.Mortar)("upper_bottom", "lower_top")
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, nu, tractions={"top": [0.0] * (dim - 1) + [-1.0]}),
        dirichlet=bcs, **({"ties": [cond]} if tie else {"contact": [cond]}))
    sol = df.solve(problem, method="tfeti", rtol=1e-12)
    err = scale = 0.0
    for body in ("lower", "upper"):
        x, u = sol.displacement(body)
        if dim == 3:
            ex = np.stack([nu * x[:, 0], nu * x[:, 1], -x[:, 2]], 1) / E
        else:
            ex = np.stack([nu * (1 + nu) * x[:, 0], -(1 - nu**2) * x[:, 1]], 1) / E
        err, scale = max(err, np.abs(u - ex).max()), max(scale, np.abs(ex).max())
    p = sol.forces(0)["pressure"]
    expect = np.eye(dim)[-1] * -1.0 if tie else 1.0
    return err / scale, float(np.abs(p - expect).max()), sol.report.hessian_mults


def hertz2d(h: float) -> tuple[float, float, float, float, int]:
    """(p0 error, half-width, Hertz's a, block element there, F-multiplications)."""
    mesh = df.build_mesh(disk_on_block, h, 1.7 * h, recombine="block")
    sol = df.solve(hertz.disk_problem(mesh), method="tfeti", rtol=1e-8)
    pmax, half, element = hertz.mixed_figures(sol, mesh, 2)
    return pmax / hertz.DISK_P0 - 1.0, half, hertz.DISK_A, element, sol.report.hessian_mults


def hertz3d(h_sphere: float, h_block: float) -> tuple[float, float, float, float, int]:
    """(p0 error, contact radius, Hertz's a, block element there, F-multiplications)."""
    mesh = df.build_mesh(sphere_on_block, h_sphere, h_block, recombine="block")
    problem, _ = hertz.sphere_problem(mesh, df.Parts(4))
    sol = df.solve(problem, method="tfeti", rtol=1e-9)
    pmax, radius, element = hertz.mixed_figures(sol, mesh, 3)
    return pmax / hertz.SPHERE_P0 - 1.0, radius, hertz.SPHERE_A, element, \
        sol.report.hessian_mults


def main() -> None:
    out = ["| cells (lower / upper) | condition | slave | ‖u − u_exact‖∞ rel. | max traction "
           "error | F-mults |", "|---|---|---|---|---|---|"]
    names = {(2, "lower"): "quadrilaterals / triangles", (2, "upper"): "triangles / "
             "quadrilaterals", (3, "lower"): "hexahedra / tetrahedra",
             (3, "upper"): "tetrahedra / hexahedra"}
    slave_kind = {(2, "lower"): "triangles' edges", (2, "upper"): "quadrilaterals' edges",
                  (3, "lower"): "triangles", (3, "upper"): "quadrilaterals"}
    for dim in (2, 3):
        for rec in ("lower", "upper"):
            for tie in (False, True):
                e, p, m = patch(dim, rec, tie)
                out.append(f"| {names[dim, rec]} | {'tie' if tie else 'contact'} | "
                           f"{slave_kind[dim, rec]} | {e:.1e} | {p:.1e} | {m} |")
    out += ["", "| h (disk / block) | p_max / p0 − 1 | half-width | Hertz a | block element "
            "there | F-mults |", "|---|---|---|---|---|---|"]
    for h in (0.2, 0.1, 0.05):
        e, half, a, el, m = hertz2d(h)
        out.append(f"| {h} / {1.7 * h:.3g} | {e:+.2%} | {half:.3f} | {a:.3f} | {el:.3f} | {m} |")
    out += ["", "| h (sphere / block at the contact) | p_max / p0 − 1 | contact radius | Hertz a | "
            "block element there | F-mults |", "|---|---|---|---|---|---|"]
    for hs, hb in ((0.4, 0.25), (0.25, 0.15)):
        e, rad, a, el, m = hertz3d(hs, hb)
        out.append(f"| {hs} / {hb} | {e:+.2%} | {rad:.3f} | {a:.3f} | {el:.3f} | {m} |")
    if MPI.COMM_WORLD.rank == 0:
        print("\n".join(out))


if __name__ == "__main__":
    main()
