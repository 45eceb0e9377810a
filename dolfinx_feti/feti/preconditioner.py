"""The dual preconditioner a solve asks for, by name (option ``preconditioner``)."""

from __future__ import annotations

from .precond import DirichletPreconditioner, LumpedPreconditioner
from .precond_explicit import ExplicitDirichletPreconditioner


def make_preconditioner(kind: str, primal, factor: str | None = None,
                        scaling: str = "multiplicity", explicit: bool = False):
    """``"none"`` → None, ``"lumped"``, ``"dirichlet"`` (``scaling``: see the module).

    ``primal`` is a primal system (its ``preconditioner_operands()``) or the operands.
    ``explicit``: the Dirichlet preconditioner with its local blocks B_s S_s B_sᵀ formed once
    (:mod:`.precond_explicit`; with the explicit dual operator).
    """
    if kind == "none":
        return None
    operands = primal.preconditioner_operands() if hasattr(primal, "preconditioner_operands") \
        else primal
    if kind == "lumped":
        return LumpedPreconditioner(operands, scaling, factor)
    if kind == "dirichlet" and explicit:
        return ExplicitDirichletPreconditioner(operands, factor, scaling)
    if kind == "dirichlet":
        return DirichletPreconditioner(operands, factor, scaling)
    raise ValueError(f"unknown preconditioner {kind!r}: use 'none', 'lumped' or 'dirichlet'")



__all__ = ["make_preconditioner"]
