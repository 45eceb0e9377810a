"""What each rank holds after the set-up: its subdomains' cells and dof points, and its rows.

The set-up (:mod:`.share_distributed`, for every way of holding the mesh) leaves each rank:

- the cells of its own subdomains and their dof points, renumbered locally in the order of
  their global numbers (so every "sorted by global node" order of the canonical dof layout is
  kept, and the local mesh is a :class:`~dolfinx_feti.mesh.MeshData` like the global one);
- its subdomains' (subdomain, dof point) pairs and the multiplicity of each point;
- its own rows of B, with their global columns, and the rows of contact and friction (the
  same on every rank: they live on the contact surfaces, which are small);
- the per-subdomain facets of the boundary groups, and the verdict of rank 0's check of each
  group for boundary integrals.

The rows and their order do not depend on the number of ranks.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from ..constraints.rows import Rows
from ..errors import InputError
from ..mesh.data import MeshData
from ..mesh.dofpoints import DofPoints, degree2_entities
from ..mesh.topology import row_keys


@dataclass
class LocalDecomposition:
    """The part of a :class:`~.mesh.decompose.Decomposition` one rank needs.

    Subdomains keep their global numbers; dof points are numbered locally (see
    :class:`RankShare`).

    Attributes:
        subs: This rank's subdomains (contiguous, increasing).
        cell_sub: Subdomain of each local cell.
        sub_body: Body index of every subdomain.
        sub_rank: Owner rank of every subdomain.
        sub_size: Number of dof points of every subdomain.
        pair_node: Local dof point of each local (subdomain, point) pair, by subdomain then
            point.
        pair_ptr: Pairs of ``subs[i]`` are ``pair_ptr[i]:pair_ptr[i+1]``.
        multiplicity: Number of subdomains holding the point of each local pair.
    """

    subs: np.ndarray
    cell_sub: np.ndarray
    sub_body: np.ndarray
    sub_rank: np.ndarray
    sub_size: np.ndarray
    pair_node: np.ndarray
    pair_ptr: np.ndarray
    multiplicity: np.ndarray

    @property
    def num_subdomains(self) -> int:
        """Number of subdomains of the whole problem."""
        return self.sub_body.size

    def nodes(self, s: int) -> np.ndarray:
        """Sorted local dof points of the local subdomain ``s``."""
        i = int(np.searchsorted(self.subs, s))
        return self.pair_node[self.pair_ptr[i]:self.pair_ptr[i + 1]]


@dataclass
class RankRows:
    """The rows of B as one rank holds them.

    Attributes:
        own: This rank's rows (``e_row`` local, 0 … n − 1).
        cols: Global primal column of each entry of ``own``.
        start: Global index of the first own row.
        size: Number of rows of the whole problem.
        contact: The inequality and friction rows of the whole problem (every rank), ...
        contact_index: ... and their global indices (ascending).
    """

    own: Rows
    cols: np.ndarray
    start: int
    size: int
    contact: Rows
    contact_index: np.ndarray

    def contact_rows(self, index: np.ndarray) -> np.ndarray:
        """Positions in ``contact`` of rows given by their global indices."""
        pos = np.searchsorted(self.contact_index, index)
        if np.any(self.contact_index[np.minimum(pos, self.contact_index.size - 1)] != index):
            raise ValueError("not a contact or friction row")
        return pos

    @property
    def inequality_index(self) -> np.ndarray:
        """Global indices of the inequality rows (ascending)."""
        return self.contact_index[self.contact.inequality]


@dataclass
class RankShare:
    """What one rank holds of a decomposed problem (module docstring).

    Attributes:
        mesh: The cells of this rank's subdomains as a mesh, nodes numbered locally.
        points: Their dof points, numbered locally (vertices first).
        point_ids: Global number of each local dof point (ascending).
        cell_ids: Global number of each local cell (ascending).
        num_points: Number of dof points of the whole mesh.
        num_cells: Number of cells of the whole mesh.
        dec: The local decomposition.
        facets: Per local subdomain, boundary group → its facets there (local vertices).
        group_errors: Boundary group → why it cannot carry a boundary integral (rank 0's
            check on the whole mesh), for the groups that cannot.
        rows: The rank's rows of B.
        extra: What the method needs besides (FETI-DP: the corners and floating motions of
            this rank's dofs), or None.
        directory: On a distributed mesh, the subdomains and Dirichlet mask of the local
            points (:class:`.share_distributed.NodeDirectory`); None otherwise.
    """

    mesh: MeshData
    points: DofPoints
    point_ids: np.ndarray
    cell_ids: np.ndarray
    num_points: int
    num_cells: int
    dec: LocalDecomposition
    facets: dict[int, dict[str, np.ndarray]]
    group_errors: dict[str, str]
    rows: RankRows
    extra: object = field(default=None, repr=False)
    directory: object = field(default=None, repr=False)

    @property
    def pair_points(self) -> np.ndarray:
        """Global dof point of each local (subdomain, point) pair, in the order of the dofs."""
        return self.point_ids[self.dec.pair_node]

    def check_group(self, group: str, what: str) -> None:
        """Refuse a boundary group the whole mesh does not have, or that has inner facets."""
        self.mesh.check_group_name(group)  # the local mesh has every group's name
        if group in self.group_errors:
            raise InputError(self.group_errors[group].replace("{what}", what))


def row_slice(rows: Rows, start: int, stop: int) -> Rows:
    """The rows ``start:stop`` of ``rows`` (entries sorted by row; renumbered from 0)."""
    lo, hi = np.searchsorted(rows.e_row, [start, stop])
    out = {}
    for f in fields(Rows):
        v = getattr(rows, f.name)
        out[f.name] = v[lo:hi] if f.name.startswith("e_") else v[start:stop]
    out["e_row"] = out["e_row"] - start
    return Rows(**out)


def row_subset(rows: Rows, index: np.ndarray) -> Rows:
    """The rows ``index`` (ascending) of ``rows``, renumbered 0 … len(index) − 1."""
    new = np.full(rows.size, -1, dtype=np.int64)
    new[index] = np.arange(index.size)
    keep = new[rows.e_row] >= 0
    out = {}
    for f in fields(Rows):
        v = getattr(rows, f.name)
        out[f.name] = v[keep] if f.name.startswith("e_") else v[index]
    out["e_row"] = new[rows.e_row[keep]]
    return Rows(**out)


def local_entities(cell_type: str, cells: np.ndarray, nv: int, first: dict[int, int]
                    ) -> dict[int, tuple[np.ndarray, int]]:
    """The entity index of the local dof points (degree 2), in local vertex numbers.

    The local points of one dimension are the global ones in the same (key) order: a
    monotone renumbering of the vertices keeps the order of the sorted vertex tuples.
    """
    out: dict[int, tuple[np.ndarray, int]] = {}
    for dim, local in degree2_entities(cell_type) if first else ():
        v = cells[:, np.array(local)]
        out[dim] = (np.unique(row_keys(v.reshape(-1, v.shape[2]), nv)), first[dim])
    return out


__all__ = ["LocalDecomposition", "RankRows", "RankShare", "row_slice", "row_subset"]
