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
from ..mesh.data import MeshData
from ..mesh.decompose import Decomposition
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
    return free_of_gram(Y.T @ Y, Y.shape[0])


def free_of_gram(G: np.ndarray, rows: int) -> np.ndarray:
    """:func:`_free_motions` from the Gram matrix ``G = YᵀY`` of ``rows`` rows (k × k)."""
    if rows == 0:
        return np.eye(G.shape[0])
    w, V = np.linalg.eigh(G)
    return V[:, w <= RANK_RTOL * max(np.trace(G), 1e-300)]


def _scaled(x: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and size of a point set (for well-scaled rigid motions)."""
    return box_scale(x.min(axis=0), x.max(axis=0))


def box_scale(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and size of the bounding box ``[lo, hi]``."""
    return 0.5 * (lo + hi), max(float(np.linalg.norm(hi - lo)), 1e-300)


def scaled_motions(x: np.ndarray, bs: int) -> np.ndarray:
    """The rigid motions at points ``x`` scaled by their own box, (n, bs, k)."""
    centre, scale = _scaled(x)
    return rigid_motions(x, bs, centre, scale).reshape(x.shape[0], bs, -1)


def glob_keys(ptr: np.ndarray, subs: np.ndarray, points: np.ndarray, on_boundary: np.ndarray,
              width: int) -> np.ndarray:
    """The glob key of each of ``points``.

    The key is the point's sorted subdomains (``subs[ptr[p]:ptr[p + 1]]``) padded with −1 to
    ``width``, then whether it lies on the outer boundary (``on_boundary``, one per point).
    """
    mult = np.diff(ptr)[points]
    key = np.full((points.size, width + 1), -1, dtype=np.int64)
    pos = ptr[points][:, None] + np.arange(width)
    valid = np.arange(width) < mult[:, None]
    key[:, :width] = np.where(valid, subs[np.minimum(pos, subs.size - 1)], -1)
    key[:, width] = on_boundary
    return key


def primal_globs(key: np.ndarray, edges: bool) -> np.ndarray:
    """Which points are primal, from the :func:`glob_keys` of all interface points.

    ``key`` holds one row per point. The vertices (a glob of one point) are primal, and with
    ``edges`` every point of three or more subdomains or on the outer boundary.
    """
    _, inverse, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    primal = count[inverse.ravel()] == 1
    if edges:
        primal |= ((key[:, :-1] >= 0).sum(axis=1) >= 3) | (key[:, -1] == 1)
    return primal


def _pair_rows(Y: np.ndarray, corner: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """The rigid-motion rows of the corners' components and of the fixed ones."""
    return Y[corner[:, None] & np.ones(Y.shape[1], dtype=bool) | fixed]


def joined_rigidly(Y: np.ndarray, corner: np.ndarray, fixed: np.ndarray) -> bool:
    """Whether the shared corners and fixed dofs join two subdomains rigidly.

    The arguments are those of :func:`join_pair`.
    """
    return _free_motions(_pair_rows(Y, corner, fixed)).shape[1] == 0


def join_pair(Y: np.ndarray, corner: np.ndarray, fixed: np.ndarray,
              avoided: np.ndarray | None = None) -> np.ndarray:
    """The shared points two subdomains need as corners to be joined rigidly (greedily).

    Args:
        Y: (n, bs, k) the rigid motions at the points both subdomains hold
            (:func:`scaled_motions`), in the order of their global numbers.
        corner: (n,) which of them are corners already.
        fixed: (n, bs) their Dirichlet mask.
        avoided: (n,) points to take only if nothing else helps.

    Returns:
        The positions of the points to add, in the order taken.
    """
    corner = corner.copy()
    rows = _pair_rows(Y, corner, fixed)
    free = _free_motions(rows)
    added = []
    while free.shape[1]:
        cand = np.flatnonzero(~corner)
        if cand.size == 0:
            break
        score = np.linalg.norm(Y[cand] @ free, axis=(1, 2))
        if avoided is not None:
            score[avoided[cand]] *= 1e-6  # only if nothing else helps
        best = int(np.argmax(score))
        if not score[best] > 1e-14:
            break
        corner[cand[best]] = True
        added.append(cand[best])
        rows = np.concatenate([rows, Y[cand[best]]])
        free = _free_motions(rows)
    return np.array(added, dtype=np.int64)


def held_alone(x: np.ndarray, fixed: np.ndarray, bs: int) -> bool:
    """Whether a subdomain is held rigidly by its Dirichlet conditions alone.

    ``x`` holds its points, ``fixed`` (n, bs) their Dirichlet mask.
    """
    if not fixed.any():
        return False
    return _free_motions(scaled_motions(x, bs)[fixed]).shape[1] == 0


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


def components_of_pairs(pairs: np.ndarray, n: int) -> np.ndarray:
    """Component of each of ``n`` subdomains in the graph of the subdomain ``pairs`` (P, 2)."""
    graph = sp.coo_matrix((np.ones(pairs.shape[0]), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
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
        free = _free_motions(rigid_motions(x[nodes], bs, centre, scale).reshape(
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


def motions_at(x: np.ndarray, comp: np.ndarray, bs: int, centre: np.ndarray, scale: float,
               free: np.ndarray) -> np.ndarray:
    """The free motions (columns of ``free``, k × m) at the dofs (points ``x``, ``comp``).

    The rigid motions are scaled by ``centre`` and ``scale`` (those of the component).
    """
    Y = rigid_motions(x, bs, centre, scale).reshape(x.shape[0], bs, free.shape[0])
    return Y[np.arange(x.shape[0]), comp] @ free


def body_label(body_names, bodies: np.ndarray) -> str:
    """The name of a component's motions: the names of its bodies, sorted, joined by '+'."""
    return "+".join(sorted({body_names[b] for b in bodies}))
