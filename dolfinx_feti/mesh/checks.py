"""Sanity checks of a mesh before any heavy work: cells, conformity, contact surfaces.

Each check raises :class:`~dolfinx_feti.errors.InputError` with a message that names the fault,
the body and an example position (with the gmsh node tags), so that a broken mesh is refused
before anything is assembled or written, identically on every rank (all inputs are the global
arrays of :class:`~dolfinx_feti.mesh.gmsh_input.MeshData`).

- :func:`check_mesh` (called by :func:`~dolfinx_feti.read_gmsh` and by
  :class:`~dolfinx_feti.ContactProblem`): finite coordinates, cells that refer to existing
  nodes, no empty body, no degenerate cell (zero area/volume), no inverted cell (two cells on
  the same side of their common facet: the mesh folds over itself), no facet in more than two
  cells (overlapping cells).
- :func:`check_conforming` (called by :class:`~dolfinx_feti.ContactProblem`): no boundary node
  of a body lies on a boundary facet of the same body without being one of its vertices — two
  pieces of one body that touch without sharing their nodes (coincident duplicate nodes, or
  hanging nodes of non-matching meshes) are not glued, and the body would silently have a
  crack there. Nodes on contact surfaces are exempt.
- :func:`check_boundary_group` (for contact surfaces, the loaded groups of
  :class:`~dolfinx_feti.Elasticity` and :class:`~dolfinx_feti.Poisson`, and every
  ``sub.ds(group)`` of a forms callback): the group consists of boundary facets (a facet
  between two cells has no outward side, and ``ds`` over it would count it only where a
  subdomain boundary passes).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from .data import MeshData
from .topology import (
    cell_facets,
    cell_volumes,
    corner_jacobians,
    facet_index,
    facets_per_cell,
    reference,
    row_keys,
)

#: A cell with |volume| <= DEGENERATE_RTOL · (its longest edge)^tdim has no volume.
DEGENERATE_RTOL = 1e-10
#: A node within CONFORMING_RTOL · (the facet's diameter) of a boundary facet lies on it.
CONFORMING_RTOL = 1e-6

_CHECKED: list = []  # the arrays of the last mesh that passed check_mesh (identity)
_CONFORMING: list = []  # (x, cells, cell_body, result) of the last conformity computation


def _where(mesh: MeshData, nodes) -> str:
    """Positions and gmsh tags of a few nodes, for messages."""
    nodes = np.atleast_1d(np.asarray(nodes))
    tags = mesh.node_tags[nodes] if mesh.node_tags.size == mesh.num_nodes else nodes
    pts = ", ".join(f"{np.round(mesh.x[n], 9).tolist()} (node {int(t)})"
                    for n, t in zip(nodes, tags, strict=True))
    return pts


def _body(mesh: MeshData, cell: int) -> str:
    return repr(mesh.body_names[int(mesh.cell_body[cell])])


def check_mesh(mesh: MeshData) -> None:
    """Refuse a mesh that is no valid finite element mesh (see the module docstring).

    Raises:
        InputError: Naming the fault, the body and an example position.
    """
    if _CHECKED and _CHECKED[0] is mesh.x and _CHECKED[1] is mesh.cells:
        return
    x, cells = mesh.x, mesh.cells
    if not np.all(np.isfinite(x)):
        bad = np.flatnonzero(~np.isfinite(x).all(axis=1))
        raise InputError(f"the mesh has {bad.size} nodes with non-finite coordinates (NaN or "
                         f"Inf), e.g. node {int(mesh.node_tags[bad[0]])} at "
                         f"{x[bad[0]].tolist()}")
    if cells.size and (cells.min() < 0 or cells.max() >= mesh.num_nodes):
        raise InputError("the mesh's cells refer to nodes that do not exist")
    counts = np.bincount(mesh.cell_body, minlength=len(mesh.body_names))
    if np.any(counts == 0):
        empty = [mesh.body_names[b] for b in np.flatnonzero(counts == 0)]
        raise InputError(f"empty physical groups: bodies {empty} (physical groups of dimension "
                         f"{mesh.tdim}) hold no cell; the bodies with cells are "
                         f"{[n for n, c in zip(mesh.body_names, counts, strict=True) if c]}")
    _check_degenerate(mesh)
    _check_folds(mesh)
    _check_bodies_apart(mesh)
    _CHECKED[:] = [x, cells]


def mark_checked(mesh: MeshData) -> None:
    """Record that ``mesh`` passed :func:`check_mesh`, so that the next call returns at once.

    For a copy broadcast from the rank that checked it.
    """
    _CHECKED[:] = [mesh.x, mesh.cells]


def _check_degenerate(mesh: MeshData) -> None:
    x, cells, tdim = mesh.x, mesh.cells, mesh.tdim
    ref = reference(cells, mesh.cell_type)
    longest = np.zeros(cells.shape[0])
    for a, b in ref.edges:  # the 3 to 12 edges of a cell
        longest = np.maximum(longest, np.linalg.norm(x[cells[:, a]] - x[cells[:, b]], axis=1))
    if ref.simplex:
        vol = np.abs(cell_volumes(x, cells, mesh.cell_type))
        folded = np.zeros(cells.shape[0], dtype=bool)
    else:  # every corner of a quadrilateral/hexahedron must span a volume, all of one sign
        J = corner_jacobians(x, cells, mesh.cell_type)
        vol = np.abs(J).min(axis=1)
        folded = (J.max(axis=1) > 0) & (J.min(axis=1) < 0)
    bad = np.flatnonzero((vol <= DEGENERATE_RTOL * longest**tdim) & ~folded)
    if bad.size:
        c = bad[0]
        what = "area" if tdim == 2 else "volume"
        raise InputError(
            f"the mesh has {bad.size} degenerate cells (zero {what}: flat or with a repeated "
            f"node), e.g. cell {int(c)} of body {_body(mesh, c)} with nodes at "
            f"{_where(mesh, cells[c])}; remesh (or remove the cells)")
    if np.any(folded):
        c = int(np.flatnonzero(folded)[0])
        raise InputError(
            f"the mesh has {int(folded.sum())} folded (self-intersecting) {mesh.cell_type} "
            f"cells, e.g. cell {c} of body {_body(mesh, c)} with nodes at "
            f"{_where(mesh, cells[c])}: its corners do not all turn the same way (vertices "
            "out of order, or a non-convex cell); remesh")


def _check_folds(mesh: MeshData) -> None:
    """Facets in more than two cells; neighbours on the same side of their common facet."""
    x, cells, tdim, ct = mesh.x, mesh.cells, mesh.tdim, mesh.cell_type
    if cells.shape[0] < 2:
        return
    nf = facets_per_cell(cells, ct)
    keys, order, _ = facet_index(cells, ct)
    same = keys[1:] == keys[:-1]
    triple = same[1:] & same[:-1]
    if np.any(triple):
        i = int(np.flatnonzero(triple)[0])
        cs = order[i:i + 3] // nf
        raise InputError(
            f"the mesh has {int(triple.sum())} facets shared by more than two cells (the cells "
            f"overlap), e.g. cells {cs.tolist()} of bodies "
            f"{', '.join(sorted({_body(mesh, c) for c in cs}))} at the facet with nodes at "
            f"{_where(mesh, np.sort(cell_facets(cells[cs[:1]], ct)[0, order[i] % nf]))}")
    if mesh.gdim != tdim:
        return  # no orientation to compare for a surface mesh in 3D
    i = np.flatnonzero(same)
    c1, l1 = order[i] // nf, order[i] % nf
    c2 = order[i + 1] // nf
    facet = np.sort(cell_facets(cells, ct)[c1, l1], axis=1)  # the same node order for both sides
    p = x[facet]
    base = p[:, 1:tdim] - p[:, :1]  # (P, tdim - 1, gdim): tdim vertices span the facet's plane

    def side(c):  # the side of the cell's centroid (of the opposite vertex for a simplex):
        # det[base; centroid - p_0], written out (np.linalg.det is one LAPACK call a row)
        d = x[cells[c]].mean(axis=1) - p[:, 0]
        if tdim == 2:
            return base[:, 0, 0] * d[:, 1] - base[:, 0, 1] * d[:, 0]
        return np.einsum("ij,ij->i", np.cross(base[:, 0], base[:, 1]), d)

    s1, s2 = side(c1), side(c2)
    bad = np.flatnonzero(s1 * s2 >= 0.0)
    if bad.size:
        k = bad[0]
        a, b = int(c1[k]), int(c2[k])
        raise InputError(
            f"the mesh has inverted cells: at {bad.size} facets the two cells that share the "
            f"facet lie on the same side of it (the mesh folds over itself), e.g. cells {a} and "
            f"{b} of bodies {', '.join(sorted({_body(mesh, a), _body(mesh, b)}))} at the facet "
            f"with nodes "
            f"at {_where(mesh, facet[k])}; a node was moved across an opposite facet: remesh")


def overlapping_cells(mesh: MeshData, neighbours: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Boundary cells of one body whose centre lies strictly inside a cell of another body.

    Two bodies that overlap have a piece of boundary of one inside the other, so only the
    cells at the boundary are tested, each against the cells with the ``neighbours`` nearest
    centres (a containing cell is among them on any reasonable mesh).

    Returns:
        ``(inner, outer)``: the cells whose centre is inside, and the cells containing it.
    """
    none = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
    x, cells, tdim = mesh.x, mesh.cells, mesh.tdim
    if len(mesh.body_names) < 2 or mesh.gdim != tdim or cells.shape[0] < 2:
        return none
    pts = x[cells]  # (C, vertices, gdim)
    centre = pts.mean(axis=1)
    inner = np.unique(boundary_facets(mesh)[1])
    k = min(neighbours, cells.shape[0])
    _, near = cKDTree(centre).query(centre[inner], k=k)
    inner, outer = np.repeat(inner, k), near.reshape(-1)
    other = mesh.cell_body[outer] != mesh.cell_body[inner]
    outer, inner = outer[other], inner[other]
    if outer.size == 0:
        return none
    # A quadrilateral/hexahedron is tested as its Kuhn simplices (2 or 6, about the diagonal
    # from vertex 0 to the last one in tensor order), a simplex as itself.
    split = _KUHN.get(mesh.cell_type, [list(range(tdim + 1))])
    inside = np.zeros(outer.size, dtype=bool)
    for simplex in split:  # over the 1 to 6 simplices of a cell, not over cells
        q = pts[outer][:, simplex]
        T = np.swapaxes(q[:, 1:] - q[:, :1], 1, 2)  # (P, gdim, tdim) edge vectors
        lam = np.linalg.solve(T, (centre[inner] - q[:, 0])[:, :, None])[:, :, 0]
        bary = np.concatenate([1.0 - lam.sum(axis=1, keepdims=True), lam], axis=1)
        inside |= bary.min(axis=1) > 1e-9
    return inner[inside], outer[inside]


