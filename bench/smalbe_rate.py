"""The outer-loop rate of SMALBE on B1: how fast ||G̃x|| falls per outer iteration.

With the inner problems solved tightly (M = 0.01 ||PFP||) the outer loop is the exact
augmented-Lagrangian iteration, whose rate depends on ρ/||PFP|| and on the problem only. For
ρ ∈ {1.1, 10, 100} ||PFP|| and H/h = 8 with 128 and 512 subdomains it prints the geometric
mean of ||G̃x_{k+1}|| / ||G̃x_k|| over the outer iterations, and c in the fit
rate = 1 / (1 + c ρ/||PFP||). Writes ``output/bench/smalbe_rate.md``.

Run: ``python bench/smalbe_rate.py`` (about 20 s).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    """Sweep ρ at two numbers of subdomains and write the table."""
    rows = []
    for H in (1 / 8, 1 / 16):
        problem = P.b1(P.elements_per_unit(H, 8), H)
        for rho in (1.1, 10.0, 100.0):
            r = df.solve(problem, rtol=1e-6, smalbe_rho=rho, smalbe_M=0.01).report
            dx = np.array([h["Dx"] for h in r.extra["history"]])
            # the last step is cut by the stopping test; skip it when there are others
            steps = dx[1:] / dx[:-1]
            steps = steps[:-1] if steps.size > 1 else steps
            rate = float(np.exp(np.mean(np.log(steps)))) if steps.size else float("nan")
            c = (1.0 / rate - 1.0) / rho
            rows.append([r.sizes["subdomains"], rho, r.outer_iterations, r.hessian_mults,
                         f"{rate:.3f}", f"{c:.2f}"])
            if P.is_root():
                print(rows[-1], flush=True)
    if P.is_root():
        md = ["# SMALBE outer-loop rate on B1 (H/h = 8, M = 0.01 ||PFP||, rtol 1e-6)", "",
              f"Machine: {P.machine()}. Code: {P.git_state()}.", "",
              P.md_table(["subdomains", "ρ/‖PFP‖", "outer", "F-mults",
                          "mean ‖G̃x‖ ratio per outer", "c in 1/(1 + c ρ/‖PFP‖)"], rows), ""]
        out = ROOT / "output/bench/smalbe_rate.md"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text("\n".join(md) + "\n")
        print("\n".join(md))


if __name__ == "__main__":
    main()
