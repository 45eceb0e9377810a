"""What each rank holds after the set-up: its subdomains' cells and dof points, and its rows.

The decomposition and the constraint rows are computed on rank 0, the rank that read the mesh,
from the global arrays (so they do not depend on the number of ranks), then split by owner and
scattered. After that a rank holds:

- the cells of its own subdomains and their dof points, renumbered locally in the order of
  their global numbers (so every "sorted by global node" order of the canonical dof layout is
  kept, and the local mesh is a :class:`~dolfinx_feti.mesh.MeshData` like the global one);
- its subdomains' (subdomain, dof point) pairs and the multiplicity of each point;
- its own rows of B, with their global columns, and the rows of contact and friction (the
  same on every rank: they live on the contact surfaces, which are small);
- the per-subdomain facets of the boundary groups, and the verdict of rank 0's check of each
  group for boundary integrals.

Nothing of the size of the whole mesh, or of all rows, is kept on a rank other than 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np
from mpi4py import MPI

from ..constraints.rows import Rows
from ..errors import InputError, collective
from ..mesh.checks import boundary_group_verdicts
from ..mesh.data import MeshData
from ..mesh.decompose import Decomposition
from ..mesh.dofpoints import DofPoints, degree2_entities
from ..mesh.topology import REFERENCE, locate_facets, row_keys
from ..parallel.exchange import hand_out


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


def row_ranges(rows: Rows, dec: Decomposition, size: int) -> np.ndarray:
    """Rank r owns the rows ``bounds[r]:bounds[r+1]`` (rows are sorted by owner)."""
    owner = dec.sub_rank[rows.min_subdomain()]
    return np.r_[0, np.cumsum(np.bincount(owner, minlength=size))].astype(np.int64)


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


def _subdomain_facets(mesh: MeshData, dec: Decomposition) -> dict[int, dict[str, np.ndarray]]:
    """Boundary groups split by the subdomain of the cell each facet bounds."""
    out: dict[int, dict[str, np.ndarray]] = {}
    for name, f in mesh.facet_groups.items():
        if f.shape[0] == 0:
            continue
        cell, _ = locate_facets(mesh.cells, f, mesh.cell_type)
        sub = np.where(cell >= 0, dec.cell_sub[np.maximum(cell, 0)], -1)
        order = np.argsort(sub, kind="stable")
        subs, start = np.unique(sub[order], return_index=True)
        stops = np.r_[start[1:], sub.size]
        for s, a, b in zip(subs, start, stops, strict=True):
            if s >= 0:
                out.setdefault(int(s), {})[name] = f[order[a:b]]
    return out


def _piece(mesh: MeshData, points: DofPoints, dec: Decomposition, rows: Rows,
           facets: dict, multiplicity: np.ndarray, bs: int, rank: int,
           cell_order: np.ndarray, row_bounds: np.ndarray, index: np.ndarray) -> dict:
    """Rank ``rank``'s share of the global objects (computed on rank 0).

    ``cell_order`` lists the cells by subdomain, ``row_bounds`` the ranks' row ranges;
    ``index`` is scratch space of one entry per global dof point (global → local number).
    """
    subs = dec.local_subdomains(rank)
    s0, s1 = (int(subs[0]), int(subs[-1]) + 1) if subs.size else (0, 0)
    a, b = np.searchsorted(dec.cell_sub[cell_order], [s0, s1])
    pairs = slice(int(dec.sub_ptr[s0]), int(dec.sub_ptr[s1]))
    start, stop = int(row_bounds[rank]), int(row_bounds[rank + 1])
    own = row_slice(rows, start, stop)
    cols = bs * dec.pair_index(own.e_sub, own.e_node) + own.e_comp if own.e_row.size else \
        np.zeros(0, dtype=np.int64)
    common = {"subs": subs, "multiplicity": multiplicity[dec.pair_node[pairs]],
              "pair_ptr": dec.sub_ptr[s0:s1 + 1] - dec.sub_ptr[s0] if subs.size else
              np.zeros(1, int), "own": own, "cols": cols.astype(np.int64), "start": start}
    if b - a == dec.cell_sub.size and dec.sub_ptr[-1] == dec.pair_node.size and pairs == \
            slice(0, dec.pair_node.size) and _all_points_used(points):
        # the whole problem on one rank: the local numbering is the global one, no copies
        return {**common, "x": mesh.x, "cell_body": mesh.cell_body, "node_tags": mesh.node_tags,
                "point_x": points.x, "cell_points": points.cell_points,
                "ids": np.arange(points.num_points), "cell_ids": np.arange(b - a),
                "cell_sub": dec.cell_sub, "pair_node": dec.pair_node,
                "facets": {int(s): dict(facets.get(int(s), {})) for s in subs},
                "entity_first": {d: int(first) for d, (_, first) in points.entities.items()},
                "entities": points.entities}
    cells = np.sort(cell_order[a:b])
    cp = points.cell_points[cells]
    used = np.zeros(index.size, dtype=bool)
    used[cp] = True
    ids = np.flatnonzero(used)
    del used
    index[ids] = np.arange(ids.size)
    nv = int(np.searchsorted(ids, mesh.num_nodes))
    return {
        **common, "x": mesh.x[ids[:nv]], "cell_body": mesh.cell_body[cells],
        "node_tags": mesh.node_tags[ids[:nv]], "point_x": points.x[ids],
        "cell_points": index[cp], "ids": ids, "cell_ids": cells,
        "cell_sub": dec.cell_sub[cells], "pair_node": index[dec.pair_node[pairs]],
        "facets": {int(s): {n: index[f] for n, f in facets.get(int(s), {}).items()}
                   for s in subs},
        "entity_first": {d: int(np.searchsorted(ids, first))
                         for d, (_, first) in points.entities.items()},
    }


def _all_points_used(points: DofPoints) -> bool:
    """Whether every dof point is a point of some cell (then the whole mesh needs no map)."""
    used = np.zeros(points.num_points, dtype=bool)
    used[points.cell_points] = True
    return bool(used.all())


def share_out(mesh: MeshData, points: DofPoints | None, dec: Decomposition | None,
              rows: Rows | None, bs: int, comm: MPI.Comm, extra: list | None = None
              ) -> RankShare:
    """Split rank 0's global decomposition and rows into the ranks' shares (collective).

    Args:
        mesh: The global mesh (only rank 0's arrays are read; elsewhere its names and types).
        points: The global dof points (only rank 0's; None elsewhere).
        dec: The global decomposition (only rank 0's; None elsewhere).
        rows: All rows, sorted by owner (only rank 0's; None elsewhere).
        bs: Components per node.
        comm: The ranks.
        extra: Per rank, something more to hand over (only rank 0's), kept as ``extra``.
    """
    common = make = None
    with collective(comm, "decomposition"):
        if comm.rank == 0:
            ptr, _ = dec.node_subdomains()
            facets = _subdomain_facets(mesh, dec)
            mult = np.diff(ptr)
            if np.any(np.diff(rows.e_row) < 0):  # entries by row, for row_slice
                rows = rows.permuted(np.arange(rows.size))
            cell_order = np.argsort(dec.cell_sub, kind="stable")
            bounds = row_ranges(rows, dec, comm.size)
            index = np.empty(points.num_points, dtype=np.int64)

            def make(r):
                piece = _piece(mesh, points, dec, rows, facets, mult, bs, r, cell_order,
                               bounds, index)
                piece["extra"] = None if extra is None else extra[r]
                return piece

            contact = np.flatnonzero(rows.inequality | rows.tangential)
            common = {"sub_body": dec.sub_body, "sub_rank": dec.sub_rank,
                      "sub_size": np.diff(dec.sub_ptr), "size": rows.size,
                      "contact": row_subset(rows, contact), "contact_index": contact,
                      "group_errors": boundary_group_verdicts(mesh),
                      "num_points": points.num_points, "degree": points.degree,
                      "num_cells": mesh.cells.shape[0]}
    common = comm.bcast(common, root=0)
    p = hand_out(comm, make, "handing out the shares")
    nvc = REFERENCE[mesh.cell_type].num_vertices  # the vertices come first among the points
    # the names and types of the whole mesh, the arrays of this rank's cells
    local_mesh = replace(mesh.names_only(), x=p["x"],
                         cells=np.ascontiguousarray(p["cell_points"][:, :nvc]),
                         cell_body=p["cell_body"], node_tags=p["node_tags"], counts={})
    nv = int(p["x"].shape[0])
    entities = p["entities"] if "entities" in p else local_entities(
        mesh.cell_type, local_mesh.cells, nv, p["entity_first"])
    local_points = DofPoints(common["degree"], mesh.cell_type, p["point_x"], p["cell_points"],
                             nv, entities)
    dec_local = LocalDecomposition(
        subs=p["subs"], cell_sub=p["cell_sub"], sub_body=common["sub_body"],
        sub_rank=common["sub_rank"], sub_size=common["sub_size"], pair_node=p["pair_node"],
        pair_ptr=p["pair_ptr"], multiplicity=p["multiplicity"])
    rank_rows = RankRows(own=p["own"], cols=p["cols"], start=p["start"], size=common["size"],
                         contact=common["contact"], contact_index=common["contact_index"])
    return RankShare(mesh=local_mesh, points=local_points, point_ids=p["ids"],
                     cell_ids=p["cell_ids"], num_points=common["num_points"],
                     num_cells=common["num_cells"], dec=dec_local,
                     facets=p["facets"], group_errors=common["group_errors"], rows=rank_rows,
                     extra=p["extra"])


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


__all__ = ["LocalDecomposition", "RankRows", "RankShare", "row_ranges", "row_slice",
           "row_subset", "share_out"]
