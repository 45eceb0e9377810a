"""QP solvers for FETI: CG, MPRGP (box), MPGP (box and discs) and SMALBE-M (+ equalities).

Only NumPy, SciPy, petsc4py and mpi4py are used: vectors are PETSc Vecs (possibly distributed),
operators PETSc Mats (AIJ or python shells), equality constraints small and replicated.
"""

from .cg import cg
from .discs import Discs, SeparableSet
from .equality import (
    EqualityConstraint,
    OrthonormalConstraint,
    Projector,
    RowBlockConstraint,
    homogenize,
    orthonormalize,
    penalized_operator,
    projected_operator,
)
from .mpgp import mpgp
from .mprgp import mprgp
from .norm import NormEstimate, estimate_norm
from .precond import Preconditioner, ProjectedPreconditioner
from .result import ConvergedReason, QPResult
from .shell import python_shell
from .smalbe import smalbe

__all__ = [
    "ConvergedReason",
    "Discs",
    "EqualityConstraint",
    "NormEstimate",
    "OrthonormalConstraint",
    "Preconditioner",
    "ProjectedPreconditioner",
    "Projector",
    "QPResult",
    "RowBlockConstraint",
    "SeparableSet",
    "cg",
    "estimate_norm",
    "homogenize",
    "mpgp",
    "mprgp",
    "orthonormalize",
    "penalized_operator",
    "projected_operator",
    "python_shell",
    "smalbe",
]
