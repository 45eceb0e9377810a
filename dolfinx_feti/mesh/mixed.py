"""A model whose bodies are of different cell types: one :class:`MeshData` per type.

DOLFINx 0.5.2 has no mesh of several cell types, and every stage of this package (topology,
dof points, decomposition, assembly) reads meshes of one type. A gmsh model with, say, a
hexahedral block under a tetrahedral body is therefore read as one mesh per (cell type,
order), each holding the bodies of that type: every body is of one type, so every subdomain
(which lies in one body) is of one type too. The meshes share no node — bodies of different
types touch only through contact or ties — and each keeps the facets of every boundary group
that lie on its bodies (a group such as a symmetry plane through both bodies is split).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .data import MeshData


@dataclass
class MixedMesh:
    """The meshes of a model with bodies of several cell types, one mesh per type.

    Attributes:
        parts: One mesh per (cell type, order), in the order of their first body's tag.
        body_names: Every body, in tag order (across the parts).
    """

    parts: tuple[MeshData, ...]
    body_names: tuple[str, ...]

    @property
    def gdim(self) -> int:
        """Geometric dimension."""
        return self.parts[0].gdim

    @property
    def tdim(self) -> int:
        """Topological dimension of the cells."""
        return self.parts[0].tdim

    @property
    def cell_types(self) -> tuple[str, ...]:
        """The cell type of each part."""
        return tuple(p.cell_type for p in self.parts)

    def part_of_body(self, name: str) -> int:
        """The index of the part that holds a body, with an error listing the bodies."""
        for i, p in enumerate(self.parts):
            if name in p.body_names:
                return i
        raise InputError(f"unknown body {name!r}: the mesh's bodies are {list(self.body_names)}")

    def parts_of_group(self, name: str) -> tuple[int, ...]:
        """The parts holding facets of a boundary group, with an error listing the groups."""
        found = tuple(i for i, p in enumerate(self.parts) if name in p.facet_groups)
        if not found:
            known = sorted({g for p in self.parts for g in p.facet_groups})
            raise InputError(f"unknown boundary group {name!r}: the mesh's boundary physical "
                             f"groups are {known}")
        return found

    @classmethod
    def of(cls, parts) -> MixedMesh:
        """The meshes of bodies of different cell types as one mesh, e.g. DOLFINx meshes.

        For meshes made apart, one per cell type (DOLFINx 0.5 has no mesh of two types):
        ``df.MixedMesh.of([df.from_dolfinx(hexes, ...), df.from_dolfinx(tets, ...)])``. The
        solution is then one Function per mesh, on the user's own meshes. A boundary group
        may be named in several meshes (e.g. a symmetry plane through two bodies).

        Args:
            parts: The meshes (:class:`MeshData`, held whole on every rank), two or more.

        Raises:
            InputError: Fewer than two meshes, meshes of different dimensions, a body name
                used twice, a name used for a body and a boundary group, or a mesh not
                held whole on every rank.
        """
        parts = tuple(parts)
        if len(parts) < 2 or not all(isinstance(p, MeshData) for p in parts):
            raise InputError("MixedMesh.of: expected two or more MeshData (one per cell "
                             "type), e.g. from from_dolfinx")
        if any(not p.holds_arrays or p.root_only is not None for p in parts):
            raise InputError("MixedMesh.of: every mesh must be held whole on every rank "
                             "(from_dolfinx/read_gmsh with replicate=True, distribute=False)")
        if len({p.gdim for p in parts}) != 1:
            raise InputError(f"MixedMesh.of: meshes of different dimensions "
                             f"{[p.gdim for p in parts]}")
        bodies = [b for p in parts for b in p.body_names]
        if len(set(bodies)) != len(bodies):
            raise InputError(f"MixedMesh.of: a body name is used in two meshes ({bodies}): "
                             "name the bodies apart (from_dolfinx(..., names=...))")
        clash = sorted(set(bodies) & {g for p in parts for g in p.facet_groups})
        if clash:
            raise InputError(f"physical group name {clash[0]!r} is used twice")
        return cls(parts, tuple(bodies))

    def describe(self) -> str:
        """One line per part: its cell type and bodies (for messages)."""
        return "; ".join(f"{p.cell_type} (order {p.geometry_degree}): bodies "
                         f"{list(p.body_names)}" for p in self.parts)


def mixed_mesh(parts: list[MeshData], facet_counts: dict[str, int],
               body_names: list[str]) -> MixedMesh:
    """The parts of a mixed model as one :class:`MixedMesh`, after the checks across them.

    Args:
        parts: One mesh per cell type, each with the facets of the boundary groups on it.
        facet_counts: The number of facets of each boundary group in the model (of the
            facet types of the parts' cells).
        body_names: Every body, in tag order.

    Raises:
        InputError: A name used for a body and a boundary group, two parts that share a node
            (bodies of different types must be joined by a tie or contact, not by nodes), or
            a boundary facet that lies on no body of its type.
    """
    clash = sorted(set(body_names) & set(facet_counts))
    if clash:
        raise InputError(f"physical group name {clash[0]!r} is used twice")
    for a in range(len(parts)):
        for b in range(a + 1, len(parts)):
            common = np.intersect1d(parts[a].node_tags, parts[b].node_tags)
            if common.size:
                raise InputError(
                    f"the {parts[a].cell_type} bodies {list(parts[a].body_names)} and the "
                    f"{parts[b].cell_type} bodies {list(parts[b].body_names)} share "
                    f"{common.size} nodes (e.g. gmsh node {int(common[0])}): bodies of "
                    "different cell types are meshed apart and joined by a Tie or contact")
    for name, count in facet_counts.items():
        held = sum(p.facet_groups[name].shape[0] for p in parts if name in p.facet_groups)
        if held != count:
            raise InputError(f"boundary group {name!r} has {count - held} facets that lie on "
                             "no body of their cell type (their nodes belong to no cell of "
                             "such a body)")
    return MixedMesh(tuple(parts), tuple(body_names))


__all__ = ["MixedMesh", "mixed_mesh"]
