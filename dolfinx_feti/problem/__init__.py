"""What a user describes: the contact problem and its conditions.

:mod:`.changes` says what may change between load cases of one set-up.
"""

from .contact_problem import (
    ByFunction,
    ByTags,
    ContactProblem,
    Coulomb,
    Cylinder,
    Dirichlet,
    Mortar,
    NodeToNode,
    Parts,
    Plane,
    RigidObstacle,
    SignedDistance,
    Sphere,
    Tie,
    Tresca,
)
from .rigid_motion import RigidMotion

__all__ = ["ByFunction", "ByTags", "ContactProblem", "Coulomb", "Cylinder", "Dirichlet",
           "Mortar", "NodeToNode", "Parts", "Plane", "RigidMotion", "RigidObstacle",
           "SignedDistance", "Sphere", "Tie", "Tresca"]
