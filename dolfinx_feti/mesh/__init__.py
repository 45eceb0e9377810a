"""Mesh input (gmsh), geometry utilities and decomposition into subdomains."""

from .auto_parts import Auto
from .data import MeshData
from .decompose import ByFunction, ByTags, Decomposition, Parts, decompose
from .dolfinx_input import from_dolfinx
from .gmsh_input import build_mesh, read_gmsh
from .mixed import MixedMesh

__all__ = ["Auto", "ByFunction", "ByTags", "Decomposition", "MeshData", "MixedMesh", "Parts",
           "build_mesh", "decompose", "from_dolfinx", "read_gmsh"]
