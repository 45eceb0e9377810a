"""Large-deformation contact: Newton over FETI against PETSc SNES VI, run time against error.

The soft hemisphere of demos/demo_rubber_hemisphere.py (quarter model, R = 1, compressible
neo-Hookean E = 1, ν = 0.3, its top pushed down by δ onto a frictionless rigid plane in load
steps): the same energy, mesh and load steps solved by

- ``df.solve_path`` (Newton, each iteration an exact contact QP by FETI-DP over ``--parts``
  subdomains) at each Newton tolerance of ``--newton-rtol``;
- SNES VI (``vinewtonrsls``, the plane as a bound on u_z, the Dirichlet values as equal bounds,
  MUMPS LU in each Newton step) at each SNES tolerance of ``--snes-rtol``;

each against a reference: SNES VI at rtol 1e-14 (its own time not counted). Error = max|u −
u_ref| / max|u_ref| at the last step, and the relative error of the force on the plane. One
process (SNES VI runs on one rank). Run:

    OMP_NUM_THREADS=1 PYTHONPATH=$PWD python bench/newton_snes.py [--h 0.1,0.07,0.05]

(uniform meshes: ``--h`` is the element size everywhere).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

import dolfinx_feti as df
from dolfinx_feti.io.meshes_rubber import quarter_hemisphere

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "support"))
from rubber_cases import hemisphere_bounds, rubber_hemisphere  # noqa: E402
from snes_vi import match, neo_hookean, snes_vi  # noqa: E402


def floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",")]


parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=floats, default=[0.1, 0.07, 0.05],
                    help="element sizes (at the contact and away from it)")
parser.add_argument("--delta", type=float, default=0.15, help="travel of the top / R")
parser.add_argument("--steps", type=int, default=4)
parser.add_argument("--parts", type=int, default=4)
parser.add_argument("--newton-rtol", type=floats, default=[1e-5, 1e-8])
parser.add_argument("--snes-rtol", type=floats, default=[1e-5, 1e-8])
parser.add_argument("--json", type=Path, default=Path("output/bench/newton_snes.json"))
args = parser.parse_args()
R, E, nu = 1.0, 1.0, 0.3
mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
loads = args.delta * R * np.arange(1, args.steps + 1) / args.steps


def snes(mesh, rtol):
    """(u in the mesh's node order, force on the plane, SNES iterations, seconds)."""
    wall = time.perf_counter()
    X, U, Rv, its = snes_vi(mesh, neo_hookean(mu, lmbda), hemisphere_bounds, -R, loads, rtol=rtol,
                            factor="mumps")
    wall = time.perf_counter() - wall
    touching = X[:, 2] + U[:, 2] + R < 1e-9
    return U[match(X, mesh.x)], float(Rv[touching, 2].sum()), sum(its), wall


def feti(mesh, newton_rtol):
    """(u, force on the plane, Newton iterations, F-multiplications, seconds)."""
    wall = time.perf_counter()
    sols = df.solve_path(lambda t: rubber_hemisphere(mesh, t, args.parts, E, nu, R), loads,
                         method="fetidp", rtol=min(1e-6, newton_rtol), newton_rtol=newton_rtol,
                         progress=False)
    wall = time.perf_counter() - wall
    last = sols[-1]
    assert all(s.report.converged for s in sols)
    newton = sum(s.report.extra["newton_iterations"] for s in sols)
    mults = sum(s.report.hessian_mults for s in sols)
    return last.nodal_values(), float(last.total_contact_force[2]), newton, mults, wall


def error(u, f, u_ref, f_ref) -> tuple[float, float]:
    """Max-norm error of u relative to max|u_ref|, relative error of the force."""
    return float(np.abs(u - u_ref).max() / np.abs(u_ref).max()), abs(f - f_ref) / abs(f_ref)


rows = []
for h in args.h:
    mesh = df.build_mesh(quarter_hemisphere, R=R, h_contact=h, h_far=h)
    dofs = 3 * mesh.x.shape[0]
    ref = snes(mesh, 1e-14)[:2]

    for r in args.snes_rtol:
        u, f, its, wall = snes(mesh, r)
        eu, ef = error(u, f, *ref)
        rows.append(dict(h=h, dofs=dofs, solver="SNES VI (MUMPS)", tol=r, iterations=its,
                         hessian_mults=None, seconds=wall, error_u=eu, error_force=ef))
    for r in args.newton_rtol:
        u, f, its, mults, wall = feti(mesh, r)
        eu, ef = error(u, f, *ref)
        rows.append(dict(h=h, dofs=dofs, solver=f"Newton + FETI-DP, Parts({args.parts})",
                         tol=r, iterations=its, hessian_mults=mults, seconds=wall,
                         error_u=eu, error_force=ef))
    for row in rows[-len(args.snes_rtol) - len(args.newton_rtol):]:
        print(f"h {row['h']:<5} dofs {row['dofs']:>6}  {row['solver']:<26} tol {row['tol']:.0e}"
              f"  {row['iterations']:>3} it  {row['seconds']:7.2f} s  error u "
              f"{row['error_u']:.1e}  force {row['error_force']:.1e}", flush=True)

args.json.parent.mkdir(parents=True, exist_ok=True)
args.json.write_text(json.dumps(rows, indent=1))
print(f"wrote {args.json}")
