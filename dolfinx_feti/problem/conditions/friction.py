"""The friction laws a contact condition may carry: :class:`Tresca`, :class:`Coulomb`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ...validation import Either, Function, Instance, Integer, Maybe, Real, checked
from .base import POINT_FUNCTION
from .file_table import file_table


@file_table("friction", "tresca", needs_elasticity="friction")
@dataclass(frozen=True)
@checked(bound=Either(Real(ge=0, inf=True), Function(),
                      what=f"a slip bound: a number >= 0, inf (no slip) or {POINT_FUNCTION}"))
class Tresca:
    """Given (Tresca) friction: the tangential traction is bounded by the slip bound ``g``.

    At each contact node the tangential nodal force satisfies |λ_T| <= g(x)·A with A the
    node's lumped area (length in 2D) on the slave surface: the node sticks (no relative
    tangential displacement) while |λ_T| < g(x)·A and slips against the friction force when
    |λ_T| = g(x)·A. In 2D this is a box on one tangential multiplier, in 3D a disc on two.

    Args:
        bound: The slip bound g >= 0, a traction (force per unit area, per unit length in
            2D): a number, ``numpy.inf`` (no slip: the tangential rows become equalities) or
            ``bound(x) -> (n,)`` of the node coordinates ``x`` (n, gdim).
    """

    bound: float | Callable[[np.ndarray], np.ndarray]

    def key(self) -> tuple:
        """What the friction rows' values depend on (a set-up's update compares it)."""
        return "tresca", self.bound if callable(self.bound) else float(self.bound)

    def fixed_point(self) -> None:
        """Tresca is solved by one QP: no fixed point."""
        return None

    def with_value(self, value: float) -> Tresca:
        """The same law with the slip bound ``value`` (a step of a ``[loading]`` path)."""
        return replace(self, bound=float(value))


@file_table("friction", "coulomb", needs_elasticity="friction")
@dataclass(frozen=True)
@checked(coefficient=Real(ge=0), rtol=Real(gt=0, lt=1), max_steps=Integer(ge=1, le=10**6))
class Coulomb:
    """Coulomb friction, solved by a fixed point on Tresca problems.

    The slip bound of each contact node is 𝓕 times its normal nodal force: g_i = 𝓕 λ_N,i.
    Each fixed-point step solves a Tresca problem (warm-started from the previous step) with
    the bound taken from the previous normal forces; the first step uses g = ∞ (no slip). The
    iteration stops when max_i |g_i − 𝓕 λ_N,i| <= rtol max_i λ_N,i over all Coulomb nodes
    (the Coulomb residual of the iterate, in physical units; the inner solves' accuracy
    follows it, docs/friction.md) or after ``max_steps`` steps (then the report says not
    converged). With several Coulomb pairs the smallest ``rtol`` and the largest
    ``max_steps`` apply.

    Args:
        coefficient: The friction coefficient 𝓕 >= 0.
        rtol: The Coulomb residual max|g − 𝓕 λ_N| / max λ_N that ends the fixed point.
        max_steps: Budget of fixed-point steps (Tresca solves).
    """

    coefficient: float
    rtol: float = 1e-6
    max_steps: int = 50

    def key(self) -> tuple:
        """What the friction rows' values depend on (a set-up's update compares it)."""
        return "coulomb", float(self.coefficient), float(self.rtol), int(self.max_steps)

    def fixed_point(self) -> tuple[float, int]:
        """The fixed point's stopping residual and budget of steps."""
        return float(self.rtol), int(self.max_steps)

    def with_value(self, value: float) -> Coulomb:
        """The same law with the coefficient ``value`` (a step of a ``[loading]`` path)."""
        return replace(self, coefficient=float(value))




Friction = Tresca | Coulomb
#: The check of a condition's ``friction`` field.
FRICTION = Maybe(Instance(Tresca, Coulomb))
