"""The ranks' shares of a distributed mesh, built without any rank holding the whole problem.

The counterpart of :func:`~dolfinx_feti.setup.share.share_out` for a mesh read with
``distribute=True`` (:mod:`.mesh.distributed`): every rank starts from its block of cells and
ends with the same :class:`~dolfinx_feti.setup.share.RankShare` that rank 0 would have handed it,
field for field:

1. the decomposition of the distributed mesh (:mod:`.mesh.distributed_decompose`: the serial
   subdomains, computed in parallel);
2. the global dof points of the local cells and the number of points of every subdomain
   (:mod:`.mesh.distributed_points`), hence the owner of every subdomain;
3. the cells, with their points and boundary facets, move to the owners of their subdomains;
4. the node directory gives every point the subdomains holding it; the Dirichlet mask and the
   rows each rank owns follow from it (:mod:`.constraints.distributed_rows`), in the serial
   order.

Only arrays of one entry per subdomain (owners, sizes, bodies) are global.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace

import numpy as np
from mpi4py import MPI

from ..constraints.build import surface_rows
from ..constraints.distributed_rows import dirichlet_mask_distributed, own_rows, shared_points
from ..constraints.friction import friction_data
from ..constraints.rows import Rows
from ..errors import InputError, collective
from ..mesh.decompose import pair_keys
from ..mesh.distributed_decompose import decompose_distributed
from ..mesh.distributed_points import (
    SubdomainDirectory,
    index_ranges,
    migrate,
    number_points,
    owners,
    point_coordinates,
    unique_sorted,
)
from ..mesh.dofpoints import DofPoints, dof_points
from ..mesh.topology import REFERENCE, locate_few_facets
from ..parallel.exchange import answer, exchange
from ..timing import Timer
from .share import LocalDecomposition, RankRows, RankShare, local_entities, row_subset


@dataclass
class NodeDirectory:
    """What a rank knows of its points beyond its own subdomains (a distributed mesh).

    Attributes:
        ptr, subs: The sorted subdomains (all ranks') holding local point i are
            ``subs[ptr[i]:ptr[i + 1]]``.
        fixed: (n, bs) Dirichlet mask of the local points.
    """

    ptr: np.ndarray
    subs: np.ndarray
    fixed: np.ndarray


def share_from_parts(problem, comm: MPI.Comm, timer: Timer | None = None, whole=None
                     ) -> tuple[RankShare, Surface | None, list]:
    """This rank's share of ``problem``, whose mesh is distributed (collective).

    Args:
        problem: The contact problem (``problem.mesh.part`` is set).
        comm: The mesh's ranks.
        timer: Records the phases ``decomposition``, ``distribution`` (dof points, the node
            directory, the cells moved to their owners) and ``constraints`` (rows).
        whole: For the blocks of a curved mesh held whole, its dof points
            (:class:`.whole_mesh.WholePoints`: the geometry nodes of edges and faces); None
            otherwise.

    Returns:
        ``(share, surface, mortar)``: the share; with contact or ties, the cells along the
        contact surfaces gathered on rank 0 (:class:`Surface`; None elsewhere and without
        contact); what the mortar search found (every rank).
    """
    mesh, part, bs = problem.mesh, problem.mesh.part, problem.value_size
    if MPI.Comm.Compare(part.comm, comm) not in (MPI.IDENT, MPI.CONGRUENT):
        raise InputError("the mesh is distributed over another communicator "
                         "(read_gmsh(..., distribute=True)): solve on that communicator")
    timer = Timer() if timer is None else timer
    cells = part.vertex_ids[mesh.cells]
    cell_x = mesh.x[mesh.cells]
    with timer.phase("decomposition"):
        cell_sub, sub_body = decompose_distributed(
            cells, cell_x, part.cell_ids, mesh.cell_body, mesh.cell_type, mesh.body_names,
            mesh.num_cells, problem.decomposition, comm, whole=part.whole_cells)
    with timer.phase("distribution"):
        cell_points, num_points, first = number_points(cells, mesh.cell_type, problem.degree,
                                                       mesh.num_nodes, comm)
        nsub = sub_body.size
        # built before the cells move, the directory answers for their points after it
        directory = SubdomainDirectory(cell_points, cell_sub, num_points, nsub, comm)
        sub_size = directory.sub_size
        sub_rank = owners(sub_size, comm.size)

        dest = sub_rank[cell_sub]
        facets = _move_facets(mesh, dest, cell_sub, comm)
        cells, cell_x, cell_body, cell_ids, cell_sub, cell_points, tags = migrate(
            dest, cells, cell_x, mesh.cell_body, part.cell_ids, cell_sub, cell_points,
            mesh.node_tags[mesh.cells], comm=comm, key=part.cell_ids)
        local_mesh, points, pids, vids = _local_mesh(
            mesh, cells, cell_x, cell_body, tags, cell_points, first, problem.degree, whole)
        local_points = points.cell_points
        subs = np.flatnonzero(sub_rank == comm.rank)
        keys = pair_keys(cell_sub, local_points, pids.size)
        pair_sub, pair_node = keys // pids.size, keys % pids.size
        pair_ptr = np.searchsorted(pair_sub, np.r_[subs, subs[-1] + 1] if subs.size else [0])
        ptr, node_subs = directory.ask(pids)
        multiplicity = np.diff(ptr)[pair_node]
        dec = LocalDecomposition(subs=subs, cell_sub=cell_sub, sub_body=sub_body,
                                 sub_rank=sub_rank, sub_size=sub_size, pair_node=pair_node,
                                 pair_ptr=pair_ptr, multiplicity=multiplicity)

    with timer.phase("constraints"):
        names = list(mesh.facet_groups)
        f_vert, f_group, f_sub, f_index = facets
        local_f = np.searchsorted(vids, f_vert)
        sub_facets: dict[int, dict[str, np.ndarray]] = {int(s): {} for s in subs}
        for s in np.unique(f_sub):  # over this rank's subdomains
            here = f_sub == s
            for g in np.unique(f_group[here]):
                sub_facets.setdefault(int(s), {})[names[g]] = local_f[here & (f_group == g)]

        conditions = _dirichlet_points(problem, local_mesh, points, local_f, f_group, names, pids)
        # a point no other rank holds has all its cells, so all its facets, here: no exchange
        fixed, values = dirichlet_mask_distributed(
            pids, conditions, bs, num_points, comm,
            shared=shared_points(ptr, node_subs, sub_rank, comm.rank))
        nodes = NodeDirectory(ptr, node_subs, fixed)
        surface = None
        extra = Rows.empty(mesh.gdim)
        mortar: list = []
        if problem.contact or problem.ties:
            on = np.isin(f_group, [names.index(g) for g in _contact_groups(problem)])
            surface, extra, mortar = gather_surface(
                problem, (f_vert[on], f_group[on], f_index[on], local_f[on]), names, local_mesh,
                cell_ids, cell_points, local_points, pids, nodes, comm, whole)
        own, start, size = own_rows(pids, ptr, node_subs, fixed, values, bs, mesh.gdim,
                                    problem.gluing, sub_rank, comm, extra=extra)
        cols = columns(own, pair_sub, pair_node, pids, num_points, sub_size, sub_rank, bs, comm)
        rows = RankRows(own=own, cols=cols, start=start, size=size,
                        **_contact_rows(own, start, extra, comm))
    share = RankShare(mesh=local_mesh, points=points, point_ids=pids, cell_ids=cell_ids,
                      num_points=num_points, num_cells=mesh.num_cells, dec=dec,
                      facets=sub_facets, group_errors=dict(part.verdicts.boundary), rows=rows,
                      directory=nodes)
    return share, surface, mortar


def _move_facets(mesh, dest: np.ndarray, cell_sub: np.ndarray, comm: MPI.Comm):
    """The boundary facets sent with the cell they bound to its new rank.

    Returns:
        ``(vertices, group, subdomain, position in the group)`` of the facets this rank
        receives, ordered by subdomain, group, then the file's order.
    """
    part = mesh.part
    names = list(mesh.facet_groups)
    facets = [mesh.facet_groups[n] for n in names]
    nvf = len(REFERENCE[mesh.cell_type].facets[0])
    all_f = np.concatenate(facets) if facets else np.zeros((0, nvf), dtype=np.int64)
    group = np.repeat(np.arange(len(names)), [f.shape[0] for f in facets])
    index = np.concatenate([part.facet_index[n] for n in names]) if names else \
        np.zeros(0, dtype=np.int64)
    f_cell, _ = locate_few_facets(mesh.cells, all_f, mesh.cell_type)
    (vertices, group, sub, index), *_ = exchange(
        comm, dest[f_cell], part.vertex_ids[all_f], group, cell_sub[f_cell], index)
    order = np.lexsort((index, group, sub))
    return vertices[order], group[order], sub[order], index[order]


def _local_mesh(mesh, cells, cell_x, cell_body, tags, cell_points, first, degree, whole):
    """The rank's cells as a mesh and their dof points, numbered in the global order.

    The points of a curved mesh's edges and faces are its geometry nodes (``whole``).

    Returns:
        ``(local mesh, local dof points, global number of each point, of each vertex)``.
    """
    vids, local_cells = _compact(cells)
    x = np.zeros((vids.size, mesh.gdim))
    x[local_cells.ravel()] = cell_x.reshape(-1, mesh.gdim)
    node_tags = np.zeros(vids.size, dtype=mesh.node_tags.dtype)
    node_tags[local_cells.ravel()] = tags.ravel()
    if degree == 1:  # the points are the vertices (number_points)
        pids, point_x, local_points = vids, x, local_cells
    else:
        pids, point_x = point_coordinates(cell_points, cells, cell_x, mesh.cell_type, degree)
        local_points = np.searchsorted(pids, cell_points)
    if whole is not None:
        point_x = whole.of(pids)
    local_mesh = replace(mesh.names_only(), x=x, cells=local_cells, cell_body=cell_body,
                         node_tags=node_tags, counts={}, part=None)
    local_first = {d: int(np.searchsorted(pids, f)) for d, f in first.items()}
    entities = local_entities(mesh.cell_type, local_cells, vids.size, local_first)
    points = DofPoints(degree, mesh.cell_type, point_x, local_points, vids.size, entities)
    return local_mesh, points, pids, vids


def _compact(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(cells, return_inverse=True)``, the inverse in the shape of ``cells``.

    By a mask over the range of the numbers when it is not much longer than ``cells`` (a
    rank's vertices are mostly a few ranges of the global numbering), else by a sort.
    """
    lo, hi = (int(cells.min()), int(cells.max())) if cells.size else (0, -1)
    if hi - lo >= cells.size:
        vids, _, inverse = unique_sorted(cells.ravel())
        return vids, inverse.reshape(cells.shape)
    mark = np.zeros(hi - lo + 1, dtype=bool)
    mark[cells - lo] = True
    vids = np.flatnonzero(mark)
    local = np.empty(mark.size, dtype=np.int64)
    local[vids] = np.arange(vids.size)
    return vids + lo, local[cells - lo]


def _contact_groups(problem) -> list[str]:
    """The boundary groups of the problem's contact conditions and ties."""
    return sorted({g for c in [*problem.contact, *problem.ties] for g in c.groups})


def _contact_rows(own: Rows, start: int, extra: Rows, comm: MPI.Comm) -> dict:
    """The contact rows of the whole problem (every rank) and their global indices.

    ``extra`` holds them in the order of the serial concatenation; sorted stably by their
    smallest subdomain they are in the global order. Each rank knows the global index of
    those it owns.
    """
    mine = np.flatnonzero(own.inequality | own.tangential) + start
    index = np.concatenate(comm.allgather(mine)).astype(np.int64)
    ordered = extra.permuted(np.argsort(extra.min_subdomain(), kind="stable")) if extra.size \
        else extra
    if ordered.size and np.any(np.diff(ordered.e_row) < 0):
        ordered = ordered.permuted(np.arange(ordered.size))
    contact = row_subset(ordered, np.flatnonzero(ordered.inequality | ordered.tangential))
    if contact.size != index.size:
        raise AssertionError("the ranks' contact rows are not the gathered ones")
    return {"contact": contact, "contact_index": index}


@dataclass
class Surface:
    """The cells along the contact surfaces of a distributed mesh, gathered on rank 0.

    Attributes:
        problem: The problem on the mesh of those cells (its points numbered compactly).
        point_ids: Global dof point of each of its points (ascending).
        fixed: (points, bs) mask of its points' Dirichlet-held components (the rows were
            built with it: the symmetry planes of the friction rows).
    """

    problem: object
    point_ids: np.ndarray
    fixed: np.ndarray | None = None

    def local(self, points: np.ndarray) -> np.ndarray:
        """The surface mesh's point of each global point."""
        return np.searchsorted(self.point_ids, points)


def gather_surface(problem, facets, names, local_mesh, cell_ids, cell_points, local_points,
                   pids, nodes, comm, whole=None):
    """The contact and tie rows of a distributed mesh, from its contact surfaces (collective).

    Every rank sends rank 0 the cells of its subdomains at a node of a contact group's facet,
    with their points' subdomain lists and Dirichlet flags; rank 0 builds the rows on that
    one layer of cells with the serial builders (:func:`.constraints.build.surface_rows`) and
    maps its points back to the global ones (a monotone map: every order by point survives).

    Args:
        problem: The problem (on the distributed mesh).
        facets: This rank's contact facets: global vertices, group index, index in the
            group, local vertices.
        names: The boundary groups, by index.
        local_mesh: This rank's cells (local vertices).
        cell_ids: Their global numbers.
        cell_points: Their global dof points.
        local_points: Their local dof points.
        pids: The global number of each local point.
        nodes: The subdomains and the Dirichlet mask of the local points
            (:class:`NodeDirectory`).
        comm: The ranks.
        whole: A curved mesh's :class:`.whole_mesh.WholePoints`, or None.

    Returns:
        ``(surface, rows, mortar)``: the :class:`Surface` (rank 0; None elsewhere), the rows
        (every rank) in global points, what the mortar search found (every rank).
    """
    f_vert, f_group, f_index, local_f = facets
    # every cell at a surface node: the boundary around the surfaces is then the whole mesh's
    # (the open-rim check of a mortar surface reads the facets next to its rim)
    on = np.unique(np.concatenate(comm.allgather(np.unique(f_vert))))
    nv = local_mesh.x.shape[0]
    sc = np.flatnonzero(np.isin(pids[:nv][local_mesh.cells], on).any(axis=1))
    sp = np.unique(local_points[sc])
    counts = np.diff(nodes.ptr)[sp]
    piece = {"ids": cell_ids[sc], "vertices": pids[:nv][local_mesh.cells[sc]],
             "x": local_mesh.x[local_mesh.cells[sc]], "body": local_mesh.cell_body[sc],
             "tags": local_mesh.node_tags[local_mesh.cells[sc]], "cp": cell_points[sc],
             "f_vert": f_vert, "f_group": f_group, "f_index": f_index,
             "points": pids[sp], "counts": counts, "fixed": nodes.fixed[sp],
             "subs": nodes.subs[index_ranges(nodes.ptr[sp], counts)]}
    pieces = comm.gather(piece, root=0)
    surface = out = None
    with collective(comm, "constraints"):
        if comm.rank == 0:
            mesh, gmap, node_ptr, node_subs, fixed_s = _surface_mesh(problem, pieces, names,
                                                                      whole)
            surf = copy.copy(problem)
            object.__setattr__(surf, "mesh", mesh)  # the same conditions on the layer of cells
            if dof_points(mesh, problem.degree).num_points != gmap.size:
                raise AssertionError("the surface points do not match the gathered ones")
            mortar: list = []
            blocks = surface_rows(surf, node_ptr, node_subs, fixed_s, mortar)
            rows = Rows.concatenate(blocks) if blocks else Rows.empty(mesh.gdim)
            if not np.all(np.isfinite(rows.rhs)) or not np.all(np.isfinite(rows.e_coef)):
                raise InputError("non-finite constraint data (a gap or an obstacle distance "
                                 "is NaN or Inf)")
            rows = replace(rows, e_node=gmap[rows.e_node], node=np.where(
                rows.node >= 0, gmap[np.maximum(rows.node, 0)], -1), partner=np.where(
                rows.partner >= 0, gmap[np.maximum(rows.partner, 0)], -1))
            surface = Surface(surf, gmap, fixed_s)
            out = (rows, mortar)
    rows, mortar = comm.bcast(out, root=0)
    return surface, rows, mortar


def surface_friction(surface: Surface, rows: RankRows):
    """The friction data of a distributed mesh (rank 0), from the contact rows.

    :func:`~.constraints.friction.friction_data` on the contact rows in their global order,
    with the points of the surface mesh; its row indices then become global ones.
    """
    c = rows.contact
    found = friction_data(surface.problem, replace(c, node=surface.local(c.node)),
                          surface.fixed)
    if found is None:
        return None
    index = rows.contact_index
    return replace(found, rows=index[found.rows], normal_row=index[found.normal_row])


def _surface_mesh(problem, pieces: list[dict], names: list[str], whole=None):
    """Rank 0: the gathered cells as a mesh, its points' global numbers and directory.

    On a curved mesh held whole (``whole``) the gathered cells keep their geometry nodes.
    """
    def cat(key):
        return np.concatenate([p[key] for p in pieces])

    order = np.argsort(cat("ids"))
    vertices = cat("vertices")[order]
    vids, cells = np.unique(vertices, return_inverse=True)
    cells = cells.reshape(vertices.shape)
    names_of = problem.mesh
    x = np.zeros((vids.size, names_of.gdim))
    x[cells.ravel()] = cat("x")[order].reshape(-1, names_of.gdim)
    tags = np.zeros(vids.size, dtype=names_of.node_tags.dtype)
    tags[cells.ravel()] = cat("tags")[order].ravel()
    f_vert, f_group, f_index = cat("f_vert"), cat("f_group"), cat("f_index")
    groups = {}
    for g, name in enumerate(names):
        sel = np.flatnonzero(f_group == g)
        sel = sel[np.argsort(f_index[sel], kind="stable")]  # the file's order
        groups[name] = np.searchsorted(vids, f_vert[sel])
    mesh = replace(names_of.names_only(), x=x, cells=cells, cell_body=cat("body")[order],
                   node_tags=tags, facet_groups=groups, counts={}, part=None,
                   high_order=None if whole is None else _restricted(whole.mesh.high_order, vids))
    pts = dof_points(mesh, problem.degree)
    gmap = np.empty(pts.num_points, dtype=np.int64)
    gmap[pts.cell_points] = cat("cp")[order]
    points, counts, subs, fixed = cat("points"), cat("counts"), cat("subs"), cat("fixed")
    first_sub = np.cumsum(counts) - counts
    _, first = np.unique(points, return_index=True)  # a point sent by several ranks
    at = first[np.searchsorted(points[first], gmap)]
    node_ptr = np.r_[0, np.cumsum(counts[at])].astype(np.int64)
    node_subs = subs[index_ranges(first_sub[at], counts[at])]
    return mesh, gmap, node_ptr, node_subs.astype(np.int32), fixed[at]


def _restricted(high_order: dict, vids: np.ndarray) -> dict:
    """The geometry nodes of the entities whose vertices are all among ``vids`` (ascending).

    Their vertices are numbered by their position in ``vids``.
    """
    out = {}
    for dim, (ent, pos) in high_order.items():
        keep = np.all(np.isin(ent, vids), axis=1)
        out[dim] = (np.searchsorted(vids, ent[keep]), pos[keep])
    return out


def _dirichlet_points(problem, local_mesh, points, local_f, f_group, names, pids) -> list:
    """Per Dirichlet condition: the global points on this rank's facets of its group."""
    conditions = []
    for bc in problem.dirichlet:
        f = local_f[f_group == names.index(bc.group)]
        on = np.unique(points.facet_points(local_mesh, f)) if f.size else \
            np.zeros(0, dtype=np.int64)
        conditions.append((bc, pids[on], points.x[on]))
    return conditions


def columns(own: Rows, pair_sub, pair_node, pids, num_points, sub_size, sub_rank, bs, comm):
    """The global primal column of every entry of this rank's rows.

    The column of (subdomain s, point p, component c) is bs · (the pairs of the subdomains
    before s + the position of p among the sorted points of s) + c; the position is asked of
    the rank that owns s (a gluing row touches subdomains of other ranks).
    """
    sub_start = np.r_[0, np.cumsum(sub_size)].astype(np.int64)
    (s_asked, p_asked), order, counts, rcounts = exchange(
        comm, sub_rank[own.e_sub], own.e_sub.astype(np.int64), own.e_node.astype(np.int64))
    pairs = pair_sub * np.int64(num_points) + pids[pair_node]  # sorted: (subdomain, point)
    want = s_asked * np.int64(num_points) + p_asked
    pos = np.searchsorted(pairs, want)
    if want.size and (np.any(pos >= pairs.size) or np.any(pairs[np.minimum(
            pos, pairs.size - 1)] != want)):
        raise AssertionError("a row refers to a point outside its subdomain")
    within = pos - np.searchsorted(pair_sub, s_asked)
    return bs * (sub_start[own.e_sub] + answer(comm, within, order, counts, rcounts)) \
        + own.e_comp


__all__ = ["NodeDirectory", "share_from_parts"]
