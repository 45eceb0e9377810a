"""Preconditioners for the QP solvers: a uniform, counting front end and SMALBE's inner one.

A preconditioner here is an approximation of the *inverse* of the Hessian, symmetric positive
(semi)definite, applied as ``y = M^{-1} x``. The solvers accept

- a PETSc Mat (``M.mult(x, y)``), e.g. an assembled approximate inverse or a python shell;
- any object with ``mult(x, y)`` (the same calling convention, no Mat needed);
- a PETSc PC (``pc.apply(x, y)``), e.g. a Jacobi or ILU PC set up on some matrix;
- a plain callable ``f(x, y)``.

It must not modify ``x`` and must fill ``y`` completely.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from petsc4py import PETSc

from .equality import EqualityConstraint


class Preconditioner:
    """Wraps any accepted preconditioner and counts its applications (``count``)."""

    def __init__(self, M) -> None:
        self.M = M
        if isinstance(M, Preconditioner):
            self._apply: Callable[[PETSc.Vec, PETSc.Vec], None] = M.apply  # both count
        elif isinstance(M, PETSc.PC):
            self._apply = M.apply
        elif hasattr(M, "mult"):
            self._apply = M.mult
        elif callable(M):
            self._apply = M
        else:
            raise TypeError("preconditioner: need a PETSc Mat or PC, an object with "
                            f"mult(x, y), or a callable f(x, y); got {type(M).__name__}")
        self.count = 0

    def apply(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """Set ``y = M^{-1} x``."""
        self._apply(x, y)
        self.count += 1


class ProjectedPreconditioner:
    """``y = P M^{-1} P x + (1/rho) Q x`` with ``Q = D^T D``, ``P = I - Q`` (``D`` orthonormal).

    The natural preconditioner of SMALBE's inner Hessian ``H = A + rho D^T D`` when
    ``A = P A P`` (FETI: ``A = P F P``): ``H`` is block diagonal in ``Im P + Im D^T``, equal to
    ``P A P`` on ``Im P`` and to ``rho I`` on ``Im D^T``, so this operator is exact on
    ``Im D^T`` and is the classical projected preconditioner ``P M^{-1} P`` on ``Im P``.
    Symmetric positive (semi)definite whenever ``M^{-1}`` is. One application costs one
    ``M^{-1}`` and two products with ``D`` (two small ``Allreduce``), nothing with ``A``.

    Has ``mult(x, y)``, so it is itself an accepted preconditioner.

    Args:
        M: The preconditioner of ``A`` (anything :class:`Preconditioner` accepts).
        con: The equality constraint ``D`` with orthonormal rows.
        rho: The penalty (> 0).
    """

    def __init__(self, M, con: EqualityConstraint, rho: float) -> None:
        if not rho > 0:
            raise ValueError(f"ProjectedPreconditioner: rho must be positive, got {rho}")
        self.M = M if isinstance(M, Preconditioner) else Preconditioner(M)
        self.con, self.rho = con, float(rho)
        self._q: PETSc.Vec | None = None
        self._w: PETSc.Vec | None = None

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """Set ``y = P M^{-1} P x + (1/rho) Q x``."""
        if self._q is None or self._q.getSizes() != x.getSizes():
            self._q, self._w = x.duplicate(), x.duplicate()
        q, w = self._q, self._w
        self.con.mult_transpose(self.con.mult(x), q)  # q = Q x
        x.copy(w)
        w.axpy(-1.0, q)  # w = P x
        self.M.apply(w, y)  # y = M^{-1} P x
        dy = self.con.mult(y)
        self.con.mult_transpose(np.asarray(dy), w)
        y.axpy(-1.0, w)  # y = P M^{-1} P x
        y.axpy(1.0 / self.rho, q)