#: Kuhn simplices of a quadrilateral and a hexahedron (tensor-order vertices).
_KUHN = {"quadrilateral": [[0, 1, 3], [0, 2, 3]],
         "hexahedron": [[0, 1 << a, (1 << a) | (1 << b), 7]
                        for a in range(3) for b in range(3) if a != b]}


def _check_bodies_apart(mesh: MeshData) -> None:
    """Refuse bodies that overlap in space (deeper than about a third of a cell)."""
    inner, outer = overlapping_cells(mesh)
    if inner.size == 0:
        return
    a, b = int(inner[0]), int(outer[0])
    pairs = sorted({tuple(sorted((_body(mesh, i), _body(mesh, o))))
                    for i, o in zip(inner, outer, strict=True)})
    centre = np.round(mesh.x[mesh.cells[a]].mean(axis=0), 9).tolist()
    raise InputError(
        f"bodies overlap in space: {np.unique(inner).size} cells have their centre inside a "
        f"cell of another body ({', '.join(' and '.join(p) for p in pairs)}), e.g. cell {a} of "
        f"body {_body(mesh, a)} centred at {centre} inside cell {b} of body {_body(mesh, b)} "
        f"with nodes at {_where(mesh, mesh.cells[b])}. Bodies are apart or touch along their "
        "boundaries; move them apart (an initial penetration shallower than about a third of "
        "a cell is accepted: contact pushes it out)")


