"""The rigid motion of an obstacle's body along a load path: a centre and a rotation angle.

An obstacle (:class:`~dolfinx_feti.Plane`, :class:`~dolfinx_feti.Sphere`, ...) gives the
surface's position at a step; friction needs more: which material point of the obstacle's
surface a contact node stuck to has gone where. A rigid disc spinning in place has the same
surface at every step, but its surface moves. :class:`RigidMotion` is the pose of the
obstacle's body at the step — a point of the body (``center``) and the rotation angle about it
from the body's reference orientation — and :func:`material_displacement` the motion of the
body's points between two poses: y ↦ c₁ + R₁R₀ᵀ(y − c₀).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..validation import Maybe, Real, Vector, checked


@dataclass(frozen=True)
@checked(center=Vector(), angle=Real(), axis=Maybe(Vector(3, nonzero=True)))
class RigidMotion:
    """The pose of a rigid obstacle's body at one step of a load path.

    Give it at every step of the path (``RigidObstacle(..., motion=RigidMotion(...))``); the
    friction rows then measure the slip of each contact node against the material point of the
    obstacle's surface it touches: between two steps the obstacle's points move by
    y ↦ c₁ + R(θ₁ − θ₀)(y − c₀) (2D; in 3D R₁R₀ᵀ about the axes).

    Args:
        center: A point of the body (the centre of a disc or a wheel, the pivot of a spinning
            punch), one coordinate per dimension of the mesh; its change between steps is the
            obstacle's translation.
        angle: The body's rotation angle about ``center`` from its reference orientation, in
            radians, counter-clockwise (2D) or right-handed about ``axis`` (3D). A disc of
            radius R rolling without slip to +x: ``angle = −(translation)/R``.
        axis: 3D only: the rotation axis (any length, not zero); not needed for ``angle = 0``
            (a translation).
    """

    center: Sequence[float]
    angle: float = 0.0
    axis: Sequence[float] | None = None

    def check_dimension(self, gdim: int, group: str) -> None:
        """Refuse, naming the condition's group, a motion of the wrong dimension."""
        where = f"RigidObstacle on {group!r}: motion"
        if len(self.center) != gdim:
            raise InputError(f"{where}.center has {len(self.center)} coordinates, the mesh is "
                             f"{gdim}D")
        if gdim == 3 and self.axis is None and self.angle != 0.0:
            raise InputError(f"{where}: a rotation in 3D needs its axis (RigidMotion(center, "
                             "angle, axis=(ax, ay, az)))")
        if gdim == 2 and self.axis is not None:
            raise InputError(f"{where}: in 2D the rotation is about the out-of-plane axis; "
                             "give no axis")

    def rotation(self) -> np.ndarray:
        """The rotation matrix (gdim × gdim) of the pose."""
        if self.angle == 0.0:  # a translation (3D needs no axis then)
            return np.eye(len(self.center))
        c, s = np.cos(self.angle), np.sin(self.angle)
        if self.axis is None:
            return np.array([[c, -s], [s, c]])
        a = np.asarray(self.axis, dtype=float)
        a = a / np.linalg.norm(a)
        K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
        return np.eye(3) + s * K + (1.0 - c) * (K @ K)  # Rodrigues


def material_displacement(before: RigidMotion, after: RigidMotion, y: np.ndarray
                          ) -> np.ndarray:
    """Where the body's points at ``y`` (k, gdim) in the pose ``before`` go in ``after``, minus y.

    y ↦ c₁ + R₁R₀ᵀ(y − c₀) − y, per row.
    """
    R = after.rotation() @ before.rotation().T
    c0 = np.asarray(before.center, dtype=float)
    c1 = np.asarray(after.center, dtype=float)
    return c1 + (y - c0) @ R.T - y


__all__ = ["RigidMotion", "material_displacement"]
