"""Clipping of convex polygons in a plane, many pairs at once (mortar overlaps)."""

from __future__ import annotations

import numpy as np


def clip_polygons(subject: np.ndarray, count: np.ndarray, clip: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Sutherland–Hodgman clipping of many polygon pairs at once.

    Convex polygons ``subject`` (P, V, 2) with ``count`` vertices each are clipped by
    counter-clockwise convex polygons ``clip`` (P, C, 2) (triangles or quadrilaterals);
    returns the polygons and their counts. A polygon clipped away by one edge stays empty:
    only the others are carried on.
    """
    P = subject.shape[0]
    alive = np.flatnonzero(count > 0)
    subject, count, clip = subject[alive], count[alive], clip[alive]
    C = clip.shape[1]
    for e in range(C):  # over the 3 or 4 edges of the clipping polygons
        p0, p1 = clip[:, e], clip[:, (e + 1) % C]
        edge = p1 - p0

        def side(v, p0=p0, edge=edge):  # > 0 inside (left of a counter-clockwise edge)
            return edge[..., 0] * (v[..., 1] - p0[..., 1]) - edge[..., 1] * (v[..., 0] - p0[..., 0])

        n, V = subject.shape[:2]
        rng = np.arange(n)
        out = np.zeros((n, 2 * V, 2))
        n_out = np.zeros(n, dtype=np.int64)
        for k in range(V):
            valid = k < count
            cur = subject[:, k]
            nxt = subject[rng, (k + 1) % np.maximum(count, 1)]
            sc, sn = side(cur), side(nxt)
            inc, inn = sc >= 0.0, sn >= 0.0
            denom = np.where(sc - sn == 0.0, 1.0, sc - sn)
            cross = cur + (sc / denom)[:, None] * (nxt - cur)
            put = valid & (inc != inn)  # the edge crosses the clip line: its crossing point
            out[rng[put], n_out[put]] = cross[put]
            n_out += put
            put = valid & inn  # the end point is inside
            out[rng[put], n_out[put]] = nxt[put]
            n_out += put
        # At most V + C vertices survive the C edges: keep only the columns in use.
        subject, count = out[:, :max(int(n_out.max(initial=0)), 1)], n_out
        live = count > 0
        alive, subject, count, clip = alive[live], subject[live], count[live], clip[live]
    poly = np.zeros((P, subject.shape[1], 2))
    poly[alive] = subject
    counts = np.zeros(P, dtype=np.int64)
    counts[alive] = count
    return poly, counts


def fan_quadrature(poly: np.ndarray, count: np.ndarray, rule_x: np.ndarray,
                   rule_w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Quadrature points of convex polygons, each cut into a fan of triangles about its centroid.

    A fan about a vertex has fewer triangles, but slivers: on trapezoids a rational
    integrand's error grows a hundredfold.

    Args:
        poly: Polygons (P, V, 2), ``count`` (P,) vertices each (>= 3).
        count: The number of vertices of each polygon.
        rule_x: A rule's points on the reference triangle (Q, 2) ...
        rule_w: ... and its weights relative to the triangle's area (Q,).

    Returns:
        ``(first, pair, q, w)``: the first triangle of each polygon, the polygon of each
        triangle (T,), the points (T, Q, 2) and their weights (T, Q), listed polygon after
        polygon (so ``np.add.reduceat(..., first)`` sums per polygon).
    """
    first = np.cumsum(count) - count
    pair = np.repeat(np.arange(count.size), count)
    k = np.arange(pair.size) - first[pair]
    v0 = (poly.sum(axis=1) / count[:, None])[pair]
    e1 = poly[pair, k] - v0
    e2 = poly[pair, (k + 1) % count[pair]] - v0
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    q = v0[:, None] + rule_x[None, :, 0:1] * e1[:, None] + rule_x[None, :, 1:2] * e2[:, None]
    return first, pair, q, area[:, None] * rule_w

