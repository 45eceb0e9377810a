"""What FETI-DP keeps primal, and the rigid motions of the floating bodies: the kernels.

:mod:`.distributed_corners` chooses both from every rank's share with the kernels here (per
glob, per pair of subdomains, per component) and hands them to the algebraic transform
:class:`~dolfinx_feti.feti.corners.EliminateCorners` as plain arrays. The same choice made on
the global arrays of a whole mesh (``choose_corners``, ``floating_motions``: the set-up before
issue 21) is the tests' oracle, ``tests/support/serial_setup.py``.

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

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .rigid import rigid_motions

#: Eigenvalues of a Gram matrix of rigid-motion rows (coordinates scaled to O(1)) below this
#: times its trace count as zero.
RANK_RTOL = 1e-10


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


def components_of_pairs(pairs: np.ndarray, n: int) -> np.ndarray:
    """Component of each of ``n`` subdomains in the graph of the subdomain ``pairs`` (P, 2)."""
    graph = sp.coo_matrix((np.ones(pairs.shape[0]), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


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
