"""P2 against P1 on the 3D Hertz problem with mortar contact (independent meshes).

The quarter model of :func:`dolfinx_feti.io.meshes_occ.sphere_on_block` (a hemisphere of
radius R = 8 on a block, each body meshed on its own: the contact surfaces do not match; the
sphere is the slave), both bodies E = 200, ν = 0.3, a total force F = 20 on the flat top of
the hemisphere. P1 and P2 on meshes of size h at the contact (h_block = 5/3 h); P2 on a mesh
about twice as coarse has about as many dofs. The meshes are first-order (straight-sided):
the P2 edge dof points of the sphere lie on the chords, inside the sphere by the sagitta
h²/8R (mortar on curved 3D facets is not built: :class:`dolfinx_feti.Mortar` refuses a
second-order 3D mesh).

For each run the pressure at the slave dof points (nodal force / ∫ Ñ_j, the transformed basis
of 6-node triangles) is compared with Hertz's p(r) = p0 sqrt(1 − r²/a²), a = (3FR/4E*)^(1/3),
p0 = 3F/(2πa²), E* = E/(2(1 − ν²)): the peak error, the computed contact radius (the
largest r with a positive pressure), the RMS and maximum of p_h − p over the dof points with
r < 0.9 a, relative to p0; and the same for the smoothed pressure (force over patch area).

Run: ``python bench/hertz3d_mortar_degree.py --p1-h 0.15 0.1 0.075 --p2-h 0.3 0.2 0.15``
(serially or under mpirun).
"""

from __future__ import annotations

import argparse

import numpy as np
from hertz_degree import save_rows
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes_occ import sphere_on_block

F, R, E, NU = 20.0, 8.0, 200.0, 0.3
E_STAR = E / (2.0 * (1.0 - NU**2))
A = (3.0 * F * R / (4.0 * E_STAR)) ** (1.0 / 3.0)
P0 = 3.0 * F / (2.0 * np.pi * A**2)


def errors(r: np.ndarray, p: np.ndarray) -> dict:
    """Peak, RMS and largest error (r < 0.9 a) of a pressure against Hertz's, relative to p0."""
    hertz = P0 * np.sqrt(np.maximum(1 - r**2 / A**2, 0.0))
    inner = r < 0.9 * A
    return {"peak_error": float((p.max() - P0) / P0),
            "rms_error": float(np.sqrt(np.mean((p[inner] - hertz[inner]) ** 2)) / P0),
            "max_error_inner": float(np.abs(p[inner] - hertz[inner]).max() / P0)}


def run(h: float, degree: int, comm: MPI.Comm, parts: int) -> dict:
    mesh = df.build_mesh(sphere_on_block, h, 5.0 / 3.0 * h, comm=comm)
    t = F / 4 / (np.pi * R**2 / 4)
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"load": (0.0, 0.0, -t)}, degree=degree),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sym_x", components=[0]),
                   df.Dirichlet("sym_y", components=[1])],
        contact=[df.Mortar("sphere_contact", "block_contact")],
        decomposition=df.Parts(parts))
    sol = df.solve(problem, comm=comm, rtol=1e-10)
    c = sol.contact
    r = np.linalg.norm(c.x[:, :2], axis=1)
    p = c.pressure
    active = p > 1e-8 * p.max()
    smooth = errors(r, sol.smoothed_pressure())
    return {"degree": degree, "h": h, "dofs": sol.report.sizes["primal"],
            "contact_points": int(r.size), "converged": sol.report.converged,
            "warnings": list(sol.report.warnings), **errors(r, p),
            "radius": float(r[active].max()), "radius_error": float(r[active].max() - A),
            "smoothed": smooth, "total_force": float(sol.total_contact_force[2])}


def print_row(r: dict) -> None:
    """One line of the table."""
    s = r["smoothed"]
    print(f"P{r['degree']} h={r['h']:<5} dofs={r['dofs']:>7} peak {100 * r['peak_error']:+6.2f} %"
          f"  a_h-a {r['radius_error']:+.4f}  rms {100 * r['rms_error']:.2f} %"
          f"  max(r<0.9a) {100 * r['max_error_inner']:.2f} %  smoothed: peak "
          f"{100 * s['peak_error']:+.2f} % rms {100 * s['rms_error']:.2f} % max "
          f"{100 * s['max_error_inner']:.2f} %  force {r['total_force']:.6f}"
          f"  warnings {len(r['warnings'])}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--p1-h", type=float, nargs="*", default=[0.15, 0.1])
    parser.add_argument("--p2-h", type=float, nargs="*", default=[0.3, 0.2])
    parser.add_argument("--parts", type=int, default=8)
    parser.add_argument("--json", default=None, help="write the rows here")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        print(f"Hertz: a = {A:.4f}, p0 = {P0:.4f}", flush=True)
    rows = [run(h, degree, comm, args.parts)
            for degree, hs in ((1, args.p1_h), (2, args.p2_h)) for h in hs]
    for r in rows if comm.rank == 0 else []:
        print_row(r)
    save_rows(comm, args.json, {"a": A, "p0": P0}, rows)


if __name__ == "__main__":
    main()
