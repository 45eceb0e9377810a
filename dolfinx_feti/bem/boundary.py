"""The boundary polygons of a rank's subdomains, from the cells the rank holds (P1, 2D).

A facet of a subdomain's cells that no other cell of the same subdomain has is on its
boundary; it is oriented so that its cell lies to its left (the outer boundary runs
counter-clockwise, holes clockwise: the outward normal is always (τ₂, −τ₁)). Each subdomain is
moved to its centre and scaled to a diameter of at most 1/2 for the integral operators: the 2D
single layer is positive definite only on a boundary of diameter below 1 (Steinbach 2008),
and the Steklov–Poincaré operator of the Laplace and Lamé equations does not change under a
scaling (both ∂_n and ds scale, their product does not).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..mesh.topology import cell_facets
from .galerkin import BoundaryMesh


@dataclass
class Boundaries:
    """The boundaries of a rank's subdomains.

    Attributes:
        mesh: The scaled boundary polygons, one per local subdomain, in the order of ``subs``.
        pair: Per node of ``mesh``, the rank's (subdomain, point) pair it is (local index).
        x: Per node of ``mesh``, its coordinates (unscaled).
        centre: Per subdomain, the centre it was moved to.
        scale: Per subdomain, the factor its coordinates were multiplied by.
    """

    mesh: BoundaryMesh
    pair: np.ndarray
    x: np.ndarray
    centre: np.ndarray
    scale: np.ndarray

    def scaled(self, X: np.ndarray, sub: np.ndarray) -> np.ndarray:
        """Points ``X`` of the local subdomains ``sub`` (indices into ``subs``) scaled alike."""
        return (X - self.centre[sub]) * self.scale[sub, None]


def pair_keys(share) -> np.ndarray:
    """A sorted key per (subdomain, point) pair of the rank: local subdomain × points + point."""
    dec = share.dec
    return np.repeat(np.arange(dec.subs.size), np.diff(dec.pair_ptr)) * share.points.x.shape[0] \
        + dec.pair_node


def subdomain_boundaries(share) -> Boundaries:
    """The boundary polygon of every local subdomain of a rank's share.

    Raises:
        InputError: When a subdomain's boundary is not a union of closed polygons (it touches
            itself at a vertex).
    """
    dec, pts = share.dec, share.points
    nv = {"triangle": 3, "quadrilateral": 4}[share.mesh.cell_type]
    cells = pts.cell_points[:, :nv]
    x = pts.x[:, :2]
    local = np.searchsorted(dec.subs, dec.cell_sub)  # local subdomain of each cell
    f = cell_facets(cells, share.mesh.cell_type)
    nf = f.shape[1]
    F = f.reshape(-1, 2)
    fs = np.repeat(local, nf)
    fc = np.repeat(np.arange(cells.shape[0]), nf)
    lo, hi = F.min(axis=1), F.max(axis=1)
    order = np.lexsort((hi, lo, fs))
    key = np.stack([fs[order], lo[order], hi[order]], axis=1)
    first = np.r_[True, np.any(key[1:] != key[:-1], axis=1)]
    count = np.diff(np.r_[np.flatnonzero(first), order.size])
    single = order[np.flatnonzero(first)[count == 1]]
    F, fs, fc = F[single], fs[single], fc[single]
    # the cell to the left of each boundary facet
    centroid = x[cells[fc]].mean(axis=1)
    t = x[F[:, 1]] - x[F[:, 0]]
    c = centroid - x[F[:, 0]]
    flip = t[:, 0] * c[:, 1] - t[:, 1] * c[:, 0] < 0
    F[flip] = F[flip][:, ::-1]
    by_sub = np.argsort(fs, kind="stable")
    F, fs = F[by_sub], fs[by_sub]
    nsub = dec.subs.size
    npts = x.shape[0]
    node_key, inv = np.unique(fs[:, None] * npts + F, return_inverse=True)
    inv = inv.reshape(-1, 2)
    node_sub, node_pt = node_key // npts, node_key % npts
    starts = np.bincount(inv[:, 0], minlength=node_key.size)
    ends = np.bincount(inv[:, 1], minlength=node_key.size)
    bad = (starts != 1) | (ends != 1)
    if np.any(bad):
        s = int(dec.subs[node_sub[np.flatnonzero(bad)[0]]])
        raise InputError(f"TBETI: the boundary of subdomain {s} is not a union of closed "
                         "polygons (it touches itself at a vertex); choose another decomposition")
    elem_off = np.r_[0, np.cumsum(np.bincount(fs, minlength=nsub))].astype(np.int64)
    node_off = np.r_[0, np.cumsum(np.bincount(node_sub, minlength=nsub))].astype(np.int64)
    pair = np.searchsorted(pair_keys(share), node_key)
    xb = x[node_pt]
    lo_box = np.minimum.reduceat(xb, node_off[:-1], axis=0)
    hi_box = np.maximum.reduceat(xb, node_off[:-1], axis=0)
    centre = 0.5 * (lo_box + hi_box)
    scale = 0.5 / np.linalg.norm(hi_box - lo_box, axis=1)
    xs = (xb - centre[node_sub]) * scale[node_sub, None]
    return Boundaries(mesh=BoundaryMesh(xs, inv, node_off, elem_off), pair=pair, x=xb,
                      centre=centre, scale=scale)


__all__ = ["Boundaries", "pair_keys", "subdomain_boundaries"]
