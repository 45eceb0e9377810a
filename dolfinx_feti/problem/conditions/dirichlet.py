"""Prescribed values on a boundary group: :class:`Dirichlet`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ...validation import Either, Function, Integer, Maybe, Real, SequenceOf, Text, Vector, checked
from .base import POINT_FUNCTION
from .file_table import file_table


@file_table("dirichlet", components="components", per_component="value")
@dataclass(frozen=True)
@checked(group=Text(),
         value=Either(Real(), Vector(), Function(),
                      what=f"a finite number, one per component, or {POINT_FUNCTION}"),
         components=Maybe(SequenceOf(Integer(ge=0), unique=True, nonempty=True)))
class Dirichlet:
    """Prescribed values on a boundary group.

    Args:
        group: Name of the boundary physical group.
        value: A number, one number per component, or ``value(x) -> (n, ncomp)`` of the node
            coordinates ``x`` (n, gdim).
        components: The constrained components (e.g. ``(0,)`` for a symmetry plane normal to x);
            all components when ``None``.
    """

    group: str
    value: float | Sequence[float] | Callable[[np.ndarray], np.ndarray] = 0.0
    components: Sequence[int] | None = None
