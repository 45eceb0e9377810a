"""Self-contact: the pairs of facets of one surface that may touch each other, each pair once.

A :class:`~dolfinx_feti.Mortar` condition whose slave and master are the same boundary group
couples that surface to itself. The search of :func:`.mortar.candidate_pairs` then also
returns pairs a surface forms with itself without any contact in sight, which are dropped
here:

- a facet and its own neighbourhood (the facets sharing a vertex with it: the surface goes
  on there, it does not touch);
- facets that do not face each other from the outside: each facet's centroid must lie in
  front of the other facet (along its outward normal, up to a quarter of the two facets'
  sizes, which allows a small penetration), so that the two sides of a thin wall, which face
  each other through the material, are no pair.

What is left is two-sided: a facet A facing B gives the pair (A, B) and the pair (B, A), and
rows on both sides would hold the same gap twice (redundant rows, the contact force split
between them arbitrarily). So each pair is kept in one orientation only, chosen per contact
zone rather than per facet so that every slave facet keeps all its master facets (the mortar
integrals of a slave node need its whole support): the facets that take part in some pair
are grouped into zones (connected through shared vertices), numbered by their first facet
(the group's order: the same on every rank), and a pair is kept with the facet of the lower
zone as the slave. Within one zone facing itself (a surface folded onto itself without a
break in between) the slave is the facet whose normal points along the first positive
direction of :data:`TIE_BREAK`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

#: Each facet's centroid may lie behind the other facet by this times the facets' sizes.
FRONT_TOL = 0.25
#: The orientation of the pairs of a zone facing itself: the slave's normal · this > 0.
TIE_BREAK = np.array([0.5773502691896258, 0.8164965809277261, 0.0])


def one_sided_pairs(x: np.ndarray, facets: np.ndarray, normals: np.ndarray, i: np.ndarray,
                    j: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The candidate pairs (i, j) of a surface with itself that may be a contact, once each.

    Args:
        x: Node coordinates.
        facets: The surface's facets (node numbers).
        normals: Their outward unit normals.
        i: Slave facet of each candidate pair (from :func:`.mortar.candidate_pairs`).
        j: Master facet of each candidate pair (of the same surface).

    Returns:
        The kept (i, j), sorted by slave then master facet, and the zone of every facet
        (−1 for a facet in no kept pair).
    """
    # Facets sharing a vertex (the facet itself included): one surface, not a contact.
    share = (facets[i][:, :, None] == facets[j][:, None, :]).any(axis=(1, 2))
    c = x[facets].mean(axis=1)
    r = np.linalg.norm(x[facets] - c[:, None], axis=2).max(axis=1)
    d = c[j] - c[i]
    tol = FRONT_TOL * (r[i] + r[j])
    front = (np.einsum("ij,ij->i", d, normals[i]) >= -tol) & \
        (np.einsum("ij,ij->i", d, normals[j]) <= tol)
    keep = ~share & front
    i, j = i[keep], j[keep]
    zone = _zones(facets, np.union1d(i, j))
    tie = np.einsum("ij,j->i", normals[i], TIE_BREAK[:normals.shape[1]]) > 0.0
    keep = (zone[i] < zone[j]) | ((zone[i] == zone[j]) & tie)
    i, j = i[keep], j[keep]
    order = np.lexsort((j, i))
    return i[order], j[order], zone


def _zones(facets: np.ndarray, used: np.ndarray) -> np.ndarray:
    """The connected pieces (through shared vertices) of the ``used`` facets, else −1.

    The pieces are numbered in the order of their first facet.
    """
    zone = np.full(facets.shape[0], -1, dtype=np.int64)
    if used.size == 0:
        return zone
    f = facets[used]
    nodes, local = np.unique(f, return_inverse=True)
    local = local.reshape(f.shape)
    inc = sp.csr_matrix((np.ones(local.size), (np.repeat(np.arange(used.size), f.shape[1]),
                                               local.ravel())), shape=(used.size, nodes.size))
    _, label = connected_components(inc @ inc.T, directed=False)
    # connected_components numbers the pieces in the order of their first vertex of the
    # graph, which is the order of the used facets: the first facet of each piece decides.
    zone[used] = label
    return zone
