"""Mesh input (gmsh), geometry utilities and decomposition into subdomains."""

from .decompose import ByFunction, ByTags, Decomposition, Parts, decompose
from .gmsh_input import MeshData, read_gmsh

__all__ = ["ByFunction", "ByTags", "Decomposition", "MeshData", "Parts", "decompose", "read_gmsh"]
