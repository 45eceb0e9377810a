"""The model pieces of a problem file that the Python API has no ready-made object for.

A Poisson source given per body and by boxes (:class:`FilePoisson`, :class:`SourceBox`), and an
affine traction (:class:`AffineTraction`); :mod:`dolfinx_feti.io.problemfile` builds them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import ufl

from .forms import Poisson


@dataclass(frozen=True)
class SourceBox:
    """A constant source ``value`` in the axis-aligned box ``min <= x <= max``."""

    min: tuple[float, ...]
    max: tuple[float, ...]
    value: float

    def indicator(self, x) -> Any:
        """The box's indicator function as a UFL expression of the spatial coordinate x."""
        inside = None
        for a, (lo, hi) in enumerate(zip(self.min, self.max, strict=True)):
            c = ufl.And(ufl.ge(x[a], lo), ufl.le(x[a], hi))
            inside = c if inside is None else ufl.And(inside, c)
        return ufl.conditional(inside, self.value, 0.0)


class FilePoisson(Poisson):
    """:class:`~dolfinx_feti.Poisson` with the source of a problem file.

    The source f is the sum of a constant per body (``source``) and the values of the boxes
    (``source_boxes``) that contain the point; the boxes need no expression language.
    """

    def __init__(self, source: float | Mapping[str, float] = 0.0, *,
                 boxes: Sequence[SourceBox] = (), flux: Mapping | None = None,
                 k: float | Mapping[str, float] = 1.0) -> None:
        self.body_source = dict(source) if isinstance(source, Mapping) else None
        self.boxes = tuple(boxes)
        constant = 0.0 if isinstance(source, Mapping) else float(source)
        if self.boxes:
            def f(x):
                expr = constant
                for b in self.boxes:
                    expr = expr + b.indicator(x)
                return expr
            super().__init__(f, flux=flux, k=k)
        else:
            super().__init__(constant, flux=flux, k=k)

    def __call__(self, V, sub):
        """The forms on one subdomain (the per-body source added to Poisson's)."""
        a, L = super().__call__(V, sub)
        if self.body_source:
            values = {b: self.body_source.get(b, 0.0) for b in sub.bodies}
            f = sub.cellwise(values)
            if not (isinstance(f, float) and f == 0.0):
                L = L + f * ufl.TestFunction(V) * sub.dx()
        return a, L


@dataclass(frozen=True)
class AffineTraction:
    """The traction t(x) = value + gradient · x (``gradient[i][j]`` = ∂t_i/∂x_j)."""

    value: tuple[float, ...]
    gradient: tuple[tuple[float, ...], ...] | None = None

    def scaled(self, s: float) -> AffineTraction:
        """The traction s·t (a load step of the ``[loading]`` table)."""
        return AffineTraction(tuple(s * v for v in self.value), None if self.gradient is None
                              else tuple(tuple(s * g for g in row) for row in self.gradient))

    def __call__(self, x) -> Any:
        """t as a UFL vector of the spatial coordinate x."""
        comps = []
        for i, v in enumerate(self.value):
            t = v
            for j, gij in enumerate(self.gradient[i] if self.gradient else ()):
                if gij != 0.0:
                    t = t + gij * x[j]
            comps.append(t)
        return ufl.as_vector(comps)


