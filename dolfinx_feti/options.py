"""Solver options: explicit keyword arguments, overridable from the PETSc options database.

Every field ``name`` can be set on the command line as ``-feti_<name> value`` (e.g.
``-feti_rtol 1e-8 -feti_mprgp_gamma 1``); command-line values win over the Python defaults but
not over keyword arguments given explicitly to :func:`dolfinx_feti.solve`.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields

from petsc4py import PETSc

from .errors import InputError
from .factor import check_factor, default_factor


def option_value(tokens: Sequence[str], i: int) -> str | None:
    """The value of the option at ``tokens[i]``, or None if it has none.

    That is the next token, unless there is none or it is itself an option (it starts with "-"
    and is not a number such as ``-1e-3``).
    """
    value = tokens[i + 1] if i + 1 < len(tokens) else None
    if value is not None and value.startswith("-"):
        try:
            float(value)
        except ValueError:
            return None
    return value


def insert_command_line(argv: list[str] | None = None, prefix: str = "-feti_") -> None:
    """Put ``-feti_*`` command-line options into PETSc's options database.

    DOLFINx initializes petsc4py without ``sys.argv``, so PETSc never sees them otherwise.
    Values already in the database are kept. A flag with no value is stored as "1".
    """
    argv = sys.argv[1:] if argv is None else argv
    opts = PETSc.Options()
    for i, token in enumerate(argv):
        if not token.startswith(prefix):
            continue
        value = option_value(argv, i)
        name = token[1:]
        if not opts.hasName(name):
            opts.setValue(name, "1" if value is None else value)


@dataclass
class SolverOptions:
    """Parameters of the FETI solve.

    Attributes:
        rtol: Stop when ||g^P|| <= rtol ||b|| (b the projected dual linear term).
        eq_rtol: Stop only when also ||Gλ − e|| <= eq_rtol ||b|| / ||PFP||; default ``rtol``.
        max_it: Budget of inner iterations (all outer iterations together).
        max_outer: Budget of SMALBE outer iterations. Outer iterations with no inner work cost
            no F-multiplication; 2D elasticity with 512 subdomains needs 166 (docs/benchmarks.md).
        factor: Sparse Cholesky package for the subdomain matrices ("cholmod", "mumps", "petsc");
            a package this PETSc lacks is refused. Default: the best this PETSc has (CHOLMOD,
            else PETSc's own; measured in docs/solvers.md).
        mprgp_gamma: MPRGP's proportioning parameter Γ.
        mprgp_expansion: "fixed", "optimal" or "projcg".
        mprgp_alpha: Expansion step length: "fixed" (ᾱ = 1.95/||A||) or "bb" (Barzilai–Borwein,
            accepted only if the energy decreases; needs mprgp_expansion "fixed").
        preconditioner: "none", "lumped" (B K Bᵀ, the default) or "dirichlet" (B S Bᵀ),
            applied projected in CG and in the face (free set) in MPRGP.
        preconditioner_scaling: "stiffness" (the default; Rixen–Farhat: Z B Δ K Δ Bᵀ Z with
            Δ = diag(K)⁻¹, Z = (B Δ Bᵀ)⁻¹) or "multiplicity" (the orthonormal rows of B as they
            are). Where B Δ Bᵀ is singular (redundant rows) the preconditioner falls back to
            multiplicity scaling with a warning. Measured in docs/solvers.md.
        qp: "auto" (CG / SMALBE / MPRGP as the problem needs) or "penalty" (the dual penalty
            FETI-NCG_ρ: MPRGP on PFP + ρQ, the equality only approximated: ||Gλ|| = O(1/ρ)).
        penalty_rho: ρ of qp="penalty", relative to ||PFP||.
        smalbe_rho: SMALBE's penalty ρ relative to ||PFP||.
        smalbe_M: SMALBE's initial M relative to ||PFP||. The reference value 100 stalls the
            outer loop (136 outer iterations on the 3D two-block problem); 1 needs 1-28 outer
            iterations and the fewest F-multiplications on B1, 2D Hertz and the 3D blocks
            (see docs/solvers.md).
        smalbe_eta: SMALBE's η relative to ||b|| (None: the solver's default).
        smalbe_beta: SMALBE's divisor of M.
        smalbe_acceleration: "none" (the plain multiplier update μ += ρG̃λ of the theory) or
            "anderson" (Anderson acceleration of that update, memory reset when the active set
            changes; see docs/solvers.md).
        smalbe_depth: Memory of the Anderson acceleration (number of past updates).
        norm_rtol: Relative tolerance of the Lanczos estimate of ||PFP||.
        verbose: 0 quiet, 1 one line per phase, 2 also every iteration (rank 0 only).
    """

    rtol: float = 1e-6
    eq_rtol: float | None = None
    max_it: int = 5000
    max_outer: int = 1000
    factor: str = field(default_factory=default_factor)
    mprgp_gamma: float = 1.0
    mprgp_expansion: str = "fixed"
    mprgp_alpha: str = "fixed"
    preconditioner: str = "lumped"
    preconditioner_scaling: str = "stiffness"
    qp: str = "auto"
    penalty_rho: float = 1e3
    smalbe_rho: float = 1.1
    smalbe_M: float = 1.0
    smalbe_eta: float | None = None
    smalbe_beta: float = 2.0
    smalbe_acceleration: str = "anderson"
    smalbe_depth: int = 3
    norm_rtol: float = 1e-4
    verbose: int = 0

    @classmethod
    def create(cls, prefix: str = "feti_", **kwargs) -> SolverOptions:
        """Defaults, then the PETSc options database under ``prefix``, then ``kwargs``."""
        names = {f.name for f in fields(cls)}
        unknown = set(kwargs) - names
        if unknown:
            raise InputError(f"unknown solver options {sorted(unknown)}; known: {sorted(names)}")
        insert_command_line(prefix=f"-{prefix}")
        opts = PETSc.Options(prefix)
        values = {}
        for f in fields(cls):
            if not opts.hasName(f.name):
                continue
            kind = str(f.type)
            try:
                if "int" in kind:
                    values[f.name] = opts.getInt(f.name)
                elif "float" in kind:
                    values[f.name] = opts.getReal(f.name)
                else:
                    values[f.name] = opts.getString(f.name)
            except PETSc.Error:
                raise InputError(f"PETSc option -{prefix}{f.name} {opts.getString(f.name)!r}: "
                                 f"expected {'an integer' if 'int' in kind else 'a number'}"
                                 ) from None
        values.update({k: v for k, v in kwargs.items() if v is not None})
        out = cls(**values)
        out.validate()
        return out

    def replace(self, **kwargs) -> SolverOptions:
        """A validated copy with some fields changed (unknown names are an InputError)."""
        names = {f.name for f in fields(self)}
        unknown = set(kwargs) - names
        if unknown:
            raise InputError(f"unknown solver options {sorted(unknown)}; known: {sorted(names)}")
        out = dataclasses.replace(self, **{k: v for k, v in kwargs.items() if v is not None})
        out.validate()
        return out

    def validate(self) -> None:
        """Raise InputError for impossible values."""
        for name in ("rtol", "norm_rtol", "mprgp_gamma"):
            v = getattr(self, name)
            if not v > 0:
                raise InputError(f"solver option {name} must be positive, got {v}")
        if self.eq_rtol is not None and not self.eq_rtol > 0:
            raise InputError(f"solver option eq_rtol must be positive, got {self.eq_rtol}")
        if self.max_it < 1 or self.max_outer < 1:
            raise InputError("solver options max_it and max_outer must be >= 1")
        check_factor(self.factor)
        if self.mprgp_expansion not in ("fixed", "optimal", "projcg"):
            raise InputError("mprgp_expansion must be 'fixed', 'optimal' or 'projcg', got "
                             f"{self.mprgp_expansion!r}")
        if self.mprgp_alpha not in ("fixed", "bb"):
            raise InputError(f"mprgp_alpha must be 'fixed' or 'bb', got {self.mprgp_alpha!r}")
        if self.mprgp_alpha == "bb" and self.mprgp_expansion != "fixed":
            raise InputError("mprgp_alpha 'bb' needs mprgp_expansion 'fixed'")
        if self.preconditioner not in ("none", "lumped", "dirichlet"):
            raise InputError("preconditioner must be 'none', 'lumped' or 'dirichlet', got "
                             f"{self.preconditioner!r}")
        if self.preconditioner_scaling not in ("multiplicity", "stiffness"):
            raise InputError("preconditioner_scaling must be 'multiplicity' or 'stiffness', got "
                             f"{self.preconditioner_scaling!r}")
        if self.qp not in ("auto", "penalty"):
            raise InputError(f"qp must be 'auto' or 'penalty', got {self.qp!r}")
        if not self.penalty_rho > 0:
            raise InputError(f"penalty_rho must be positive, got {self.penalty_rho}")
        if self.smalbe_beta <= 1:
            raise InputError(f"smalbe_beta must be > 1, got {self.smalbe_beta}")
        if self.smalbe_acceleration not in ("none", "anderson"):
            raise InputError("smalbe_acceleration must be 'none' or 'anderson', got "
                             f"{self.smalbe_acceleration!r}")
        if self.smalbe_depth < 1:
            raise InputError(f"smalbe_depth must be >= 1, got {self.smalbe_depth}")

    def to_dict(self) -> dict:
        """Plain dict (for the JSON report)."""
        return asdict(self)
