"""What FETI-DP keeps primal, and the rigid motions of the floating bodies, from the geometry.

Both are chosen here, on the global arrays of the mesh and the decomposition (the same on every
rank), and handed to the algebraic transform :class:`~dolfinx_feti.feti.corners.EliminateCorners`
as plain arrays.

Corners. The interface nodes (in two or more subdomains) fall into *globs*: the nodes with the
same set of subdomains and the same position (on the outer boundary or not). A glob of one node
is a vertex: a cross point of three or more subdomains, or the end of an interface on the outer
boundary. The vertices are the corners, as in the seed's FETI-DP (2D: 2 × 2 subdomains per
body give 5 corners per body). In 3D the vertices alone leave the dual operator badly
conditioned (a classic result of FETI-DP theory, and what bench/hertz3d_fetidp.py measures), so
``edges=True`` takes the edges whole: every interface node outside the faces shared by two
subdomains inside the body. Then every two subdomains that share a facet must be joined
rigidly by the corners they share (together with the dofs both hold fixed): the relative rigid
motions of the pair must have no kernel on those dofs. Where they do (irregular decompositions),
shared interface nodes are added, greedily the one that removes most of what is left. This
makes every K_rr nonsingular and S_cc singular only by the rigid motions of floating bodies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..constraints.rows import Kind, Rows
from ..mesh.checks import boundary_facets
from ..mesh.decompose import Decomposition
from ..mesh.gmsh_input import MeshData
from ..mesh.topology import facet_neighbours
from .rigid import rigid_motions

#: Eigenvalues of a Gram matrix of rigid-motion rows (coordinates scaled to O(1)) below this
#: times its trace count as zero.
RANK_RTOL = 1e-10


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


def _free_motions(Y: np.ndarray) -> np.ndarray:
    """Orthonormal basis (k × r) of the motions a with Y a = 0, for rows Y (m × k)."""
    k = Y.shape[1]
    if Y.shape[0] == 0:
        return np.eye(k)
    G = Y.T @ Y
    w, V = np.linalg.eigh(G)
    return V[:, w <= RANK_RTOL * max(np.trace(G), 1e-300)]


def _scaled(x: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and size of a point set (for well-scaled rigid motions)."""
    lo, hi = x.min(axis=0), x.max(axis=0)
    return 0.5 * (lo + hi), max(float(np.linalg.norm(hi - lo)), 1e-300)


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
    width = int(mult.max(initial=0))
    key = np.full((inter.size, width + 1), -1, dtype=np.int64)
    pos = ptr[inter][:, None] + np.arange(width)
    valid = np.arange(width) < mult[inter][:, None]
    key[:, :width] = np.where(valid, subs[np.minimum(pos, subs.size - 1)], -1)
    key[:, width] = on_boundary[inter]
    _, inverse, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    corner = np.zeros(N, dtype=bool)
    corner[inter[count[inverse.ravel()] == 1]] = True
    if edges:  # every interface node outside the faces (two subdomains, inside the body)
        corner[inter[(mult[inter] >= 3) | on_boundary[inter]]] = True
    avoided = np.zeros(N, dtype=bool)
    if avoid is not None:
        avoided[avoid] = True
        corner &= ~avoided
    vertices = int(corner.sum())

    # every pair of subdomains sharing a facet is joined rigidly by its shared corners
    cells = facet_neighbours(mesh.cells, mesh.cell_type)
    pair = np.sort(dec.cell_sub[cells], axis=1)
    pair = np.unique(pair[pair[:, 0] != pair[:, 1]], axis=0)
    x = mesh.x if x is None else x
    held = {}
    for s, t in pair:
        both = np.intersect1d(dec.nodes(int(s)), dec.nodes(int(t)), assume_unique=True)
        centre, scale = _scaled(x[both])
        Y = rigid_motions(x[both], bs, centre, scale).reshape(both.size, bs, -1)
        if all(_held(held, dec, x, fixed, bs, int(u)) for u in (s, t)):
            continue
        rows = Y[corner[both][:, None] & np.ones(bs, dtype=bool) | fixed[both]]
        free = _free_motions(rows)
        while free.shape[1]:
            cand = np.flatnonzero(~corner[both])
            if cand.size == 0:
                break
            score = np.linalg.norm(Y[cand] @ free, axis=(1, 2))
            score[avoided[both[cand]]] *= 1e-6  # only if nothing else helps
            best = int(np.argmax(score))
            if not score[best] > 1e-14:
                break
            corner[both[cand[best]]] = True
            rows = np.concatenate([rows, Y[cand[best]]])
            free = _free_motions(rows)
    nodes = np.flatnonzero(corner)
    unknown = corner[:, None] & ~fixed
    index = np.full((N, bs), -1, dtype=np.int64)
    index[unknown] = np.arange(int(unknown.sum()))
    return Corners(nodes=nodes, index=index, count=int(unknown.sum()), vertices=vertices)


def _held(cache: dict, dec: Decomposition, x: np.ndarray, fixed: np.ndarray, bs: int,
          s: int) -> bool:
    """Whether subdomain ``s`` is held rigidly by its Dirichlet conditions alone."""
    if s not in cache:
        nodes = dec.nodes(s)
        f = fixed[nodes]
        if not f.any():
            cache[s] = False
        else:
            centre, scale = _scaled(x[nodes])
            Y = rigid_motions(x[nodes], bs, centre, scale).reshape(nodes.size, bs, -1)
            cache[s] = _free_motions(Y[f]).shape[1] == 0
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
    cells = facet_neighbours(mesh.cells, mesh.cell_type)
    pair = dec.cell_sub[cells]
    pair = pair[pair[:, 0] != pair[:, 1]]
    n = dec.num_subdomains
    graph = sp.coo_matrix((np.ones(pair.shape[0]), (pair[:, 0], pair[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


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
        centre, scale = _scaled(x[nodes])
        Y = rigid_motions(x[nodes], bs, centre, scale).reshape(nodes.size, bs, -1)
        free = _free_motions(Y[fixed[nodes]])
        if free.shape[1] == 0:
            continue
        for out, (dof_node, dof_comp, dof_sub) in zip(columns, parts, strict=True):
            mine = np.flatnonzero(np.isin(dof_sub, subs))
            Z = np.zeros((dof_node.size, free.shape[1]))
            Yl = rigid_motions(x[dof_node[mine]], bs, centre, scale).reshape(
                mine.size, bs, Y.shape[2])[np.arange(mine.size), dof_comp[mine]]
            Z[mine] = Yl @ free
            Z[fixed[dof_node, dof_comp]] = 0.0
            out.append(Z)
        names = sorted({mesh.body_names[b] for b in dec.sub_body[subs]})
        bodies += ["+".join(names)] * free.shape[1]
    Z = [np.hstack(cols) if cols else np.zeros((p[0].size, 0))
         for cols, p in zip(columns, parts, strict=True)]
    return Z, bodies
