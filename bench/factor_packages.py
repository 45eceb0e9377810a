"""Sparse Cholesky packages for the subdomain K⁺: factorization time and time per F-multiplication.

Run: ``python bench/factor_packages.py`` (3D stacked blocks, n = 16, 1 and 4 parts per block).
"""

from __future__ import annotations

import dolfinx_feti as df
from dolfinx_feti import meshes


def main() -> None:
    """Print one line per (decomposition, package)."""
    mesh = df.build_mesh(meshes.blocks3d, 16)
    print("| parts per block | package | primal dofs | subdomains | factorization [s] | "
          "ms per F-mult |")
    print("|---|---|---|---|---|---|")
    for parts in (1, 4):
        prob = df.ContactProblem(
            mesh, df.Elasticity(1000.0, 0.3, tractions={"top": (0.0, 0.0, -1.0)}),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sides_upper", components=[0, 1])],
            contact=[df.NodeToNode("contact_upper", "contact_lower")],
            decomposition=df.Parts(parts))
        for factor in ("cholmod", "mumps", "petsc"):
            r = df.solve(prob, rtol=1e-8, factor=factor).report
            t = r.timings
            print(f"| {parts} | {factor} | {r.sizes['primal']} | {r.sizes['subdomains']} | "
                  f"{t['factorization']:.2f} | {1e3 * t['iterations'] / r.hessian_mults:.1f} |")


if __name__ == "__main__":
    main()
