"""Sparse direct solvers for the subdomain matrices: factorization time and time per solve.

For a few test problems this builds the matrices the library factors — K with its fixing dofs
replaced by identity rows (what K⁺ factors, all subdomains of the rank as one block-diagonal
matrix) and B diag(K)⁻¹ Bᵀ (the stiffness scaling of the default preconditioner) — and
factors each with every PETSc package of this build: Cholesky by CHOLMOD, MUMPS and PETSc's own
(with its orderings), and for comparison LU by MUMPS, SuperLU and SuperLU_DIST. It prints
(and writes) one table per matrix: factorization time (best of 3), time per solve (the mean of
``--solves`` solves, best of 3 batches) and the relative residual. The package that the option
``factor`` takes by default (:func:`dolfinx_feti.factor.default_factor`) was chosen from
these tables.

Run: ``python bench/factor_packages.py [--quick] [--out DIR]`` (one rank; writes
``DIR/factor_packages_<stack>.md``, by default ``output/bench``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

import problems
from dolfinx_feti import compat
from dolfinx_feti.factor import available_factors, default_factor
from dolfinx_feti.feti.kplus import choose_fixing_dofs
from dolfinx_feti.setup.stages import dual_qp

ROOT = Path(__file__).resolve().parents[1]
#: Without reordering a 3D matrix fills in completely: measured only up to this size.
NATURAL_MAX = 10000

#: (label, PC type, solver package, ordering or None for the package's own).
CANDIDATES = [
    ("cholmod", "cholesky", "cholmod", None),
    ("mumps", "cholesky", "mumps", None),
    ("petsc natural", "cholesky", "petsc", "natural"),
    ("petsc nd", "cholesky", "petsc", "nd"),
    ("petsc qmd", "cholesky", "petsc", "qmd"),
    ("petsc rcm", "cholesky", "petsc", "rcm"),
    ("mumps LU", "lu", "mumps", None),
    ("superlu LU", "lu", "superlu", None),
    ("superlu_dist LU", "lu", "superlu_dist", None),
]


def fixed_matrix(system) -> sp.csr_matrix:
    """K with the fixing dofs' rows and columns replaced by identity rows (what K⁺ factors)."""
    K, kernels = system.K, list(system.kernels)
    offsets = np.concatenate([[0], np.cumsum([R.shape[0] for R in kernels])])
    fixed = np.concatenate([choose_fixing_dofs(R) + o for R, o in zip(kernels, offsets,
                                                                       strict=False)])
    free = np.ones(K.shape[0], dtype=bool)
    free[fixed] = False
    keep = sp.diags(free.astype(float))
    A = (keep @ K @ keep + sp.diags((~free).astype(float))).tocsr()
    A.eliminate_zeros()
    return A


def scaling_matrix(system) -> sp.csr_matrix:
    """B diag(K)⁻¹ Bᵀ (serial)."""
    indptr, indices, data = system.B.getValuesCSR()
    B = sp.csr_matrix((data, indices, indptr), shape=system.B.getSize())
    return (B @ sp.diags(1.0 / system.K.diagonal()) @ B.T).tocsr()


def measure(A: sp.csr_matrix, pc_type: str, package: str, ordering: str | None,
            solves: int) -> tuple[float, float, float] | None:
    """(factorization s, solve s, relative residual), or None if this PETSc lacks the package."""
    A = A.tocsr()
    A.sort_indices()
    M = PETSc.Mat().createAIJ(size=A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                                 A.indices.astype(PETSc.IntType), A.data),
                              comm=PETSc.COMM_SELF)
    M.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    M.setOption(PETSc.Mat.Option.SPD, True)
    b, x = M.createVecs()
    b.array[:] = np.random.default_rng(0).standard_normal(A.shape[0])
    best = np.inf
    try:
        for _ in range(3):
            ksp = PETSc.KSP().create(PETSc.COMM_SELF)
            ksp.setOperators(M)
            ksp.setType("preonly")
            pc = ksp.getPC()
            pc.setType(pc_type)
            pc.setFactorSolverType(package)
            if ordering is not None:
                pc.setFactorOrdering(ordering)
            t = time.perf_counter()
            ksp.setUp()
            best = min(best, time.perf_counter() - t)
            if _ < 2:
                ksp.destroy()
    except PETSc.Error:
        return None
    ksp.solve(b, x)  # warm-up
    t_solve = np.inf
    for _ in range(3):  # the best of 3 batches: this machine is shared
        t = time.perf_counter()
        for _ in range(solves):
            ksp.solve(b, x)
        t_solve = min(t_solve, (time.perf_counter() - t) / solves)
    res = np.linalg.norm(A @ x.array_r - b.array_r) / np.linalg.norm(b.array_r)
    for obj in (ksp, M, b, x):
        obj.destroy()
    return best, t_solve, float(res)


def cases(quick: bool):
    """(name, problem) of the test problems measured."""
    if quick:
        return [("2D Hertz h = 0.05, Parts(4)", problems.hertz2d(parts=4)),
                ("3D blocks n = 8, Parts(1)", problems.blocks3d(8, parts=1))]
    return [("2D Hertz h = 0.05, Parts(4)", problems.hertz2d(parts=4)),
            ("B1 n = 128, 128 subdomains (H = 1/8)", problems.b1(128, 0.125)),
            ("3D blocks n = 16, Parts(1)", problems.blocks3d(16, parts=1)),
            ("3D blocks n = 16, Parts(4)", problems.blocks3d(16, parts=4))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two small problems only")
    parser.add_argument("--solves", type=int, default=20, help="solves timed per factor")
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench")
    args = parser.parse_args()
    if MPI.COMM_WORLD.size != 1:
        raise SystemExit("run this benchmark on one rank")
    stack = compat.version_label()
    lines = [f"# Sparse direct solvers, {stack}", "",
             f"Cholesky packages of this PETSc: {', '.join(available_factors())}; "
             f"default of the option `factor`: {default_factor()}.", ""]
    for name, problem in cases(args.quick):
        system = dual_qp(problem, MPI.COMM_SELF).primal  # the primal system that was dualized
        for what, A in (("K with fixing dofs (K⁺)", fixed_matrix(system)),
                        ("B diag(K)⁻¹ Bᵀ (stiffness scaling)", scaling_matrix(system))):
            lines += [f"## {name}: {what}, n = {A.shape[0]}, nnz = {A.nnz}", "",
                      "| solver | factorization [ms] | solve [ms] | residual |",
                      "|---|---|---|---|"]
            for label, pc_type, package, ordering in CANDIDATES:
                if ordering == "natural" and A.shape[0] > NATURAL_MAX:
                    lines.append(f"| {label} | not measured (n > {NATURAL_MAX}: minutes) | | |")
                    continue
                r = measure(A, pc_type, package, ordering, args.solves)
                lines.append(f"| {label} | not in this PETSc | | |" if r is None else
                             f"| {label} | {1e3 * r[0]:.3g} | {1e3 * r[1]:.3g} | {r[2]:.0e} |")
                print(lines[-1] if r is not None else f"| {label} | - |", flush=True)
            lines.append("")
    args.out.mkdir(parents=True, exist_ok=True)
    tag = compat.DOLFINX_VERSION.split(".post")[0].replace(".", "_")
    path = args.out / f"factor_packages_dolfinx{tag}.md"
    path.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"written to {path}")


if __name__ == "__main__":
    main()
