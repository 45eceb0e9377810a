"""SMALBE-M's penalty ρ and initial M on three problems: outer iterations and F-multiplications.

Writes ``output/bench/smalbe_parameters.md``. Run: ``python bench/smalbe_parameters.py``.
ρ and M are relative to ||PFP|| (the reference implementation's defaults are ρ = 1.1, M = 100).
"""

from __future__ import annotations

import sys
from pathlib import Path

from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parent))
import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def problems() -> dict[str, df.ContactProblem]:
    """B1 (n = 16, 4×4 grid per membrane), 2D Hertz (4 parts per body), 3D blocks (2 parts)."""
    return {
        "B1 n=16, 32 subdomains": P.b1(16, 0.25),
        "Hertz 2D, Parts(4)": P.hertz2d(4),
        "3D blocks, Parts(2)": P.blocks3d(4, 2, sides=False),
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
