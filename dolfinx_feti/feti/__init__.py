"""FETI: generalized inverses, dual operators, coarse space data and primal recovery."""

from .kplus import FixingNodesInverse
from .tfeti import TotalFETI

__all__ = ["FixingNodesInverse", "TotalFETI"]
