"""The outer-loop rate of SMALBE on B1: how fast ||G̃x|| falls per outer iteration.

With the inner problems solved tightly (M = 0.01 ||PFP||) the outer loop is the exact
augmented-Lagrangian iteration, whose rate depends on ρ/||PFP|| and on the problem only. For
ρ ∈ {1.1, 10, 100} ||PFP|| and H/h = 8 with 128 and 512 subdomains it prints the geometric
mean of ||G̃x_{k+1}|| / ||G̃x_k|| over the outer iterations, and c in the fit
rate = 1 / (1 + c ρ/||PFP||). Then, on B1 with 32 subdomains (small enough for dense
matrices), the spectrum of the outer iteration's contraction (I + ρS)⁻¹ at the converged
active set (S = G̃_F A_FF⁻¹ G̃_Fᵀ, computed as I − ρ G̃_F H_FF⁻¹ G̃_Fᵀ with H = PFP + ρG̃ᵀG̃):
the few eigenvalues away from 0 are what the plain update pays for in every outer
iteration and the Anderson acceleration removes. Writes ``output/bench/smalbe_rate.md``.

Run: ``python bench/smalbe_rate.py`` (about 30 s).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parent))
import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402
from dolfinx_feti.qp import smalbe  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def contraction_spectrum(H: float = 0.25, ratio: int = 8, rho: float = 1.1) -> np.ndarray:
    """Eigenvalues of the outer contraction at the solution of B1 (dense; one rank only)."""
    qp = df.dual_qp(P.b1(P.elements_per_unit(H, ratio), H))
    n = qp.b.getSize()
    e, y = qp.start(), qp.start()
    A = np.zeros((n, n))
    D = np.zeros((qp.constraint.m, n))
    for j in range(n):
        e.set(0.0)
        e.array[j] = 1.0
        qp.A.mult(e, y)
        A[:, j] = y.array_r
        D[:, j] = qp.constraint.mult(e)
    x = qp.start()
    smalbe(qp.A, qp.b, qp.constraint, x, lb=qp.lb, rtol=1e-10, norm_A=qp.norm_A,
           eq_scale=qp.norm_A, rho=rho * qp.norm_A, M=qp.norm_A, max_outer=1000)
    lb = qp.lb.array_r
    free = ~(np.isfinite(lb) & (x.array_r <= lb + 1e-12))
    r = rho * qp.norm_A
    Hff = (A + r * D.T @ D)[np.ix_(free, free)]
    T = np.eye(D.shape[0]) - r * D[:, free] @ np.linalg.solve(Hff, D[:, free].T)
    return np.sort(np.linalg.eigvalsh(0.5 * (T + T.T)))[::-1]


def main() -> None:
    """Sweep ρ at two numbers of subdomains and write the table."""
    rows = []
    for H in (1 / 8, 1 / 16):
        problem = P.b1(P.elements_per_unit(H, 8), H)
        for rho in (1.1, 10.0, 100.0):
            r = df.solve(problem, rtol=1e-6, smalbe_rho=rho, smalbe_M=0.01,
                         smalbe_acceleration="none").report
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
    spectrum = contraction_spectrum() if MPI.COMM_WORLD.size == 1 else None
    if P.is_root():
        md = ["# SMALBE outer-loop rate on B1 (H/h = 8, M = 0.01 ||PFP||, rtol 1e-6, plain "
              "multiplier update)", "",
              f"Machine: {P.machine()}. Code: {P.git_state()}.", "",
              P.md_table(["subdomains", "ρ/‖PFP‖", "outer", "F-mults",
                          "mean ‖G̃x‖ ratio per outer", "c in 1/(1 + c ρ/‖PFP‖)"], rows), ""]
        if spectrum is not None:
            md += ["Contraction (I + ρS)⁻¹ of the outer iteration at the solution, B1 with 32 "
                   "subdomains (H/h = 8, ρ = 1.1‖PFP‖): its largest eigenvalues "
                   + ", ".join(f"{v:.3g}" for v in spectrum[:4])
                   + f"; {int(np.sum(spectrum > 1e-12))} of {spectrum.size} above 1e-12.", ""]
        out = ROOT / "output/bench/smalbe_rate.md"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text("\n".join(md) + "\n")
        print("\n".join(md))


if __name__ == "__main__":
    main()
