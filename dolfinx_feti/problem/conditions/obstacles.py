"""Rigid obstacles as signed distances, the shapes a :class:`~.rigid_obstacle.RigidObstacle` takes.

:class:`Plane`, :class:`Sphere`, :class:`Cylinder`, :class:`SignedDistance`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from ...validation import Function, Real, Vector, checked
from .base import POINT_FUNCTION
from .file_table import file_table


def _plus(p: Sequence[float], d: Sequence[float]) -> tuple[float, ...]:
    return tuple(float(a) + float(b) for a, b in zip(p, d, strict=True))


class Obstacle(Protocol):
    """A rigid obstacle as a signed distance: positive outside the obstacle."""

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance φ(x) and its gradient at the points ``x`` (n, gdim)."""


@file_table("obstacle", "plane")
@dataclass(frozen=True)
@checked(point=Vector(), normal=Vector(nonzero=True))
class Plane:
    """The half-space {(x − point)·normal <= 0}; ``normal`` points out of the obstacle.

    ``point`` and ``normal`` have one coordinate per dimension of the mesh.
    """

    point: Sequence[float]
    normal: Sequence[float]

    #: A translation leaves the normal at every point as it was (friction rows of a small-
    #: deformation path can follow it; a curved obstacle's cannot).
    keeps_normals = True

    def coordinates(self) -> dict[str, Sequence[float]]:
        """The vectors that need one coordinate per dimension of the mesh."""
        return {"point": self.point, "normal": self.normal}

    def translated(self, d: Sequence[float]) -> Plane:
        """The same obstacle moved by ``d`` (a load step of a moving obstacle)."""
        return replace(self, point=_plus(self.point, d))

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        n = np.asarray(self.normal, dtype=float)
        n = n / np.linalg.norm(n)
        p = np.asarray(self.point, dtype=float)
        return (x - p) @ n, np.broadcast_to(n, x.shape).copy()


@file_table("obstacle", "sphere")
@dataclass(frozen=True)
@checked(center=Vector(), radius=Real(gt=0))
class Sphere:
    """A rigid ball (a disc in 2D) of radius ``radius`` centred at ``center``."""

    center: Sequence[float]
    radius: float

    def coordinates(self) -> dict[str, Sequence[float]]:
        """The vectors that need one coordinate per dimension of the mesh."""
        return {"center": self.center}

    def translated(self, d: Sequence[float]) -> Sphere:
        """The same obstacle moved by ``d`` (a load step of a moving obstacle)."""
        return replace(self, center=_plus(self.center, d))

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        d = x - np.asarray(self.center, dtype=float)
        r = np.linalg.norm(d, axis=1)
        return r - self.radius, d / np.maximum(r, 1e-300)[:, None]


@file_table("obstacle", "cylinder", dims=(3,), hint="use a sphere (a disc) in 2D")
@dataclass(frozen=True)
@checked(point=Vector(3), axis=Vector(3, nonzero=True), radius=Real(gt=0))
class Cylinder:
    """A rigid infinite cylinder (3D) with an axis through ``point`` along ``axis``."""

    point: Sequence[float]
    axis: Sequence[float]
    radius: float

    def coordinates(self) -> dict[str, Sequence[float]]:
        """The vectors that need one coordinate per dimension of the mesh."""
        return {"point": self.point, "axis": self.axis}

    def translated(self, d: Sequence[float]) -> Cylinder:
        """The same obstacle moved by ``d`` (a load step of a moving obstacle)."""
        return replace(self, point=_plus(self.point, d))

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        a = np.asarray(self.axis, dtype=float)
        a = a / np.linalg.norm(a)
        d = x - np.asarray(self.point, dtype=float)
        d = d - np.outer(d @ a, a)
        r = np.linalg.norm(d, axis=1)
        return r - self.radius, d / np.maximum(r, 1e-300)[:, None]


@dataclass(frozen=True)
@checked(fn=Function(f"{POINT_FUNCTION} returning (phi (n,), grad (n, gdim))"))
class SignedDistance:
    """A rigid obstacle given by a user signed distance ``fn(x) -> (phi, grad)``."""

    fn: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        return self.fn(x)

    def translated(self, d: Sequence[float]) -> SignedDistance:
        """The same obstacle moved by ``d``: φ(x − d)."""
        shift = np.asarray(d, dtype=float)
        return SignedDistance(lambda x, _fn=self.fn: _fn(x - shift[: x.shape[1]]))
