"""The replicated set-up, kept as the oracle of the one set-up pipeline.

Before the pipeline was one (issue 21), a mesh held whole was decomposed, given its rows and
split into the ranks' shares on rank 0 from the global arrays; the distributed set-up
(:mod:`dolfinx_feti.setup.share_distributed`) was written to reproduce it field for field.
Every way of holding the mesh now runs the distributed one; this is the specification its
tests compare with: :func:`build_rows` (all rows from the global decomposition),
:func:`share_out` (rank 0 splits and hands out the shares), :func:`fetidp_parts` (FETI-DP's
corners and floating motions from the global arrays) and :func:`choose_method` (the rule of
``method="auto"`` on the global rows).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from scipy.sparse.csgraph import connected_components

from dolfinx_feti.constraints import Kind
from dolfinx_feti.constraints.build import surface_rows
from dolfinx_feti.constraints.dirichlet import dirichlet_mask, dirichlet_rows
from dolfinx_feti.constraints.gluing import gluing_rows
from dolfinx_feti.constraints.mortar_rows import MortarInfo
from dolfinx_feti.constraints.rows import Rows
from dolfinx_feti.errors import InputError, collective
from dolfinx_feti.fem import corners as C
from dolfinx_feti.fem.corners import (
    body_label,
    components_of_pairs,
    glob_keys,
    held_alone,
    join_pair,
    motions_at,
    primal_globs,
    scaled_motions,
)
from dolfinx_feti.fem.rigid import rigid_motions
from dolfinx_feti.mesh.checks import boundary_facets, boundary_group_verdicts
from dolfinx_feti.mesh.data import MeshData
from dolfinx_feti.mesh.decompose import Decomposition
from dolfinx_feti.mesh.dofpoints import DofPoints
from dolfinx_feti.mesh.topology import REFERENCE, facet_neighbours, locate_facets
from dolfinx_feti.parallel.exchange import hand_out
from dolfinx_feti.problem.contact_problem import ContactProblem
from dolfinx_feti.setup.method_rule import method_by_time
from dolfinx_feti.setup.share import (
    LocalDecomposition,
    RankRows,
    RankShare,
    local_entities,
    row_slice,
    row_subset,
)
from dolfinx_feti.setup.stages import CORNER_EDGES, CORNERS_ON_CONTACT


def build_rows(problem: ContactProblem, dec: Decomposition,
               mortar: list[MortarInfo] | None = None) -> Rows:
    """Gluing, Dirichlet and contact rows, sorted by the subdomain that owns them.

    ``mortar``, when given, receives what the contact search found for each :class:`Mortar`
    and :class:`Tie` condition (for the report and the post-solve checks).

    Rows are sorted (stably) by the smallest subdomain they touch, so the rows owned by a rank
    are contiguous and the global order does not depend on the number of ranks. The normal and
    tangential (friction) rows of a contact node touch the same subdomains, so they stay
    consecutive.
    """
    mesh, bs = problem.mesh, problem.value_size
    node_ptr, node_subs = dec.node_subdomains()
    fixed, values = dirichlet_mask(problem, mesh)
    blocks = [gluing_rows(node_ptr, node_subs, fixed, bs, mesh.gdim, problem.gluing),
              dirichlet_rows(node_ptr, node_subs, fixed, values, bs, mesh.gdim),
              *surface_rows(problem, node_ptr, node_subs, fixed, mortar)]
    rows = Rows.concatenate(blocks)
    if not np.all(np.isfinite(rows.rhs)) or not np.all(np.isfinite(rows.e_coef)):
        raise InputError("non-finite constraint data (a Dirichlet value, a gap or an obstacle "
                         "distance is NaN or Inf)")
    return rows.permuted(np.argsort(rows.min_subdomain(), kind="stable"))


def row_ranges(rows: Rows, dec: Decomposition, size: int) -> np.ndarray:
    """Rank r owns the rows ``bounds[r]:bounds[r+1]`` (rows are sorted by owner)."""
    owner = dec.sub_rank[rows.min_subdomain()]
    return np.r_[0, np.cumsum(np.bincount(owner, minlength=size))].astype(np.int64)


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


def fetidp_parts(problem: ContactProblem, dec, rows, size: int) -> list[dict]:
    """FETI-DP's corners and floating motions, for the dofs of each rank (on rank 0)."""
    mesh, bs = problem.mesh, problem.value_size
    fixed, _ = dirichlet_mask(problem, mesh)
    avoid = None if CORNERS_ON_CONTACT else np.unique(np.r_[
        rows.e_node[~np.isin(rows.kind[rows.e_row], (Kind.GLUE, Kind.DIRICHLET))]])
    x = problem.dof_points.x
    corners = choose_corners(mesh, dec, fixed, bs, avoid, x,
                             edges=CORNER_EDGES and mesh.gdim == 3)
    dofs = []
    for r in range(size):
        pairs = dec.rank_pairs(r)
        node = np.repeat(dec.pair_node[pairs], bs)
        dofs.append((node, np.tile(np.arange(bs), node.size // bs),
                     np.repeat(dec.pair_sub[pairs], bs)))
    modes, bodies = floating_motions(mesh, dec, rows, fixed, bs, dofs, x,
                                     primal_components(mesh, dec))
    info = {"corner_nodes": int(corners.nodes.size), "vertices": corners.vertices,
            "corner_dofs": corners.count}
    return [{"corners": corners.local(node, comp), "count": corners.count, "modes": Z,
             "bodies": bodies, "info": info} for (node, comp, _), Z in zip(dofs, modes,
                                                                          strict=True)]


def choose_method(problem: ContactProblem, dec, rows) -> str:
    """The method ``method="auto"`` picks, by the rule of
    :func:`dolfinx_feti.setup.method_rule.method_by_time`, on the global arrays.

    Reads the global decomposition and rows (on the rank that holds them).
    """
    return method_by_time(bool(np.any(rows.kind == Kind.GLUE)), dec.num_subdomains,
                          len(problem.mesh.body_names), problem.mesh.gdim)


def serial_share_problem(problem: ContactProblem, comm: MPI.Comm, method: str = "tfeti"):
    """The set-up of a whole mesh as it was: rank 0 decomposes, builds the rows, hands out.

    Returns:
        The :class:`~dolfinx_feti.setup.stages.SharedProblem` of the replicated set-up.
    """
    from dolfinx_feti.constraints.friction import friction_data
    from dolfinx_feti.mesh.decompose import decompose
    from dolfinx_feti.setup.stages import SharedProblem

    dec = rows = extra = common = fdata = None
    with collective(comm, "decomposition"):
        if comm.rank == 0:
            dec = decompose(problem.mesh, problem.decomposition, comm.size, problem.dof_points)
    with collective(comm, "constraints"):
        if comm.rank == 0:
            mortar: list = []
            rows = build_rows(problem, dec, mortar)
            if method == "auto":
                method = choose_method(problem, dec, rows)
            if method == "fetidp":
                extra = fetidp_parts(problem, dec, rows, comm.size)
            common = (method, mortar)
            fdata = friction_data(problem, rows, dirichlet_mask(problem, problem.mesh)[0])
    method, mortar = comm.bcast(common, root=0)
    fdata = comm.bcast(fdata, root=0)
    share = share_out(problem.mesh, problem.dof_points if comm.rank == 0 else None, dec,
                      rows, problem.value_size, comm, extra)
    return SharedProblem(share, method, mortar, fdata, comm=comm)


def serial_dual_qp(problem: ContactProblem, comm: MPI.Comm = MPI.COMM_WORLD,
                   method: str = "tfeti", **options):
    """:func:`dolfinx_feti.dual_qp` on the replicated set-up (:func:`serial_share_problem`)."""
    from dolfinx_feti.fem.assembly import assemble_subdomains
    from dolfinx_feti.setup.stages import qp_of_share
    from dolfinx_feti.timing import Timer

    timer = Timer()
    shared = serial_share_problem(problem, comm, method)
    data = assemble_subdomains(problem, shared.share, comm, timer)
    return qp_of_share(problem, shared, data, timer=timer, **options)


def _same(a, b, what: str) -> None:
    a, b = np.asarray(a), np.asarray(b)
    nan = a.dtype.kind == "f"  # NaN marks "none" in some fields (e.g. friction coefficients)
    assert a.shape == b.shape and np.array_equal(a, b, equal_nan=nan), what


def assert_same_shares(qa, qb) -> None:
    """Two dual QPs' set-ups hand this rank the same share, field for field, bit for bit.

    The cells, dof points (numbers and coordinates), decomposition, facets, rows (own,
    columns, contact), friction data and, for FETI-DP, the corners (the floating motions are
    the same space, summed in another order: ``tests/setup/test_distributed_fetidp.py``).
    """
    a, b = qa.share, qb.share
    for name in ("cell_ids", "point_ids", "num_points", "num_cells"):
        _same(getattr(a, name), getattr(b, name), name)
    for name in ("cells", "cell_body", "node_tags", "x"):
        _same(getattr(a.mesh, name), getattr(b.mesh, name), f"mesh.{name}")
    assert a.mesh.geometry_degree == b.mesh.geometry_degree
    _same(a.points.cell_points, b.points.cell_points, "cell_points")
    _same(a.points.x, b.points.x, "points.x")
    for f in fields(a.dec):
        _same(getattr(a.dec, f.name), getattr(b.dec, f.name), f"dec.{f.name}")
    assert a.facets.keys() == b.facets.keys()
    for s in a.facets:
        assert a.facets[s].keys() == b.facets[s].keys()
        for g in a.facets[s]:
            _same(a.facets[s][g], b.facets[s][g], f"facets[{s}][{g}]")
    assert a.group_errors == b.group_errors
    for name in ("cols", "start", "size", "contact_index"):
        _same(getattr(a.rows, name), getattr(b.rows, name), f"rows.{name}")
    assert (qa.friction is None) == (qb.friction is None)
    if qa.friction is not None:
        for f in fields(qa.friction):
            _same(getattr(qa.friction, f.name), getattr(qb.friction, f.name),
                  f"friction.{f.name}")
    for f in fields(Rows):
        _same(getattr(a.rows.own, f.name), getattr(b.rows.own, f.name), f"own.{f.name}")
        _same(getattr(a.rows.contact, f.name), getattr(b.rows.contact, f.name),
              f"contact.{f.name}")
    assert qa.method == qb.method
    if qa.method == "fetidp":
        for key in ("corners", "count", "bodies", "info"):
            va, vb = a.extra[key], b.extra[key]
            if isinstance(va, dict):
                assert va == vb, key
            else:
                _same(va, vb, f"extra[{key}]")


# FETI-DP's corners and floating motions on the global arrays (the serial drivers of the
# kernels in dolfinx_feti.fem.corners, which fem/distributed_corners.py reproduces)


@dataclass
class Corners:
    """The corner nodes and the numbering of their unknowns.

    Attributes:
        nodes: Corner nodes (global, sorted), including nodes whose every component is fixed.
        index: (N, bs) index of the corner unknown of (node, component), −1 if none (not a
            corner, or a fixed component).
        count: Number of corner unknowns.
        vertices: How many of the nodes are vertices (the rest were added for rigidity).
    """

    nodes: np.ndarray
    index: np.ndarray
    count: int
    vertices: int

    def local(self, dof_node: np.ndarray, dof_comp: np.ndarray) -> np.ndarray:
        """The corner unknown of each local dof, −1 for the others."""
        return self.index[dof_node, dof_comp]


def choose_corners(mesh: MeshData, dec: Decomposition, fixed: np.ndarray,
                   bs: int, avoid: np.ndarray | None = None,
                   x: np.ndarray | None = None, edges: bool = False) -> Corners:
    """The corners of a decomposition (see the module docstring).

    Args:
        mesh: The mesh.
        dec: The decomposition.
        fixed: (N, bs) mask of the components with Dirichlet conditions.
        bs: Components per node.
        avoid: Nodes not to take as vertices; taken only where a pair of subdomains needs
            them to be joined rigidly and no other shared node does it.
        edges: Also every interface node outside the faces (3D: the edges, whole).
        x: Coordinates of the dof points that number the nodes (default: the mesh vertices).
            The vertices come first among them, so the outer boundary marks mesh vertices.
    """
    N = dec.num_nodes
    ptr, subs = dec.node_subdomains()
    mult = np.diff(ptr)
    inter = np.flatnonzero(mult >= 2)
    on_boundary = np.zeros(N, dtype=bool)
    on_boundary[np.unique(boundary_facets(mesh)[0])] = True
    key = glob_keys(ptr, subs, inter, on_boundary[inter], int(mult.max(initial=0)))
    corner = np.zeros(N, dtype=bool)
    corner[inter[primal_globs(key, edges)]] = True
    avoided = np.zeros(N, dtype=bool)
    if avoid is not None:
        avoided[avoid] = True
        corner &= ~avoided
    vertices = int(corner.sum())

    # every pair of subdomains sharing a facet is joined rigidly by its shared corners
    x = mesh.x if x is None else x
    held: dict[int, bool] = {}
    for s, t in facet_pairs(mesh, dec.cell_sub):
        if all(_held(held, dec, x, fixed, bs, int(u)) for u in (s, t)):
            continue
        both = np.intersect1d(dec.nodes(int(s)), dec.nodes(int(t)), assume_unique=True)
        added = join_pair(scaled_motions(x[both], bs), corner[both], fixed[both], avoided[both])
        corner[both[added]] = True
    return numbered(corner, fixed, vertices)


def numbered(corner: np.ndarray, fixed: np.ndarray, vertices: int) -> Corners:
    """The :class:`Corners` of a corner mask (N,) with the Dirichlet mask (N, bs)."""
    nodes = np.flatnonzero(corner)
    unknown = corner[:, None] & ~fixed
    index = np.full(fixed.shape, -1, dtype=np.int64)
    index[unknown] = np.arange(int(unknown.sum()))
    return Corners(nodes=nodes, index=index, count=int(unknown.sum()), vertices=vertices)


def facet_pairs(mesh: MeshData, cell_sub: np.ndarray) -> np.ndarray:
    """The pairs (s < t) of subdomains that share a facet, sorted, each once."""
    pair = np.sort(cell_sub[facet_neighbours(mesh.cells, mesh.cell_type)], axis=1)
    return np.unique(pair[pair[:, 0] != pair[:, 1]], axis=0)


def _held(cache: dict, dec: Decomposition, x: np.ndarray, fixed: np.ndarray, bs: int,
          s: int) -> bool:
    """Whether subdomain ``s`` is held rigidly by its Dirichlet conditions alone."""
    if s not in cache:
        nodes = dec.nodes(s)
        cache[s] = held_alone(x[nodes], fixed[nodes], bs)
    return cache[s]


def components(rows: Rows, num_subdomains: int) -> np.ndarray:
    """Component of every subdomain: subdomains joined by equality rows (gluing, ties)."""
    eq = ~rows.inequality & (rows.kind != Kind.TANGENT)
    sel = eq[rows.e_row]
    r, s = rows.e_row[sel], rows.e_sub[sel].astype(np.int64)
    order = np.argsort(r, kind="stable")
    r, s = r[order], s[order]
    first = np.searchsorted(r, r)  # the first entry of each entry's row
    graph = sp.coo_matrix((np.ones(s.size), (s, s[first])),
                          shape=(num_subdomains, num_subdomains))
    return connected_components(graph, directed=False)[1]


def primal_components(mesh: MeshData, dec: Decomposition) -> np.ndarray:
    """Component of every subdomain for FETI-DP: subdomains joined through shared facets.

    Subdomains that share a facet are joined rigidly by their corners (:func:`choose_corners`);
    bodies joined only by rows of B (mortar ties, contact) are not: their relative rigid
    motions stay in the kernel of K̃.
    """
    return components_of_pairs(facet_pairs(mesh, dec.cell_sub), dec.num_subdomains)


def floating_motions(mesh: MeshData, dec: Decomposition, rows: Rows, fixed: np.ndarray,
                     bs: int, parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                     x: np.ndarray | None = None, comp: np.ndarray | None = None
                     ) -> tuple[list[np.ndarray], list[str]]:
    """The rigid motions of the floating components that their fixed dofs allow.

    ``parts`` lists dof sets (e.g. one per rank) as ``(dof_node, dof_comp, dof_sub)``: the
    global node, component and subdomain of each dof; ``x`` holds the coordinates of the dof
    points numbering the nodes (default: the vertices); ``comp`` the component of every
    subdomain (default: joined by equality rows, :func:`components`; FETI-DP:
    :func:`primal_components`).

    Returns:
        Per part, the motions at its dofs, n × m with the same m columns for every part (zero
        on fixed dofs), and the bodies of each column.
    """
    x = mesh.x if x is None else x
    comp = components(rows, dec.num_subdomains) if comp is None else comp
    columns: list[list[np.ndarray]] = [[] for _ in parts]
    bodies: list[str] = []
    for c in range(int(comp.max(initial=-1)) + 1):
        subs = np.flatnonzero(comp == c)
        nodes = np.unique(dec.pair_node[np.isin(dec.pair_sub, subs)])
        centre, scale = C._scaled(x[nodes])
        free = C._free_motions(rigid_motions(x[nodes], bs, centre, scale).reshape(
            nodes.size, bs, -1)[fixed[nodes]])
        if free.shape[1] == 0:
            continue
        for out, (dof_node, dof_comp, dof_sub) in zip(columns, parts, strict=True):
            mine = np.flatnonzero(np.isin(dof_sub, subs))
            Z = np.zeros((dof_node.size, free.shape[1]))
            Z[mine] = motions_at(x[dof_node[mine]], dof_comp[mine], bs, centre, scale, free)
            Z[fixed[dof_node, dof_comp]] = 0.0
            out.append(Z)
        bodies += [body_label(mesh.body_names, dec.sub_body[subs])] * free.shape[1]
    Z = [np.hstack(cols) if cols else np.zeros((p[0].size, 0))
         for cols, p in zip(columns, parts, strict=True)]
    return Z, bodies
