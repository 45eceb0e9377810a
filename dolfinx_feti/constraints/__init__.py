"""Constraint rows of B: gluing, Dirichlet (Total FETI), contact. Pure NumPy, no DOLFINx."""

from .rows import Kind, Rows

__all__ = ["Kind", "Rows"]
