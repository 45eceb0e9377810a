"""The contact pressure fields against Hertz: force / lumped area, and the smoothed one.

``contact.pressure`` (the nodal force over the node's lumped area) and
``Solution.smoothed_pressure()`` (the force over the area of the node's patch), each against
Hertz's pressure at the slave nodes: RMS and largest error over the nodes within 0.8 a (3D) or
0.9 a (2D), and the peak, relative to p0. Mortar contact, P1, independent meshes:
the sphere on a block of tetrahedra (``meshes_occ.sphere_on_block``, h 0.15 / 0.25) and the
2D disk on a block (``meshes_occ.disk_on_block``, h and 1.7 h).

Run: ``python bench/contact_pressure_fields.py [--h2d 0.2 0.1 0.05]``
(serially or under mpirun; the sphere's problem is that of tests/test_mortar.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

_TESTS = Path(__file__).resolve().parents[1] / "tests"
sys.path[:0] = [str(_TESTS / "support"), str(_TESTS / "constraints")]
from hertz_degree import NU, P0, A, E, P, R  # noqa: E402
from test_mortar import SPHERE_F, SPHERE_R, sphere_problem  # noqa: E402

import dolfinx_feti as df  # noqa: E402
from dolfinx_feti.io.meshes_occ import disk_on_block, sphere_on_block  # noqa: E402

F3, R3 = SPHERE_F, SPHERE_R  # the sphere: the force (of the whole sphere), its radius
E_STAR = E / (2.0 * (1.0 - NU**2))


def errors(p: np.ndarray, hertz: np.ndarray, inner: np.ndarray, p0: float) -> str:
    e = (p[inner] - hertz[inner]) / p0
    return (f"RMS {100 * np.sqrt(np.mean(e**2)):5.2f} %  largest {100 * np.abs(e).max():5.2f} %"
            f"  peak {100 * (p.max() / p0 - 1):+6.2f} %")


def report(name: str, sol: df.Solution, r: np.ndarray, a: float, p0: float, inner_r: float):
    hertz = p0 * np.sqrt(np.maximum(1 - r**2 / a**2, 0.0))
    inner = r < inner_r * a
    smooth = sol.smoothed_pressure()
    if sol.comm.rank == 0:
        print(f"{name} ({int(inner.sum())} nodes)")
        print(f"  force / lumped area: {errors(sol.contact.pressure, hertz, inner, p0)}")
        print(f"  smoothed           : {errors(smooth, hertz, inner, p0)}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--h2d", type=float, nargs="*", default=[0.2, 0.1, 0.05])
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    mesh = df.build_mesh(sphere_on_block, 0.15, 0.25, comm=comm)
    sol = df.solve(sphere_problem(mesh)[0], comm=comm, rtol=1e-9)
    a3 = (3 * F3 * R3 / (4 * E_STAR)) ** (1 / 3)
    report("sphere on a block, tetrahedra h 0.15 / 0.25", sol,
           np.linalg.norm(sol.contact.x[:, :2], axis=1), a3, 3 * F3 / (2 * np.pi * a3**2), 0.8)
    for h in args.h2d:
        mesh = df.build_mesh(disk_on_block, h, 1.7 * h, comm=comm)
        problem = df.ContactProblem(
            mesh, df.Elasticity(E, NU, tractions={"load": (0.0, -P / 2 / R)}),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
            contact=[df.Mortar("disk_contact", "block_contact")], decomposition=df.Parts(4))
        sol = df.solve(problem, comm=comm, rtol=1e-10)
        report(f"2D disk on a block, h {h} / {1.7 * h:.3g}", sol, sol.contact.x[:, 0], A, P0, 0.9)


if __name__ == "__main__":
    main()
