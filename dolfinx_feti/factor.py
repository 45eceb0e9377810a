"""The sparse Cholesky packages that the option ``factor`` names, and the default among them.

The subdomain matrices (K⁺) and the dual matrix of the stiffness scaling are factored once and
solved with once or twice per F-multiplication, so the solve time counts more than the
factorization time. Measured on the subdomain matrices of the test problems
(``python bench/factor_packages.py``, docs/solvers.md): CHOLMOD, where PETSc has it (Debian's
PETSc 3.18 beside DOLFINx 0.5.2), factors fastest and solves as fast as the others or nearly;
PETSc's own Cholesky (nested-dissection ordering) solves 2-9x faster than MUMPS and is the
default where CHOLMOD is missing (the PETSc 3.25 of DOLFINx 0.11's wheel); MUMPS, built for
distributed matrices, pays a per-solve overhead that dominates on subdomain-sized matrices,
but factors large 3D subdomains fastest (``factor="mumps"`` for few large 3D subdomains).
"""

from __future__ import annotations

import functools

from petsc4py import PETSc

from .errors import InputError

#: Values of the option ``factor``, best first (the first one available is the default).
FACTORS = ("cholmod", "petsc", "mumps")


def set_cholesky(pc: PETSc.PC, factor: str) -> None:
    """Make ``pc`` a Cholesky factorization by the package ``factor``.

    PETSc's own Cholesky orders the matrix by nested dissection (its default; the benchmark
    shows the other orderings).
    """
    pc.setType("cholesky")
    pc.setFactorSolverType(factor)


@functools.cache
def available_factors() -> tuple[str, ...]:
    """The packages of :data:`FACTORS` that this PETSc can use for a sequential Cholesky."""
    return tuple(f for f in FACTORS if _works(f))


def _works(factor: str) -> bool:
    """Whether a Cholesky factorization of a 2×2 SPD matrix by ``factor`` sets up."""
    A = PETSc.Mat().createAIJ(size=(2, 2), nnz=2, comm=PETSc.COMM_SELF)
    A.setValues([0, 1], [0, 1], [2.0, -1.0, -1.0, 2.0])
    A.assemble()
    A.setOption(PETSc.Mat.Option.SPD, True)
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    try:
        ksp.setOperators(A)
        ksp.setType("preonly")
        set_cholesky(ksp.getPC(), factor)
        ksp.setUp()
        return True
    except PETSc.Error:
        return False
    finally:
        ksp.destroy()
        A.destroy()


def default_factor() -> str:
    """The best package this PETSc has (see the module docstring)."""
    available = available_factors()
    if not available:  # PETSc's own Cholesky is always built in: this would be a broken PETSc
        raise InputError("no sparse Cholesky package works in this PETSc (tried "
                         f"{', '.join(FACTORS)})")
    return available[0]


def check_factor(factor: str) -> None:
    """Raise InputError unless ``factor`` names a package of this PETSc."""
    if factor not in FACTORS:
        raise InputError(f"factor must be one of 'cholmod', 'mumps', 'petsc', got {factor!r}")
    if factor not in available_factors():
        petsc = ".".join(str(v) for v in PETSc.Sys.getVersion())
        raise InputError(f"factor {factor!r} is not available in this PETSc ({petsc}); "
                         f"available: {', '.join(available_factors())}")


__all__ = ["FACTORS", "available_factors", "check_factor", "default_factor", "set_cholesky"]
