"""DOLFINx meshes as input: a (distributed) mesh with cell tags and facet tags → MeshData.

The input is read in two steps. :func:`local_part` describes what this rank holds of the mesh in
global numbers only — its owned cells by their input index, their vertices by input node index,
the coordinates of its nodes, the tags of its cells and the vertices of its tagged facets —
with no communication: that is the form a distributed pipeline (no rank holding the whole mesh)
would start from. :func:`gather` then builds the global arrays of :class:`MeshData` that the
pipeline uses today, identical on every rank: nodes and cells are numbered in DOLFINx's input
order (the order of the arrays the mesh was created from, e.g. gmsh's node tags and the cells
of the physical groups with ``gmshio``), which does not depend on the number of ranks, so the
decomposition, the rows and the results do not either. With ``distribute=True``,
:func:`scatter` builds them on rank 0 only, which checks them and hands every rank a block of
the cells (:func:`~.distributed.scatter_mesh`); the output then finds the user's nodes and
cells through directories keyed by their input index, spread over the ranks.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from .. import compat
from ..errors import InputError, collective
from ..parallel.exchange import answer, exchange
from .data import MeshData, answered_by_root
from .dofpoints import degree2_entities
from .topology import REFERENCE, cell_facets, locate_facets, row_keys


@dataclass(frozen=True)
class DolfinxSource:
    """The link from :class:`MeshData` back to the DOLFINx mesh it was made from.

    Attributes:
        mesh: The user's DOLFINx mesh (the solution is returned on it).
        input_nodes: The DOLFINx input index of each global vertex (sorted).
        input_cells: The DOLFINx input index of each global cell (sorted).
        root_only: For a mesh whose arrays rank 0 holds (``replicate=False``), the
            communicator: the two tables are on rank 0 only, which answers the lookups.
        directory: For a distributed mesh (``distribute=True``), the communicator: each
            table is then this rank's share of a directory, ``(input indices, global
            numbers)`` of the input indices ``i`` with ``i % size == rank``, and a lookup
            asks the rank that keeps each index.
    """

    mesh: object
    input_nodes: np.ndarray | tuple | None
    input_cells: np.ndarray | tuple | None
    root_only: object = None
    directory: object = None

    def _positions(self, table, asked: np.ndarray) -> np.ndarray:
        if self.directory is not None:
            return _ask_directory(self.directory, table, asked)
        if self.root_only is None:
            return np.searchsorted(table, asked)
        return answered_by_root(self.root_only, np.asarray(asked, dtype=np.int64),
                                lambda q: np.searchsorted(table, q))

    def vertex_ids(self) -> np.ndarray:
        """The global vertex of each local geometry node of the mesh."""
        return self._positions(self.input_nodes, compat.node_input_indices(self.mesh))

    def cell_ids(self) -> np.ndarray:
        """The global cell of each local cell (owned and ghost) of the mesh."""
        return self._positions(self.input_cells, compat.cell_input_indices(self.mesh))


def _directory(comm, keys: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """This rank's share of a directory input index → global number (collective).

    Every rank registers its (key, value) pairs (a key may come from several ranks, with the
    same value); the rank ``key % size`` keeps each key.
    """
    keys = np.asarray(keys, dtype=np.int64)
    (k, v), *_ = exchange(comm, keys % comm.size, keys, np.asarray(values, dtype=np.int64))
    k, first = np.unique(k, return_index=True)
    return k, v[first]


def _ask_directory(comm, table: tuple[np.ndarray, np.ndarray], asked) -> np.ndarray:
    """The global numbers of the input indices ``asked`` from the directory (collective)."""
    asked = np.asarray(asked, dtype=np.int64)
    (q,), order, counts, rcounts = exchange(comm, asked % comm.size, asked)
    keys, values = table
    found = np.full(q.size, -1, dtype=np.int64)
    if keys.size:
        pos = np.minimum(np.searchsorted(keys, q), keys.size - 1)
        found = np.where(keys[pos] == q, values[pos], -1)
    got = answer(comm, found, order, counts, rcounts)
    # an index nobody registered would map a user's dof to no point: stop on every rank
    if comm.allreduce(bool(np.any(got < 0)), op=MPI.LOR):
        raise AssertionError("from_dolfinx: an input index of the user's mesh is not in the "
                             "directory of the distributed mesh")
    return got


@dataclass
class LocalPart:
    """What one rank holds of a DOLFINx mesh, in global (input) numbers.

    Attributes:
        cell_index: Input index of each owned cell.
        cell_nodes: Input node index of each vertex of the owned cells (reference order).
        cell_tag: The cell tag of each owned cell (-1: untagged).
        node_index: Input index of each local geometry node (owned and ghost).
        node_x: Their coordinates.
        facet_nodes: Input node indices of the vertices of the tagged local facets.
        facet_tag: Their tags.
        high_nodes: For a second-order mesh, the input index of each owned cell's geometry
            nodes beyond its vertices (basix's order: edges, faces, interior), else (c, 0).
    """

    cell_index: np.ndarray
    cell_nodes: np.ndarray
    cell_tag: np.ndarray
    node_index: np.ndarray
    node_x: np.ndarray
    facet_nodes: np.ndarray
    facet_tag: np.ndarray
    high_nodes: np.ndarray


def from_dolfinx(mesh, cell_tags=None, facet_tags=None,
                 names: Mapping[str, int | tuple[int, int]] | None = None,
                 replicate: bool = True, distribute: bool = False) -> MeshData:
    """A DOLFINx mesh with its tags as the mesh of a :class:`~dolfinx_feti.ContactProblem`.

    The cell tags name the bodies, the facet tags the boundary groups (Dirichlet, loads,
    contact surfaces). The mesh may be distributed over the ranks of its communicator as
    DOLFINx distributes it; call this on all of them. The solution of a problem on the
    returned data is a Function on ``mesh`` itself (``solution.u``).

    Args:
        mesh: A DOLFINx mesh of triangles, quadrilaterals, tetrahedra or hexahedra of
            geometry degree 1 or 2 (curved cells; the problem then takes a degree-2 space),
            whose geometric dimension is its cells' (a 2D mesh with ``gdim=2``).
            An object with ``mesh``, ``cell_tags``, ``facet_tags`` and ``physical_groups``
            (the result of ``dolfinx.io.gmsh.model_to_mesh`` in DOLFINx ≥ 0.10) is accepted
            whole, its names taken from the physical groups.
        cell_tags: MeshTags of the cells: every cell needs a tag (its body).
        facet_tags: MeshTags of facets (boundary groups); None for none.
        names: Group name → tag, or → ``(dim, tag)`` when a tag number is used by cells and
            by facets. Tags without a name are named by their number (``"3"``).
        replicate: Every rank receives the global arrays (the default), or only rank 0 of the
            mesh's communicator gathers them and the others keep the names (as
            :func:`~dolfinx_feti.read_gmsh` with ``replicate=False``).
        distribute: Spread the mesh over the ranks instead, as
            :func:`~dolfinx_feti.read_gmsh` with ``distribute=True``: rank 0 gathers and
            checks the whole mesh, hands every rank a compact block of the cells
            (consecutive along a space-filling curve, in DOLFINx's input order within the
            block) and keeps only its own block (``mesh.part``); no rank holds the whole
            mesh after the input, and the output finds the user's nodes and cells through a
            directory spread over the ranks. Not with ``replicate=False`` (which asks rank 0
            to keep the whole mesh) nor with curved cells.

    Returns:
        The mesh data (global arrays on every rank, node order of DOLFINx's input; or each
        rank's block, see ``distribute``).

    Raises:
        InputError: For an unsupported mesh (cell type, curved cells, a 2D mesh in 3D),
            tags of the wrong dimension, untagged cells, names of tags that do not exist, or
            ``distribute=True`` with ``replicate=False`` or a curved mesh.
    """
    if not compat.is_mesh(mesh) and hasattr(mesh, "mesh") and hasattr(mesh, "cell_tags"):
        groups = getattr(mesh, "physical_groups", None) or {}
        if names is None:
            names = {str(n): (int(g[0]), int(g[1])) for n, g in groups.items()}
        mesh, cell_tags, facet_tags = mesh.mesh, mesh.cell_tags, mesh.facet_tags
    if not compat.is_mesh(mesh):
        raise InputError(f"from_dolfinx: expected a dolfinx.mesh.Mesh, got "
                         f"{type(mesh).__name__}")
    cell_type, gdim, degree = compat.describe_mesh(mesh)
    if cell_type not in REFERENCE:
        raise InputError(f"from_dolfinx: {cell_type} cells are not supported: only triangles, "
                         "quadrilaterals, tetrahedra and hexahedra")
    tdim = REFERENCE[cell_type].tdim
    if degree not in (1, 2):
        raise InputError(f"from_dolfinx: the mesh's coordinate element has degree {degree}; "
                         "meshes of order 1 and 2 are supported")
    if gdim != tdim:
        raise InputError(f"from_dolfinx: the mesh of {cell_type} cells has geometric dimension "
                         f"{gdim}; a {tdim}D problem needs gdim={tdim} (e.g. "
                         f"gmshio.model_to_mesh(gmsh.model, comm, 0, gdim={tdim}))")
    if cell_tags is None:
        raise InputError("from_dolfinx: cell_tags are needed (they name the bodies)")
    for tags, dim, what in ((cell_tags, tdim, "cell_tags"), (facet_tags, tdim - 1, "facet_tags")):
        if tags is not None and compat.tags_data(tags)[0] != dim:
            raise InputError(f"from_dolfinx: {what} are tags of entities of dimension "
                             f"{compat.tags_data(tags)[0]}, expected {dim}")
        if tags is not None:
            check_tags_belong(mesh, tags, dim, what)
    if distribute:
        if not replicate:
            raise InputError("from_dolfinx: distribute=True spreads the mesh over the ranks; "
                             "replicate=False (rank 0 keeps the whole mesh) contradicts it: "
                             "pass one of them")
        if degree != 1:
            raise InputError("from_dolfinx: a curved (second-order) mesh cannot be distributed "
                             "yet: use distribute=False")
        return scatter(local_part(mesh, cell_tags, facet_tags), mesh, cell_type, names)
    return gather(local_part(mesh, cell_tags, facet_tags), mesh, cell_type, names, replicate)


def check_tags_belong(mesh, tags, dim: int, what: str) -> None:
    """Refuse MeshTags of another mesh before DOLFINx indexes with them (collective).

    DOLFINx trusts the entity indices of MeshTags: those of another mesh, out of range, make
    it read past its arrays (a segmentation fault), and in range they tag other entities (a
    Dirichlet group inside a body). Tags made on ``mesh`` pass at once; tags made on another
    mesh pass only when their indices are this rank's entities and each tagged entity has the
    same vertices in both meshes (the same mesh, e.g. read twice from one file).

    Raises:
        InputError: On every rank, naming the tags and what is wrong.
    """
    own, theirs = compat.mesh_topology(mesh), compat.tags_topology(tags)
    same = theirs is not None and theirs == own
    if mesh.comm.allreduce(bool(same), op=MPI.LAND):
        return
    _, idx, values = compat.tags_data(tags)
    offsets, vertices = compat.entity_vertices(own, dim)
    other = None if theirs is None else compat.entity_vertices(theirs, dim)
    with collective(mesh.comm, "mesh"):
        n = offsets.size - 1
        kind = "cells" if dim == mesh.topology.dim else "facets"
        if idx.size != values.size:
            raise InputError(f"from_dolfinx: {what} hold {idx.size} entities but {values.size} "
                             "values")
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise InputError(f"from_dolfinx: {what} belong to another mesh: they tag entity "
                             f"{int(idx.max() if idx.max() >= n else idx.min())} but this "
                             f"rank's part of the mesh has {n} {kind} (0 to {n - 1}); make the "
                             "tags on the mesh you pass (the mesh and the tags of one "
                             "gmshio.model_to_mesh call)")
        if other is not None and idx.size:
            o_off, o_vert = other
            if idx.max() >= o_off.size - 1 or not np.array_equal(
                    _rows(offsets, vertices, idx), _rows(o_off, o_vert, idx)):
                raise InputError(f"from_dolfinx: {what} belong to another mesh: the entities "
                                 f"they tag have other vertices in the mesh passed (it is not "
                                 "the mesh the tags were made on); make the tags on the mesh "
                                 "you pass")


def _rows(offsets: np.ndarray, array: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """The concatenated rows ``idx`` of an adjacency list (offsets, array)."""
    counts = offsets[idx + 1] - offsets[idx]
    start = np.repeat(offsets[idx] - np.cumsum(counts) + counts, counts)
    return array[start + np.arange(int(counts.sum()))]


def local_part(mesh, cell_tags, facet_tags) -> LocalPart:
    """This rank's part of the mesh in global (input) numbers; no communication."""
    owned, _ = compat.cell_counts(mesh)
    gin = compat.node_input_indices(mesh)
    ref = REFERENCE[compat.describe_mesh(mesh)[0]]
    geom = gin[compat.cell_geometry_nodes(mesh)[:owned]]
    cell_nodes, high = geom[:, :ref.num_vertices], geom[:, ref.num_vertices:]
    tag = np.full(owned, -1, dtype=np.int64)
    _, idx, val = compat.tags_data(cell_tags)
    mine = idx < owned
    tag[idx[mine]] = val[mine]
    if facet_tags is not None:
        dim, fidx, fval = compat.tags_data(facet_tags)
        width = len(ref.facets[0])  # the vertices come first among a facet's nodes
        fnodes = gin[compat.entity_geometry_nodes(mesh, dim, fidx)[:, :width]] if fidx.size \
            else np.zeros((0, width), dtype=np.int64)
    else:
        fnodes = np.zeros((0, 2), dtype=np.int64)
        fval = np.zeros(0, dtype=np.int64)
    return LocalPart(cell_index=compat.cell_input_indices(mesh)[:owned].astype(np.int64),
                     cell_nodes=cell_nodes.astype(np.int64), cell_tag=tag,
                     node_index=gin.astype(np.int64), node_x=compat.geometry_x(mesh).copy(),
                     facet_nodes=fnodes.astype(np.int64), facet_tag=fval,
                     high_nodes=high.astype(np.int64))


def gather(part: LocalPart, mesh, cell_type: str,
           names: Mapping[str, int | tuple[int, int]] | None,
           replicate: bool = True) -> MeshData:
    """The global MeshData from every rank's part (collective on the mesh's communicator).

    With ``replicate=False`` only rank 0 gathers and holds the arrays; the others get
    :meth:`MeshData.names_only`.
    """
    comm = mesh.comm
    if replicate or comm.size == 1:
        return _global(comm.allgather(part), mesh, cell_type, names)
    parts, data, names_only = comm.gather(part, root=0), None, None
    with collective(comm, "mesh"):
        if comm.rank == 0:
            data = _global(parts, mesh, cell_type, names)
            names_only = data.names_only()
    del parts
    if comm.rank == 0:
        comm.bcast(names_only, root=0)
        data.source = DolfinxSource(mesh, data.source.input_nodes, data.source.input_cells,
                                    comm)
    else:
        data = comm.bcast(None, root=0)
        data.source = DolfinxSource(mesh, None, None, comm)
    data.root_only = comm
    return data


def scatter(part: LocalPart, mesh, cell_type: str,
            names: Mapping[str, int | tuple[int, int]] | None) -> MeshData:
    """Each rank's block of the mesh from every rank's part (collective).

    Rank 0 gathers the parts into the whole mesh, checks it and hands it out as
    :func:`~.distributed.scatter_mesh` does; the link to the user's mesh becomes a directory
    of the input indices of the vertices and cells (:class:`DolfinxSource`).
    """
    from .distributed import scatter_mesh

    comm = mesh.comm
    parts, whole = comm.gather(part, root=0), None
    with collective(comm, "mesh"):
        if comm.rank == 0:
            whole = _global(parts, mesh, cell_type, names)
    del parts
    input_cells = whole.source.input_cells if comm.rank == 0 else None
    data = scatter_mesh(whole, comm)
    del whole
    cells_in = answered_by_root(comm, data.part.cell_ids, lambda ids: input_cells[ids])
    data.source = DolfinxSource(
        mesh, _directory(comm, data.node_tags, data.part.vertex_ids),
        _directory(comm, cells_in, data.part.cell_ids), directory=comm)
    return data


def _global(parts: list[LocalPart], mesh, cell_type: str,
            names: Mapping[str, int | tuple[int, int]] | None) -> MeshData:
    """The global MeshData from all ranks' parts."""
    cat = {k: np.concatenate([getattr(p, k) for p in parts]) for k in vars(parts[0])}
    order = np.argsort(cat["cell_index"], kind="stable")
    input_cells = cat["cell_index"][order]
    if np.any(np.diff(input_cells) == 0):
        raise InputError("from_dolfinx: a cell is owned by two ranks (corrupt mesh)")
    cell_nodes, cell_tag = cat["cell_nodes"][order], cat["cell_tag"][order]
    tdim = REFERENCE[cell_type].tdim
    if np.any(cell_tag < 0):
        raise InputError(f"from_dolfinx: {int(np.sum(cell_tag < 0))} of {cell_tag.size} cells "
                         "have no cell tag; every cell must belong to a body (tag all cells, "
                         f"e.g. with physical groups of dimension {tdim} in gmsh)")
    used = np.unique(cell_nodes)  # global vertex v is input node used[v]
    uidx, first = np.unique(cat["node_index"], return_index=True)
    x = cat["node_x"][first][np.searchsorted(uidx, used)]
    cells = np.searchsorted(used, cell_nodes)

    cell_values = np.unique(cell_tag)
    fnodes, fval = cat["facet_nodes"], cat["facet_tag"]
    facet_values = np.unique(fval)
    body_name, facet_name = _names(cell_values, facet_values, tdim, names)
    body_index = np.searchsorted(cell_values, cell_tag)

    facet_groups: dict[str, np.ndarray] = {}
    if fnodes.shape[0]:
        pos = np.minimum(np.searchsorted(used, fnodes), used.size - 1)
        if np.any(used[pos] != fnodes):
            raise InputError("from_dolfinx: tagged facets have vertices in no cell")
        # One facet per (tag, vertex set) (a facet on a rank boundary is tagged on both
        # ranks), in the vertex order of the facet in its cell: the same for any ranks.
        keys = row_keys(pos, used.size)
        key_rank = np.searchsorted(np.unique(keys), keys)
        one = np.unique(np.stack([fval, key_rank], axis=1), axis=0, return_index=True)[1]
        fglob, fval_u = pos[one], fval[one]
        cell, local = locate_facets(cells, fglob, cell_type)
        if np.any(cell < 0):
            raise InputError("from_dolfinx: facet tags mark entities that are no facet of a "
                             "cell")
        fglob = cell_facets(cells, cell_type)[cell, local]
        for v in facet_values:
            facet_groups[facet_name[int(v)]] = fglob[fval_u == v]

    high_order = None
    if cat["high_nodes"].shape[1]:  # curved cells: the node of each edge, face, interior
        high_order = {}
        hx = cat["node_x"][first][np.searchsorted(uidx, cat["high_nodes"][order])]
        col = 0
        for dim, local in degree2_entities(cell_type):
            ents = cells[:, np.array(local)]  # (C, ne, nve)
            ne = ents.shape[1]
            flat = ents.reshape(-1, ents.shape[2])
            _, one = np.unique(row_keys(flat, used.size), return_index=True)
            high_order[dim] = (flat[one], hx[:, col:col + ne].reshape(-1, hx.shape[2])[one])
            col += ne

    group_tags = {body_name[int(v)]: int(v) for v in cell_values}
    group_tags.update({facet_name[int(v)]: int(v) for v in facet_values})
    from .checks import check_mesh  # degenerate or inverted cells

    data = MeshData(x=x, cells=cells, cell_type=cell_type,
                    cell_body=body_index.astype(np.int32),
                    body_names=tuple(body_name[int(v)] for v in cell_values),
                    facet_groups=facet_groups, node_tags=used.astype(np.int64),
                    group_tags=group_tags,
                    source=DolfinxSource(mesh, used, input_cells), high_order=high_order)
    check_mesh(data)
    return data


def _names(cell_values: np.ndarray, facet_values: np.ndarray, tdim: int,
           names: Mapping[str, int | tuple[int, int]] | None
           ) -> tuple[dict[int, str], dict[int, str]]:
    """tag → name for the cell tags and the facet tags, with the checks of ``names``."""
    body = {int(v): str(int(v)) for v in cell_values}
    facet = {int(v): str(int(v)) for v in facet_values}
    named: dict[tuple[int, int], str] = {}  # (dim, tag) → the name given to it
    for name, tag in dict(names or {}).items():
        if isinstance(tag, tuple):
            if len(tag) != 2 or tag[0] not in (tdim, tdim - 1):
                raise InputError(f"from_dolfinx: names[{name!r}] = {tag}: expected a tag or "
                                 f"(dim, tag) with dim {tdim} (cells) or {tdim - 1} (facets)")
            dim, value = int(tag[0]), int(tag[1])
            targets = [body] if dim == tdim else [facet]
        else:
            value = int(tag)
            targets = [t for t in (body, facet) if value in t]
            if len(targets) == 2:
                raise InputError(f"from_dolfinx: tag {value} ({name!r}) is used by cells and "
                                 f"by facets: give names[{name!r}] = (dim, {value})")
        targets = [t for t in targets if value in t]
        if not targets:
            raise InputError(f"from_dolfinx: names[{name!r}] = {tag}: no such tag; the cell "
                             f"tags are {sorted(body)}, the facet tags {sorted(facet)}")
        key = (tdim if targets[0] is body else tdim - 1, value)
        if key in named:  # one group has one name: a second would silently replace the first
            raise InputError(f"from_dolfinx: names {named[key]!r} and {name!r} both name the "
                             f"{'cell' if key[0] == tdim else 'facet'} tag {value}; give each "
                             "tag one name (a group used in two roles is named once and used "
                             "twice)")
        named[key] = str(name)
        targets[0][value] = str(name)
    every = list(body.values()) + list(facet.values())
    twice = sorted({n for n in every if every.count(n) > 1})
    if twice:
        raise InputError(f"from_dolfinx: group names used twice: {twice}")
    return body, facet


__all__ = ["DolfinxSource", "LocalPart", "from_dolfinx", "gather", "local_part", "scatter"]
