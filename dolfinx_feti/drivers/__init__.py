"""Drivers: loops over one :class:`~dolfinx_feti.FetiSolver` (load paths, load cases)."""

from .load_path import solve_cases, solve_path
from .path_output import History, TimeSeries, setup_seconds

__all__ = ["History", "TimeSeries", "setup_seconds", "solve_cases", "solve_path"]
