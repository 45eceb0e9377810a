"""Contact of a body with a rigid obstacle: :class:`RigidObstacle`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ...errors import InputError
from ...validation import Instance, Maybe, Text, checked
from ..rigid_motion import RigidMotion
from .file_table import file_table
from .friction import FRICTION, Friction
from .obstacles import Obstacle

if TYPE_CHECKING:
    from ..contact_problem import ContactProblem


@file_table("contact", "obstacle", infer_from=("group",), one_of={"obstacle": "obstacle"},
            needs_elasticity="a rigid obstacle", python_only=("motion",))
@dataclass(frozen=True)
@checked(group=Text(), obstacle=Instance(methods=("distance",), what="an obstacle (Plane, "
                                         "Sphere, Cylinder, SignedDistance)"),
         friction=FRICTION, motion=Maybe(Instance(RigidMotion)))
class RigidObstacle:
    """Contact of a body's boundary group with a rigid obstacle.

    The condition at each node is φ(x + u) >= 0, linearized: ∇φ(x)·u >= −φ(x). Nodes that
    start inside the obstacle (φ < 0) are pushed out: an initial penetration is honoured.
    ``friction`` (``None``, :class:`Tresca` or :class:`Coulomb`) acts on the tangential part
    of u (the obstacle does not move). On a load path, ``motion`` (a
    :class:`~dolfinx_feti.problem.rigid_motion.RigidMotion`: the pose of the obstacle's body,
    a centre and a rotation angle, given at every step) makes the friction rows measure each
    node's slip against the material point of the obstacle's surface (a spinning or rolling
    disc); without it a small-deformation path measures the slip in the fixed frame and the
    Newton driver against the translation of the obstacle (docs/friction.md).
    """

    group: str
    obstacle: Obstacle
    friction: Friction | None = None
    motion: RigidMotion | None = None

    #: What it makes of its surfaces: ``"contact"`` (inequality rows, in
    #: ``ContactProblem.contact``) or ``"tie"`` (equality rows, in ``ContactProblem.ties``).
    role = "contact"
    #: Whether the rows come from the mortar search (and the report checks them after).
    mortar = False
    #: A body against an obstacle, not against itself.
    self_contact = False

    @property
    def groups(self) -> tuple[str, ...]:
        """The boundary groups the condition reads."""
        return (self.group,)

    def check(self, problem: ContactProblem) -> None:
        """Refuse, by name, what this condition cannot take on ``problem``'s mesh."""
        problem.mesh.facets(self.group)
        if problem.value_size == 1:
            raise InputError("rigid obstacles need a vector (elasticity) problem")
        if self.motion is not None:
            self.motion.check_dimension(problem.mesh.gdim, self.group)

    def structure_key(self) -> tuple:
        """What a set-up depends on (:mod:`.changes`).

        Not the obstacle's position, nor the friction values: only the obstacle's kind and
        whether there is friction.
        """
        return (type(self).__name__, self.group, type(self.obstacle).__name__,
                self.friction is not None)

