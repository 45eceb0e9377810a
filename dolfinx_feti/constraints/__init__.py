"""Constraint rows of B: gluing, Dirichlet (Total FETI), contact. Pure NumPy, no DOLFINx."""

from .build import build_rows
from .rows import Kind, Rows

__all__ = ["Kind", "Rows", "build_rows"]
