"""The FETI layer as algebra: primal systems, their transforms, dualization, preconditioners.

Nothing here builds meshes or assembles: the FEM side (:mod:`dolfinx_feti.fem`) hands over the
subdomain matrices, loads, kernels and dof maps, and :mod:`dolfinx_feti.setup.stages` chains
the steps.
"""

from .corners import CornerSystem, EliminateCorners
from .dualize import Dualization
from .kplus import FixingNodesInverse
from .system import BlockSystem
from .transforms import EliminateDirichlet

__all__ = ["BlockSystem", "CornerSystem", "Dualization", "EliminateCorners", "EliminateDirichlet",
           "FixingNodesInverse"]
