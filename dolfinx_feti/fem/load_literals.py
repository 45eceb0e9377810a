"""Loads given as functions of x, compiled once: their numbers become runtime constants.

A traction ``t(x) = (q / (2 R), -P / (2 R) + m x[0])`` whose numbers change from one load case
to the next is, for UFL, a new expression each time: new literals, a new signature, a new form
to compile. Its *structure* does not change. :func:`literals` finds the float literals of the
expression, :func:`structure` is the expression with each literal replaced by its place (the
key of :mod:`~dolfinx_feti.fem.load_form`'s kept form), and :func:`with_constants` builds the
expression with runtime constants in the literals' places, created in that order, so that a new
case of the same structure sets the constants to :func:`literals`' values and assembles.

Integer literals (exponents, indices) stay literals: they are part of the structure.
"""

from __future__ import annotations

from collections.abc import Callable

import ufl
from ufl.constantvalue import FloatValue
from ufl.corealg.traversal import pre_traversal, unique_pre_traversal

from .. import compat
from .form_checks import check_finite_literals


def literals(expr) -> list[FloatValue]:
    """The distinct float literals of ``expr`` in pre-order (equal values are one literal)."""
    return [n for n in unique_pre_traversal(expr) if isinstance(n, FloatValue)]


def structure(expr, lits: list[FloatValue]) -> tuple:
    """``expr`` as a hashable tree with each float literal replaced by its place in ``lits``.

    Other terminals by their ``repr`` (a user's Function or Constant by its count: another
    object is another structure); operators by type and number of operands.
    """
    place = {lit: i for i, lit in enumerate(lits)}
    key = []
    for n in pre_traversal(expr):
        if isinstance(n, FloatValue):
            key.append(("literal", place[n]))
        elif n._ufl_is_terminal_:
            key.append(("terminal", type(n).__name__, n.ufl_shape)
                       if isinstance(n, ufl.SpatialCoordinate) else repr(n))
        else:
            key.append((type(n).__name__, len(n.ufl_operands)))
    return tuple(key)


def with_constants(expr, lits: list[FloatValue], mesh):
    """``expr`` with runtime constants on ``mesh`` in the literals' places (made in order).

    Raises:
        InputError: A literal is NaN or infinite (named before any assembly).
    """
    if not lits:
        return expr
    check_finite_literals(expr, "a load given as a function of x")
    return ufl.replace(expr, {lit: compat.constant(mesh, float(lit)) for lit in lits})


def load_key(load: Callable, mesh) -> tuple:
    """The structure of ``load(x)`` on ``mesh`` (see :func:`structure`)."""
    expr = load(ufl.SpatialCoordinate(mesh))
    return structure(expr, literals(expr))


def load_values(load: Callable, mesh) -> list[float]:
    """The values of ``load(x)``'s literals on ``mesh``, in the order of :func:`literals`."""
    return [float(lit) for lit in literals(load(ufl.SpatialCoordinate(mesh)))]


__all__ = ["literals", "load_key", "load_values", "structure", "with_constants"]
