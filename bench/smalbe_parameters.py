"""SMALBE-M's penalty ρ and initial M on three problems: outer iterations and F-multiplications.

Writes ``output/bench/smalbe_parameters.md``. Run: ``python bench/smalbe_parameters.py``.
ρ and M are relative to ||PFP|| (the reference implementation's defaults are ρ = 1.1, M = 100).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import ufl
from mpi4py import MPI

import dolfinx_feti as df

ROOT = Path(__file__).resolve().parent.parent


def problems() -> dict[str, df.ContactProblem]:
    """B1 (n = 16, 4×4 grid per membrane), 2D Hertz (4 parts per body), 3D blocks (2 parts)."""
    b1 = df.read_gmsh(ROOT / "meshes/membranes_16.msh")

    def f(x):
        return ufl.conditional(ufl.lt(x[0], 1.0), ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0),
                               ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0))

    grid = df.ByFunction(lambda m: (np.floor(m[:, 0] / 0.25)
                                    + 100 * np.floor(m[:, 1] / 0.25)).astype(np.int64))
    hertz = df.read_gmsh(ROOT / "meshes/hertz2d.msh")
    blocks = df.read_gmsh(ROOT / "meshes/blocks3d.msh")
    return {
        "B1 n=16, 32 subdomains": df.ContactProblem(
            b1, df.Poisson(source=f), dirichlet=[df.Dirichlet("dirichlet")],
            contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=grid),
        "Hertz 2D, Parts(4)": df.ContactProblem(
            hertz, df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -10.0 / 16)}),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
            contact=[df.NodeToNode("disk_contact", "block_contact")], decomposition=df.Parts(4)),
        "3D blocks, Parts(2)": df.ContactProblem(
            blocks, df.Elasticity(1000.0, 0.3, tractions={"top": (0.0, 0.0, -1.0)}),
            dirichlet=[df.Dirichlet("bottom")],
            contact=[df.NodeToNode("contact_upper", "contact_lower")], decomposition=df.Parts(2)),
    }


def main() -> None:
    """Sweep (ρ, M) × rtol and write the table."""
    settings = [(1.1, 100.0), (1.1, 1.0), (10.0, 1.0), (10.0, 0.1), (100.0, 1.0), (10.0, 10.0)]
    lines = ["| problem | ρ/‖PFP‖ | M/‖PFP‖ | rtol | converged | outer | F-mults |",
             "|---|---|---|---|---|---|---|"]
    for name, prob in problems().items():
        for rho, M in settings:
            for rtol in (1e-6, 1e-10):
                r = df.solve(prob, rtol=rtol, smalbe_rho=rho, smalbe_M=M, max_outer=500).report
                lines.append(f"| {name} | {rho} | {M} | {rtol:.0e} | {r.converged} | "
                             f"{r.outer_iterations} | {r.hessian_mults} |")
    if MPI.COMM_WORLD.rank == 0:
        out = ROOT / "output/bench/smalbe_parameters.md"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text("\n".join(lines) + "\n")
        print("\n".join(lines))


if __name__ == "__main__":
    main()
