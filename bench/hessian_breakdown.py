"""Where the time of one Hessian multiplication P F P goes.

Splits one application of the projected dual operator into the subdomain forward/backward
solves (one block-diagonal CHOLMOD factor per rank), the two sparse products with B, the rest
of the K⁺ application (copying in and out, zeroing the fixing dofs), and the projector.
Run: ``python bench/hessian_breakdown.py``.
"""

from __future__ import annotations

import time

import numpy as np
import ufl
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes
from dolfinx_feti.qp import Projector, RowBlockConstraint, orthonormalize, projected_operator


def b1(n: int, H: float) -> df.ContactProblem:
    mesh = df.build_mesh(meshes.membranes, n)
    k = int(round(2 / H))

    def f(x):
        return ufl.conditional(ufl.lt(x[0], 1.0), ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0),
                               ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0))

    return df.ContactProblem(
        mesh, df.Poisson(source=f), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")],
        decomposition=df.ByFunction(lambda m: (np.floor(m[:, 0] / H)
                                               + k * np.floor(m[:, 1] / H)).astype(np.int64)))


def blocks(n: int, parts: int) -> df.ContactProblem:
    mesh = df.build_mesh(meshes.blocks3d, n)
    return df.ContactProblem(
        mesh, df.Elasticity(1000.0, 0.3, tractions={"top": (0.0, 0.0, -1.0)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sides_upper", components=[0, 1])],
        contact=[df.NodeToNode("contact_upper", "contact_lower")], decomposition=df.Parts(parts))


def best(fn, repeat: int = 20) -> float:
    """Median wall time of ``fn()`` over ``repeat`` runs."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def breakdown(name: str, problem: df.ContactProblem) -> str:
    comm = MPI.COMM_WORLD
    qp = df.dual_qp(problem, comm)
    dec, feti = qp.dec, qp.feti
    ocon = orthonormalize(RowBlockConstraint(feti.Gt_local, comm), rhs=feti.e)
    A = projected_operator(feti.F, ocon)
    P = Projector(ocon)
    x = feti.d.duplicate()
    x.setRandom()
    y = x.duplicate()
    w, v = feti.B.createVecRight(), feti.B.createVecRight()
    w.setRandom()
    def solves_only():  # the sparse triangular solves alone, on the held vectors
        qp.primal.Kplus._chol.solve_in_place()

    t_pfp = best(lambda: A.mult(x, y))
    t_f = best(lambda: feti.F.mult(x, y))
    t_solve = best(solves_only)
    t_kplus = best(lambda: feti.apply_kplus(w, v))
    t_bt = best(lambda: feti.B.multTranspose(x, w))
    t_b = best(lambda: feti.B.mult(v, y))
    t_p = best(lambda: P.apply(x, y))
    dofs = feti.primal_size[1] / dec.num_subdomains
    overhead = t_pfp - t_solve
    return (f"| {name} | {feti.primal_size[1]} | {dec.num_subdomains} | {dofs:.0f} | "
            f"{1e3 * t_pfp:.2f} | {1e3 * t_solve:.2f} | {1e3 * (t_kplus - t_solve):.2f} | "
            f"{1e3 * (t_bt + t_b):.2f} | {1e3 * 2 * t_p:.2f} | {1e3 * (t_pfp - t_f):.2f} | "
            f"{100 * overhead / t_pfp:.1f} % |")


def main() -> None:
    """Print the table."""
    print("| problem | primal dofs | subdomains | dofs/subdomain | P F P [ms] | solves [ms] | "
          "K⁺ copies [ms] | B, Bᵀ [ms] | 2 projections [ms] | PFP − F [ms] | not solves |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, prob in [("B1 n=128, H=1/4", b1(128, 0.25)), ("B1 n=256, H=1/8", b1(256, 0.125)),
                       ("B1 n=512, H=1/4", b1(512, 0.25)),
                       ("3D blocks n=16, 2×2 parts", blocks(16, 2)),
                       ("3D blocks n=16, 2×8 parts", blocks(16, 8))]:
        print(breakdown(name, prob), flush=True)


if __name__ == "__main__":
    main()
