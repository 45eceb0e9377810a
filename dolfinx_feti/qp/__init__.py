"""QP solvers for FETI: CG, MPRGP (box), MPGP (box and discs) and SMALBE-M (+ equalities).

Only NumPy, SciPy, petsc4py and mpi4py are used: vectors are PETSc Vecs (possibly distributed),
operators PETSc Mats (AIJ or python shells), equality constraints small and replicated.

The solvers are objects (:class:`CG`, :class:`MPGP`, :class:`MPRGP`, :class:`SMALBE`, all
:class:`QPSolver`), set up once and applied to any :class:`QP` by ``solve(qp, x)``; the
functions ``cg``, ``mpgp``, ``mprgp``, ``smalbe`` are their one-call forms.
"""

from .cg import CG, cg
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
from .mpgp import MPGP, mpgp
from .mprgp import MPRGP, mprgp
from .norm import NormEstimate, estimate_norm
from .precond import Preconditioner, ProjectedPreconditioner
from .problem import QP
from .result import ConvergedReason, QPResult
from .shell import python_shell
from .smalbe import SMALBE, Absolute, smalbe
from .solver import QPSolver
from .stopping import MaxGradientTest

__all__ = [
    "CG",
    "MPGP",
    "MPRGP",
    "QP",
    "SMALBE",
    "Absolute",
    "ConvergedReason",
    "Discs",
    "EqualityConstraint",
    "MaxGradientTest",
    "NormEstimate",
    "OrthonormalConstraint",
    "Preconditioner",
    "ProjectedPreconditioner",
    "Projector",
    "QPResult",
    "QPSolver",
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