def boundary_facets(mesh: MeshData) -> tuple[np.ndarray, np.ndarray]:
    """The facets that belong to one cell only, and that cell: ``(facets (F, nvf), cell)``."""
    ct = mesh.cell_type
    nf = facets_per_cell(mesh.cells, ct)
    keys, order, _ = facet_index(mesh.cells, ct)
    n = keys.size
    single = np.ones(n, dtype=bool)
    same = keys[1:] == keys[:-1]
    single[1:] &= ~same
    single[:-1] &= ~same
    pos = order[single]
    cell, local = pos // nf, pos % nf
    return cell_facets(mesh.cells, ct)[cell, local], cell


def _point_facet_distance(pts: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """Distance of each point to the facet (segment, triangle or quad) of the same row.

    A quadrilateral (tensor vertex order) is taken as its two triangles 0-1-3 and 0-3-2.
    """
    if facets.shape[1] == 4:
        return np.minimum(_point_facet_distance(pts, facets[:, [0, 1, 3]]),
                          _point_facet_distance(pts, facets[:, [0, 3, 2]]))
    a = facets[:, 0]
    if facets.shape[1] == 2:
        e = facets[:, 1] - a
        t = np.clip(np.einsum("ij,ij->i", pts - a, e) / np.einsum("ij,ij->i", e, e), 0.0, 1.0)
        return np.linalg.norm(pts - a - t[:, None] * e, axis=1)
    e1, e2 = facets[:, 1] - a, facets[:, 2] - a
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1)[:, None]
    d = pts - a
    h = np.einsum("ij,ij->i", d, n)
    q = d - h[:, None] * n  # in the facet's plane
    g11, g12, g22 = (np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e1, e2),
                     np.einsum("ij,ij->i", e2, e2))
    r1, r2 = np.einsum("ij,ij->i", q, e1), np.einsum("ij,ij->i", q, e2)
    det = g11 * g22 - g12 * g12
    u, v = (g22 * r1 - g12 * r2) / det, (g11 * r2 - g12 * r1) / det
    inside = (u >= -CONFORMING_RTOL) & (v >= -CONFORMING_RTOL) & (u + v <= 1 + CONFORMING_RTOL)
    return np.where(inside, np.abs(h), np.inf)


