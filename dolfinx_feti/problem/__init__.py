"""What a user describes: the contact problem and its conditions.

:mod:`.contact_problem` holds :class:`ContactProblem`; :mod:`.conditions` the condition
classes, one module each; :mod:`.changes` says what may change between load cases of one
set-up.
"""

from ..mesh.decompose import ByFunction, ByTags, Parts
from .conditions import (
    Coulomb,
    Cylinder,
    Dirichlet,
    Mortar,
    NodeToNode,
    Plane,
    RigidObstacle,
    SignedDistance,
    Sphere,
    Tie,
    Tresca,
)
from .contact_problem import ContactProblem
from .rigid_motion import RigidMotion

__all__ = ["ByFunction", "ByTags", "ContactProblem", "Coulomb", "Cylinder", "Dirichlet",
           "Mortar", "NodeToNode", "Parts", "Plane", "RigidMotion", "RigidObstacle",
           "SignedDistance", "Sphere", "Tie", "Tresca"]
