"""The conditions of a contact problem, one module per class.

A new condition is a new module here (a frozen dataclass with its ``@checked`` fields and the
behaviour docs/architecture.md lists) and its row builder in :mod:`dolfinx_feti.constraints`.
"""

from .dirichlet import Dirichlet
from .friction import Coulomb, Friction, Tresca
from .mortar import Mortar
from .node_to_node import NodeToNode
from .obstacles import Cylinder, Obstacle, Plane, SignedDistance, Sphere
from .rigid_obstacle import RigidObstacle
from .tie import Tie

__all__ = ["Coulomb", "Cylinder", "Dirichlet", "Friction", "Mortar", "NodeToNode", "Obstacle",
           "Plane", "RigidObstacle", "SignedDistance", "Sphere", "Tie", "Tresca"]