def nonconforming_nodes(mesh: MeshData) -> tuple[np.ndarray, np.ndarray]:
    """Boundary nodes of a body that lie on a boundary facet of the same body, not its vertex.

    Returns:
        ``(node, facet)``: the nodes and, for each, one such facet (global node indices).
    """
    c = _CONFORMING
    if c and c[0] is mesh.x and c[1] is mesh.cells and c[2] is mesh.cell_body:
        return c[3]
    facets, cell = boundary_facets(mesh)
    body = mesh.cell_body[cell]
    out_node, out_facet = [], []
    for b in np.unique(body):
        F = facets[body == b]
        nodes = np.unique(F)
        pts = mesh.x[F]
        center = pts.mean(axis=1)
        radius = np.linalg.norm(pts - center[:, None, :], axis=2).max(axis=1)
        diam = 2.0 * radius
        cand = cKDTree(mesh.x[nodes]).query_ball_point(center, radius * (1 + 1e-6) + 1e-300)
        lens = np.fromiter((len(c) for c in cand), dtype=np.int64, count=len(cand))
        if lens.sum() == 0:
            continue
        fi = np.repeat(np.arange(F.shape[0]), lens)
        ni = nodes[np.concatenate([np.asarray(c, dtype=np.int64) for c in cand])]
        own = (F[fi] == ni[:, None]).any(axis=1)
        fi, ni = fi[~own], ni[~own]
        dist = _point_facet_distance(mesh.x[ni], pts[fi])
        hit = dist <= CONFORMING_RTOL * diam[fi]
        out_node.append(ni[hit])
        out_facet.append(F[fi[hit]])
    result = (np.concatenate(out_node) if out_node else np.zeros(0, dtype=np.int64),
              np.concatenate(out_facet) if out_facet else
              np.zeros((0, facets.shape[1]), dtype=np.int64))
    _CONFORMING[:] = [mesh.x, mesh.cells, mesh.cell_body, result]
    return result


