"""3D Tresca friction: MPGP 'tangent' (the default) against 'interior' and frictionless.

MPGP with curved faces ('tangent') against the published MPGP ('interior') and the
frictionless solve, on the two stacked blocks of ``demos/demo_tresca3d.py`` (E = 1, ν = 0.3,
top displaced by (0.02, 0.01, −0.02), g = 0.0075, Parts(2) per block) for growing n.

Run: ``python bench/friction3d_mpgp.py`` (``--help``). Writes
``output/bench/friction3d_mpgp.md``. The MPGP variant is chosen by replacing the class
``MPGP`` that the FETI driver makes SMALBE's inner solver from
(``dolfinx_feti.drivers.qp_solve.MPGP``, looked up at each solve). Each row checks that the
variant reached the solver: the two friction columns must differ in their counts or the
bench stops. (Until this check, the bench replaced ``dolfinx_feti.qp.smalbe.INNER['mpgp']``,
which only the function form ``smalbe()`` reads: both columns were the default 'tangent'.)
"""

from __future__ import annotations

import argparse
import functools
import importlib
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

# the module that makes the FETI solve's QP solvers (imported by name: a package attribute
# of the same name may be a function)
qp_solve = importlib.import_module("dolfinx_feti.drivers.qp_solve")

ROOT = Path(__file__).resolve().parent.parent
SHIFT = (0.02, 0.01, -0.02)


def main() -> None:
    """Sweep n and rtol and write the table."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=str, default="4,6,8,10", help="elements per unit length")
    parser.add_argument("--rtol", type=str, default="1e-6,1e-8")
    parser.add_argument("--g", type=float, default=0.0075)
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/friction3d_mpgp.md")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    plain = qp_solve.MPGP
    lines = [f"3D blocks, Tresca g = {args.g}, Parts(2) per block, {comm.size} rank(s); "
             "F-multiplications (SMALBE outer iterations), seconds", "",
             "| n | contact nodes | rtol | frictionless | MPGP 'interior' | MPGP 'tangent' | "
             "slipping |", "|---|---|---|---|---|---|---|"]
    for n in (int(v) for v in args.n.split(",")):
        mesh = df.build_mesh(meshes.blocks3d, n=n, comm=comm)
        for rtol in (float(v) for v in args.rtol.split(",")):
            cells, counts = [], []
            for friction, face in ((None, None), (df.Tresca(args.g), "interior"),
                                   (df.Tresca(args.g), "tangent")):
                qp_solve.MPGP = plain if face is None else functools.partial(plain, face=face)
                problem = df.ContactProblem(
                    mesh, df.Elasticity(1.0, 0.3),
                    dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=SHIFT)],
                    contact=[df.NodeToNode("contact_upper", "contact_lower",
                                           friction=friction)],
                    decomposition=df.Parts(2))
                t0 = time.perf_counter()
                sol = df.solve(problem, comm=comm, rtol=rtol, max_it=50000)
                r = sol.report
                counts.append((r.hessian_mults, r.outer_iterations, r.iterations))
                cells.append(f"{r.hessian_mults} ({r.outer_iterations}), "
                             f"{time.perf_counter() - t0:.2f} s"
                             + ("" if r.converged else " NOT CONVERGED"))
                slipping = (np.mean(sol.contact.state == df.ContactData.SLIP)
                            if friction is not None else 0.0)
            qp_solve.MPGP = plain
            if counts[1] == counts[2]:
                raise RuntimeError("MPGP 'interior' and 'tangent' gave the same counts: the "
                                   "variant did not reach the solver")
            lines.append(f"| {n} | {sol.contact.node.size} | {rtol:g} | " + " | ".join(cells)
                         + f" | {100 * slipping:.0f} % |")
            if comm.rank == 0:
                print(lines[-1], flush=True)
    if comm.rank == 0:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("\n".join(lines) + "\n")
        print("\n".join(lines))


if __name__ == "__main__":
    main()
