"""The QP the solvers take: ``min 1/2 x^T A x - b^T x`` over a constraint set and ``D x = 0``.

As PERMON's QP object: the Hessian (a PETSc Mat, AIJ or a python shell), the linear term, the
constraint set (PERMON's QPC: :class:`.box.Box` for bounds, :class:`.discs.SeparableSet` for
bounds and discs, None for no inequality), an optional equality constraint with orthonormal
rows (:mod:`.equality`), and what is known about ``A``: its norm and a preconditioner (an
approximate inverse). Nothing here knows of FETI: any NumPy/PETSc QP is one.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from petsc4py import PETSc

from .box import Box
from .discs import Discs, SeparableSet
from .equality import EqualityConstraint


@dataclass
class QP:
    """``min 1/2 x^T A x - b^T x`` s.t. ``x`` in ``constraints`` and ``eq x = 0``.

    Attributes:
        A: Symmetric positive semidefinite Hessian (PETSc Mat).
        b: Linear term (PETSc Vec; its layout is that of the unknowns).
        constraints: The inequality constraint set (:class:`.box.Box` or
            :class:`.discs.SeparableSet`, built on ``b``'s layout), or None for none.
        eq: Equality constraint ``D`` with orthonormal rows, or None.
        norm_A: ``||A||`` if known (else the solvers estimate it and count the products).
        preconditioner: An approximate inverse of ``A`` (a PETSc Mat or PC, an object with
            ``mult(x, y)`` or a callable ``f(x, y)``; see :mod:`.precond`), or None.
        operator_key: What names the operator for Krylov recycling (:mod:`.recycle`): None
            for ``(A,)``; SMALBE's inner QP ``(A, rho)`` (its shell ``A + rho DᵀD`` is made
            anew for each solve).
    """

    A: PETSc.Mat
    b: PETSc.Vec
    constraints: Box | SeparableSet | None = None
    eq: EqualityConstraint | None = None
    norm_A: float | None = None
    preconditioner: Any = None
    operator_key: tuple | None = None

    @classmethod
    def create(cls, A: PETSc.Mat, b: PETSc.Vec, *, lb=None, ub=None, discs: Discs | None = None,
               eq: EqualityConstraint | None = None, norm_A: float | None = None,
               preconditioner: Any = None) -> QP:
        """The QP with the constraint set of the bounds and discs (collective).

        Args:
            A: Hessian.
            b: Linear term.
            lb: Lower bound (Vec laid out like ``b``, scalar, or None for ``-inf``).
            ub: Upper bound (likewise; None for ``+inf``); infinite on disc entries.
            discs: :class:`.discs.Discs` on pairs of local entries, or None.
            eq: Equality constraint with orthonormal rows, or None.
            norm_A: ``||A||`` if known.
            preconditioner: Approximate inverse of ``A``, or None.

        Raises:
            ValueError: (on every rank) for infeasible or invalid bounds or discs.
        """
        if discs is not None:
            constraints: Box | SeparableSet | None = SeparableSet(lb, ub, discs, b)
        elif lb is not None or ub is not None:
            constraints = Box(lb, ub, b)
        else:
            constraints = None
        return cls(A, b, constraints, eq, norm_A, preconditioner)

    def child(self, **changes: Any) -> QP:
        """A QP with some fields changed (e.g. SMALBE's inner QP: new ``A``, ``b``, no ``eq``)."""
        return dataclasses.replace(self, **changes)


__all__ = ["QP"]
