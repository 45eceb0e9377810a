"""P2 against P1 on the 2D Hertz problem (half model, node-to-node contact).

P1 on a mesh of size h (contact zone; 20 h far from it) and P2 on the mesh of size 2h have
comparable numbers of dofs (P2 about 1.7 times more on these graded meshes: the table lists
them). P2 runs twice: on the straight-sided first-order mesh (its edge dof points on the disk
lie on chords, inside the circle by the sagitta h²/8R) and on the second-order (curved) mesh
of the same model (``gmsh.model.mesh.setOrder(2)``: edge nodes on the circle; isoparametric
P2). On the curved mesh a disk edge node sits at the arc's mid-angle, up to ~1e-4 off the
block's edge midpoint in x, so the pairs are matched with ``match_tol=1e-2`` (of the edge
length); the gap is measured along the block's normal (y), which that offset does not change.

For each run the contact pressure at the slave dof points (nodal force / lumped length) is
compared with Hertz's p(x) = p0 sqrt(1 - x²/a²): the peak error, the half-width of the
computed contact zone, and the RMS and maximum of p_h - p over the dof points with x < 0.9 a
(away from the edge of the contact zone, where every nodal scheme smears the pressure over one
element), relative to p0.

Run: ``python bench/hertz_degree.py [--h 0.2 0.1 0.05 0.025]`` (serially or under mpirun).
"""

from __future__ import annotations

import argparse
import json

import gmsh
import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

R, P, E, NU = 8.0, 10.0, 200.0, 0.3
E_STAR = E / (2.0 * (1.0 - NU**2))
A = 2.0 * np.sqrt(R * P / (np.pi * E_STAR))
P0 = np.sqrt(P * E_STAR / (np.pi * R))


def curved_hertz2d(**kwargs):
    """The Hertz model with second-order cells (edge nodes on the circle)."""
    groups = meshes.hertz2d(**kwargs)
    gmsh.model.mesh.setOrder(2)
    return groups


def run(h: float, degree: int, curved: bool, comm: MPI.Comm) -> dict:
    model = curved_hertz2d if curved else meshes.hertz2d
    mesh = df.build_mesh(model, h_contact=h, h_far=20 * h, R=R, comm=comm)
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"load": (0.0, -P / 2 / R)}, degree=degree),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.NodeToNode("disk_contact", "block_contact",
                               match_tol=1e-2 if curved else 1e-4)],
        decomposition=df.Parts(2))
    sol = df.solve(problem, comm=comm, rtol=1e-10)
    return hertz_errors(sol, degree=degree, curved=curved, h=h)


def hertz_errors(sol, **meta) -> dict:
    """The pressure at the slave dof points against Hertz's (see the module's text)."""
    c = sol.contact
    x, p = c.x[:, 0], c.pressure
    hertz = P0 * np.sqrt(np.maximum(1 - x**2 / A**2, 0.0))
    inner = x < 0.9 * A
    active = p > 1e-8 * p.max()
    return {**meta, "dofs": sol.report.sizes["primal"],
            "contact_points": int(x.size), "converged": sol.report.converged,
            "warnings": list(sol.report.warnings),
            "peak_error": float((p.max() - P0) / P0),
            "half_width": float(x[active].max()), "half_width_error": float(x[active].max() - A),
            "rms_error": float(np.sqrt(np.mean((p[inner] - hertz[inner]) ** 2)) / P0),
            "max_error_inner": float(np.abs(p[inner] - hertz[inner]).max() / P0),
            "total_force": float(sol.total_contact_force[1])}


def save_rows(comm: MPI.Comm, path: str | None, hertz: dict, rows: list[dict]) -> None:
    """Rank 0 writes Hertz's values and the rows as JSON to ``path`` (when given)."""
    if comm.rank == 0 and path:
        with open(path, "w") as f:
            json.dump({"hertz": hertz, "rows": rows}, f, indent=1)


def print_row(r: dict) -> None:
    """One line of the table."""
    kind = "curved  " if r["curved"] else "straight"
    print(f"P{r['degree']} {kind} h={r['h']:<6} dofs={r['dofs']:>7} "
          f"peak {100 * r['peak_error']:+6.2f} %"
          f"  a_h-a {r['half_width_error']:+.4f}  rms {100 * r['rms_error']:.2f} %"
          f"  max(x<0.9a) {100 * r['max_error_inner']:.2f} %"
          f"  force {r['total_force']:.6f}  warnings {len(r['warnings'])}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--h", type=float, nargs="+", default=[0.2, 0.1, 0.05, 0.025])
    parser.add_argument("--json", default=None, help="write the rows here")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    for h in args.h:
        for degree, hd, curved in ((1, h, False), (2, 2 * h, False), (2, 2 * h, True)):
            rows.append(run(hd, degree, curved, comm))
            if comm.rank == 0:
                print_row(rows[-1])
    save_rows(comm, args.json, {"a": A, "p0": P0}, rows)


if __name__ == "__main__":
    main()