def check_conforming(mesh: MeshData, exempt_groups: Iterable[str] = (),
                     found: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Refuse two pieces of one body that touch without sharing nodes (a hidden crack).

    Args:
        mesh: The mesh.
        exempt_groups: Boundary groups (the contact surfaces) whose nodes may lie on the body's
            other boundary facets.
        found: The result of :func:`nonconforming_nodes`, if already known (a distributed
            mesh keeps it from the check of the whole mesh at input).

    Raises:
        InputError: Naming the body, the number of such nodes and an example.
    """
    node, facet = nonconforming_nodes(mesh) if found is None else found
    exempt = [np.unique(mesh.facet_groups[g]) for g in exempt_groups if g in mesh.facet_groups]
    if exempt and node.size:
        keep = ~np.isin(node, np.concatenate(exempt))
        node, facet = node[keep], facet[keep]
    if node.size == 0:
        return
    size = np.ptp(mesh.x[facet], axis=1).max(axis=1)
    dist = np.linalg.norm(mesh.x[facet] - mesh.x[node][:, None, :], axis=2)
    coincident = dist <= CONFORMING_RTOL * size[:, None]  # (n, tdim): which vertex it sits on
    dup = coincident.any(axis=1)
    first = int(np.argmin(dup))  # an example of a hanging node if there is one
    owner = np.flatnonzero((mesh.cells == node[first]).any(axis=1))[0]
    if dup[first]:
        how = f"coincides with node {_where(mesh, facet[first][coincident[first]][:1])}"
    else:
        how = f"lies on the boundary facet with nodes at {_where(mesh, facet[first])}"
    n_dup = np.unique(node[dup]).size
    n_hang = np.unique(node[~dup]).size
    raise InputError(
        f"the mesh is not conforming in body {_body(mesh, owner)}: {np.unique(node).size} "
        f"boundary nodes lie on boundary facets of the same body without being their vertices "
        f"({n_dup} duplicate nodes at the position of another node, {n_hang} hanging nodes "
        f"inside a facet), e.g. the node at {_where(mesh, node[first])} {how}. Two pieces of "
        "the body touch there without sharing nodes, so they would not be glued (a hidden "
        "crack). Fragment the geometry (gmsh.model.occ.fragment) or merge the nodes "
        "(gmsh.model.mesh.removeDuplicateNodes); if the pieces are meant to be separate "
        "bodies in contact, give them different physical groups and a contact condition")


def check_contact_surface(mesh: MeshData, group: str) -> None:
    """Refuse a contact surface with facets inside the mesh (between two cells).

    Raises:
        InputError: Naming the group and the bodies on the two sides.
    """
    check_boundary_group(mesh, group, "contact surface",
                         "so they have no outward normal. A contact surface must be on the "
                         "boundary: bodies in contact need their own nodes there (do not "
                         "fragment or glue them together)")


def check_boundary_group(mesh: MeshData, group: str, what: str = "boundary group",
                         why: str = "") -> None:
    """Refuse a boundary group with facets inside the mesh (between two cells).

    A boundary integral ``ds`` over such facets would count them only where a subdomain
    boundary happens to pass (the answer would depend on the decomposition), and a contact
    surface there has no outward side.

    Raises:
        InputError: Naming the group, what it is used for and the bodies on the two sides.
    """
    f = mesh.facets(group)
    nf = facets_per_cell(mesh.cells, mesh.cell_type)
    keys, order, bound = facet_index(mesh.cells, mesh.cell_type)
    if not f.size or f.max() >= bound:
        return
    k = row_keys(f, bound)
    lo = np.searchsorted(keys, k, side="left")
    hi = np.searchsorted(keys, k, side="right")
    inner = np.flatnonzero(hi - lo >= 2)
    if inner.size == 0:
        return
    i = inner[0]
    cs = order[lo[i]:hi[i]] // nf
    bodies = " and ".join(sorted({_body(mesh, c) for c in cs}))
    raise InputError(
        f"{what} {group!r}: {inner.size} of its {f.shape[0]} facets lie inside the mesh, "
        f"between two cells (e.g. between bodies {bodies} at the facet with nodes at "
        f"{_where(mesh, f[i])}), "
        + (why or "where a boundary integral (ds) is not defined: its value would depend on "
           "the decomposition. Use a group of boundary facets"))


def unfit_groups(mesh: MeshData, check) -> dict[str, str]:
    """Group → the message of ``check(mesh, group)``, for the boundary groups it refuses.

    For verdicts made once on the whole mesh and applied later, when a problem says what it
    uses each group for (a ``{what}`` in a message stands for that use).
    """
    errors = {}
    for name in mesh.facet_groups:
        try:
            check(mesh, name)
        except InputError as e:
            errors[name] = str(e)
    return errors


def boundary_group_verdicts(mesh: MeshData) -> dict[str, str]:
    """:func:`unfit_groups` of :func:`check_boundary_group`, the use left as ``{what}``."""
    return unfit_groups(mesh, lambda m, name: check_boundary_group(m, name, "{what}"))


__all__ = ["boundary_facets", "boundary_group_verdicts", "check_boundary_group", "check_conforming",
           "check_contact_surface", "check_mesh", "nonconforming_nodes", "unfit_groups"]
